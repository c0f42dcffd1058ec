"""``hexapod_pin.simulate`` with joint and drive effects (damping, springs, armature, Coulomb
friction) on loaded robots, a bare closed-loop model and a one-coordinate slider.

Independent routes: the energy balance ``E(t) + dissipated work(t) = E(0)`` with the energies
recomputed here from the recorded states on raw Pinocchio (``crba`` of a model without
armature plus ``diag(armature)``, ``computePotentialEnergy`` plus ``1/2 K dq^2`` written
out) and the dissipated work integrated here from the recorded velocities (Simpson's rule);
closed-form solutions of one coordinate (a damped slider, a mass on a spring, a slider
with dry friction pushed, tilted or coasting to a stop, the creep speed of the regularised
friction); a sliding four-bar against an RK4 run of the rigid one with the friction torque
applied as a command.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import scipy.integrate
import scipy.linalg

import hexapod_pin as hp
from hexapod_pin.core import simulate as simulate_module
from hexapod_pin.core.closed_loop import ClosedLoopModel
from hexapod_pin.core.description import LoopsSpec
from hexapod_pin.core.dynamics import forward_dynamics_tree
from hexapod_pin.core.simulate import Trajectory, simulate
from hexapod_pin.core.simulation import ClosedLoopIntegrator, resolve_integrator

DATA = Path(__file__).resolve().parents[1] / "data"
ROBOTS = {
    "four_bar": lambda: hp.load_robot(DATA / "four_bar" / "four_bar.urdf"),
    "stewart": lambda: hp.load_robot(DATA / "stewart" / "stewart.urdf"),
}


@pytest.fixture(scope="module", params=sorted(ROBOTS))
def robot(request):
    return ROBOTS[request.param]()


@pytest.fixture(scope="module")
def five_bar():
    """A bare ClosedLoopModel (no platform) and an assembled hanging configuration."""
    clm = hp.load_parallel_robot(DATA / "parallel" / "five_bar_3d")
    guess = np.zeros(clm.nq)
    for joint, value in (("mot1", 0.9), ("free1", 1.0), ("mot2", 2.0), ("free2", -1.0)):
        guess[clm.joint_q_index(joint)] = value
    return clm, clm.assemble(guess).q


def slider(mass: float = 2.0, tilt: float = 0.0) -> ClosedLoopModel:
    """One prismatic joint along x (actuated, no closure) on a rail tilted by ``tilt``:
    gravity's component along the rail is ``-g sin(tilt)``."""
    model = pin.Model()
    jid = model.addJoint(0, pin.JointModelPX(), pin.SE3.Identity(), "slider")
    model.appendBodyToJoint(jid, pin.Inertia(mass, np.zeros(3), 0.01 * np.eye(3)),
                            pin.SE3.Identity())
    model.addBodyFrame("cart", jid, pin.SE3.Identity(), 0)
    model.gravity.linear[:] = 9.81 * np.array([-np.sin(tilt), 0.0, -np.cos(tilt)])
    return ClosedLoopModel(model, LoopsSpec((), ("slider",)), name="slider")


def energies_here(clm: ClosedLoopModel, eff: dict, q: np.ndarray, v: np.ndarray) -> float:
    """``1/2 v^T (M + diag(armature)) v + V_gravity + 1/2 K dq^2`` on a copy of the tree
    without armature (written here, not the library's energy module)."""
    model = pin.Model(clm.tree_model)
    model.armature[:] = 0.0
    data = model.createData()
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T + np.diag(eff.get("armature", np.zeros(clm.nv)))
    out = 0.5 * v @ mass @ v + pin.computePotentialEnergy(model, data, q)
    if "stiffness" in eff:
        dq = pin.difference(model, eff["spring_reference"], q)
        out += 0.5 * np.dot(eff["stiffness"] * dq, dq)
    return float(out)


def simpson(traj: Trajectory, power: np.ndarray) -> np.ndarray:
    """The cumulative integral of ``power`` over the recorded times (Simpson's rule)."""
    return scipy.integrate.cumulative_simpson(power, x=traj.times, initial=0.0)


def start(clm: ClosedLoopModel, q: np.ndarray, speed: float) -> tuple[np.ndarray, np.ndarray]:
    """A moving initial state on the closures (actuators at ``speed``)."""
    return q, clm.velocity_from_actuated(q, np.full(clm.n_actuated, speed))


