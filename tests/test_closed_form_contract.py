"""The closed-form contract (:mod:`hexapod_pin.core.closed_form`): both robots' dynamics are
built on it, a third closed form written here gets the plumbing (bounds, checks, errors,
batches, statics, energies, lazy details) by supplying only the contract's kernels, and
the hexapod's and planar robot's numbers are those stored before the rebuild.

The third closed form is a vertical lift: an actuated carriage (prismatic along world z)
carries a platform that hangs from the world on its own prismatic z joint, the loop closed
by a point closure between them. Its closed form (``tau = (m_c + m_p)(zdd + g) - f``) is
checked against a KKT solve on raw Pinocchio written in the test.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, NoReturn

import numpy as np
import pinocchio as pin
import pytest

import hexapod_pin as hp
from hexapod_pin.core import kernel_status
from hexapod_pin.core.closed_form import (ClosedFormDynamics, ClosedFormKernels, Inputs,
                                          LazyParts, TreeDetails, check_batch)
from hexapod_pin.core.closed_loop import ClosedLoopModel
from hexapod_pin.core.description import build_model, parse_loops
from hexapod_pin.core.dynamics import ClosedLoopDynamics
from hexapod_pin.core.results import (ForwardDynamicsResult, InverseDynamicsResult,
                                      ReducedDynamics)
from hexapod_pin.errors import (ActuatorSaturationError, BatchActuatorSaturationError,
                                BatchUnreachablePoseError, InputError, UnreachablePoseError)
from hexapod_pin.hexapod.dynamics import HexapodDynamics
from hexapod_pin.planar.dynamics import PlanarDynamics

REFERENCE = Path(__file__).resolve().parent / "data" / "closed_form_reference.npz"
G = 9.81
M_CARRIAGE, M_PLATFORM = 0.7, 1.3
STROKE = 1.0

LIFT_URDF = f"""<?xml version="1.0"?>
<robot name="lift">
  <link name="world"/>
  <joint name="lift" type="prismatic">
    <parent link="world"/><child link="carriage"/><axis xyz="0 0 1"/>
    <limit lower="-2" upper="2" effort="100" velocity="10"/>
  </joint>
  <link name="carriage">
    <inertial><origin xyz="0 0 0.05"/><mass value="{M_CARRIAGE}"/>
      <inertia ixx="0.01" iyy="0.01" izz="0.01" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="carriage_tip_joint" type="fixed">
    <parent link="carriage"/><child link="carriage_tip"/><origin xyz="0.2 0 0.1"/>
  </joint>
  <link name="carriage_tip"/>
  <joint name="platform_z" type="prismatic">
    <parent link="world"/><child link="platform"/><origin xyz="0.2 0 0.1"/>
    <axis xyz="0 0 1"/><limit lower="-2" upper="2" effort="100" velocity="10"/>
  </joint>
  <link name="platform">
    <inertial><origin xyz="0 0 0.02"/><mass value="{M_PLATFORM}"/>
      <inertia ixx="0.02" iyy="0.02" izz="0.02" ixy="0" ixz="0" iyz="0"/></inertial>
  </link>
  <joint name="platform_anchor_joint" type="fixed">
    <parent link="platform"/><child link="platform_anchor"/>
  </joint>
  <link name="platform_anchor"/>
</robot>
"""
LIFT_LOOPS = """closures:
  - {name: hold, type: point, frame1: carriage_tip, frame2: platform_anchor}
actuated: [lift]
"""


class LiftGeometry:
    """The lift's one design number (what the base reads from a geometry)."""

    def __init__(self, max_actuator_force: float = np.inf) -> None:
        self.max_actuator_force = max_actuator_force


def lift_model() -> ClosedLoopModel:
    model = build_model(LIFT_URDF, source="lift")
    model.gravity = pin.Motion(np.array([0.0, 0.0, -G, 0.0, 0.0, 0.0]))
    return ClosedLoopModel(model, parse_loops(LIFT_LOOPS), name="lift", urdf_xml=LIFT_URDF)


