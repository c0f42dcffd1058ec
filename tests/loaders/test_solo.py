"""Solo-12 standing: free-flyer base, four feet held by point closures to the world.

Independent routes: Newton-Euler for the whole body (sum of contact forces = m (c_ddot - g),
moments = rate of centroidal angular momentum, both from Pinocchio's centroidal
algorithms, not from the closure multipliers), energy balance along the forward-dynamics
motion (finite differences of T + V), virtual power, and the three forward-dynamics routes.
"""

import numpy as np
import pinocchio as pin
import pytest
import scipy.linalg

from hexapod_pin.loaders import robots
from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree
from hexapod_pin.errors import ActuatorSaturationError, AssemblyError

from conftest import fd_constraint_jacobian, random_configuration

G = 9.81


@pytest.fixture(scope="module")
def solo():
    return robots.solo12()


@pytest.fixture(scope="module")
def standing(solo):
    return robots.solo12_stand(solo, [0.01, -0.005, 0.20], [0.02, 0.05, 0.1]).q


def _tau(clm, u):
    tau = np.zeros(clm.nv)
    tau[clm.actuated_v] = u
    return tau


def test_model_and_actuation(solo, standing):
    assert (solo.nq, solo.nv, solo.n_rows, solo.n_actuated) == (19, 18, 12, 12)
    assert solo.model.names[1] == "root_joint"
    report = robots.actuation_report(solo, standing)
    assert (report.rank, report.mobility, report.controlled) == (12, 6, 6)
    assert report.status == "redundant" and report.actuation_redundancy == 6
    assert report.sufficient


def test_standing_assembly_holds_the_base_and_the_feet(solo, standing):
    assert np.max(np.abs(solo.residual(standing))) <= 1e-10
    np.testing.assert_allclose(standing[:7], robots.base_configuration(
        [0.01, -0.005, 0.20], [0.02, 0.05, 0.1]), atol=0)
    data = solo.model.createData()
    pin.framesForwardKinematics(solo.model, data, standing)
    feet = robots.solo12_default_foot_positions()
    for foot, point in zip(robots.SOLO12_FEET, feet):
        np.testing.assert_allclose(data.oMf[solo.model.getFrameId(foot)].translation, point,
                                   atol=1e-10)
    assert np.all(feet[:, 2] == 0.0)
    # a base too high for the legs cannot be assembled
    with pytest.raises(AssemblyError):
        robots.solo12_stand(solo, [0.0, 0.0, 0.5])


def test_constraint_jacobian_matches_finite_differences(solo):
    q = random_configuration(solo.model, np.random.default_rng(7))
    np.testing.assert_allclose(solo.constraint_jacobian(q), fd_constraint_jacobian(solo, q),
                               atol=1e-8)


def test_static_torques_balance_the_weight(solo, standing):
    v, a = robots.motion_with_base(solo, standing, np.zeros(6), np.zeros(6))
    assert np.max(np.abs(v)) < 1e-14 and np.max(np.abs(a)) < 1e-12
    result = inverse_dynamics_tree(solo, standing, v, a, bounds=robots.SOLO12_TORQUE_LIMIT)
    forces = result.multipliers.reshape(4, 3)        # ground on each foot, world axes (N)
    mass = sum(solo.model.inertias[j].mass for j in range(solo.model.njoints))
    assert np.sum(forces[:, 2]) == pytest.approx(mass * G, rel=1e-10)
    np.testing.assert_allclose(np.sum(forces[:, :2], axis=0), 0.0, atol=1e-9)
    # moments about the centre of mass vanish (Euler's law at rest)
    data = solo.model.createData()
    com = pin.centerOfMass(solo.model, data, standing)
    pin.framesForwardKinematics(solo.model, data, standing)
    feet = [data.oMf[solo.model.getFrameId(f)].translation for f in robots.SOLO12_FEET]
    moment = sum(np.cross(p - com, f) for p, f in zip(feet, forces))
    np.testing.assert_allclose(moment, 0.0, atol=1e-9)
    assert np.all(np.abs(result.actuator_forces) <= robots.SOLO12_TORQUE_LIMIT)
    # holding still: forward dynamics of those torques gives zero acceleration
    for method in ("pinocchio", "qp", "kkt"):
        fd = forward_dynamics_tree(solo, standing, v, result.actuator_forces, method=method)
        np.testing.assert_allclose(fd.a, 0.0, atol=1e-9)