# --------------------------------------------------------------------------------- damping
def test_damped_robots_lose_exactly_the_dissipated_work(robot):
    clm = robot.model
    damping = np.linspace(0.05, 0.2, clm.nv)
    traj = simulate(robot.with_effects(damping=damping), 0.3, 5e-4,
                    initial=start(clm, robot.kinematics.home_q, 0.5))
    assert traj.status == "completed", traj.message
    power = np.einsum("ij,j,ij->i", traj.v, damping, traj.v)
    np.testing.assert_allclose(traj.dissipated_power, power, rtol=1e-12, atol=1e-300)
    work = simpson(traj, power)
    scale = max(traj.kinetic.max(), work[-1])
    assert work[-1] > 1e-2 * scale                     # it dissipated (the test can fail)
    np.testing.assert_allclose(traj.dissipated_work, work, atol=1e-8 * scale)
    total = [energies_here(clm, {}, q, v) for q, v in zip(traj.q, traj.v)]
    np.testing.assert_allclose(traj.energies, total, atol=1e-10 * scale)
    # E + W = E(0) with the work integrated here (independent of the code's quadrature)
    np.testing.assert_allclose(traj.energies + work, traj.energies[0], atol=1e-8 * scale)
    assert np.abs(traj.energy_residual).max() <= 1e-8 * scale
    np.testing.assert_array_equal(traj.work, 0.0)


def test_damped_bare_model_loses_exactly_the_dissipated_work(five_bar):
    clm, q0 = five_bar
    damping = np.full(clm.nv, 0.02)
    traj = simulate(clm.with_effects(damping=damping), 0.3, 5e-4,
                    initial=(q0, np.zeros(clm.nv)))
    assert traj.status == "completed" and traj.integrator == "rk4", traj.message
    work = simpson(traj, np.einsum("ij,j,ij->i", traj.v, damping, traj.v))
    scale = max(traj.kinetic.max(), work[-1])
    assert work[-1] > 1e-3 * scale
    np.testing.assert_allclose(traj.energies + work, traj.energies[0], atol=1e-8 * scale)
    np.testing.assert_allclose(traj.dissipated_work, work, atol=1e-8 * scale)


def test_a_damped_slider_follows_the_exponential_decay():
    """``(m + a) v' = -d v``: ``v = v0 exp(-d t / (m + a))``, dissipated work
    ``1/2 (m + a) v0^2 (1 - exp(-2 d t / (m + a)))``; RK4 at 1 ms, ``d dt / m = 1e-3``:
    relative error ~ (d dt / m)^4 per unit time, far below 1e-10."""
    m, arm, d, v0 = 2.0, 0.5, 2.5, 1.5
    clm = slider(m).with_effects(damping=[d], armature=[arm])
    traj = simulate(clm, 1.0, 1e-3, initial=(np.zeros(1), np.array([v0])))
    inertia = m + arm
    decay = np.exp(-d * traj.times / inertia)
    np.testing.assert_allclose(traj.v[:, 0], v0 * decay, rtol=1e-10)
    np.testing.assert_allclose(traj.q[:, 0], v0 * inertia / d * (1 - decay), rtol=1e-10,
                               atol=1e-14)
    np.testing.assert_allclose(traj.dissipated_work, 0.5 * inertia * v0 ** 2 * (1 - decay ** 2),
                               rtol=1e-10, atol=1e-14)


# --------------------------------------------------------------------------------- springs
def spring_effects(clm: ClosedLoopModel, q0: np.ndarray, joints: str = "1-dof") -> dict:
    """Springs of 20 (N/m, N m/rad) on the one-coordinate joints (or on every coordinate),
    relaxed at a configuration near ``q0``."""
    model = clm.tree_model
    stiffness = np.zeros(clm.nv)
    for joint in model.joints[1:]:
        if joints == "all" or joint.nv == 1:
            stiffness[joint.idx_v:joint.idx_v + joint.nv] = 20.0
    rng = np.random.default_rng(1)
    return {"stiffness": stiffness,
            "spring_reference": pin.integrate(model, q0, rng.uniform(-0.1, 0.1, clm.nv))}


def spring_run(robot, eff: dict, dt: float) -> Trajectory:
    q0 = robot.kinematics.home_q
    return simulate(robot.with_effects(**eff), 0.3, dt, initial=(q0, np.zeros(robot.model.nv)),
                    projection_tol=1e-12)