class LiftDynamics(ClosedFormDynamics):
    """A closed form that supplies only the contract's kernels: the tree state, the wrench
    on the tree, its errors and the three single-state routes (pose = platform height z)."""

    dim = 1
    n_actuators = 1
    closure_shape = (1, 3)
    INVERSE_METHODS = ("kkt",)
    FORWARD_METHODS = ("nullspace",)

    def __init__(self, model: ClosedLoopModel, geometry: LiftGeometry) -> None:
        super().__init__(geometry, model, None, lambda pose, branch: None)  # type: ignore
        self.dyn = ClosedLoopDynamics(model)
        self.coords = np.array([model.joint_v_index("lift"), model.joint_v_index("platform_z")])
        self.platform_v = model.joint_v_index("platform_z")

    @property
    def batch_kernels_apply(self) -> bool:
        return False                        # no batch kernels: the base runs state by state

    def _state(self, pose: Any, twist: Any) -> tuple[np.ndarray, np.ndarray]:
        p, t = self.vector(pose, "pose"), self.vector(twist, "twist")
        code = kernel_status.OK
        if not (np.isfinite(p).all() and np.isfinite(t).all()):
            code = kernel_status.NONFINITE
        elif abs(p[0]) > STROKE:
            code = kernel_status.UNREACHABLE
        if code != kernel_status.OK:
            self.refuse(code, ((pose, "pose"), (twist, "twist")))
        q, v = np.zeros(self.model.nq), np.zeros(self.model.nv)
        q[self.coords], v[self.coords] = p[0], t[0]
        return q, v

    def tree_state(self, pose: Any, twist: Any, branch: Any = None
                   ) -> tuple[np.ndarray, np.ndarray]:
        return self._state(pose, twist)

    def tau_ext(self, wrench: np.ndarray | None, pose: np.ndarray) -> np.ndarray:
        tau = np.zeros(self.model.nv)
        if wrench is not None:
            tau[self.platform_v] = wrench[0]
        return tau

    def raise_kernel_status(self, code: int, inputs: Inputs, info: np.ndarray | None = None,
                            index: int | None = None, pose: np.ndarray | None = None
                            ) -> NoReturn:
        z = float(np.asarray(inputs[0][0] if pose is None else pose, dtype=float)[0])
        raise UnreachablePoseError([0], [abs(z) - STROKE])

    def _details(self, state: tuple, tau: np.ndarray, wrench: np.ndarray | None,
                 pose: np.ndarray, push: float) -> TreeDetails:
        # the carriage pushes the platform up with `push`; the multiplier is the force of
        # the platform ON the carriage (frame1), world axes
        parts = LazyParts(self.dyn, self.lock, to_multipliers=lambda closure: -closure.ravel())
        return TreeDetails(parts, state, tau, tau_ext=self.tau_ext(wrench, pose),
                           closure=np.array([[0.0, 0.0, push]]), wanted=False)

    def _inputs(self, wrench: Any) -> np.ndarray | None:
        return None if wrench is None else self.vector(wrench, "wrench")

    def inverse_dynamics(self, pose: Any, twist: Any, twist_dot: Any, wrench: Any = None, *,
                         branch: Any = None, method: str = "kkt", bounded: bool = True,
                         joint_wrenches: bool = True) -> InverseDynamicsResult:
        self.check_method(method, self.INVERSE_METHODS)
        q, v = self._state(pose, twist)
        acc, w = self.vector(twist_dot, "twist_dot"), self._inputs(wrench)
        f = 0.0 if w is None else w[0]
        tau = np.array([(M_CARRIAGE + M_PLATFORM) * (acc[0] + G) - f])
        self.check_bounds(tau, self.bounds(bounded))
        a = np.zeros(self.model.nv)
        a[self.coords] = acc[0]
        pose_a = np.array(pose, dtype=float)
        details = self._details((q, v, a), tau, w, pose_a, M_PLATFORM * (acc[0] + G) - f)
        return InverseDynamicsResult(tau, q, v, a, method, "solved", 0, details,
                                     self.conditioning(pose_a, np.ones(1)))

    def forward_dynamics(self, pose: Any, twist: Any, actuator_forces: Any, wrench: Any = None,
                         *, branch: Any = None, method: str = "nullspace"
                         ) -> ForwardDynamicsResult:
        self.check_method(method, self.FORWARD_METHODS)
        q, v = self._state(pose, twist)
        tau, w = self.vector(actuator_forces, "actuator_forces"), self._inputs(wrench)
        f = 0.0 if w is None else w[0]
        zdd = (tau[0] + f) / (M_CARRIAGE + M_PLATFORM) - G
        a = np.zeros(self.model.nv)
        a[self.coords] = zdd
        pose_a = np.array(pose, dtype=float)
        details = self._details((q, v, a), tau, w, pose_a, M_PLATFORM * (zdd + G) - f)
        return ForwardDynamicsResult(np.array([zdd]), np.array([zdd]), a, method, "solved", 0,
                                     details, self.conditioning(pose_a, np.ones(1)))

    def reduced_dynamics(self, pose: Any, twist: Any, branch: Any = None) -> ReducedDynamics:
        self._state(pose, twist)
        total = M_CARRIAGE + M_PLATFORM
        vmap = np.zeros((self.model.nv, 1))
        vmap[self.coords] = 1.0
        return ReducedDynamics(np.array([[total]]), np.array([total * G]), np.ones((1, 1)),
                               vmap)


