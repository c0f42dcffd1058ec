"""The sympy Lagrangian derivation of the planar 3-PRR against the Pinocchio-based model."""

import json
from pathlib import Path

import numpy as np
import pytest

from hexapod_pin.planar.geometry import PlanarGeometry
from hexapod_pin.planar.robot import Planar3PRR
from hexapod_pin.planar.symbolic import (PlanarSymbolicDynamics, derive_equations,
                                         numeric_functions)

from test_planar import random_pose

# sympy is a test/dev dependency; hexapod_pin.planar.symbolic imports it only when used
sympy = pytest.importorskip("sympy")

GEOMETRIES = {
    "default": PlanarGeometry(),
    "other": PlanarGeometry(rail_radius=0.4, platform_radius=0.15, link_length=0.33,
                            slider_mass=0.7, link_mass=0.35, platform_mass=1.6,
                            platform_inertia=0.005, gravity=9.5),
}


@pytest.fixture(scope="module", params=sorted(GEOMETRIES))
def pair(request):
    geometry = GEOMETRIES[request.param]
    return Planar3PRR(geometry), PlanarSymbolicDynamics(geometry)


def _coordinates(robot, pose, twist=None, twist_dot=None):
    """Symbolic coordinates (s, phi, x, y, theta) from the Pinocchio tree state."""
    order = np.concatenate([robot.indices.slider, robot.indices.link, robot.indices.platform])
    q = robot.configuration(pose)[order]
    if twist is None:
        return q
    v = robot.velocity(pose, twist)[order]
    if twist_dot is None:
        return q, v
    return q, v, robot.acceleration(pose, twist, twist_dot)[order]


def test_derivation_structure():
    eq = derive_equations()
    assert eq.mass_matrix.shape == (9, 9) and eq.constraint_jacobian.shape == (6, 9)
    assert sympy.simplify(eq.mass_matrix - eq.mass_matrix.T) == sympy.zeros(9, 9)
    # T = 1/2 qdot^T M qdot: the kinetic energy is quadratic in the velocities
    quad = (eq.qdot.T * eq.mass_matrix * eq.qdot)[0] / 2
    assert sympy.simplify(sympy.expand(quad - eq.kinetic_energy)) == 0
    # the constraints do not involve the velocities, the generalised force is linear
    assert not eq.constraints.free_symbols & set(eq.qdot)
    assert eq.generalized_force.jacobian(list(eq.tau) + list(eq.wrench)).free_symbols == set()
    assert numeric_functions() is numeric_functions()   # generated once, cached


def test_constraints_jacobian_and_drift_by_finite_differences(pair):
    robot, sym = pair
    rng = np.random.default_rng(1)
    pose = random_pose(robot, rng)
    twist = rng.normal(size=3) * [0.2, 0.2, 1.0]
    q, v = _coordinates(robot, pose, twist)
    np.testing.assert_allclose(sym.constraints(q), 0.0, atol=1e-14)   # the tree closes them
    h = 1e-6
    fd = np.array([(sym.constraints(q + h * e) - sym.constraints(q - h * e)) / (2 * h)
                   for e in np.eye(9)]).T
    np.testing.assert_allclose(sym.constraint_jacobian(q), fd, atol=1e-9)
    fd_drift = (sym.constraint_jacobian(q + h * v) - sym.constraint_jacobian(q - h * v)) @ v \
        / (2 * h)
    np.testing.assert_allclose(sym.constraint_drift(q, v), fd_drift, atol=1e-8)
    np.testing.assert_allclose(sym.constraint_jacobian(q) @ v, 0.0, atol=1e-14)
    np.testing.assert_allclose(sym.complete_velocity(q, twist), v, atol=1e-12)


