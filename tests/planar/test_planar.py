"""The planar 3-PRR robot: description, kinematics, statics, dynamics (independent routes)."""

import dataclasses
import json
import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
import scipy.optimize
import yourdfpy

from hexapod_pin.core.description import build_model
from hexapod_pin.errors import (AssemblyError, GeometryError, InputError, SingularityError,
                                StrokeLimitError, UnreachablePoseError)
from hexapod_pin.planar.assembly_modes import same_pose as _same_pose
from hexapod_pin.planar.geometry import ALL_BRANCHES, PlanarGeometry, planar_urdf
from hexapod_pin.planar.robot import Planar3PRR

from conftest import fd_constraint_jacobian, random_configuration

ROOT = Path(__file__).resolve().parents[2]
REFERENCE = Path(__file__).resolve().parents[1] / "data" / "reference_states.json"
#: a geometry with six real assembly modes at SIX_MODE_S (found by a random search)
SIX_MODE_GEOMETRY = dict(rail_radius=0.35, platform_radius=0.25, link_length=0.4,
                         rail_half_length=0.6)
SIX_MODE_S = np.array([-0.19903168, -0.03662372, 0.1864951])
#: default-geometry slider coordinates that admit no assembly at all
NO_MODE_S = np.array([0.08217701239287256, -0.13812797174167782, -0.2754158856382832])


@pytest.fixture(scope="module")
def planar():
    return Planar3PRR.default()


@pytest.fixture(scope="module")
def six_mode():
    return Planar3PRR(PlanarGeometry(**SIX_MODE_GEOMETRY))


def random_pose(robot, rng, scale=1.0, branch=None):
    """A random reachable pose near home, inside the strokes, away from singularities."""
    for _ in range(1000):
        pose = scale * np.concatenate([rng.uniform(-0.03, 0.03, 2), rng.uniform(-0.2, 0.2, 1)])
        try:
            s = robot.inverse_kinematics(pose, branch=branch)
            jac = robot.jacobian(pose, branch=branch)
        except (UnreachablePoseError, StrokeLimitError, SingularityError):
            continue
        sv = np.linalg.svd(jac, compute_uv=False)
        links = robot.link_vectors(pose, s) @ robot.geometry.rail_directions.T
        if sv[-1] > 0.05 * sv[0] and np.min(np.abs(np.diag(links))) > 0.05:
            return pose
    raise RuntimeError("no random pose found")


def hand_points(g, pose, s):
    """Slider and platform joint points computed by hand from the issue's conventions."""
    a = np.pi / 2 + 2 * np.pi / 3 * np.arange(3)
    sliders = np.stack([g.rail_radius * np.cos(a) - s * np.sin(a),
                        g.rail_radius * np.sin(a) + s * np.cos(a)], axis=1)
    points = np.stack([pose[0] + g.platform_radius * np.cos(a + pose[2]),
                       pose[1] + g.platform_radius * np.sin(a + pose[2])], axis=1)
    return sliders, points


# -- geometry ------------------------------------------------------------------------------
def test_geometry_defaults_and_home():
    g = PlanarGeometry()
    assert (g.rail_radius, g.platform_radius, g.link_length) == (0.35, 0.12, 0.30)
    assert (g.slider_mass, g.link_mass, g.platform_mass) == (0.5, 0.2, 1.0)
    assert (g.platform_inertia, g.gravity, g.rail_half_length) == (0.002, 9.81, 0.30)
    assert g.home_slider == pytest.approx(math.sqrt(0.3 ** 2 - 0.23 ** 2))
    assert g.home_slider == pytest.approx(0.1926, abs=1e-4)
    with pytest.raises(dataclasses.FrozenInstanceError):
        g.rail_radius = 1.0


@pytest.mark.parametrize("changes, field", [
    (dict(link_length=-0.3), "link_length"),
    (dict(slider_mass=0.0), "slider_mass"),
    (dict(platform_inertia=float("nan")), "platform_inertia"),
    (dict(gravity=-1.0), "gravity"),
    (dict(rail_radius=True), "rail_radius"),
    (dict(rail_radius="0.3"), "rail_radius"),
    (dict(platform_radius=0.4), "platform_radius"),
    (dict(link_length=0.2), "link_length"),          # shorter than R - r: no home
    (dict(rail_half_length=0.1), "rail_half_length"),  # home outside the stroke
    (dict(max_actuator_force=0.0), "max_actuator_force"),
    (dict(max_actuator_force=np.nan), "max_actuator_force"),
    (dict(max_actuator_force=-np.inf), "max_actuator_force"),
])
def test_geometry_rejects_bad_values(changes, field):
    with pytest.raises(GeometryError) as info:
        PlanarGeometry(**changes)
    assert info.value.field == field


# -- description -----------------------------------------------------------------------------
def test_urdf_loads_in_yourdfpy_and_pinocchio(tmp_path):
    text = planar_urdf(PlanarGeometry(link_length=0.33, link_mass=0.25))
    path = tmp_path / "planar.urdf"
    path.write_text(text)
    robot = yourdfpy.URDF.load(str(path), build_scene_graph=True, load_meshes=False)
    types = [j.type for j in robot.robot.joints]
    assert types.count("prismatic") == 5 and types.count("revolute") == 4
    assert robot.link_map["link_1"].inertial.mass == pytest.approx(0.25)
    assert robot.joint_map["link_1_tip_mount"].origin[0, 3] == pytest.approx(0.33)
    # yourdfpy's own forward kinematics puts slider 0 on rail 0 (midpoint (0, R), u = (-1, 0))
    cfg = {name: 0.0 for name in robot.actuated_joint_names}
    cfg["slider_0"] = 0.1
    robot.update_cfg(cfg)
    np.testing.assert_allclose(robot.get_transform("slider_0")[:3, 3], [-0.1, 0.35, 0.0],
                               atol=1e-12)
    model = build_model(text)
    assert (model.nq, model.nv) == (9, 9)
    assert model.check(model.createData())


