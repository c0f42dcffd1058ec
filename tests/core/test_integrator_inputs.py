"""``ClosedLoopIntegrator``: its input checks, and continuous, ball, planar, SphericalZYX
and translation joints.

Independent routes: the configuration rate against central differences of
``pin.integrate``; the semi-implicit Euler step against ``pin.aba`` and ``pin.integrate``;
RK4 runs of a four-bar whose passive joints are continuous and of a spatial loop with a
ball joint checked against the anchor distance (numpy, from Pinocchio's frame placements)
and against the total energy from ``pin.computeKineticEnergy`` /
``pin.computePotentialEnergy``.
"""

from __future__ import annotations

import math

import numpy as np
import pinocchio as pin
import pytest
import stress_robots
from hypothesis import given, settings
from hypothesis import strategies as st

from hexapod_pin.core.closed_loop import ClosedLoopModel
from hexapod_pin.core.description import build_model, parse_loops
from hexapod_pin.core.simulation import PROJECTION_TOL, ClosedLoopIntegrator
from hexapod_pin.errors import InputError

PROFILE = settings(max_examples=30, deadline=None, database=None, derandomize=True)


def _inertial(mass: float, com: str) -> str:
    return (f'<inertial><origin xyz="{com}"/><mass value="{mass}"/><inertia '
            f'ixx="{mass * 0.01}" ixy="0" ixz="0" iyy="{mass * 0.01}" iyz="0" '
            f'izz="{mass * 0.002}"/></inertial>')


#: a planar four-bar in the x-z plane (hinges about y): a revolute crank, a coupler and a
#: rocker on URDF ``continuous`` joints (Pinocchio's JointModelRUBY, q = (cos, sin))
FOUR_BAR = f"""<?xml version="1.0"?>
<robot name="four_bar"><link name="world"/>
<joint name="crank" type="revolute"><parent link="world"/><child link="crank"/>
  <axis xyz="0 1 0"/><limit lower="-10" upper="10" effort="1" velocity="10"/></joint>
<link name="crank">{_inertial(1.0, "0 0 0.1")}</link>
<joint name="coupler" type="continuous"><parent link="crank"/><child link="coupler"/>
  <origin xyz="0 0 0.2"/><axis xyz="0 1 0"/></joint>
<link name="coupler">{_inertial(0.5, "0.25 0 0")}</link>
<joint name="coupler_tip_mount" type="fixed"><parent link="coupler"/>
  <child link="coupler_tip"/><origin xyz="0.5 0 0"/></joint>
<link name="coupler_tip"/>
<joint name="rocker" type="continuous"><parent link="world"/><child link="rocker"/>
  <origin xyz="0.4 0 0"/><axis xyz="0 1 0"/></joint>
<link name="rocker">{_inertial(0.8, "0 0 0.17")}</link>
<joint name="rocker_tip_mount" type="fixed"><parent link="rocker"/>
  <child link="rocker_tip"/><origin xyz="0 0 0.35"/></joint>
<link name="rocker_tip"/>
</robot>
"""
FOUR_BAR_LOOPS = ("closures:\n  - {name: pin, type: point, frame1: coupler_tip, "
                  "frame2: rocker_tip}\nactuated: [crank]\n")

#: every joint kind of the integrator on one tree without closures: a free-flyer root,
#: continuous joints on an axis and off the axes, a planar joint, a nested free-flyer
MIXED = f"""<?xml version="1.0"?>
<robot name="mixed"><link name="base">{_inertial(2.0, "0 0 0")}</link>
<joint name="c_x" type="continuous"><parent link="base"/><child link="l1"/>
  <origin xyz="0.1 0 0"/><axis xyz="1 0 0"/></joint>
<link name="l1">{_inertial(1.0, "0 0.1 0")}</link>
<joint name="c_tilted" type="continuous"><parent link="l1"/><child link="l2"/>
  <origin xyz="0 0.2 0"/><axis xyz="0 0.6 0.8"/></joint>
<link name="l2">{_inertial(1.0, "0.1 0 0")}</link>
<joint name="plane" type="planar"><parent link="l2"/><child link="l3"/>
  <origin xyz="0.2 0 0" rpy="0.3 0.2 0.1"/><axis xyz="0 0 1"/></joint>
<link name="l3">{_inertial(1.0, "0 0 0.1")}</link>
<joint name="hinge" type="revolute"><parent link="l3"/><child link="l4"/>
  <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
<link name="l4">{_inertial(1.0, "0.1 0 0")}</link>
<joint name="float" type="floating"><parent link="l4"/><child link="l5"/>
  <origin xyz="0 0 0.3"/></joint>
<link name="l5">{_inertial(1.0, "0 0 0.05")}</link>
</robot>
"""