def test_springs_keep_the_energy_with_their_potential(robot):
    """Springs only, RK4: the energy drifts by RK4's O(dt^4) (measured: 30x less at half
    the step), down to 1e-10 of the spring energy's swing at 0.25 ms (projection_tol
    1e-12: the 1e-10 default leaves a floor of ~1e-9 J on the four-bar). Without the
    springs' term the total would vary by that whole swing."""
    clm = robot.model
    eff = spring_effects(clm, robot.kinematics.home_q)
    coarse, traj = spring_run(robot, eff, 5e-4), spring_run(robot, eff, 2.5e-4)
    assert traj.status == "completed", traj.message
    springs = np.array([energies_here(clm, eff, q, v) - energies_here(clm, {}, q, v)
                        for q, v in zip(traj.q, traj.v)])
    swing = springs.max() - springs.min()
    assert swing > 1e-3
    total = [energies_here(clm, eff, q, v) for q, v in zip(traj.q, traj.v)]
    np.testing.assert_allclose(traj.energies, total, atol=1e-10 * swing)
    drift = np.abs(traj.energies - traj.energies[0]).max()
    assert drift <= 1e-8 * swing
    assert drift <= np.abs(coarse.energies - coarse.energies[0]).max() / 8   # order >= 3
    np.testing.assert_array_equal(traj.dissipated_work, 0.0)


def test_springs_on_a_free_flyer_keep_the_energy():
    robot = ROBOTS["stewart"]()
    eff = spring_effects(robot.model, robot.kinematics.home_q, joints="all")
    traj = spring_run(robot, eff, 5e-4)
    assert np.abs(traj.energies - traj.energies[0]).max() <= 1e-8 * traj.kinetic.max()


def test_a_mass_on_a_spring_oscillates_at_the_natural_frequency():
    """``(m + a) x'' = -k (x - x_ref)`` from rest at ``x_ref + A``: ``x = x_ref + A cos(w t)``,
    ``w = sqrt(k / (m + a))``; RK4 at 1 ms, ``w dt = 6e-3``: phase error ~ (w dt)^4 w t /
    120 ~ 1e-11."""
    m, arm, k, ref, amp = 2.0, 0.5, 40.0, 0.1, 0.05
    clm = slider(m).with_effects(stiffness=[k], spring_reference=[ref], armature=[arm])
    traj = simulate(clm, 2.0, 1e-3, initial=(np.array([ref + amp]), np.zeros(1)))
    w = np.sqrt(k / (m + arm))
    np.testing.assert_allclose(traj.q[:, 0], ref + amp * np.cos(w * traj.times), atol=1e-10)
    np.testing.assert_allclose(traj.v[:, 0], -amp * w * np.sin(w * traj.times), atol=1e-9)
    np.testing.assert_allclose(traj.energies, traj.energies[0], atol=1e-10)


# -------------------------------------------------------------------------------- armature
def test_armature_keeps_the_energy_with_the_rotors(robot):
    clm = robot.model
    arm = np.zeros(clm.nv)
    arm[clm.actuated_v] = 0.3
    traj = simulate(robot.with_effects(armature=arm), 0.3, 5e-4,
                    initial=start(clm, robot.kinematics.home_q, 0.5))
    assert traj.status == "completed", traj.message
    rotors = 0.5 * np.einsum("ij,j,ij->i", traj.v, arm, traj.v)
    assert rotors.max() > 1e-2 * traj.kinetic.max()      # the rotors matter here
    total = [energies_here(clm, {"armature": arm}, q, v) for q, v in zip(traj.q, traj.v)]
    scale = traj.kinetic.max()
    np.testing.assert_allclose(traj.energies, total, atol=1e-10 * scale)
    assert np.abs(traj.energies - traj.energies[0]).max() <= 1e-8 * scale
    # the rigid model's energy of the same motion is not conserved (the test can fail)
    rigid = traj.energies - rotors
    assert np.abs(rigid - rigid[0]).max() > 1e-4 * scale


# --------------------------------------------------------------------- Coulomb friction
@pytest.mark.parametrize("push", [2.9, -2.9, 3.0])
def test_a_slider_pushed_below_its_friction_stays_exactly_at_rest(push):
    clm = slider().with_effects(coulomb=[3.0])
    traj = simulate(clm, 0.5, 1e-3, actuator_forces=[push], initial=(np.zeros(1), np.zeros(1)))
    assert traj.status == "completed" and traj.integrator == "stick_slip", traj.message
    np.testing.assert_array_equal(traj.v, 0.0)
    np.testing.assert_array_equal(traj.q, 0.0)
    np.testing.assert_array_equal(traj.dissipated_work, 0.0)