def test_home_closures_and_redundant_rows(planar):
    model = planar.model
    assert model.n_rows == 9 and model.nv == 9 and model.n_actuated == 3
    q = planar.home_configuration
    assert np.max(np.abs(model.residual(q))) <= 1e-12
    rng = np.random.default_rng(3)
    for _ in range(3):
        q = random_configuration(model.model, rng)
        jac = model.constraint_jacobian(q)
        # the out-of-plane rows of the three point closures are identically zero ...
        assert np.all(jac[[2, 5, 8]] == 0.0)
        info = model.rank(q)
        # ... and the library reports them as the redundant ones
        assert info.rank == 6 and info.n_rows == 9
        assert info.redundant_rows.tolist() == [2, 5, 8]
        assert model.mobility(q) == 3
    del rng


def test_generic_assembly_and_velocity_with_redundant_rows(planar):
    """The generic core's Gauss-Newton assembly and velocity completion on the planar
    model (9 rows, rank 6): finite answers equal to the closed forms."""
    pose = np.array([0.015, -0.01, 0.12])
    q_exact = planar.configuration(pose)
    q0 = q_exact.copy()
    q0[planar.indices.link] += [0.05, -0.04, 0.03]
    q0[planar.indices.platform] += [0.01, -0.01, 0.02]
    result = planar.model.assemble(q0)          # sliders held
    assert result.residual_norm <= 1e-12
    np.testing.assert_allclose(result.q, q_exact, atol=1e-10)
    twist = np.array([0.1, -0.05, 0.3])
    v = planar.model.complete_velocity(q_exact, planar.indices.platform, twist)
    assert np.all(np.isfinite(v))
    np.testing.assert_allclose(v, planar.velocity(pose, twist), atol=1e-12)


def test_constraint_jacobian_matches_finite_differences(planar):
    model = planar.model
    q = planar.configuration([0.01, -0.02, 0.1])
    np.testing.assert_allclose(model.constraint_jacobian(q), fd_constraint_jacobian(model, q),
                               atol=1e-9)


# -- reference states ----------------------------------------------------------------------
def test_reference_states():
    entries = json.loads(REFERENCE.read_text())["planar"]
    assert entries
    for entry in entries:
        robot = Planar3PRR(PlanarGeometry(**entry["geometry"]))
        pose, wrench = entry["pose"], entry["wrench"]

        def close(mine, ref):
            ref = np.asarray(ref)
            np.testing.assert_allclose(mine, ref, rtol=0, atol=1e-9 * max(1.0, np.abs(ref).max()))

        close(robot.inverse_kinematics(pose), entry["s"])
        close(robot.jacobian(pose), entry["jacobian"])
        close(robot.inverse_dynamics(pose, entry["twist"], entry["twist_dot"],
                                     wrench).actuator_forces,
              entry["actuator_forces"])
        close(robot.static_forces(pose, wrench), entry["static_forces"])


# -- inverse kinematics ----------------------------------------------------------------------
def test_home_inverse_kinematics(planar):
    np.testing.assert_allclose(planar.inverse_kinematics(planar.home_pose),
                               planar.home_actuators, atol=1e-15)
    np.testing.assert_allclose(planar.home_actuators, 0.19261360284258225, rtol=1e-14)


def _branch_id(branch):
    return "".join("+-"[int(sign < 0)] for sign in branch)


@pytest.mark.parametrize("branch", ALL_BRANCHES, ids=_branch_id)
def test_ik_fk_round_trip_every_branch(planar, branch):
    rng = np.random.default_rng(7)
    g = planar.geometry
    for _ in range(4):
        pose = random_pose(planar, rng)
        s = planar.inverse_kinematics(pose, branch=branch, check_limits=False)
        sliders, points = hand_points(g, pose, s)
        np.testing.assert_allclose(np.linalg.norm(points - sliders, axis=1), g.link_length,
                                   atol=1e-14)
        # the branch sign is the side of the slider relative to the foot of the perpendicular
        np.testing.assert_array_equal(planar.branch_of(pose, s), branch)
        guess = pose + rng.normal(scale=0.01, size=3)
        np.testing.assert_allclose(planar.forward_kinematics(s, guess=guess), pose, atol=1e-10)
        modes = planar.assembly_modes(s)
        assert 1 <= len(modes) <= 6
        assert sum(_same_pose(m, pose, 1e-9) for m in modes) == 1
        q = planar.configuration(pose, branch=branch)
        assert np.max(np.abs(planar.model.residual(q))) <= 1e-12
        np.testing.assert_allclose(planar.actuator_positions(q), s, atol=0)
        np.testing.assert_allclose(planar.pose_from_configuration(q), pose, atol=0)


def test_every_assembly_mode_round_trips(six_mode):
    modes = six_mode.assembly_modes(SIX_MODE_S)
    assert len(modes) == 6
    for pose in modes:
        branch = six_mode.branch_of(pose, SIX_MODE_S)
        np.testing.assert_allclose(six_mode.inverse_kinematics(pose, branch=branch),
                                   SIX_MODE_S, atol=1e-11)
        np.testing.assert_allclose(six_mode.forward_kinematics(SIX_MODE_S, guess=pose + 1e-3),
                                   pose, atol=1e-10)
        q = six_mode.configuration(pose, branch=branch)
        assert np.max(np.abs(six_mode.model.residual(q))) <= 1e-12


def _multistart(robot, s, n, seed):
    """Every solution that scipy's Levenberg-Marquardt finds from n random starts, on loop
    equations written out here (a route independent of the library's Newton)."""
    g = robot.geometry
    rng = np.random.default_rng(seed)
    span = g.rail_radius + g.link_length

    def residual(pose):
        sliders, points = hand_points(g, pose, s)
        return np.linalg.norm(points - sliders, axis=1) - g.link_length

    found = []
    for _ in range(n):
        guess = np.array([*rng.uniform(-span, span, 2), rng.uniform(-np.pi, np.pi)])
        sol = scipy.optimize.least_squares(residual, guess, method="lm", xtol=1e-15,
                                           ftol=1e-15, gtol=1e-15)
        if np.max(np.abs(residual(sol.x))) > 1e-11:
            continue
        pose = sol.x.copy()
        pose[2] = np.angle(np.exp(1j * pose[2]))
        if not any(_same_pose(pose, f, 1e-7) for f in found):
            found.append(pose)
    return found


