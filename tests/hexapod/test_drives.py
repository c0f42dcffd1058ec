"""The hexapod's drives in its compiled routes: as-built tilted rails, the compiled fast
path and simulator (against the tree simulator), effects the kernels do not model.

The shared checks of both closed forms (each effect against terms written in the test, the
tree routes, batches, stick / slip, derivatives) are in ``tests/test_closed_form_effects.py``.
"""

from __future__ import annotations

import numpy as np
import pytest

import hexapod_pin as hp
from hexapod_pin.core.dynamics import forward_dynamics_tree
from hexapod_pin.errors import InputError
from hexapod_pin.hexapod.fast import FastStepper, fast_dynamics, simulate_fast

CARRIAGES = [f"carriage_{i}" for i in range(6)]


def close(got, want, tol):
    """``|got - want| <= tol max(1, |want|_max)`` elementwise."""
    got, want = np.asarray(got, dtype=float), np.asarray(want, dtype=float)
    np.testing.assert_allclose(got, want, rtol=0.0,
                               atol=tol * max(1.0, float(np.abs(want).max(initial=0.0))))


@pytest.fixture(scope="module")
def rigid():
    return hp.Hexapod.default()


@pytest.fixture(scope="module")
def drives(rigid):
    """Armature, damping and springs (relaxed near home) on the carriages."""
    ref = {c: [rigid.home_q[i] + 0.002] for i, c in enumerate(CARRIAGES)}
    return rigid.with_effects(armature={c: 0.2 + 0.05 * i for i, c in enumerate(CARRIAGES)},
                              damping={c: 3.0 for c in CARRIAGES},
                              stiffness={c: 40.0 for c in CARRIAGES}, spring_reference=ref)


def test_armature_is_inertia_not_weight_on_tilted_rails():
    """Rails tilted by 0.05 rad out of the horizontal plane: the carriages' weight has a
    component along them, the rotors' armature none. Statics are unchanged by the
    armature, inverse dynamics gains exactly ``a qddot``, and the compiled batch equals the
    tree route's forward dynamics (1e-10)."""
    base = hp.HexapodGeometry()
    tilt = np.zeros((6, 3))
    tilt[:, 2] = 0.05 * np.array([1, -1, 1, -1, 1, -1])
    tilted = hp.Hexapod(base.as_built(line_directions=tilt))
    uz = tilted.geometry.chain_geometry.line_directions[:, 2]
    assert np.abs(uz).min() > 0.04
    heavy = tilted.with_effects(armature={c: 0.7 for c in CARRIAGES})
    pose = tilted.home_pose
    close(heavy.static_forces(pose), tilted.static_forces(pose), 1e-12)
    close(heavy.static_forces_batch(pose[None])[0], tilted.static_forces(pose), 1e-12)
    twist, twist_dot = np.full(6, 0.03), np.array([0.2, -0.1, 0.3, 0.5, -0.4, 0.2])
    res = tilted.inverse_dynamics(pose, twist, twist_dot)
    qdd = res.acceleration[tilted.indices.carriage_v]
    got = heavy.inverse_dynamics_batch(pose[None], twist[None], twist_dot[None])
    close(got.actuator_forces[0], res.actuator_forces + 0.7 * qdd, 1e-10)
    u = res.actuator_forces
    batch = heavy.forward_dynamics_batch(pose[None], twist[None], u[None])
    tree = forward_dynamics_tree(heavy.model, res.configuration, res.velocity, u, method="kkt")
    close(batch.actuator_accelerations[0], tree.a[heavy.indices.carriage_v], 1e-10)


def test_fast_dynamics_carries_the_drives(drives):
    """The compiled single-state routes equal the Pinocchio routes with the drives."""
    fast = fast_dynamics(drives)
    pose, twist = drives.home_pose + 0.003, np.full(6, 0.04)
    twist_dot, wrench = np.linspace(-0.5, 0.5, 6), np.linspace(1.0, -1.0, 6)
    ref = drives.inverse_dynamics(pose, twist, twist_dot, wrench)
    close(fast.inverse_dynamics(pose, twist, twist_dot, wrench), ref.actuator_forces, 1e-10)
    close(fast.forward_dynamics(pose, twist, ref.actuator_forces, wrench), twist_dot, 1e-10)
    close(fast.static_forces(pose, wrench), drives.static_forces(pose, wrench), 1e-12)