@pytest.mark.parametrize("push", [3.5, -4.0])
def test_a_slider_pushed_above_its_friction_slides_with_the_analytic_acceleration(push):
    """``m a = u - c sign(u)``: ``v = a t`` exactly (a constant force, semi-implicit Euler),
    ``x = a t^2 / 2`` to ``a t dt``."""
    m, c, dt = 2.0, 3.0, 1e-3
    clm = slider(m).with_effects(coulomb=[c])
    traj = simulate(clm, 0.5, dt, actuator_forces=[push], initial=(np.zeros(1), np.zeros(1)))
    acc = (push - c * np.sign(push)) / m
    np.testing.assert_allclose(traj.v[:, 0], acc * traj.times, rtol=1e-12, atol=1e-15)
    assert np.all(np.abs(traj.q[:, 0] - 0.5 * acc * traj.times ** 2)
                  <= abs(acc) * traj.times * dt + 1e-15)
    # the friction's power is c |v|, and its work c |x| (the held force along each step)
    np.testing.assert_allclose(traj.dissipated_power, c * np.abs(traj.v[:, 0]), rtol=1e-12)
    np.testing.assert_allclose(traj.dissipated_work, c * np.abs(traj.q[:, 0]), rtol=1e-12,
                               atol=1e-15)


@pytest.mark.parametrize("tilt, moves", [(0.1, False), (0.2, True)])
def test_a_slider_on_a_tilted_rail_holds_or_slides(tilt, moves):
    """Weight along the rail ``m g sin(tilt)`` against friction ``c = 3 N`` (m = 2 kg:
    breakaway at ``sin(tilt) = 0.153``): held exactly, or ``a = -g sin(tilt) + c / m``."""
    m, c = 2.0, 3.0
    clm = slider(m, tilt).with_effects(coulomb=[c])
    traj = simulate(clm, 0.3, 1e-3, initial=(np.zeros(1), np.zeros(1)))
    if not moves:
        np.testing.assert_array_equal(traj.v, 0.0)
        return
    acc = -9.81 * np.sin(tilt) + c / m
    np.testing.assert_allclose(traj.v[:, 0], acc * traj.times, rtol=1e-12, atol=1e-15)


def test_a_coasting_slider_sticks_at_the_analytic_time():
    """``m v' = -c`` from ``v0``: it stops at ``t* = m v0 / c`` after ``x* = m v0^2 / (2 c)``
    and stays there; all its kinetic energy is dissipated."""
    m, c, v0, dt = 2.0, 3.0, 1.3, 1e-3
    clm = slider(m).with_effects(coulomb=[c])
    traj = simulate(clm, 1.5, dt, initial=(np.zeros(1), np.array([v0])))
    t_stop = m * v0 / c
    moving = traj.v[:, 0] != 0.0
    first_stop = traj.times[np.argmin(moving)]
    assert t_stop <= first_stop + 1e-12 <= t_stop + dt + 1e-12
    assert not moving[traj.times >= first_stop - 1e-12].any()       # stuck for good
    np.testing.assert_allclose(traj.v[moving, 0], v0 - c / m * traj.times[moving], atol=1e-12)
    assert abs(traj.q[-1, 0] - m * v0 ** 2 / (2 * c)) <= v0 * dt
    assert traj.dissipated_work[-1] == pytest.approx(c * traj.q[-1, 0], rel=1e-12)
    # the balance of a first-order scheme: each step misses dt^2 c^2 / (2 m)
    miss = np.abs(traj.energy_residual).max()
    assert miss <= 1.01 * (t_stop / dt + 1) * dt ** 2 * c ** 2 / (2 * m)