def mixed_model() -> ClosedLoopModel:
    """:data:`MIXED` with a ball joint, a SphericalZYX joint and a translation joint
    added (URDF has no such joints), each carrying a body."""
    model = build_model(MIXED, root_joint=pin.JointModelFreeFlyer())
    parent = model.getJointId("hinge")
    inertia = pin.Inertia(0.7, np.array([0.05, 0.0, 0.1]), np.diag([0.02, 0.03, 0.01]))
    for name, joint, xyz in (("ball", pin.JointModelSpherical(), [0.0, 0.1, 0.2]),
                             ("zyx", pin.JointModelSphericalZYX(), [0.1, 0.0, 0.2]),
                             ("slide3", pin.JointModelTranslation(), [0.0, 0.2, 0.1])):
        jid = model.addJoint(parent, joint, pin.SE3(np.eye(3), np.array(xyz)), name)
        model.appendBodyToJoint(jid, inertia, pin.SE3.Identity())
        parent = jid
    return ClosedLoopModel(model, parse_loops("closures: []\nactuated: []\n"))


def ball_loop() -> ClosedLoopModel:
    """A spatial loop: arm A hinged about y at the origin (0.5 m down), arm C hinged about
    z at A's tip (0.4 m along x), rod B hung from (0.4, 0, 0) by a ball joint (0.5 m
    down); C's tip pinned to B's tip (point closure). Mobility 2 (one: B's spin)."""
    model = pin.Model()

    def body(jid, mass, com):
        model.appendBodyToJoint(jid, pin.Inertia(mass, np.array(com), np.diag(
            [mass * 0.01, mass * 0.01, mass * 0.002])), pin.SE3.Identity())
    a = model.addJoint(0, pin.JointModelRY(), pin.SE3.Identity(), "A")
    body(a, 1.0, [0.0, 0.0, -0.25])
    c = model.addJoint(a, pin.JointModelRZ(), pin.SE3(np.eye(3), np.array([0, 0, -0.5])), "C")
    body(c, 0.5, [0.2, 0.0, 0.0])
    b = model.addJoint(0, pin.JointModelSpherical(), pin.SE3(np.eye(3), np.array([0.4, 0, 0])),
                       "B")
    body(b, 0.7, [0.0, 0.0, -0.25])
    for name, jid, xyz in (("c_tip", c, [0.4, 0.0, 0.0]), ("b_tip", b, [0.0, 0.0, -0.5])):
        model.addFrame(pin.Frame(name, jid, pin.SE3(np.eye(3), np.array(xyz)),
                                 pin.FrameType.OP_FRAME))
    return ClosedLoopModel(model, parse_loops(
        "closures:\n  - {name: ball, type: point, frame1: c_tip, frame2: b_tip}\n"
        "actuated: [A]\n"))


def ladder() -> ClosedLoopModel:
    return stress_robots.ladder_model(1, [1.0, 0.5], [0.3])


_LADDER: list = []


def ladder_state():
    """(integrator, q, v, tau) of the one-loop ladder, assembled (built once)."""
    if not _LADDER:
        clm = ladder()
        q = clm.assemble(pin.neutral(clm.model) + 0.2).q
        v = clm.complete_velocity(q, clm.actuated_v, [0.5])
        _LADDER.append((ClosedLoopIntegrator(clm), q, v, np.zeros(clm.nv)))
    return _LADDER[0]