@pytest.mark.parametrize("case", ["default-home", "default-moved", "six-modes", "four-modes"])
def test_assembly_modes_match_brute_force_multistart(case, planar, six_mode):
    robot, s = {
        "default-home": (planar, planar.home_actuators),
        "default-moved": (planar, np.array([0.15, 0.22, 0.19])),
        "six-modes": (six_mode, SIX_MODE_S),
        "four-modes": (six_mode, np.array([0.05694418, 0.13131802, -0.53408195])),
    }[case]
    modes = robot.assembly_modes(s)
    brute = _multistart(robot, s, 200, seed=11)
    assert len(brute) == len(modes), (modes, brute)
    for pose in brute:
        assert sum(_same_pose(pose, m, 1e-8) for m in modes) == 1
    for pose in modes:  # every mode closes the loops, by hand
        sliders, points = hand_points(robot.geometry, pose, s)
        np.testing.assert_allclose(np.linalg.norm(points - sliders, axis=1),
                                   robot.geometry.link_length, atol=1e-12)


def test_assembly_polynomial_is_a_sextic_vanishing_at_every_mode(six_mode):
    poly = six_mode.assembly_polynomial(SIX_MODE_S)
    assert poly.coefficients.shape == (7,)
    assert poly.removed_factor_residual < 1e-12
    values = np.polynomial.polynomial.polyval(
        np.tan((six_mode.assembly_modes(SIX_MODE_S)[:, 2] - poly.theta_offset) / 2),
        poly.coefficients)
    np.testing.assert_allclose(values, 0.0, atol=1e-10)
    # and not at a pose that does not assemble
    assert abs(np.polynomial.polynomial.polyval(
        np.tan((0.3 - poly.theta_offset) / 2), poly.coefficients)) > 1e-6


def test_no_assembly_mode(planar):
    assert planar.assembly_modes(NO_MODE_S).shape == (0, 3)
    with pytest.raises(AssemblyError) as info:
        planar.forward_kinematics(NO_MODE_S)
    assert info.value.residual_norm > 1e-6


# -- errors --------------------------------------------------------------------------------------
def test_unreachable_pose(planar):
    with pytest.raises(UnreachablePoseError) as info:
        planar.inverse_kinematics([0.0, -0.2, 0.0])
    # rail 0 is the line y = 0.35; platform point 0 at y = -0.08: 0.43 away, link 0.30
    assert 0 in info.value.carriages
    k = info.value.carriages.index(0)
    assert info.value.shortfall[k] == pytest.approx(0.43 - 0.30)


def test_stroke_limit(planar):
    pose = [-0.06, -0.06, 0.2]   # s_1 = 0.305 > rail_half_length = 0.3
    s = planar.inverse_kinematics(pose, check_limits=False)
    assert np.any(np.abs(s) > 0.3)
    with pytest.raises(StrokeLimitError) as info:
        planar.inverse_kinematics(pose)
    np.testing.assert_allclose(info.value.q, s)
    assert info.value.violations


@pytest.mark.parametrize("pose", [[0.0, 0.0], [0.0, np.nan, 0.0], "abc", [[0, 0, 0]]])
def test_bad_pose_raises_input_error(planar, pose):
    with pytest.raises(InputError):
        planar.inverse_kinematics(pose)
    with pytest.raises(InputError):
        planar.jacobian(pose)


@pytest.mark.parametrize("branch", [[1, 1], [1, 0, 1], [1, 1, 2], "x"])
def test_bad_branch_raises_input_error(planar, branch):
    with pytest.raises(InputError):
        planar.inverse_kinematics(planar.home_pose, branch=branch)


def test_bad_dynamics_inputs(planar):
    with pytest.raises(InputError):
        planar.inverse_dynamics(planar.home_pose, [0, 0], [0, 0, 0])
    with pytest.raises(InputError):
        planar.forward_dynamics(planar.home_pose, [0, 0, 0], [0, 0, np.inf])
    with pytest.raises(InputError):
        planar.static_forces(planar.home_pose, wrench=[1.0, 2.0])
    with pytest.raises(InputError):
        planar.forward_kinematics([0.1, 0.1])


def test_link_perpendicular_to_rail_is_singular(planar):
    # slider 0 right above platform point 0: link 0 perpendicular to rail 0
    pose = np.array([0.0, 0.0, 0.0])
    s = planar.home_actuators.copy()
    s[0] = 0.0
    with pytest.raises(SingularityError):
        planar.branch_of(pose + [0.0, 0.35 - 0.12 - 0.3, 0.0], s)
    # the IK of that pose has a double root; J is not finite there: an error, never NaN
    with pytest.raises((SingularityError, UnreachablePoseError)):
        planar.jacobian([0.0, 0.35 - 0.12 - 0.3, 0.0])


# -- Jacobian and velocities ---------------------------------------------------------------
@pytest.mark.parametrize("branch", [ALL_BRANCHES[0], ALL_BRANCHES[5]])
def test_jacobian_matches_finite_differences(planar, branch):
    rng = np.random.default_rng(5)
    for _ in range(3):
        pose = random_pose(planar, rng, branch=None)
        h = 1e-6
        fd = np.array([(planar.inverse_kinematics(pose + h * e, branch, False)
                        - planar.inverse_kinematics(pose - h * e, branch, False)) / (2 * h)
                       for e in np.eye(3)]).T
        np.testing.assert_allclose(planar.jacobian(pose, branch), fd, atol=1e-8)


def test_tree_velocity_and_acceleration_by_finite_differences(planar):
    """velocity() / acceleration() against differences of configuration() along a motion."""
    rng = np.random.default_rng(8)
    pose = random_pose(planar, rng)
    twist, twist_dot = rng.normal(size=3) * [0.1, 0.1, 0.5], rng.normal(size=3)

    def path(t):
        return pose + twist * t + 0.5 * twist_dot * t * t

    def rate(t):
        return twist + twist_dot * t

    h = 1e-5
    q_plus, q_minus = planar.configuration(path(h)), planar.configuration(path(-h))
    fd_v = pin.difference(planar.model.model, q_minus, q_plus) / (2 * h)
    v = planar.velocity(pose, twist)
    np.testing.assert_allclose(v, fd_v, atol=1e-8)
    np.testing.assert_allclose(planar.model.constraint_jacobian(planar.configuration(pose)) @ v,
                               0.0, atol=1e-14)
    fd_a = (planar.velocity(path(h), rate(h)) - planar.velocity(path(-h), rate(-h))) / (2 * h)
    np.testing.assert_allclose(planar.acceleration(pose, twist, twist_dot), fd_a, atol=1e-7)
    sdot = planar.jacobian(pose) @ twist
    np.testing.assert_allclose(planar.twist_from_actuator_velocities(pose, sdot), twist, atol=1e-12)