@pytest.mark.parametrize("seed", [2, 3])
def test_commanded_base_motion_is_reproduced_by_forward_dynamics(solo, standing, seed):
    rng = np.random.default_rng(seed)
    v_base = np.concatenate([0.1 * rng.normal(size=3), 0.3 * rng.normal(size=3)])
    a_base = np.concatenate([0.5 * rng.normal(size=3), 2.0 * rng.normal(size=3)])
    v, a = robots.motion_with_base(solo, standing, v_base, a_base)
    np.testing.assert_allclose(a[:6], a_base, atol=1e-12)
    inv = inverse_dynamics_tree(solo, standing, v, a, bounds=robots.SOLO12_TORQUE_LIMIT)
    assert inv.residual < 1e-9
    for method in ("pinocchio", "qp", "kkt"):
        fd = forward_dynamics_tree(solo, standing, v, inv.actuator_forces, method=method)
        np.testing.assert_allclose(fd.a[:6], a_base, atol=1e-8)
        np.testing.assert_allclose(fd.a, a, atol=1e-8)
    # Newton-Euler on the whole body, from Pinocchio's centroidal algorithms
    forces = inv.multipliers.reshape(4, 3)
    model, data = solo.model, solo.model.createData()
    mass = sum(model.inertias[j].mass for j in range(model.njoints))
    pin.centerOfMass(model, data, standing, v, a)
    np.testing.assert_allclose(forces.sum(axis=0), mass * (data.acom[0] - model.gravity.linear),
                               atol=1e-9)
    pin.computeCentroidalMomentumTimeVariation(model, data, standing, v, a)
    pin.framesForwardKinematics(model, data, standing)
    com = data.com[0]
    feet = [data.oMf[model.getFrameId(f)].translation for f in robots.SOLO12_FEET]
    moment = sum(np.cross(p - com, f) for p, f in zip(feet, forces))
    np.testing.assert_allclose(moment, data.dhg.angular, atol=1e-9)


def test_energy_and_virtual_power(solo, standing):
    rng = np.random.default_rng(4)
    v_base = np.concatenate([0.1 * rng.normal(size=3), 0.3 * rng.normal(size=3)])
    v, _ = robots.motion_with_base(solo, standing, v_base, np.zeros(6))
    u = rng.uniform(-1, 1, 12)
    fd = forward_dynamics_tree(solo, standing, v, u, method="kkt")
    model, data = solo.model, solo.model.createData()

    def energy(q, vel):
        return (pin.computeKineticEnergy(model, data, q, vel)
                + pin.computePotentialEnergy(model, data, q))

    h = 1e-4
    e_plus = energy(pin.integrate(model, standing, h * v + 0.5 * h * h * fd.a), v + h * fd.a)
    e_minus = energy(pin.integrate(model, standing, -h * v + 0.5 * h * h * fd.a), v - h * fd.a)
    power = u @ v[solo.actuated_v]                    # the closures do no work: J v = 0
    assert (e_plus - e_minus) / (2 * h) == pytest.approx(power, abs=1e-6)
    # virtual power: for every closure-consistent virtual velocity the closure forces vanish
    null = scipy.linalg.null_space(solo.constraint_jacobian(standing))
    jac = solo.constraint_jacobian(standing)
    np.testing.assert_allclose(null.T @ (jac.T @ fd.multipliers), 0.0, atol=1e-9)


def test_torque_bounds_use_the_redundancy(solo, standing):
    """The feet-fixed robot is redundantly actuated: a bound below the least-|u|^2 torques'
    peak is still met (internal forces shift the load), down to a limit where it fails."""
    v, a = robots.motion_with_base(solo, standing, np.zeros(6), np.zeros(6))
    free = inverse_dynamics_tree(solo, standing, v, a)
    peak = np.max(np.abs(free.actuator_forces))
    bounded = inverse_dynamics_tree(solo, standing, v, a, bounds=0.8 * peak)
    assert np.max(np.abs(bounded.actuator_forces)) <= 0.8 * peak * (1 + 1e-9)
    assert bounded.residual < 1e-9
    fd = forward_dynamics_tree(solo, standing, v, bounded.actuator_forces, method="kkt")
    np.testing.assert_allclose(fd.a, 0.0, atol=1e-9)
    # different torques, same (zero) motion: they differ by internal forces only
    assert np.max(np.abs(bounded.actuator_forces - free.actuator_forces)) > 1e-3
    with pytest.raises(ActuatorSaturationError) as info:
        inverse_dynamics_tree(solo, standing, v, a, bounds=0.5 * peak)
    assert np.max(np.abs(info.value.needed)) > 0.5 * peak


def test_example_runs(capsys):
    import runpy
    from pathlib import Path

    runpy.run_path(str(Path(__file__).resolve().parents[2] / "examples" / "solo12_standing.py"),
                   run_name="__main__")
    out = capsys.readouterr().out
    assert "sum of vertical contact forces" in out