@pytest.fixture(scope="module")
def lift() -> LiftDynamics:
    return LiftDynamics(lift_model(), LiftGeometry())


def kkt_reference(clm: ClosedLoopModel, q: np.ndarray, v: np.ndarray,
                  tau_ext: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``M``, ``h``, ``J_c`` on raw Pinocchio (the closure's translational rows)."""
    model = clm.model
    data = model.createData()
    mass = pin.crba(model, data, q)
    bias = pin.rnea(model, data, q, v, np.zeros(model.nv)) - tau_ext
    pin.computeJointJacobians(model, data, q)
    pin.framesForwardKinematics(model, data, q)
    jac = [pin.getFrameJacobian(model, data, model.getFrameId(name),
                                pin.ReferenceFrame.LOCAL_WORLD_ALIGNED)[:3]
           for name in ("carriage_tip", "platform_anchor")]
    return mass, bias, jac[0] - jac[1]


# -- the contract -------------------------------------------------------------------------------
def test_both_robots_are_built_on_the_contract():
    hexapod, planar = hp.Hexapod.default(), hp.Planar3PRR.default()
    assert issubclass(HexapodDynamics, ClosedFormDynamics)
    assert issubclass(PlanarDynamics, ClosedFormDynamics)
    for robot in (hexapod, planar):
        assert isinstance(robot.dynamics, ClosedFormKernels)
        # the batches, energies and statics' error plumbing come from the base, once
        assert type(robot.dynamics).inverse_dynamics_batch is \
            ClosedFormDynamics.inverse_dynamics_batch
        assert type(robot.dynamics).energies is ClosedFormDynamics.energies


def test_a_closed_form_missing_a_kernel_cannot_be_built():
    class Incomplete(ClosedFormDynamics):
        dim, n_actuators, closure_shape = 1, 1, (1, 3)

    with pytest.raises(TypeError, match="abstract"):
        Incomplete(LiftGeometry(), lift_model(), None, lambda pose, branch: None)  # type: ignore


def test_batch_checks_name_the_bad_array():
    with pytest.raises(InputError, match="twists"):
        check_batch(1, 1, poses=np.zeros((3, 1)), twists=np.zeros((2, 1)))
    with pytest.raises(InputError, match="actuator_forces"):
        check_batch(1, 2, poses=np.zeros((3, 1)), actuator_forces=np.zeros((3, 1)))
    with pytest.raises(InputError, match="twists"):
        check_batch(1, 1, poses=np.zeros((3, 1)), twists=None)
    poses, wrenches = check_batch(1, 1, poses=[[0.1], [0.2]], wrenches=None)
    assert poses.shape == (2, 1) and wrenches is None


# -- a third closed form gets the plumbing ------------------------------------------------------
@pytest.mark.parametrize("z, zd, zdd, f", [(0.1, 0.3, -0.7, None), (-0.4, -1.2, 2.5, 3.0)])
def test_the_lift_answers_as_a_kkt_solve_on_raw_pinocchio(lift, z, zd, zdd, f):
    wrench = None if f is None else [f]
    res = lift.inverse_dynamics([z], [zd], [zdd], wrench)
    q, v = lift.tree_state([z], [zd])
    tau_ext = lift.tau_ext(None if f is None else np.array([f]), np.array([z]))
    mass, bias, jac_c = kkt_reference(lift.model, q, v, tau_ext)
    a = np.zeros(lift.model.nv)
    a[lift.coords] = zdd
    # M a + h - tau_ext = S^T tau + J_c^T lambda: least squares in (tau, lambda)
    sel = np.zeros((lift.model.nv, 1))
    sel[lift.model.actuated_v, 0] = 1.0
    unknowns = np.linalg.lstsq(np.hstack([sel, jac_c.T]), mass @ a + bias, rcond=None)[0]
    np.testing.assert_allclose(res.actuator_forces, unknowns[:1], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(res.multipliers, unknowns[1:], rtol=1e-12, atol=1e-12)
    assert res.residual <= 1e-12 and res.joint_wrenches == {}
    # forward: the KKT system [[M, -J_c^T], [J_c, 0]] (a, lambda) = (S^T tau - h, 0)
    kkt = np.block([[mass, -jac_c.T], [jac_c, np.zeros((3, 3))]])
    rhs = np.concatenate([sel[:, 0] * res.actuator_forces[0] - bias, np.zeros(3)])
    sol = np.linalg.lstsq(kkt, rhs, rcond=None)[0]
    fd = lift.forward_dynamics([z], [zd], res.actuator_forces, wrench)
    np.testing.assert_allclose(fd.twist_dot, [sol[lift.platform_v]], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(fd.twist_dot, [zdd], rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(fd.multipliers, res.multipliers, rtol=1e-12, atol=1e-12)


def test_the_lift_gets_statics_energies_and_batches_from_the_base(lift):
    total = M_CARRIAGE + M_PLATFORM
    np.testing.assert_allclose(lift.static_forces([0.2], [1.5]), [total * G - 1.5], rtol=1e-14)
    e = lift.energies([0.3], [0.8])
    assert e.kinetic == pytest.approx(0.5 * total * 0.8 ** 2, rel=1e-14)
    heights = (M_CARRIAGE * (0.3 + 0.05) + M_PLATFORM * (0.3 + 0.1 + 0.02)) * G
    assert e.potential == pytest.approx(heights, rel=1e-12)
    rng = np.random.default_rng(3)
    poses, twists = rng.uniform(-0.5, 0.5, (4, 1)), rng.uniform(-1, 1, (4, 1))
    accs, wrenches = rng.uniform(-2, 2, (4, 1)), rng.uniform(-1, 1, (4, 1))
    batch = lift.inverse_dynamics_batch(poses, twists, accs, wrenches)
    for k in range(4):
        single = lift.inverse_dynamics(poses[k], twists[k], accs[k], wrenches[k])
        np.testing.assert_array_equal(batch.actuator_forces[k], single.actuator_forces)
        np.testing.assert_array_equal(batch.closure_forces[k], single.closure_forces)
    fb = lift.forward_dynamics_batch(poses, twists, batch.actuator_forces, wrenches)
    np.testing.assert_allclose(fb.twist_dot, accs, rtol=1e-12, atol=1e-12)
    np.testing.assert_allclose(lift.static_forces_batch(poses), np.full((4, 1), total * G))
    reduced = lift.reduced_dynamics_batch(poses, twists)
    assert reduced.mass_matrix.shape == (4, 1, 1) and reduced.jacobian.shape == (4, 1, 1)


def test_the_lift_gets_the_errors_from_the_base(lift):
    poses = np.array([[0.1], [0.2], [1.5], [0.0]])
    zero = np.zeros((4, 1))
    with pytest.raises(BatchUnreachablePoseError) as info:
        lift.inverse_dynamics_batch(poses, zero, zero)
    assert info.value.index == 2 and isinstance(info.value, UnreachablePoseError)
    with pytest.raises(UnreachablePoseError):
        lift.forward_dynamics([1.5], [0.0], [1.0])
    with pytest.raises(InputError, match="pose"):
        lift.inverse_dynamics([np.nan], [0.0], [0.0])
    with pytest.raises(InputError, match="method"):
        lift.inverse_dynamics([0.0], [0.0], [0.0], method="qp")
    with pytest.raises(InputError, match="twist_dots"):
        lift.inverse_dynamics_batch(poses, zero, zero[:2])
    bounded = LiftDynamics(lift_model(), LiftGeometry(max_actuator_force=25.0))
    with pytest.raises(ActuatorSaturationError):
        bounded.inverse_dynamics([0.0], [0.0], [5.0])
    assert bounded.inverse_dynamics([0.0], [0.0], [5.0], bounded=False).actuator_forces[0] \
        == pytest.approx((M_CARRIAGE + M_PLATFORM) * (5.0 + G))
    with pytest.raises(BatchActuatorSaturationError) as info:
        bounded.inverse_dynamics_batch(zero[:3], zero[:3], [[0.0], [0.0], [5.0]])
    assert info.value.index == 2
    with pytest.raises(BatchActuatorSaturationError) as info:
        bounded.static_forces_batch(zero[:2], [[0.0], [-10.0]])
    assert info.value.index == 1


# -- the rebuilt robots give the numbers stored before the rebuild ------------------------------
def reference_values() -> dict[str, np.ndarray]:
    """The dynamics outputs stored in ``tests/data/closed_form_reference.npz`` (written by the
    code before the closed forms moved onto :mod:`hexapod_pin.core.closed_form`): every
    method of both robots, single states and batches, rigid and with drive effects."""
    out: dict[str, np.ndarray] = {}
    rng = np.random.default_rng(11)
    robots = [("hexapod", hp.Hexapod.default()), ("planar", hp.Planar3PRR.default())]
    robots += [(name + "_effects", robot.with_effects(
        damping=np.where(np.isin(np.arange(robot.model.nv), robot.model.actuated_v), 0.3, 0.0),
        armature=np.where(np.isin(np.arange(robot.model.nv), robot.model.actuated_v), 0.05,
                          0.0))) for name, robot in robots]
    for name, robot in robots:
        dim = robot.pose_dim
        scale = np.array([0.01] * 3 + [0.03] * 3) if dim == 6 else np.array([0.01, 0.01, 0.03])
        poses = robot.home_pose + rng.uniform(-1, 1, (3, dim)) * scale
        twists, accs = rng.uniform(-0.1, 0.1, (3, dim)), rng.uniform(-0.5, 0.5, (3, dim))
        wrenches = rng.uniform(-2, 2, (3, dim))
        for k in range(3):
            for method in ("kkt", "qp"):
                res = robot.inverse_dynamics(poses[k], twists[k], accs[k], wrenches[k],
                                             method=method)
                out[f"{name}/id/{method}/{k}"] = np.concatenate(
                    [res.actuator_forces, np.ravel(res.closure_forces), [res.residual]])
            tau = robot.inverse_dynamics(poses[k], twists[k], accs[k]).actuator_forces
            for method in ("nullspace", "pinocchio", "qp", "kkt"):
                fd = robot.forward_dynamics(poses[k], twists[k], tau, wrenches[k], method=method)
                out[f"{name}/fd/{method}/{k}"] = np.concatenate(
                    [fd.twist_dot, np.ravel(fd.closure_forces)])
            out[f"{name}/st/{k}"] = robot.static_forces(poses[k], wrenches[k])
            red = robot.reduced_dynamics(poses[k], twists[k])
            out[f"{name}/rd/{k}"] = np.concatenate([np.ravel(red.mass_matrix), red.bias])
            e = robot.energies(poses[k], twists[k])
            out[f"{name}/en/{k}"] = np.array([e.kinetic, e.potential])
        idb = robot.inverse_dynamics_batch(poses, twists, accs, wrenches)
        out[f"{name}/idb"] = np.concatenate([np.ravel(idb.actuator_forces),
                                             np.ravel(idb.closure_forces)])
        fdb = robot.forward_dynamics_batch(poses, twists, idb.actuator_forces, wrenches)
        out[f"{name}/fdb"] = np.ravel(fdb.twist_dot)
        out[f"{name}/stb"] = np.ravel(robot.static_forces_batch(poses, wrenches))
        out[f"{name}/rdb"] = np.ravel(robot.reduced_dynamics_batch(poses, twists).mass_matrix)
    return out


def test_the_robots_give_the_numbers_stored_before_the_rebuild():
    stored = np.load(REFERENCE)
    now = reference_values()
    assert sorted(stored.files) == sorted(now)
    for key, value in now.items():
        np.testing.assert_allclose(value, stored[key], rtol=1e-14, atol=1e-14 * max(
            1.0, float(np.abs(stored[key]).max())), err_msg=key)