# -- statics ----------------------------------------------------------------------------------
def _potential_by_hand(g, pose, s):
    sliders, points = hand_points(g, pose, s)
    centres = 0.5 * (sliders + points)
    return g.gravity * (g.slider_mass * sliders[:, 1].sum() + g.link_mass * centres[:, 1].sum()
                        + g.platform_mass * pose[1])


def test_statics_match_virtual_work(planar):
    """tau . ds + w . dpose - dV = 0 for every virtual displacement: J^T tau = grad V - w,
    with V and the map pose -> s written out here (central differences)."""
    rng = np.random.default_rng(9)
    g = planar.geometry
    for _ in range(4):
        pose = random_pose(planar, rng)
        wrench = rng.normal(size=3) * [3.0, 3.0, 0.3]
        h = 1e-6
        grad_v, jac = np.empty(3), np.empty((3, 3))
        for j, e in enumerate(np.eye(3)):
            sp_, sm_ = (planar.inverse_kinematics(pose + h * e, check_limits=False),
                        planar.inverse_kinematics(pose - h * e, check_limits=False))
            grad_v[j] = (_potential_by_hand(g, pose + h * e, sp_)
                         - _potential_by_hand(g, pose - h * e, sm_)) / (2 * h)
            jac[:, j] = (sp_ - sm_) / (2 * h)
        expected = np.linalg.solve(jac.T, grad_v - wrench)
        np.testing.assert_allclose(planar.static_forces(pose, wrench), expected,
                                   rtol=1e-7, atol=1e-7)
        assert planar.energies(pose, np.zeros(3)).potential == pytest.approx(
            _potential_by_hand(g, pose, planar.inverse_kinematics(pose)), rel=1e-12)


# -- dynamics ------------------------------------------------------------------------------------
def test_forward_and_inverse_dynamics_are_inverse(planar):
    rng = np.random.default_rng(10)
    for _ in range(3):
        pose = random_pose(planar, rng)
        twist = rng.normal(size=3) * [0.2, 0.2, 1.0]
        twist_dot = rng.normal(size=3) * [1.0, 1.0, 5.0]
        wrench = rng.normal(size=3) * [2.0, 2.0, 0.2]
        forces = planar.inverse_dynamics(pose, twist, twist_dot, wrench).actuator_forces
        for method in ("nullspace", "kkt", "qp", "pinocchio"):
            res = planar.forward_dynamics(pose, twist, forces, wrench, method=method)
            assert np.all(np.isfinite(res.tree_acceleration))
            assert np.all(np.isfinite(res.closure_forces))
            np.testing.assert_allclose(res.twist_dot, twist_dot, atol=1e-8)
        # the other way round, and the two inverse-dynamics routes agree
        forces2 = rng.normal(size=3) * 5.0
        acc = planar.forward_dynamics(pose, twist, forces2, wrench).twist_dot
        for method in ("kkt", "qp"):
            np.testing.assert_allclose(
                planar.inverse_dynamics(pose, twist, acc, wrench, method=method).actuator_forces,
                forces2, atol=1e-9)


def test_multipliers_are_finite_and_in_plane(planar):
    res = planar.inverse_dynamics([0.01, 0.0, 0.1], [0.1, 0.0, 0.2], [0.0, 1.0, 0.0])
    lam = res.multipliers
    assert np.all(np.isfinite(lam))
    np.testing.assert_allclose(lam[[2, 5, 8]], 0.0, atol=1e-12)
    np.testing.assert_allclose(-res.closure_forces.reshape(-1), np.delete(lam, [2, 5, 8]))


def _rk4_energy_drift(planar, state, duration, steps):
    def deriv(state):
        pose, twist = state[:3], state[3:]
        acc = planar.forward_dynamics(pose, twist, np.zeros(3)).twist_dot
        return np.concatenate([twist, acc])

    energy0 = planar.energies(state[:3], state[3:]).total
    dt, drift = duration / steps, 0.0
    for _ in range(steps):
        k1 = deriv(state)
        k2 = deriv(state + dt / 2 * k1)
        k3 = deriv(state + dt / 2 * k2)
        k4 = deriv(state + dt * k3)
        state = state + dt / 6 * (k1 + 2 * k2 + 2 * k3 + k4)
        drift = max(drift, abs(planar.energies(state[:3], state[3:]).total - energy0))
    return drift, state


def test_energy_is_conserved_without_actuation(planar):
    """RK4 on (pose, twist) with zero actuator forces: T + V constant (gravity on), the
    drift shrinking as dt^4 (a modelling error would leave a drift that does not)."""
    start = np.concatenate([[0.0, 0.0, 0.0], [0.05, 0.1, 0.4]])
    coarse, end = _rk4_energy_drift(planar, start, 0.1, 25)
    fine, _ = _rk4_energy_drift(planar, start, 0.1, 50)
    moved = (planar.energies(end[:3], np.zeros(3)).potential
             - planar.energies(np.zeros(3), np.zeros(3)).potential)
    kinetic = planar.energies(start[:3], start[3:]).kinetic
    assert abs(moved) > 0.1 * kinetic          # energy did flow between T and V
    assert coarse < 1e-5 * kinetic
    assert fine < coarse / 10                  # fourth order: 16x for dt / 2


def test_kinetic_energy_by_hand(planar):
    rng = np.random.default_rng(12)
    g = planar.geometry
    pose = random_pose(planar, rng)
    twist = rng.normal(size=3) * [0.2, 0.2, 1.0]
    s = planar.inverse_kinematics(pose)
    sdot = planar.jacobian(pose) @ twist
    _, points = hand_points(g, pose, s)
    r = points - pose[:2]
    point_vel = twist[:2] + twist[2] * np.stack([-r[:, 1], r[:, 0]], axis=1)
    u = g.rail_directions
    slider_vel = sdot[:, None] * u
    links = planar.link_vectors(pose, s)
    rel = point_vel - slider_vel
    omega = (links[:, 0] * rel[:, 1] - links[:, 1] * rel[:, 0]) / g.link_length ** 2
    centre_vel = 0.5 * (slider_vel + point_vel)
    expected = 0.5 * (g.slider_mass * np.sum(slider_vel ** 2)
                      + g.link_mass * np.sum(centre_vel ** 2)
                      + g.link_mass * g.link_length ** 2 / 12 * np.sum(omega ** 2)
                      + g.platform_mass * np.sum(twist[:2] ** 2)
                      + g.platform_inertia * twist[2] ** 2)
    assert planar.energies(pose, twist).kinetic == pytest.approx(expected, rel=1e-12)


