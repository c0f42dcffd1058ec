"""hexapod_pin.core.energy.model_energies on every robot and a bare closed-loop model.

Independent routes: the kinetic energy against ``1/2 v^T crba(q) v``; each body's kinetic
energy against ``1/2 V_i^T I_i V_i`` with the 6x6 spatial inertia matrix and the body's
spatial velocity from ``pin.forwardKinematics``; the potential against
``-sum m_i g . c_i`` with each centre of mass from the world-frame inertia
``oMi.act(I_i)`` and the total against the system centre of mass (``pin.centerOfMass``);
the robots' own ``energies(pose, twist)``.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest

import hexapod_pin as hp
import robot_registry
from hexapod_pin.core.energy import body_names, model_energies

DATA = Path(__file__).resolve().parents[1] / "data" / "parallel"
MODELS = {
    **{name: (lambda name=name: robot_registry.get(name).model)
       for name in robot_registry.names("closed_form")},
    "five_bar": lambda: hp.load_parallel_robot(DATA / "five_bar_3d"),
}


@pytest.fixture(scope="module", params=sorted(MODELS))
def clm(request):
    return MODELS[request.param]()


def random_state(clm, seed):
    rng = np.random.default_rng(seed)
    model = clm.model
    q = pin.integrate(model, pin.neutral(model), rng.uniform(-0.5, 0.5, model.nv))
    return q, rng.uniform(-2.0, 2.0, model.nv)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_totals_match_crba_and_centre_of_mass(clm, seed):
    q, v = random_state(clm, seed)
    model, data = clm.model, clm.model.createData()
    e = model_energies(clm, q, v)
    mass_matrix = pin.crba(model, data, q)
    mass_matrix = np.triu(mass_matrix) + np.triu(mass_matrix, 1).T
    assert e.kinetic == pytest.approx(0.5 * v @ mass_matrix @ v, rel=1e-12, abs=1e-14)
    com = pin.centerOfMass(model, data, q)
    total_mass = sum(model.inertias[i].mass for i in range(1, model.njoints))
    assert e.potential == pytest.approx(-total_mass * model.gravity.linear @ com,
                                        rel=1e-12, abs=1e-12)
    assert e.total == pytest.approx(e.kinetic + e.potential, rel=1e-15, abs=1e-15)
    assert e.kinetic > 0


@pytest.mark.parametrize("seed", [0, 3])
def test_per_body_values_match_spatial_inertias(clm, seed):
    q, v = random_state(clm, seed)
    model, data = clm.model, clm.model.createData()
    pin.forwardKinematics(model, data, q, v)
    kinetic, potential = [], []
    for i in range(1, model.njoints):
        twist = data.v[i].vector
        kinetic.append(0.5 * twist @ model.inertias[i].matrix() @ twist)
        world = data.oMi[i].act(model.inertias[i])
        potential.append(-world.mass * model.gravity.linear @ world.lever)
    e = model_energies(clm, q, v)
    assert e.bodies == body_names(clm) and len(e.bodies) == model.njoints - 1
    np.testing.assert_allclose(e.kinetic_per_body, kinetic, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(e.potential_per_body, potential, rtol=1e-12, atol=1e-14)
    # the parts sum to the totals (computed by Pinocchio's own energy routines)
    assert e.kinetic_per_body.sum() == pytest.approx(e.kinetic, rel=1e-12, abs=1e-14)
    assert e.potential_per_body.sum() == pytest.approx(e.potential, rel=1e-12, abs=1e-12)


def test_potential_is_zero_with_every_centre_of_mass_at_height_zero(clm):
    """Pinocchio's convention: lifting the whole mechanism by h along -g adds M |g| h."""
    q, v = random_state(clm, 4)
    model = clm.model
    e0 = model_energies(clm, q, v)
    total_mass = sum(model.inertias[i].mass for i in range(1, model.njoints))
    shifted = pin.Model(clm.tree_model)
    shifted.gravity = model.gravity             # (the planar robot sets it on clm.model)
    up = -model.gravity.linear / np.linalg.norm(model.gravity.linear)
    for i in range(1, shifted.njoints):
        if shifted.parents[i] == 0:             # every root joint moved up by 0.3 m
            placement = shifted.jointPlacements[i]
            placement.translation = placement.translation + 0.3 * up
            shifted.jointPlacements[i] = placement
    lifted = hp.ClosedLoopModel(shifted, hp.LoopsSpec(clm.closures, clm.actuated_joints))
    e1 = model_energies(lifted, q, v)
    assert e1.potential - e0.potential == pytest.approx(
        total_mass * np.linalg.norm(model.gravity.linear) * 0.3, rel=1e-12)
    assert e1.kinetic == pytest.approx(e0.kinetic, rel=1e-12)


def test_robot_energies_agree():
    robot = hp.Hexapod.default()
    pose = robot.home_pose + np.array([0.01, -0.01, 0.01, 0.05, -0.02, 0.1])
    twist = np.array([0.1, 0.2, -0.1, 0.3, 0.1, -0.2])
    q = robot.configuration(pose)
    v = robot.model.velocity_from_actuated(q, robot.jacobian(pose) @ twist)
    ours, theirs = model_energies(robot.model, q, v), robot.energies(pose, twist)
    assert ours.kinetic == pytest.approx(theirs.kinetic, rel=1e-10)
    assert ours.potential == pytest.approx(theirs.potential, rel=1e-12)


def test_bodies_are_named_after_their_links():
    clm = hp.Hexapod.default().model
    names = body_names(clm)
    assert names[:3] == ("carriage_0", "cross_0", "leg_0")
    assert len(set(names)) == len(names)


@pytest.mark.parametrize("bad", ["shape", "nan", "inf", "complex", "text"])
def test_bad_inputs_raise_input_errors(clm, bad):
    q, v = random_state(clm, 5)
    values = {"shape": (q[:-1], v), "nan": (q, np.where(np.arange(v.size) == 0, np.nan, v)),
              "inf": (np.where(np.arange(q.size) == 0, np.inf, q), v),
              "complex": (q + 0j, v), "text": ("q", v)}
    with pytest.raises(hp.InputError):
        model_energies(clm, *values[bad])


def test_energies_keep_their_three_field_construction():
    e = hp.Energies(1.0, 2.0, 3.0)
    assert e.bodies == () and e.kinetic_per_body is None and e.potential_per_body is None
    a = hp.Energies(1.0, 2.0, 3.0, ("a",), np.ones(1), np.ones(1))
    assert a == hp.Energies(1.0, 2.0, 3.0, ("a",), np.zeros(1), np.zeros(1))  # no ValueError