def test_symbolic_and_pinocchio_dynamics_agree(pair):
    """Inverse dynamics (actuator forces, joint forces) and forward dynamics (all 9
    accelerations) of the Lagrangian model against the Pinocchio tree, 1e-9."""
    robot, sym = pair
    rng = np.random.default_rng(2)
    for _ in range(5):
        pose = random_pose(robot, rng)
        twist = rng.normal(size=3) * [0.3, 0.3, 1.5]
        twist_dot = rng.normal(size=3) * [2.0, 2.0, 8.0]
        wrench = rng.normal(size=3) * [3.0, 3.0, 0.3]
        q, v, a = _coordinates(robot, pose, twist, twist_dot)
        np.testing.assert_allclose(sym.complete_acceleration(q, v, twist_dot), a, atol=1e-10)

        pin_id = robot.inverse_dynamics(pose, twist, twist_dot, wrench)
        sym_id = sym.inverse_dynamics(q, v, a, wrench)
        np.testing.assert_allclose(sym_id.forces, pin_id.actuator_forces, rtol=0, atol=1e-9)
        # the symbolic multipliers act ON the links: the opposite of the closure forces
        np.testing.assert_allclose(sym_id.multipliers, -pin_id.closure_forces.reshape(-1),
                                   rtol=0, atol=1e-9)

        forces = rng.normal(size=3) * 5.0
        pin_fd = robot.forward_dynamics(pose, twist, forces, wrench)
        sym_fd = sym.forward_dynamics(q, v, forces, wrench)
        order = np.concatenate([robot.indices.slider, robot.indices.link,
                                robot.indices.platform])
        np.testing.assert_allclose(sym_fd.qddot, pin_fd.tree_acceleration[order], rtol=0,
                                   atol=1e-9)
        np.testing.assert_allclose(sym_fd.multipliers, -pin_fd.closure_forces.reshape(-1),
                                   rtol=0, atol=1e-9)


def test_symbolic_and_pinocchio_energies_agree(pair):
    robot, sym = pair
    rng = np.random.default_rng(3)
    pose = random_pose(robot, rng)
    twist = rng.normal(size=3) * [0.3, 0.3, 1.5]
    q, v = _coordinates(robot, pose, twist)
    kinetic, potential = sym.energy(q, v)
    energies = robot.energies(pose, twist)
    assert kinetic == pytest.approx(energies.kinetic, rel=1e-12)
    assert potential == pytest.approx(energies.potential, rel=1e-12, abs=1e-14)
    assert energies.total == pytest.approx(kinetic + potential, rel=1e-12)


def test_symbolic_statics_match_the_reference_home_state():
    """At rest the Lagrangian model alone (no Pinocchio in the numbers) gives the
    reference state's static forces."""
    entry = json.loads((Path(__file__).resolve().parents[1] / "data" / "reference_states.json")
                       .read_text())["planar"][0]
    robot = Planar3PRR(PlanarGeometry(**entry["geometry"]))
    sym = PlanarSymbolicDynamics(robot.geometry)
    q = _coordinates(robot, entry["pose"])
    res = sym.inverse_dynamics(q, np.zeros(9), np.zeros(9), entry["wrench"])
    np.testing.assert_allclose(res.forces, entry["static_forces"], rtol=1e-9)


def test_symbolic_reduced_dynamics_and_derivatives(pair):
    """M_x, h_x and the velocity map of the compiled closed form against the Lagrangian
    model projected on its own null space; the ID derivative in twist_dot and wrench
    against the symbolic KKT solve (linear in both)."""
    robot, sym = pair
    rng = np.random.default_rng(4)
    order = np.concatenate([robot.indices.slider, robot.indices.link, robot.indices.platform])
    for _ in range(3):
        pose = random_pose(robot, rng)
        twist = rng.normal(size=3) * [0.3, 0.3, 1.5]
        q, v = _coordinates(robot, pose, twist)
        gmap = np.column_stack([sym.complete_velocity(q, e) for e in np.eye(3)])
        a0 = sym.complete_acceleration(q, v, np.zeros(3))
        m_sym = gmap.T @ sym.mass_matrix(q) @ gmap
        h_sym = gmap.T @ (sym.mass_matrix(q) @ a0 + sym.bias(q, v))
        red = robot.reduced_dynamics(pose, twist)
        np.testing.assert_allclose(red.mass_matrix, m_sym, rtol=0, atol=1e-12)
        np.testing.assert_allclose(red.bias, h_sym, rtol=0, atol=1e-10)
        np.testing.assert_allclose(red.velocity_map[order], gmap, rtol=0, atol=1e-12)
        der = robot.inverse_dynamics_derivatives(pose, twist, np.zeros(3))
        d_twist_dot = np.column_stack([
            sym.inverse_dynamics(q, v, sym.complete_acceleration(q, v, e)).forces
            - sym.inverse_dynamics(q, v, a0).forces for e in np.eye(3)])
        np.testing.assert_allclose(der.d_twist_dot, d_twist_dot, rtol=0, atol=1e-9)
        d_wrench = np.column_stack([sym.inverse_dynamics(q, v, a0, e).forces
                                    - sym.inverse_dynamics(q, v, a0).forces for e in np.eye(3)])
        np.testing.assert_allclose(der.d_wrench, d_wrench, rtol=0, atol=1e-9)