def test_gravity_acts_along_minus_y(planar):
    assert np.allclose(planar.model.model.gravity.linear, [0.0, -9.81, 0.0])
    # one more kg on the platform holds like an external wrench (0, -g * 1 kg, 0) on it
    heavy = Planar3PRR(PlanarGeometry(platform_mass=2.0))
    diff = heavy.static_forces(heavy.home_pose) - planar.static_forces(planar.home_pose)
    np.testing.assert_allclose(diff, planar.static_forces(planar.home_pose, [0.0, -9.81, 0.0])
                               - planar.static_forces(planar.home_pose), atol=1e-12)


# -- example -----------------------------------------------------------------------------------
def test_example_script_runs(tmp_path):
    pytest.importorskip("matplotlib")
    out = tmp_path / "forces.png"
    proc = subprocess.run([sys.executable, str(ROOT / "examples" / "planar_statics.py"),
                           str(out)], capture_output=True, text=True, timeout=120, cwd=ROOT,
                          check=False)
    assert proc.returncode == 0, proc.stderr
    assert "static forces" in proc.stdout
    assert out.is_file() and out.stat().st_size > 1000


# -- the single-state closed form ("kkt") against the generic tree routes --------------------
def _generic_tree_state(robot, pose, twist, twist_dot, branch):
    """q from the closed form (closures checked on Pinocchio), v and a completed by the
    generic core (Pinocchio's J_c and drift, least squares): independent of the kernels."""
    model = robot.model
    q = robot.configuration(pose, branch=branch)
    v = model.complete_velocity(q, robot.indices.platform, twist)
    a = model.complete_acceleration(q, v, robot.indices.platform, twist_dot)
    return q, v, a


def _regular_pose(robot, rng, branch):
    """A random pose near home, reachable on ``branch`` (strokes not checked: the dynamics
    do not check them), well away from type I and type II singularities."""
    for _ in range(2000):
        pose = np.concatenate([rng.uniform(-0.1, 0.1, 2), rng.uniform(-1.0, 1.0, 1)])
        try:
            jac = robot.jacobian(pose, branch=branch)
        except (UnreachablePoseError, SingularityError):
            continue
        sv = np.linalg.svd(jac, compute_uv=False)
        if sv[-1] > 0.02 * sv[0] and np.abs(jac).max() < 50.0:
            return pose
    raise RuntimeError("no regular pose found")


@pytest.mark.parametrize("which, branch", [("default", ALL_BRANCHES[0]),
                                           ("default", ALL_BRANCHES[3]),
                                           ("default", ALL_BRANCHES[6]),
                                           ("six_mode", ALL_BRANCHES[0])])
def test_closed_form_dynamics_match_generic_tree_routes(which, branch, planar, six_mode):
    from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree

    robot = planar if which == "default" else six_mode
    model, idx = robot.model, robot.indices
    rng = np.random.default_rng(21)
    for _ in range(3):
        pose = _regular_pose(robot, rng, branch)
        twist = rng.normal(size=3) * [0.2, 0.2, 1.0]
        twist_dot = rng.normal(size=3) * [1.0, 1.0, 5.0]
        wrench = rng.normal(size=3) * [2.0, 2.0, 0.2]
        q, v, a = _generic_tree_state(robot, pose, twist, twist_dot, branch)
        np.testing.assert_allclose(robot.velocity(pose, twist, branch), v, rtol=0,
                                   atol=1e-13 * max(1.0, np.abs(v).max()))
        np.testing.assert_allclose(robot.acceleration(pose, twist, twist_dot, branch), a,
                                   rtol=0, atol=1e-13 * max(1.0, np.abs(a).max()))
        tau_ext = np.zeros(model.nv)
        tau_ext[idx.platform] = wrench

        res = robot.inverse_dynamics(pose, twist, twist_dot, wrench, branch=branch)
        ref = inverse_dynamics_tree(model, q, v, a, tau_ext, method="kkt")
        assert res.method == "kkt" and "closed form" in res.status
        scale = max(1.0, np.abs(ref.actuator_forces).max())
        np.testing.assert_allclose(res.actuator_forces, ref.actuator_forces, rtol=0,
                                   atol=1e-10 * scale)
        np.testing.assert_allclose(res.multipliers, ref.multipliers, rtol=0,
                                   atol=1e-10 * scale)
        np.testing.assert_allclose(-res.closure_forces.reshape(-1),
                                   np.delete(ref.multipliers, [2, 5, 8]), atol=1e-10 * scale)
        assert 0.0 <= res.residual <= 1e-10 * scale

        static = robot.static_forces(pose, wrench, branch=branch)
        zero = np.zeros(model.nv)
        np.testing.assert_allclose(
            static, inverse_dynamics_tree(model, q, zero, zero, tau_ext,
                                          method="kkt").actuator_forces, atol=1e-10 * scale)

        forces = rng.normal(size=3) * 5.0
        fd = robot.forward_dynamics(pose, twist, forces, wrench, branch=branch)
        ref_fd = forward_dynamics_tree(model, q, v, forces, tau_ext, method="kkt")
        acc_scale = max(1.0, np.abs(ref_fd.a).max())
        assert fd.method == "nullspace" and "closed form" in fd.status
        assert ref_fd.rank == 6
        np.testing.assert_allclose(fd.tree_acceleration, ref_fd.a, rtol=0,
                                   atol=1e-10 * acc_scale)
        np.testing.assert_allclose(fd.twist_dot, ref_fd.a[idx.platform], atol=1e-10 * acc_scale)
        np.testing.assert_allclose(fd.actuator_accelerations, ref_fd.a[idx.slider],
                                   atol=1e-10 * acc_scale)
        lam_scale = max(1.0, np.abs(ref_fd.multipliers).max())
        np.testing.assert_allclose(fd.multipliers, ref_fd.multipliers, rtol=0,
                                   atol=1e-10 * lam_scale)
        # the closures hold at acceleration level, evaluated on Pinocchio
        drift = model.constraint_jacobian(q) @ fd.tree_acceleration \
            + model.constraint_drift(q, v)
        assert np.max(np.abs(drift)) <= 1e-10 * acc_scale
        assert 0.0 <= ref_fd.constraint_residual <= 1e-10 * acc_scale


