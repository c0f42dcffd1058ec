"""Joint and drive effects (:mod:`hexapod_pin.core.effects`) in the generic tree routes.

References written here on raw Pinocchio and numpy: ``M + diag(armature)`` from ``crba``,
``h`` from ``nonLinearEffects``, the closures' null space from scipy's SVD, the effects'
force ``-D v - K dq - c sign(v)`` written out, and, for Coulomb friction at rest, the
stick / slip answer of a one-degree-of-freedom mechanism in closed form.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import scipy.integrate
import scipy.linalg

import hexapod_pin as hp
from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree
from hexapod_pin.core.effects import JointEffects
from hexapod_pin.core.freeze import freeze_joints
from hexapod_pin.core.tree_batch import forward_dynamics_tree_batch, inverse_dynamics_tree_batch
from hexapod_pin.errors import InputError

import stress_robots

DATA = Path(__file__).resolve().parents[1] / "data"


def _reference_forward(clm, eff, q, v, u):
    """``(M + A) a + h = S^T u - D v - K dq - c sign(v) + J^T lambda``, ``J a = -gamma``
    (null-space solve, written here; nothing at rest)."""
    model = pin.Model(clm.tree_model)
    model.armature[:] = 0.0
    data = model.createData()
    mass = pin.crba(model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T + np.diag(eff["armature"])
    bias = pin.nonLinearEffects(model, data, q, v)
    dq = pin.difference(model, eff["spring_reference"], q)
    # the spring force is minus the gradient of sum(K dq^2)/2, by central differences of
    # the energy along pin.integrate (exact -K dq on vector-space joints)
    energy = lambda x: 0.5 * np.sum(eff["stiffness"] * pin.difference(   # noqa: E731
        model, eff["spring_reference"], x) ** 2)
    step = 1e-6
    grad = np.array([(energy(pin.integrate(model, q, step * e)) - energy(pin.integrate(
        model, q, -step * e))) / (2 * step) for e in np.eye(clm.nv)])
    tau = np.zeros(clm.nv)
    tau[clm.actuated_v] = u
    tau += -eff["damping"] * v - grad - eff["coulomb"] * np.sign(v)
    del dq
    jac, gamma = clm.constraint_jacobian(q), clm.constraint_drift(q, v)
    null = scipy.linalg.null_space(jac, rcond=1e-10)
    part = np.linalg.lstsq(jac, -gamma, rcond=None)[0]
    z = np.linalg.solve(null.T @ mass @ null, null.T @ (tau - bias - mass @ part))
    return part + null @ z


def _random_effects(clm, rng, which):
    nv = clm.nv
    eff = {name: np.zeros(nv) for name in ("armature", "damping", "coulomb", "stiffness")}
    eff["spring_reference"] = pin.neutral(clm.tree_model)
    scales = {"armature": 0.3, "damping": 2.0, "coulomb": 0.7, "stiffness": 40.0}
    for name in which:
        eff[name] = rng.uniform(0.1, 1.0, nv) * scales[name]
    if "stiffness" in which:
        eff["spring_reference"] = pin.integrate(clm.tree_model, pin.neutral(clm.tree_model),
                                                rng.uniform(-0.2, 0.2, nv))
    return eff


def _state(clm, q, rng):
    """A random velocity keeping the closures (every coordinate moving: Coulomb's sign is
    defined at each)."""
    v = clm.velocity_from_actuated(q, rng.normal(size=clm.n_actuated))
    assert np.all(np.abs(v) > 1e-9)
    return v


ROBOTS = {
    "stewart": lambda: hp.load_robot(DATA / "stewart" / "stewart.urdf"),
    "four-bar": lambda: hp.load_robot(DATA / "four_bar" / "four_bar.urdf"),
}
EFFECT_SETS = [("armature",), ("damping",), ("stiffness",), ("coulomb",),
               ("armature", "damping", "stiffness", "coulomb")]


@pytest.fixture(scope="module", params=sorted(ROBOTS))
def loaded(request):
    return ROBOTS[request.param]()


@pytest.mark.parametrize("which", EFFECT_SETS, ids=["+".join(w) for w in EFFECT_SETS])
def test_each_effect_in_forward_and_inverse_dynamics_against_a_numpy_reference(loaded, which):
    rng = np.random.default_rng(3)
    clm = loaded.model
    q = loaded.kinematics.home_q
    v = _state(clm, q, rng)
    eff = _random_effects(clm, rng, which)
    model = clm.with_effects(**eff)
    u = rng.normal(size=clm.n_actuated) * 5.0
    ref = _reference_forward(clm, eff, q, v, u)
    scale = max(1.0, np.abs(ref).max())
    for method in ("pinocchio", "kkt", "qp"):
        res = forward_dynamics_tree(model, q, v, u, method=method)
        np.testing.assert_allclose(res.a, ref, atol=1e-10 * scale, err_msg=method)
    for method in ("kkt", "qp"):
        back = inverse_dynamics_tree(model, q, v, ref, method=method)
        np.testing.assert_allclose(back.actuator_forces, u, atol=1e-9 * max(1, np.abs(u).max()))
    # the rigid model is different (the test can fail)
    rigid = forward_dynamics_tree(clm, q, v, u).a
    assert np.abs(rigid - ref).max() > 1e-6 * scale


def test_batches_equal_single_states_with_effects(loaded):
    rng = np.random.default_rng(5)
    clm = loaded.model
    model = clm.with_effects(**_random_effects(clm, rng, ("armature", "damping", "stiffness",
                                                         "coulomb")))
    q0 = loaded.kinematics.home_q
    qs = np.array([q0] * 4)
    vs = np.array([_state(clm, q0, rng) for _ in range(4)])
    vs[3] = 0.0                                       # at rest: the stick / slip solve
    us = rng.normal(size=(4, clm.n_actuated))
    batch = forward_dynamics_tree_batch(model, qs, vs, us)
    for i in range(4):
        single = forward_dynamics_tree(model, qs[i], vs[i], us[i])
        np.testing.assert_allclose(batch.a[i], single.a, atol=1e-12 * max(1, np.abs(single.a).max()))
    inv = inverse_dynamics_tree_batch(model, qs, vs, batch.a)
    # moving states: the forces are unique; at rest the sticking coordinates' friction is
    # not, so the inverse answer is checked by forward dynamics instead
    np.testing.assert_allclose(inv.actuator_forces[:3], us[:3], atol=1e-9)
    again = forward_dynamics_tree(model, qs[3], vs[3], inv.actuator_forces[3]).a
    np.testing.assert_allclose(again, batch.a[3], atol=1e-9 * max(1, np.abs(again).max()))


def test_integrator_sees_the_effects():
    """RK4 simulation with damping only: the total energy drops by the dissipated work,
    integrated here from the recorded velocities (Simpson's rule)."""
    robot = ROBOTS["four-bar"]()
    clm = robot.model.with_effects(damping={"crank": 0.8, "rocker_pivot": 0.3})
    q = robot.kinematics.home_q
    v = clm.velocity_from_actuated(q, [2.0])
    res = hp.simulate(clm, 0.05, 1e-4, initial=(q, v))
    energies = res.energies
    damping = np.array([0.8 if name == "crank" else 0.3 if name == "rocker_pivot" else 0.0
                        for name in clm.model.names[1:]])
    power = np.einsum("ij,j,ij->i", res.v, damping, res.v)
    work = scipy.integrate.cumulative_simpson(power, x=res.times, initial=0.0)
    assert work[-1] > 1e-2 * abs(energies[0])
    np.testing.assert_allclose(energies + work, energies[0], atol=1e-8 * work[-1])


# -- Coulomb friction at rest: stick / slip ---------------------------------------------
def _one_dof_response(clm, q):
    """For a one-degree-of-freedom model: the crank acceleration per unit crank force
    ``g = n_c^2 / (n^T M n)`` and the rigid acceleration direction (null-space vector n)."""
    data = clm.model.createData()
    mass = pin.crba(clm.model, data, q)
    mass = np.triu(mass) + np.triu(mass, 1).T
    null = scipy.linalg.null_space(clm.constraint_jacobian(q), rcond=1e-10)
    assert null.shape[1] == 1
    n = null[:, 0]
    return n, mass


@pytest.mark.parametrize("load", [0.2, 0.9, 1.5, -1.5])
def test_coulomb_friction_at_rest_sticks_below_breakaway_and_slips_above(load):
    robot = ROBOTS["four-bar"]()
    clm = robot.model
    q = robot.kinematics.home_q
    v = np.zeros(clm.nv)
    crank = clm.joint_v_index("crank")
    rigid = forward_dynamics_tree(clm, q, v, [0.0]).a
    n, mass = _one_dof_response(clm, q)
    g = n[crank] ** 2 / (n @ mass @ n)
    breakaway = abs(rigid[crank]) / g          # the crank torque that holds it at rest
    c = 1.0 * breakaway
    model = clm.with_effects(coulomb={"crank": c})
    u = load * breakaway * np.sign(rigid[crank])   # pushing along (or against) gravity
    res = forward_dynamics_tree(model, q, v, [u])
    a_rigid = forward_dynamics_tree(clm, q, v, [u]).a[crank]
    need = a_rigid / g                          # friction torque that would stop it
    if abs(need) <= c:
        expected = 0.0
        assert "1 stick" in res.status
    else:
        expected = a_rigid - g * c * np.sign(a_rigid)
        assert "1 slip" in res.status
    assert res.a[crank] == pytest.approx(expected, abs=1e-9 * max(1.0, abs(a_rigid)))
    # the sign convention at zero velocity: inverse dynamics of the slip opposes a
    if expected != 0.0:
        back = inverse_dynamics_tree(model, q, v, res.a)
        assert back.actuator_forces[0] == pytest.approx(u, abs=1e-9 * max(1, abs(u)))


def test_sliding_friction_opposes_the_velocity_and_threshold_is_at_rest():
    robot = ROBOTS["four-bar"]()
    clm = robot.model
    q = robot.kinematics.home_q
    crank = clm.joint_v_index("crank")
    model = clm.with_effects(coulomb={"crank": 0.3}, velocity_threshold=1e-6)
    for speed in (0.5, -0.5):
        v = clm.velocity_from_actuated(q, [speed])
        a = forward_dynamics_tree(model, q, v, [0.0]).a
        a_plus = forward_dynamics_tree(clm, q, v, [-0.3 * np.sign(speed)]).a
        np.testing.assert_allclose(a, a_plus, atol=1e-10)
    v_tiny = clm.velocity_from_actuated(q, [1e-8])        # below the threshold: at rest
    res = forward_dynamics_tree(model, q, v_tiny, [0.0])
    assert "Coulomb friction at rest on 1" in res.status


# -- the record ---------------------------------------------------------------------------
def test_with_effects_returns_a_new_model_and_takes_names_or_arrays():
    robot = ROBOTS["four-bar"]()
    clm = robot.model
    by_name = clm.with_effects(damping={"crank": 0.5}, armature={"rocker_pivot": 0.1})
    arr = np.zeros(clm.nv)
    arr[clm.joint_v_index("crank")] = 0.5
    by_array = clm.with_effects(damping=arr)
    assert clm.effects.is_rigid and not by_name.effects.is_rigid
    np.testing.assert_array_equal(by_name.effects.damping, by_array.effects.damping)
    assert by_name.model.armature[clm.joint_v_index("rocker_pivot")] == 0.1
    # rotor inertia through the gear: gear^2 J_m
    geared = clm.with_effects(gear=[25.0], rotor_inertia=[2e-4])
    assert geared.effects.armature[clm.joint_v_index("crank")] == pytest.approx(625 * 2e-4)
    # a robot rebuilt with effects
    robot2 = robot.with_effects(damping={"crank": 0.5})
    assert robot2.effects.damping[clm.joint_v_index("crank")] == 0.5
    assert robot.effects.is_rigid


def test_an_armature_written_by_hand_is_adopted_everywhere():
    robot = ROBOTS["stewart"]()
    clm = robot.model.with_effects()
    q = robot.kinematics.home_q
    v = np.zeros(clm.nv)
    u = np.ones(clm.n_actuated)
    clm.model.armature[clm.actuated_v] = 0.5
    assert np.all(clm.effects.armature[clm.actuated_v] == 0.5)
    eff = {"armature": np.array(clm.model.armature), "damping": np.zeros(clm.nv),
           "coulomb": np.zeros(clm.nv), "stiffness": np.zeros(clm.nv),
           "spring_reference": pin.neutral(clm.tree_model)}
    ref = _reference_forward(clm, eff, q, v, u)
    np.testing.assert_allclose(forward_dynamics_tree(clm, q, v, u).a, ref, atol=1e-10)


@pytest.mark.parametrize("kwargs, match", [
    (dict(damping=-np.ones(3)), "must be >= 0"),
    (dict(damping=np.ones(2)), "expected shape"),
    (dict(damping={"nope": 1.0}), "not a joint"),
    (dict(stiffness=[np.nan, 0, 0]), "NaN"),
    (dict(armature=[1j, 0, 0]), "real numbers"),
    (dict(gear=[0.0]), "nonzero"),
    (dict(effort_limit=[-1.0]), "> 0"),
    (dict(gear={"rocker_pivot": 2.0}), "not an actuated joint"),
    (dict(frobnicate=1.0), "not a joint effect"),
    (dict(velocity_threshold=-1.0), ">= 0"),
    (dict(velocity_threshold=True), ">= 0"),
])
def test_bad_effects_are_refused_with_the_offending_value(kwargs, match):
    clm = ROBOTS["four-bar"]().model
    with pytest.raises(InputError, match=match):
        clm.with_effects(**kwargs)


def test_springs_on_a_free_flyer_use_the_tangent_space_and_need_a_unit_quaternion():
    """The Stewart platform's free-floating platform (a quaternion): a spring toward a
    reference configuration acts along ``pin.difference``; a reference with a non-unit
    quaternion is refused."""
    robot = ROBOTS["stewart"]()
    clm = robot.model
    q = robot.kinematics.home_q
    ref = q.copy()
    ref[-7:-4] += 0.01                             # platform 1 cm off its home position
    stiff = np.zeros(clm.nv)
    stiff[-6:] = 100.0
    model = clm.with_effects(stiffness=stiff, spring_reference=ref)
    v = np.zeros(clm.nv)
    got = forward_dynamics_tree(model, q, v, np.zeros(6)).a
    eff = {"armature": np.zeros(clm.nv), "damping": np.zeros(clm.nv),
           "coulomb": np.zeros(clm.nv), "stiffness": stiff, "spring_reference": ref}
    np.testing.assert_allclose(got, _reference_forward(clm, eff, q, v, np.zeros(6)),
                               atol=1e-10)
    bad = ref.copy()
    bad[-4:] = [0.5, 0.5, 0.5, 0.6]
    with pytest.raises(InputError, match="not unit"):
        clm.with_effects(stiffness=stiff, spring_reference=bad)


def test_a_record_of_another_tree_is_refused():
    four = ROBOTS["four-bar"]().model
    other = JointEffects.rigid(ROBOTS["stewart"]().model.model, 6)
    with pytest.raises(InputError, match="this tree needs"):
        four.with_effects(other)


def test_frozen_models_keep_the_effects_of_the_kept_coordinates():
    stress = stress_robots.build("ladder_mixed")
    rng = np.random.default_rng(8)
    clm = stress.clm.with_effects(damping=rng.uniform(0.1, 1.0, stress.clm.nv))
    q, _ = stress.sample(rng)
    frozen = freeze_joints(clm, ["bar_3"], q)
    np.testing.assert_array_equal(frozen.model.effects.damping, clm.effects.damping[frozen.v_index])


@pytest.mark.parametrize("name", ["five_bar_massless", "planar_ladder_weld", "delta_weld"])
def test_hard_classes_with_every_effect(name):
    """Massless links, redundant welds and masses over five orders of magnitude, with
    every effect: forward dynamics equals the null-space reference, inverse dynamics
    inverts it."""
    stress = stress_robots.build(name)
    rng = np.random.default_rng(13)
    q, v = stress.sample(rng)
    clm = stress.clm
    eff = _random_effects(clm, rng, ("armature", "damping", "stiffness", "coulomb"))
    eff["coulomb"][np.abs(v) <= 1e-6] = 0.0      # friction only where the sign is defined
    model = clm.with_effects(**eff)
    u = rng.normal(size=clm.n_actuated)
    ref = _reference_forward(clm, eff, q, v, u)
    res = forward_dynamics_tree(model, q, v, u, method="kkt")
    np.testing.assert_allclose(res.a, ref, atol=1e-8 * max(1.0, np.abs(ref).max()))
    back = inverse_dynamics_tree(model, q, v, res.a, method="kkt")
    np.testing.assert_allclose(back.actuator_forces, u, atol=1e-7 * max(1.0, np.abs(u).max()))


@pytest.mark.parametrize("method", ["nullspace", "pinocchio", "kkt"])
def test_loaded_robot_platform_dynamics_with_effects(loaded, method):
    """``robot.with_effects``: platform-level forward dynamics ("nullspace" solves the
    reduced equation, the others the tree) equals the tree reference mapped to the
    platform; inverse dynamics inverts it; reduced dynamics' bias holds the effects."""
    rng = np.random.default_rng(17)
    clm = loaded.model
    eff = _random_effects(clm, rng, ("armature", "damping", "stiffness", "coulomb"))
    robot = loaded.with_effects(**eff)
    pose = loaded.home_pose
    twist = rng.normal(size=loaded.pose_dim) * 0.1
    u = rng.normal(size=clm.n_actuated)
    fd = robot.forward_dynamics(pose, twist, u, method=method)
    back = robot.inverse_dynamics(pose, twist, fd.twist_dot)
    ref = _reference_forward(clm, eff, back.configuration, back.velocity, u)
    np.testing.assert_allclose(fd.tree_acceleration, ref, atol=1e-9 * max(1, np.abs(ref).max()))
    np.testing.assert_allclose(back.actuator_forces, u, atol=1e-8 * max(1, np.abs(u).max()))
    red = robot.reduced_dynamics(pose, twist)
    lhs = red.mass_matrix @ fd.twist_dot + red.bias
    np.testing.assert_allclose(lhs, red.jacobian.T @ u, atol=1e-8 * max(1, np.abs(lhs).max()))