# ----------------------------------------------------------------------- input checks
BAD_DT = [math.nan, math.inf, -math.inf, -1e-3, 0.0, -0.0, "0.001", None, True, 1j,
          np.array([1e-3]), [1e-3]]


@pytest.mark.parametrize("dt", BAD_DT, ids=[repr(x) for x in BAD_DT])
def test_step_refuses_a_bad_dt(dt):
    sim, q, v, tau = ladder_state()
    with pytest.raises(InputError) as info:
        sim.step(q, v, tau, dt)
    assert info.value.name == "dt"


@PROFILE
@given(st.one_of(st.floats(max_value=0.0), st.just(math.nan), st.just(math.inf),
                 st.integers(max_value=0)))
def test_step_refuses_non_positive_or_non_finite_dt(dt):
    sim, q, v, tau = ladder_state()
    with pytest.raises(InputError):
        sim.step(q, v, tau, dt)


@pytest.mark.parametrize("tol", BAD_DT, ids=[repr(x) for x in BAD_DT])
def test_step_refuses_a_bad_projection_tol(tol):
    sim, q, v, tau = ladder_state()
    with pytest.raises(InputError) as info:
        sim.step(q, v, tau, 1e-3, tol)
    assert info.value.name == "projection_tol"


def test_step_accepts_numbers_of_other_types_and_lists():
    """``np.float64`` and int ``dt``, lists and non-contiguous arrays: the same step as
    float64 arrays."""
    sim, q, v, tau = ladder_state()
    want = sim.step(q, v, tau, 1e-3)
    for args in ((list(q), list(v), list(tau), np.float64(1e-3)),
                 (np.repeat(q, 2)[::2], np.repeat(v, 2)[::2], tau, 1e-3),
                 (q, v, tau.tolist(), 1e-3)):
        got = sim.step(*args)
        np.testing.assert_allclose(got[0], want[0], rtol=0, atol=1e-14)
        np.testing.assert_allclose(got[1], want[1], rtol=0, atol=1e-12)
    sim.step(q, v, tau, 1)          # an int dt (1 s) is a real number
    sim.step(q, v, tau, 1e-3, np.float64(1e-9))


def _bad_states(q, v, tau):
    nan_q, inf_v, nan_tau = q.copy(), v.copy(), tau.copy()
    nan_q[1], inf_v[0], nan_tau[-1] = np.nan, np.inf, np.nan
    return [
        ("tau", (q, v, np.zeros(1))),                      # the (1,) tau
        ("tau", (q, v, np.zeros(tau.size + 1))),
        ("q", (q[:-1], v, tau)),
        ("v", (q, np.zeros((v.size, 1)), tau)),
        ("q", (nan_q, v, tau)),
        ("v", (q, inf_v, tau)),
        ("tau", (q, v, nan_tau)),
        ("q", (["a"] * q.size, v, tau)),
        ("v", (q, v.astype(complex), tau)),
        ("tau", (q, v, None)),
        ("tau", (q, v, np.ones(tau.size, dtype=bool))),
    ]


@pytest.mark.parametrize("integrator", ["rk4", "semi_implicit_euler"])
def test_step_refuses_bad_states_naming_them(integrator):
    _, q, v, tau = ladder_state()
    sim = ClosedLoopIntegrator(ladder(), integrator=integrator)
    for name, args in _bad_states(q, v, tau):
        with pytest.raises(InputError) as info:
            sim.step(*args, 1e-3)
        assert info.value.name == name, (name, args)


@PROFILE
@given(size=st.integers(0, 12), where=st.integers(0, 11),
       value=st.sampled_from([math.nan, math.inf, -math.inf, 1.0]))
def test_step_refuses_any_tau_of_the_wrong_size_or_not_finite(size, where, value):
    sim, q, v, tau = ladder_state()
    bad = np.zeros(size)
    if size:
        bad[where % size] = value
    if size == tau.size and value == 1.0:
        sim.step(q, v, bad, 1e-3)               # a good one
        return
    with pytest.raises(InputError) as info:
        sim.step(q, v, bad, 1e-3)
    assert info.value.name == "tau"