def test_compiled_simulator_equals_the_tree_simulator(drives):
    """Armature, damping and springs: the compiled run (platform coordinates) and the tree
    run (RK4) agree to 1e-9, and so do the energy dissipated by the dampers (the RK4
    quadrature of their power) and the energy balance."""
    u = drives.static_forces(drives.home_pose) + 0.3
    compiled = hp.simulate(drives, 0.1, 1e-3, actuator_forces=u, backend="compiled",
                           integrator="rk4")
    tree = hp.simulate(drives, 0.1, 1e-3, actuator_forces=u, integrator="rk4")
    assert compiled.status == tree.status == "completed"
    close(compiled.q, tree.q, 1e-9)
    close(compiled.v, tree.v, 1e-9)
    close(compiled.energies, tree.energies, 1e-9)
    assert tree.dissipated_work[-1] > 1e-4
    close(compiled.dissipated_work, tree.dissipated_work, 1e-9)
    close(compiled.dissipated_power, tree.dissipated_power, 1e-9)
    assert np.abs(compiled.energy_residual).max() < 1e-9


def test_compiled_simulator_with_friction(drives):
    """Smooth (regularised) Coulomb friction runs compiled and equals the tree; exact
    friction, which explicit steps cannot take, is run by the tree's "stick_slip"
    integrator (said in the message): a load below the friction holds the robot at rest."""
    rough = drives.with_effects(coulomb={c: 0.5 for c in CARRIAGES})
    hold = rough.static_forces(rough.home_pose)
    u = hold + 0.3
    smooth = dict(actuator_forces=u, friction_regularisation=1e-3, integrator="rk4")
    compiled = hp.simulate(rough, 0.1, 1e-3, backend="compiled", **smooth)
    tree = hp.simulate(rough, 0.1, 1e-3, **smooth)
    close(compiled.q, tree.q, 1e-9)
    close(compiled.dissipated_work, tree.dissipated_work, 1e-8)
    with pytest.raises(InputError):
        simulate_fast(rough, 0.01, 1e-3, actuator_forces=u)         # exact friction
    held = hp.simulate(rough, 0.05, 1e-3, actuator_forces=hold + 0.2, backend="compiled")
    assert "tree simulator" in held.message and held.integrator == "stick_slip"
    close(held.q, np.broadcast_to(held.q[0], held.q.shape), 1e-12)


def test_fast_stepper_steps_the_drives(drives):
    """One step at a time equals the compiled run (semi-implicit Euler)."""
    u = drives.static_forces(drives.home_pose) + 0.3
    run = simulate_fast(drives, 0.05, 1e-3, actuator_forces=u,
                        integrator="semi_implicit_euler")
    stepper = FastStepper(drives, 1e-3)
    for _ in range(50):
        stepper.step(u)
    close(stepper.pose, run.poses[-1], 1e-12)
    close(stepper.twist, run.twists[-1], 1e-12)


def test_effects_on_passive_coordinates_leave_the_kernels(drives):
    """A damper on a universal joint: the fast path answers with the Pinocchio routes, the
    compiled simulator refuses (simulate_fast, FastStepper) or hands the run to the tree
    simulator (the generic backend, said in the message)."""
    passive = drives.with_effects(damping={"u_2_b": 0.05})
    fast = fast_dynamics(passive)
    pose, twist, twist_dot = passive.home_pose, np.full(6, 0.05), np.full(6, 0.1)
    ref = passive.inverse_dynamics(pose, twist, twist_dot).actuator_forces
    close(fast.inverse_dynamics(pose, twist, twist_dot), ref, 1e-12)
    close(fast.forward_dynamics(pose, twist, ref), twist_dot, 1e-10)
    assert np.abs(ref - drives.inverse_dynamics(pose, twist, twist_dot).actuator_forces).max() \
        > 1e-6
    with pytest.raises(InputError):
        simulate_fast(passive, 0.01, 1e-3)
    with pytest.raises(InputError):
        FastStepper(passive, 1e-3)
    u = passive.static_forces(pose) + 0.2
    run = hp.simulate(passive, 0.01, 1e-3, actuator_forces=u, backend="compiled")
    tree = hp.simulate(passive, 0.01, 1e-3, actuator_forces=u)
    assert "passive coordinates" in run.message
    close(run.q, tree.q, 0.0)