def four_bar_at_rest(ratio: float):
    """The four-bar at home, at rest, with crank friction ``ratio`` times the crank torque
    that holds it against gravity (from its one-coordinate inertia, written here)."""
    robot = ROBOTS["four_bar"]()
    clm = robot.model
    q = robot.kinematics.home_q
    crank = clm.joint_v_index("crank")
    rigid = forward_dynamics_tree(clm, q, np.zeros(clm.nv), [0.0]).a
    mass = pin.crba(clm.model, clm.model.createData(), q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    n = scipy.linalg.null_space(clm.constraint_jacobian(q), rcond=1e-10)[:, 0]
    gain = n[crank] ** 2 / (n @ mass @ n)          # crank acceleration per crank torque
    hold = abs(rigid[crank]) / gain
    return robot, robot.with_effects(coulomb={"crank": ratio * hold}), ratio * hold, \
        rigid[crank], gain


def test_a_four_bar_held_by_friction_stays_at_rest():
    _, held, _, _, _ = four_bar_at_rest(1.2)
    traj = simulate(held, 0.2, 1e-3)
    assert traj.status == "completed" and traj.integrator == "stick_slip", traj.message
    np.testing.assert_array_equal(traj.v[:, held.model.joint_v_index("crank")], 0.0)
    assert np.abs(traj.v).max() <= 1e-12
    assert traj.closure_residual.max() <= 1e-10


def test_a_four_bar_sliding_against_friction_follows_the_rigid_one_with_that_torque():
    """Friction ``c`` below the holding torque: the crank slips from rest with ``a =
    a_rigid - g c sign(a_rigid)``; while it turns one way its friction is the constant
    torque ``-c sign(a_rigid)``, so the run equals an RK4 run of the rigid four-bar with
    that command, to the Euler scheme's O(dt)."""
    rigid_robot, sliding, c, a_rigid, gain = four_bar_at_rest(0.6)
    dt = 1e-4
    crank = sliding.model.joint_v_index("crank")
    traj = simulate(sliding, 0.1, dt)
    expected = a_rigid - gain * c * np.sign(a_rigid)
    # the first step's velocity is dt a (the end-of-step projection moves it by O(dt^2))
    assert traj.v[1, crank] / dt == pytest.approx(expected, rel=1e-6)
    assert np.all(np.sign(traj.v[1:, crank]) == np.sign(a_rigid))      # one way all along
    ref = simulate(rigid_robot, 0.1, dt, actuator_forces=[-c * np.sign(a_rigid)])
    scale = np.abs(ref.v).max()
    assert np.abs(traj.v - ref.v).max() <= 5 * dt * scale
    assert np.abs(traj.v - ref.v).max() > 0.0


def test_regularised_friction_creeps_at_the_analytic_speed():
    """``m v' = u - c tanh(v / v_eps)``, ``u < c``: the slider creeps at ``v_eps atanh(u /
    c)`` instead of sticking (RK4 works: the force is smooth)."""
    eps = 1e-3
    clm = slider().with_effects(coulomb=[3.0])
    traj = simulate(clm, 0.1, 1e-4, actuator_forces=[2.0], initial=(np.zeros(1), np.zeros(1)),
                    friction_regularisation=eps)
    assert traj.integrator == "rk4"
    assert traj.v[-1, 0] == pytest.approx(eps * np.arctanh(2.0 / 3.0), rel=1e-9)
    power = 3.0 * traj.v[:, 0] * np.tanh(traj.v[:, 0] / eps)
    np.testing.assert_allclose(traj.dissipated_power, power, rtol=1e-12, atol=1e-300)
    # RK4 resolves the transient (relaxation time m v_eps / c ~ 7 steps) to ~3e-8
    assert np.abs(traj.energy_residual).max() <= 1e-7 * traj.work[-1]


def test_coulomb_friction_picks_the_stick_slip_integrator_and_refuses_the_others():
    clm = slider().with_effects(coulomb=[3.0])
    rigid = slider()
    assert resolve_integrator(clm) == "stick_slip"
    assert resolve_integrator(rigid) == "rk4"
    assert resolve_integrator(clm, "auto", 1e-3) == "rk4"
    assert ClosedLoopIntegrator(clm).integrator == "stick_slip"
    state = (np.zeros(1), np.zeros(1))
    for integrator in ("rk4", "semi_implicit_euler"):
        with pytest.raises(hp.InputError, match="Coulomb friction on the velocity coordinates"):
            simulate(clm, 0.1, 1e-3, integrator=integrator, initial=state)
        with pytest.raises(hp.InputError, match="stick_slip"):
            ClosedLoopIntegrator(clm, integrator=integrator)
        # a smooth friction runs with them
        traj = simulate(clm, 0.01, 1e-3, integrator=integrator, initial=state,
                        friction_regularisation=1e-3)
        assert traj.integrator == integrator
    with pytest.raises(hp.InputError, match="friction_regularisation"):
        simulate(clm, 0.1, 1e-3, integrator="stick_slip", initial=state,
                 friction_regularisation=1e-3)
    for bad in (0.0, -1.0, float("nan"), "fast", True):
        with pytest.raises(hp.InputError, match="friction_regularisation"):
            simulate(clm, 0.1, 1e-3, initial=state, friction_regularisation=bad)
    # without friction, stick_slip is semi-implicit Euler
    a = simulate(rigid, 0.05, 1e-3, integrator="stick_slip", actuator_forces=[1.0],
                 initial=state)
    b = simulate(rigid, 0.05, 1e-3, integrator="semi_implicit_euler", actuator_forces=[1.0],
                 initial=state)
    np.testing.assert_allclose(a.v, b.v, rtol=1e-14)


def test_semi_implicit_euler_reports_the_work_of_the_held_damping():
    m, d, v0, dt = 2.0, 2.5, 1.5, 1e-3
    traj = simulate(slider(m).with_effects(damping=[d]), 0.2, dt, integrator="semi_implicit_euler",
                    initial=(np.zeros(1), np.array([v0])))
    v = traj.v[:, 0]
    held = np.concatenate([[0.0], np.cumsum(dt * d * v[:-1] * v[1:])])
    np.testing.assert_allclose(traj.dissipated_work, held, rtol=1e-12)
    assert np.abs(traj.energy_residual).max() <= 10 * dt * traj.dissipated_work[-1]


# --------------------------------------------------------------------------- the backends
def test_the_compiled_backend_refuses_effects_it_does_not_model(monkeypatch):
    class Fake:
        pass

    calls = []

    def run(robot, duration, dt, **options):
        calls.append(options)
        return "ran"

    robot = ROBOTS["four_bar"]()
    damped = robot.with_effects(damping={"crank": 0.1})
    monkeypatch.setattr(simulate_module, "COMPILED_SIMULATORS", {})
    simulate_module.register_compiled_simulator(type(robot), run)
    with pytest.raises(hp.InputError, match="does not model joint effects"):
        simulate(damped, 0.01, 1e-3, backend="compiled")
    assert simulate(robot, 0.01, 1e-3, backend="compiled") == "ran"
    assert "friction_regularisation" not in calls[-1]
    simulate_module.register_compiled_simulator(type(robot), run, supports_effects=True)
    assert simulate(damped, 0.01, 1e-3, backend="compiled") == "ran"
    assert calls[-1]["friction_regularisation"] is None and calls[-1]["integrator"] == "rk4"


def test_the_hexapods_compiled_backend_follows_a_hand_written_armature():
    """The compiled batch once ignored an armature the tree routes follow (issue 27): the
    hexapod's compiled simulator now declares the effects and agrees with the tree one."""
    assert simulate_module.compiled_simulator_of(hp.Hexapod).supports_effects
    hexapod = hp.Hexapod.default()
    # an armature written by hand into the tree: the model's effects adopt it
    hexapod.model.model.armature[hexapod.model.actuated_v] = 0.5
    assert not hexapod.effects.is_rigid
    forces = np.full(6, 3.0)
    fast = simulate(hexapod, 0.02, 1e-3, actuator_forces=forces, backend="compiled")
    tree = simulate(hexapod, 0.02, 1e-3, actuator_forces=forces, backend="tree")
    rigid = simulate(hp.Hexapod.default(), 0.02, 1e-3, actuator_forces=forces,
                     backend="compiled")
    np.testing.assert_allclose(fast.poses[-1], tree.poses[-1], rtol=0, atol=1e-9)
    assert np.abs(fast.poses[-1] - rigid.poses[-1]).max() > 1e-6


def test_a_trajectory_built_without_dissipation_records_zeros():
    n = 3
    traj = Trajectory(np.arange(n) * 0.1, np.zeros((n, 1)), np.zeros((n, 1)), None, None,
                      np.zeros((n, 1)), np.zeros((n, 1)), np.zeros((n, 1)),
                      np.zeros(n, dtype=bool), np.ones(n), np.zeros(n), np.ones(n),
                      np.zeros(n), np.zeros(n), "completed", "", 0.1, 0.0)
    np.testing.assert_array_equal(traj.dissipated_work, np.zeros(n))
    np.testing.assert_array_equal(traj.dissipated_power, np.zeros(n))
    np.testing.assert_array_equal(traj.energy_residual, np.zeros(n))
    assert traj.integrator == ""