# ------------------------------------------------------------- joints: the kinematics
def test_configuration_rate_of_every_joint_kind_against_pin_integrate():
    """``qdot`` of the integrator (continuous joints on and off the axes, planar, ball,
    SphericalZYX, translation, revolute and two free-flyers) against a central difference
    of ``pin.integrate`` at random states."""
    clm = mixed_model()
    model = clm.model
    names = {model.joints[j].shortname() for j in range(1, model.njoints)}
    assert {"JointModelRUBX", "JointModelRevoluteUnboundedUnaligned", "JointModelPlanar",
            "JointModelSpherical", "JointModelSphericalZYX", "JointModelTranslation",
            "JointModelFreeFlyer", "JointModelRZ"} <= names
    sim = ClosedLoopIntegrator(clm)
    rng = np.random.default_rng(8)
    eps = 1e-6
    for _ in range(5):
        q = pin.integrate(model, pin.neutral(model), rng.uniform(-2.0, 2.0, model.nv))
        v = rng.normal(size=model.nv)
        fd = (pin.integrate(model, q, eps * v) - pin.integrate(model, q, -eps * v)) / (2 * eps)
        np.testing.assert_allclose(sim.qdot(q, v), fd, rtol=0, atol=1e-8)


@pytest.mark.parametrize("integrator", ["rk4", "semi_implicit_euler"])
def test_steps_keep_the_unit_parts_and_euler_matches_pin(integrator):
    """A large step of the tree with every joint kind: the quaternions and (cos, sin)
    pairs stay unit; the semi-implicit Euler step is ``v + dt aba``,
    ``pin.integrate(q, dt v')``."""
    clm = mixed_model()
    model = clm.model
    sim = ClosedLoopIntegrator(clm, integrator=integrator)
    rng = np.random.default_rng(2)
    q = pin.integrate(model, pin.neutral(model), rng.uniform(-1.0, 1.0, model.nv))
    v, tau = rng.normal(size=model.nv), rng.normal(size=model.nv)
    dt = 0.05
    q_new, v_new, _ = sim.step(q, v, tau, dt)
    units = [(iq + 3, 4) for iq in _starts(model, "JointModelFreeFlyer")] + \
        [(iq, 4) for iq in _starts(model, "JointModelSpherical")] + \
        [(iq, 2) for iq in _starts(model, "JointModelRUBX")] + \
        [(iq, 2) for iq in _starts(model, "JointModelRevoluteUnboundedUnaligned")] + \
        [(iq + 2, 2) for iq in _starts(model, "JointModelPlanar")]
    assert len(units) == 6
    for start, size in units:
        assert abs(np.linalg.norm(q_new[start:start + size]) - 1.0) < 1e-14
    if integrator == "semi_implicit_euler":
        acc = pin.aba(model, model.createData(), q, v, tau)
        np.testing.assert_allclose(v_new, v + dt * acc, rtol=1e-10, atol=1e-10)
        np.testing.assert_allclose(q_new, pin.integrate(model, q, dt * v_new), rtol=0,
                                   atol=1e-12)


def _starts(model, kind):
    return [model.joints[j].idx_q for j in range(1, model.njoints)
            if model.joints[j].shortname() == kind]


def test_unsupported_joints_are_still_refused():
    model = pin.Model()
    jid = model.addJoint(0, pin.JointModelHX(0.1), pin.SE3.Identity(), "screw")
    model.appendBodyToJoint(jid, pin.Inertia.Random(), pin.SE3.Identity())
    clm = ClosedLoopModel(model, parse_loops("closures: []\nactuated: []\n"))
    with pytest.raises(InputError, match="JointModelHX"):
        ClosedLoopIntegrator(clm)


# ------------------------------------------------- closed loops with the new joints
def _anchor_distance(clm, q) -> float:
    data = clm.model.createData()
    pin.framesForwardKinematics(clm.model, data, q)
    return max(float(np.linalg.norm(
        data.oMf[clm.model.getFrameId(f"{c.name}/anchor1")].translation
        - data.oMf[clm.model.getFrameId(f"{c.name}/anchor2")].translation))
        for c in clm.closures)