def _type_two_theta(robot):
    """theta of a type II singularity at x = y = 0: by symmetry the three links then pass
    through the platform origin (zero moment arm, r_0 x n_0 = 0)."""
    g = robot.geometry

    def moment_arm(theta):
        s = robot.inverse_kinematics([0.0, 0.0, theta], check_limits=False)
        sliders, points = hand_points(g, np.array([0.0, 0.0, theta]), s)
        r, n = points[0], points[0] - sliders[0]
        return r[0] * n[1] - r[1] * n[0]

    return scipy.optimize.brentq(moment_arm, 0.5, 0.7, xtol=1e-15)


def test_type_two_singularity_raises_instead_of_a_least_squares_answer(planar):
    """At a type-II pose the actuator forces are not determined: a minimum-norm least-squares
    answer does not produce the motion (its forward dynamics misses the requested
    acceleration), so inverse dynamics and statics raise SingularityError (type II)."""
    from hexapod_pin.core.dynamics import inverse_dynamics_tree
    from hexapod_pin.errors import SingularityError

    theta = _type_two_theta(planar)
    pose = np.array([0.0, 0.0, theta])
    sv = np.linalg.svd(planar.jacobian(pose), compute_uv=False)
    assert sv[-1] < 1e-12 * sv[0]                          # type II indeed
    twist, twist_dot, wrench = np.array([0.01, 0.0, 0.1]), np.array([0.1, 0.2, 0.3]), \
        np.array([0.5, -1.0, 0.02])
    for method in ("kkt", "qp"):
        with pytest.raises(SingularityError, match="type-II"):
            planar.inverse_dynamics(pose, twist, twist_dot, wrench, method=method)
    with pytest.raises(SingularityError, match="type-II"):
        planar.static_forces(pose, wrench)
    tau_ext = np.zeros(9)
    tau_ext[planar.indices.platform] = wrench
    # near (not at) the singularity the closed form is used and still agrees
    near = pose + [0.0, 0.0, 1e-3]
    q, v, a = _generic_tree_state(planar, near, twist, twist_dot, None)
    res = planar.inverse_dynamics(near, twist, twist_dot, wrench)
    ref = inverse_dynamics_tree(planar.model, q, v, a, tau_ext, method="kkt")
    assert "closed form" in res.status
    scale = np.abs(ref.actuator_forces).max()
    np.testing.assert_allclose(res.actuator_forces, ref.actuator_forces, rtol=0,
                               atol=1e-9 * scale)
    # forward dynamics stays regular there (the closures alone fix the multipliers)
    fd = planar.forward_dynamics(pose, twist, [1.0, 2.0, 3.0], wrench)
    assert "closed form" in fd.status and np.all(np.isfinite(fd.tree_acceleration))


@pytest.mark.parametrize("call, name", [
    (lambda r: r.inverse_dynamics([0.0, np.nan, 0.0], [0, 0, 0], [0, 0, 0]), "pose"),
    (lambda r: r.inverse_dynamics([0, 0, 0], np.array([0.0, np.inf, 0.0]), [0, 0, 0]),
     "twist"),
    (lambda r: r.inverse_dynamics([0, 0, 0], [0, 0, 0], [0.0, 0.0, -np.inf]), "twist_dot"),
    (lambda r: r.inverse_dynamics([0, 0, 0], [0, 0, 0], [0, 0, 0], [np.nan, 0, 0]),
     "wrench"),
    (lambda r: r.inverse_dynamics([0, 0, 0], [0, 0], [0, 0, 0]), "twist"),
    (lambda r: r.inverse_dynamics([0, 0, 0], [0, 0, 0], [0, 0, 0], branch=[1, 2, 1]),
     "branch"),
    (lambda r: r.inverse_dynamics([0, 0, 0], [0, 0, 0], [0, 0, 0], method="qp",
                                  branch=[1, 1]), "branch"),
    (lambda r: r.inverse_dynamics([0, 0, 0], [0, 0, 0], [0, 0, 0], method="lu"), "method"),
    (lambda r: r.forward_dynamics([0, 0, 0], [0, 0, 0], [0.0, 0.0, np.inf]),
     "actuator_forces"),
    (lambda r: r.forward_dynamics([0, 0, 0], [0, 0, 0], [1.0, 2.0, 3.0, 4.0]),
     "actuator_forces"),
    (lambda r: r.forward_dynamics([0, 0, 0], [0, 0, 0], [0.0, np.nan, 0.0], method="kkt"),
     "actuator_forces"),
    (lambda r: r.forward_dynamics([0, 0, 0], [0, 0, 0], [0, 0, 0], [0, 0, np.nan]),
     "wrench"),
    (lambda r: r.forward_dynamics([0, 0, 0], "abc", [0, 0, 0]), "twist"),
    (lambda r: r.forward_dynamics([0, 0, 0], [0, 0, 0], [0, 0, 0], method="x"), "method"),
    (lambda r: r.static_forces([[0.0, 0.0, 0.0]]), "pose"),
    (lambda r: r.static_forces([0, 0, 0], np.array([[1.0], [2.0], [3.0]])), "wrench"),
    (lambda r: r.static_forces([0, 0, 0], [0.0, np.inf, 0.0]), "wrench"),
    (lambda r: r.acceleration([0, 0, 0], [0, 0, 0], [0, np.nan, 0]), "twist_dot"),
    (lambda r: r.static_forces([0, 0, 0], branch=[1, 1, 0]), "branch"),
])
def test_fast_path_names_the_bad_input(planar, call, name):
    with pytest.raises(InputError) as info:
        call(planar)
    assert info.value.name == name