def _energy(clm, q, v) -> tuple[float, float]:
    data = clm.model.createData()
    kinetic = pin.computeKineticEnergy(clm.model, data, q, v)
    return kinetic + pin.computePotentialEnergy(clm.model, data, q), kinetic


def _run(clm, q, v, steps=600, dt=1e-3):
    """RK4, unactuated: (largest anchor distance, energy drift, largest kinetic energy)."""
    sim = ClosedLoopIntegrator(clm, integrator="rk4")
    e0, _ = _energy(clm, q, v)
    worst, drift, k_max = 0.0, 0.0, 0.0
    tau = np.zeros(clm.nv)
    for _ in range(steps):
        q, v, res = sim.step(q, v, tau, dt)
        assert res <= PROJECTION_TOL
        e, k = _energy(clm, q, v)
        worst, drift, k_max = max(worst, _anchor_distance(clm, q)), max(drift, abs(e - e0)), \
            max(k_max, k)
    return worst, drift, k_max, q


def test_rk4_four_bar_on_continuous_joints_keeps_closures_and_energy():
    clm = ClosedLoopModel(build_model(FOUR_BAR), parse_loops(FOUR_BAR_LOOPS))
    kinds = [clm.model.joints[j].shortname() for j in range(1, clm.model.njoints)]
    assert kinds == ["JointModelRY", "JointModelRUBY", "JointModelRUBY"]
    q = clm.assemble(pin.neutral(clm.model)).q
    v = clm.complete_velocity(q, clm.actuated_v, [3.0])
    worst, drift, k_max, q_end = _run(clm, q, v)
    assert worst <= 2 * PROJECTION_TOL            # anchors' distance (m; rows: max-abs)
    assert k_max > 1.0
    assert drift <= 1e-6 * k_max
    for name in ("coupler", "rocker"):
        i = clm.joint_q_index(name)
        assert abs(math.hypot(q_end[i], q_end[i + 1]) - 1.0) < 1e-14
    assert abs(q_end[0] - q[0]) > 0.5                  # it moved


def test_rk4_spatial_loop_with_a_ball_joint_keeps_closures_and_energy():
    clm = ball_loop()
    start = pin.integrate(clm.model, pin.neutral(clm.model), np.array([0.3, 0.4, 0.2, -0.1,
                                                                        0.3]))
    q = clm.assemble(start, fixed=[]).q
    v = clm.complete_velocity(q, [0, 4], [2.0, 1.0])
    worst, drift, k_max, q_end = _run(clm, q, v)
    assert worst <= 2 * PROJECTION_TOL
    assert k_max > 1.0
    assert drift <= 1e-6 * k_max
    i = clm.joint_q_index("B")
    assert abs(np.linalg.norm(q_end[i:i + 4]) - 1.0) < 1e-14


def test_rk4_local_error_is_fifth_order_with_every_joint_kind():
    """One RK4 step of ``h`` from a state of the tree with every joint kind, against 32
    steps of ``h / 32``: the error (``pin.difference``) falls like ``h^5`` (a factor near 32
    when ``h`` halves): a wrong rate of any joint kind, or a unit part left off its
    manifold at the step's end, loses orders."""
    clm = mixed_model()
    model = clm.model
    rng = np.random.default_rng(6)
    q0 = pin.integrate(model, pin.neutral(model), rng.uniform(-1.0, 1.0, model.nv))
    v0, tau = 2.0 * rng.normal(size=model.nv), rng.normal(size=model.nv)
    sim = ClosedLoopIntegrator(clm, integrator="rk4")

    def error(h):
        q, v, _ = sim.step(q0, v0, tau, h)
        q_ref, v_ref = q0, v0
        for _ in range(32):
            q_ref, v_ref, _ = sim.step(q_ref, v_ref, tau, h / 32)
        return np.linalg.norm(np.r_[pin.difference(model, q_ref, q), v - v_ref])

    ratio = error(0.01) / error(0.005)
    assert 20.0 < ratio < 50.0, ratio