def test_fast_path_errors_carry_values(planar):
    from hexapod_pin.errors import ActuatorSaturationError

    unreachable = [0.0, -0.2, 0.0]
    with pytest.raises(UnreachablePoseError) as ik_info:
        planar.inverse_kinematics(unreachable)
    for call in (lambda: planar.inverse_dynamics(unreachable, [0, 0, 0], [0, 0, 0]),
                 lambda: planar.forward_dynamics(unreachable, [0, 0, 0], [0, 0, 0]),
                 lambda: planar.static_forces(unreachable)):
        with pytest.raises(UnreachablePoseError) as info:
            call()
        assert info.value.carriages == ik_info.value.carriages == [0]
        assert info.value.shortfall == pytest.approx([0.43 - 0.30])
    # a link perpendicular to its rail: the IK's double root
    perpendicular = [0.0, 0.35 - 0.12 - 0.3, 0.0]
    for call in (lambda: planar.inverse_dynamics(perpendicular, [0, 0, 0], [0, 0, 0]),
                 lambda: planar.forward_dynamics(perpendicular, [0, 0, 0], [0, 0, 0]),
                 lambda: planar.static_forces(perpendicular)):
        with pytest.raises((SingularityError, UnreachablePoseError)):
            call()
    # bounds: the needed (unbounded) forces are carried, never a clipped answer
    pose, twist, twist_dot = [0.01, 0.0, 0.1], [0.1, 0.0, 0.2], [0.0, 20.0, 0.0]
    needed = planar.inverse_dynamics(pose, twist, twist_dot).actuator_forces
    bound = 0.5 * np.abs(needed).max()
    tight = Planar3PRR(planar.geometry.replace(max_actuator_force=bound))
    for method in ("kkt", "qp"):
        with pytest.raises(ActuatorSaturationError) as info:
            tight.inverse_dynamics(pose, twist, twist_dot, method=method)
        np.testing.assert_allclose(info.value.needed, needed, rtol=1e-8)
        # bounded=False lifts the geometry's bound
        np.testing.assert_allclose(tight.inverse_dynamics(pose, twist, twist_dot, method=method,
                                                          bounded=False).actuator_forces,
                                   needed, rtol=1e-9, atol=1e-12)
    loose = Planar3PRR(planar.geometry.replace(max_actuator_force=2 * np.abs(needed).max()))
    np.testing.assert_allclose(loose.inverse_dynamics(pose, twist, twist_dot).actuator_forces,
                               needed, atol=0)


def test_fast_path_accepts_array_likes_and_returns_fresh_arrays(planar):
    pose, twist, twist_dot = np.array([0.01, -0.02, 0.1]), np.array([0.1, 0.2, 0.3]), \
        np.array([0.5, -0.4, 2.0])
    ref = planar.inverse_dynamics(pose, twist, twist_dot)
    strided = np.zeros((3, 2))
    strided[:, 0] = pose
    frozen = pose.copy()
    frozen.setflags(write=False)
    for variant in (pose.tolist(), tuple(pose), strided[:, 0], frozen, pd_series_like(pose)):
        np.testing.assert_array_equal(
            planar.inverse_dynamics(variant, twist, twist_dot).actuator_forces,
            ref.actuator_forces)
    np.testing.assert_allclose(planar.inverse_dynamics(pose.astype(np.float32), twist,
                                                       twist_dot).actuator_forces,
                               ref.actuator_forces, rtol=1e-5)
    np.testing.assert_array_equal(planar.static_forces([0, 0, 0], [1, 2, 0]),
                                  planar.static_forces(np.zeros(3), np.array([1.0, 2.0, 0.0])))
    # results own their memory: later calls and edits of one result leave the others alone
    fd = planar.forward_dynamics(pose, twist, ref.actuator_forces)
    kept = [ref.actuator_forces.copy(), ref.closure_forces.copy(), ref.multipliers.copy(),
            fd.twist_dot.copy(), fd.tree_acceleration.copy(), fd.closure_forces.copy()]
    ref.actuator_forces[:] = 0.0
    planar.inverse_dynamics(-pose, -twist, twist_dot)
    planar.forward_dynamics(-pose, -twist, [9.0, 9.0, 9.0])
    for before, now in zip(kept[1:], [ref.closure_forces, ref.multipliers, fd.twist_dot,
                                      fd.tree_acceleration, fd.closure_forces]):
        np.testing.assert_array_equal(before, now)
    np.testing.assert_array_equal(planar.inverse_dynamics(pose, twist, twist_dot).actuator_forces,
                                  kept[0])
    s = planar.inverse_kinematics(pose)
    jac = planar.jacobian(pose)
    planar.inverse_kinematics(-pose)
    np.testing.assert_array_equal(s, planar.inverse_kinematics(pose))
    np.testing.assert_array_equal(jac, planar.jacobian(pose))


def pd_series_like(values):
    """A sequence type that numpy converts (not a list, tuple or ndarray)."""
    class Seq:
        def __init__(self, data):
            self.data = list(data)

        def __len__(self):
            return len(self.data)

        def __getitem__(self, i):
            return self.data[i]

    return Seq(values)


# -- the shared API's planar specifics ------------------------------------------------------
def test_singularity_measures_by_hand(planar):
    """type I / II from link and rail vectors written out here; zero where expected."""
    rng = np.random.default_rng(31)
    g = planar.geometry
    for _ in range(3):
        pose = random_pose(planar, rng)
        s = planar.inverse_kinematics(pose)
        sliders, points = hand_points(g, pose, s)
        n, r = points - sliders, points - pose[:2]
        cosines = np.abs(np.einsum("ki,ki->k", n, g.rail_directions)) / g.link_length
        a_hat = np.column_stack([n / g.link_length,
                                 (r[:, 0] * n[:, 1] - r[:, 1] * n[:, 0])
                                 / (g.link_length * g.platform_radius)])
        meas = planar.singularity(pose)
        assert meas.type_one == pytest.approx(cosines.min(), rel=1e-12)
        assert meas.type_one_actuator == int(np.argmin(cosines))
        np.testing.assert_allclose(meas.type_two_singular_values,
                                   np.linalg.svd(a_hat, compute_uv=False), rtol=1e-12)
        assert meas.characteristic_length == g.platform_radius
    # at the type-II pose the closure matrix is singular, and the measure says so
    theta = _type_two_theta(planar)
    assert planar.singularity([0.0, 0.0, theta]).type_two < 1e-12
    assert planar.singularity([0.0, 0.0, theta + 0.05]).type_two > 1e-3
    # a link perpendicular to its rail: type one 0, no Jacobian; never raises
    meas = planar.singularity([0.0, 0.35 - 0.12 - 0.3, 0.0])
    assert meas.type_one < 1e-9 and meas.jacobian_singular_values is None
    assert meas.condition_number == np.inf


def test_joint_wrenches_transmit_the_actuator_forces(planar):
    """Pinocchio's rnea with the closure forces: each slider joint transmits its actuator
    force along its axis, the passive joints nothing about theirs."""
    rng = np.random.default_rng(32)
    pose = random_pose(planar, rng)
    twist, twist_dot = rng.normal(size=3) * [0.2, 0.2, 1.0], rng.normal(size=3)
    wrench = np.array([1.5, -2.0, 0.1])
    res = planar.inverse_dynamics(pose, twist, twist_dot, wrench)
    table = res.joint_wrenches
    scale = max(1.0, np.abs(res.actuator_forces).max())
    for k in range(3):
        assert table[f"slider_{k}"][0] == pytest.approx(res.actuator_forces[k], abs=1e-10 * scale)
        assert abs(table[f"link_{k}_joint"][5]) < 1e-10 * scale
    assert abs(table["platform_x"][0]) < 1e-10 * scale
    assert abs(table["platform_y"][1]) < 1e-10 * scale
    np.testing.assert_allclose(table["platform_theta"][[0, 1, 5]], 0.0, atol=1e-10 * scale)
    assert planar.inverse_dynamics(pose, twist, twist_dot, wrench,
                                   joint_wrenches=False).joint_wrenches == {}


def test_batches_flag_and_name_singular_states(planar):
    from hexapod_pin.errors import BatchSingularityError, SingularityError

    theta = _type_two_theta(planar)
    poses = np.array([[0.0, 0.0, 0.0], [0.01, 0.0, 0.1], [0.0, 0.0, theta],
                      [0.0, 0.35 - 0.12 - 0.3, 0.0]])
    zero = np.zeros_like(poses)
    with pytest.raises(BatchSingularityError) as info:
        planar.inverse_dynamics_batch(poses, zero, zero)
    assert info.value.index == 2 and "type-II" in str(info.value)
    # the single-state routes classify the state the same way
    with pytest.raises(SingularityError, match="type-II"):
        planar.static_forces(poses[2])
    jb = planar.jacobian_batch(poses)
    assert jb.regular.tolist() == [True, True, True, False]
    np.testing.assert_array_equal(jb.jacobian[3], 0.0)
    with pytest.raises(BatchSingularityError) as info:
        planar.forward_dynamics_batch(poses[[0, 3]], zero[:2], zero[:2])
    assert info.value.index == 1
    # forward dynamics stays regular at type II (the closures alone fix the multipliers)
    fd = planar.forward_dynamics_batch(poses[:3], zero[:3], np.ones((3, 3)))
    np.testing.assert_allclose(fd.twist_dot[2], planar.forward_dynamics(
        poses[2], [0, 0, 0], [1, 1, 1], method="kkt").twist_dot, atol=1e-9)


def test_batch_inputs_are_checked(planar):
    with pytest.raises(InputError) as info:
        planar.inverse_dynamics_batch(np.zeros((3, 3)), np.zeros((2, 3)), np.zeros((3, 3)))
    assert info.value.name == "twists"
    with pytest.raises(InputError) as info:
        planar.static_forces_batch(np.zeros((2, 3)), np.full((2, 3), np.nan))
    assert info.value.name == "wrenches"
    with pytest.raises(InputError):
        planar.inverse_kinematics_batch(np.zeros(3))


def test_branches_reach_the_dynamics(planar):
    """A non-home branch gives the tree route's answer on that branch's configuration."""
    from hexapod_pin.core.dynamics import inverse_dynamics_tree

    branch = ALL_BRANCHES[5]
    rng = np.random.default_rng(33)
    pose = _regular_pose(planar, rng, branch)
    twist, twist_dot = rng.normal(size=3) * 0.1, rng.normal(size=3)
    res = planar.inverse_dynamics(pose, twist, twist_dot, branch=branch)
    q, v, a = _generic_tree_state(planar, pose, twist, twist_dot, branch)
    ref = inverse_dynamics_tree(planar.model, q, v, a, method="kkt")
    np.testing.assert_allclose(res.actuator_forces, ref.actuator_forces, atol=1e-9)
    red = planar.reduced_dynamics(pose, twist, branch=branch)
    np.testing.assert_allclose(red.jacobian, planar.jacobian(pose, branch), atol=1e-12)
    np.testing.assert_allclose(planar.forward_dynamics(pose, twist, res.actuator_forces,
                                                       branch=branch).twist_dot,
                               twist_dot, atol=1e-9)


def test_one_type_two_predicate_for_single_and_batch_routes(planar):
    """Walking toward a type-II pose, the single-state and batch routes raise exactly where
    ``singularity().type_two`` (sigma_min(A_hat), core.measures) falls below TYPE_II_TOL:
    the one type-II test of every robot."""
    from hexapod_pin.core.measures import TYPE_II_TOL
    from hexapod_pin.errors import SingularityError

    theta = _type_two_theta(planar)
    zero = np.zeros(3)
    seen = set()
    for step in 10.0 ** -np.arange(1, 17):
        pose = np.array([0.0, 0.0, theta + step])
        measure = planar.singularity(pose).type_two
        if abs(math.log10(max(measure, 1e-300) / TYPE_II_TOL)) < 1.0:
            continue                      # within round-off of the threshold: not decisive
        singular = measure < TYPE_II_TOL
        seen.add(singular)
        routes = (lambda: planar.static_forces(pose, bounded=False),
                  lambda: planar.inverse_dynamics(pose, zero, zero, bounded=False),
                  lambda: planar.static_forces_batch(pose[None], bounded=False),
                  lambda: planar.inverse_dynamics_batch(pose[None], zero[None], zero[None],
                                                        bounded=False))
        for route in routes:
            if singular:
                with pytest.raises(SingularityError, match="type-II"):
                    route()
            else:
                route()
    assert seen == {True, False}
