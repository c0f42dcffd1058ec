"""Meshcat HTML files: what they contain, checked against the geometry; and what a
browser shows, checked in headless Chromium (skipped where Chromium is absent)."""

from __future__ import annotations

import base64
import json
import os
import re
import shutil
import subprocess
from pathlib import Path

import numpy as np
import pinocchio as pin
import pytest
from scipy.spatial.transform import Rotation

import hexapod_pin as hp
from hexapod_pin.viz import hexapod_scenes as hviz
from hexapod_pin.viz import scenes as viz

CHROMIUM = next((p for p in (shutil.which("chromium"), "/usr/bin/chromium",
                             shutil.which("chromium-browser")) if p and os.path.exists(p)),
                None)
needs_chromium = pytest.mark.skipif(CHROMIUM is None,
                                    reason="headless Chromium not installed "
                                           "(apt-get install chromium; .ci/run installs it)")

N_VISUALS = 25  # 3 rails + 6 x (carriage, cross, leg) + platform + 3 anchors
ORANGE = np.array([0.95, 0.5, 0.1])
BLUE = np.array([0.2, 0.45, 0.85])


# -- helpers ------------------------------------------------------------------------------
def decode_commands(html: str) -> list[dict]:
    """The meshcat commands embedded in a written page (independent of Scene)."""
    import umsgpack

    match = re.search(r"var hexapodPinCommands = (\[.*?\]);", html, re.DOTALL)
    assert match, "no command list in the page"
    return [umsgpack.unpackb(base64.b64decode(b)) for b in json.loads(match.group(1))]


def matrix_of(commands, path) -> np.ndarray:
    found = [c for c in commands if c["type"] == "set_transform" and c["path"] == path]
    assert found, path
    return np.array(found[-1]["matrix"], dtype=float).reshape(4, 4).T


def world_matrix(commands, path) -> np.ndarray:
    """Compose the transforms of every ancestor node that has one."""
    parts = path.strip("/").split("/")
    out = np.eye(4)
    for n in range(1, len(parts) + 1):
        sub = "/" + "/".join(parts[:n])
        if any(c["type"] == "set_transform" and c["path"] == sub for c in commands):
            out = out @ matrix_of(commands, sub)
    return out


def rotation(rpy) -> np.ndarray:
    """R = Rz(yaw) Ry(pitch) Rx(roll), from scipy (not the library)."""
    return Rotation.from_euler("ZYX", [rpy[2], rpy[1], rpy[0]]).as_matrix()


def carriage_point(geometry, i, qi):
    k = i // 2
    a = np.pi / 2 + 2 * np.pi / 3 * k
    mid = geometry.rail_radius * np.array([np.cos(a), np.sin(a), 0.0])
    u = np.array([-np.sin(a), np.cos(a), 0.0])
    return mid + qi * u, u


def platform_point(geometry, pose, k):
    a = np.pi / 2 + 2 * np.pi / 3 * k
    p = geometry.platform_radius * np.array([np.cos(a), np.sin(a), 0.0])
    return pose[:3] + rotation(pose[3:]) @ p


def color_of(commands, path) -> int:
    obj = next(c for c in commands if c["type"] == "set_object" and c["path"] == path)
    return obj["object"]["materials"][0]["color"]


def as_int(rgb) -> int:
    r, g, b = (round(255 * c) for c in rgb)
    return (r << 16) | (g << 8) | b


def render(html_path: Path, tmp_path: Path, fragment: str = "", budget_ms: int = 3000):
    """Open the page in headless Chromium: screenshot (RGB array) and the status div."""
    from PIL import Image

    png = tmp_path / f"shot{abs(hash(fragment))}.png"
    profile = tmp_path / "chromium-profile"
    cmd = [CHROMIUM, "--headless", "--no-sandbox", "--disable-gpu",
           "--enable-unsafe-swiftshader", "--use-angle=swiftshader", "--disable-quic",
           "--no-first-run", "--disable-background-networking", "--disable-component-update",
           "--disable-sync", f"--user-data-dir={profile}", f"--screenshot={png}",
           "--window-size=800,600", f"--virtual-time-budget={budget_ms}", "--dump-dom",
           html_path.resolve().as_uri() + fragment]
    done = subprocess.run(cmd, capture_output=True, text=True, timeout=120, check=False)
    assert png.is_file(), done.stderr[-2000:]
    status = re.search(r'<div id="hexapod-pin-status"([^>]*)>', done.stdout)
    assert status, "page did not load: " + done.stdout[:500]
    attrs = dict(re.findall(r'data-([a-z-]+)="([^"]*)"', status.group(1)))
    image = np.asarray(Image.open(png).convert("RGB"), dtype=float) / 255.0
    return image, attrs


def colour_pixels(image, rgb, tol=0.12) -> int:
    """Pixels near a colour after shading: hue direction close, some brightness."""
    flat = image.reshape(-1, 3)
    norm = np.linalg.norm(flat, axis=1) + 1e-9
    target = np.asarray(rgb) / np.linalg.norm(rgb)
    return int(np.sum((np.linalg.norm(flat / norm[:, None] - target, axis=1) < tol)
                      & (norm > 0.3)))


def child_pids() -> set[int]:
    me, out = os.getpid(), set()
    for stat in Path("/proc").glob("[0-9]*/stat"):
        try:
            fields = stat.read_text().rsplit(")", 1)[1].split()
        except OSError:
            continue
        if int(fields[1]) == me:
            out.add(int(stat.parent.name))
    return out


@pytest.fixture(scope="module")
def circle(robot):
    """A 2 s platform motion near home (poses sampled at 1 kHz) and carriage forces."""
    t = np.linspace(0.0, 2.0, 2001)
    poses = np.tile(robot.home_pose, (len(t), 1))
    poses[:, 0] = 0.03 * np.cos(np.pi * t)
    poses[:, 1] = 0.03 * np.sin(np.pi * t)
    poses[:, 5] = 0.2 * np.sin(np.pi * t)
    forces = np.tile([1.65, -1.65], 3)[None, :] * (1.0 + 0.5 * np.sin(2 * np.pi * t))[:, None]
    return t, poses, forces


# -- scene contents against the geometry ---------------------------------------------------
def test_pose_file_draws_the_closed_robot_where_the_geometry_says(robot, tmp_path, rng):
    pose = robot.home_pose + np.array([0.01, -0.02, -0.01, 0.05, -0.04, 0.1])
    q_tree = robot.configuration(pose)
    path = viz.write_pose_html(tmp_path / "pose.html", robot, q_tree)
    commands = decode_commands(path.read_text())
    objects = [c for c in commands if c["type"] == "set_object"]
    assert len(objects) == N_VISUALS + 3 * 2          # visuals + platform triad (2 meshes each)
    g = robot.geometry
    carriages = robot.inverse_kinematics(pose)
    for i in range(6):
        m = world_matrix(commands, f"/meshcat/hexapod/leg_{i}_0")
        axis, centre = m[:3, 2], m[:3, 3]
        bottom, top = centre - axis * g.leg_length / 2, centre + axis * g.leg_length / 2
        c_i, _ = carriage_point(g, i, carriages[i])
        np.testing.assert_allclose(bottom, c_i, atol=1e-9)
        np.testing.assert_allclose(top, platform_point(g, pose, i // 2), atol=1e-9)
    platform = world_matrix(commands, "/meshcat/hexapod/platform_0")
    np.testing.assert_allclose(platform[:3, 3], pose[:3], atol=1e-12)
    np.testing.assert_allclose(platform[:3, :3], rotation(pose[3:]), atol=1e-12)
    # colours from the URDF materials: actuated orange, platform blue, legs grey
    assert color_of(commands, "/meshcat/hexapod/carriage_3_0") == as_int(ORANGE)
    assert color_of(commands, "/meshcat/hexapod/platform_0") == as_int(BLUE)
    assert color_of(commands, "/meshcat/hexapod/leg_3_0") == as_int([0.7, 0.7, 0.72])


def test_urdf_cylinder_axis_maps_to_meshcat_y(robot):
    """meshcat cylinders run along y; the URDF's along z: the object's own matrix turns y to z."""
    scene = viz.pose_scene(robot, robot.home_configuration, frames=())
    leg = next(c for c in scene.commands if c["type"] == "set_object"
               and c["path"].endswith("leg_0_0"))
    inner = np.array(leg["object"]["object"]["matrix"]).reshape(4, 4).T
    np.testing.assert_allclose(inner[:3, :3] @ [0, 1, 0], [0, 0, 1], atol=1e-15)


def test_force_arrows_sit_on_carriages_and_platform_points(robot):
    pose = robot.home_pose + np.array([0.0, 0.01, 0.0, 0.0, 0.05, -0.1])
    q_tree = robot.configuration(pose)
    tau = np.array([3.0, -1.0, 0.5, 2.0, -4.0, 1.0])
    closure = np.arange(18, dtype=float).reshape(6, 3) - 8.0
    scale = 0.01
    scene = viz.pose_scene(robot, q_tree, actuator_forces=tau, closure_forces=closure,
                           force_scale=scale, frames=())
    commands = scene.commands
    carriages = robot.inverse_kinematics(pose)
    for i in range(6):
        m = world_matrix(commands, f"/meshcat/hexapod/overlays/actuator_{i}")
        c_i, u = carriage_point(robot.geometry, i, carriages[i])
        np.testing.assert_allclose(m[:3, 3], c_i, atol=1e-12)
        np.testing.assert_allclose(m[:3, 1], scale * tau[i] * u, atol=1e-12)  # arrow = local y
        m = world_matrix(commands, f"/meshcat/hexapod/overlays/closure_{i}")
        np.testing.assert_allclose(m[:3, 3], platform_point(robot.geometry, pose, i // 2),
                                   atol=1e-12)
        np.testing.assert_allclose(m[:3, 1], scale * closure[i], atol=1e-12)


def test_default_arrow_scale_draws_largest_force_at_fixed_length(robot):
    tau = np.array([3.0, -1.0, 0.5, 2.0, -4.0, 1.0])
    scene = viz.pose_scene(robot, robot.home_configuration, actuator_forces=tau, frames=())
    lengths = [np.linalg.norm(matrix_of(scene.commands,
                                        f"/meshcat/hexapod/overlays/actuator_{i}")[:3, 1])
               for i in range(6)]
    np.testing.assert_allclose(lengths, viz.DEFAULT_ARROW_LENGTH * np.abs(tau) / 4.0,
                               rtol=1e-12)


def test_modes_side_by_side_offsets_and_mirror(robot):
    up = robot.home_pose
    down = up * np.array([1, 1, -1, 1, 1, 1])   # the mirror image assembles the same q
    qs = hviz.hexapod_configurations(robot, [up, down], carriages=[robot.home_q] * 2)
    np.testing.assert_allclose(qs[:, robot.indices.carriage_q], [robot.home_q] * 2,
                               atol=1e-12)
    scene = viz.modes_scene(robot, qs, spacing=1.5, labels=["up", "down"])
    assert scene.count("set_object") == 2 * (N_VISUALS + 6) + 2     # and the 2 labels
    texts = [c["object"]["textures"][0]["text"] for c in scene.commands
             if c["type"] == "set_object" and c["path"].startswith("/meshcat/labels/")]
    assert texts == ["0: up", "1: down"]
    # each label stands below its copy: the second one is offset by the spacing in x
    first, second = (matrix_of(scene.commands, f"/meshcat/labels/{i}")[:3, 3] for i in (0, 1))
    np.testing.assert_allclose((second - first)[:2], [1.5, 0.0], atol=1e-9)
    assert first[2] < 0.0 and second[2] < -robot.geometry.home_height
    offset = matrix_of(scene.commands, "/meshcat/hexapod_1")[:3, 3]
    np.testing.assert_allclose(offset, [1.5, 0.0, 0.0])
    platform = world_matrix(scene.commands, "/meshcat/hexapod_1/platform_0")[:3, 3]
    np.testing.assert_allclose(platform, [1.5, 0.0, -robot.geometry.home_height], atol=1e-12)
    assert "0: up" in scene.caption and "1: down" in scene.caption


def test_modes_sequence_is_a_discrete_animation(robot):
    up = robot.home_pose
    qs = hviz.hexapod_configurations(robot, [up, up * [1, 1, -1, 1, 1, 1]],
                                    carriages=[robot.home_q] * 2)
    scene = viz.modes_scene(robot, qs, layout="sequence")
    (anim,) = [c for c in scene.commands if c["type"] == "set_animation"]
    clip = next(a for a in anim["animations"] if a["path"].endswith("platform_0"))
    track = next(t for t in clip["clip"]["tracks"] if t["name"] == ".position")
    assert track["interpolation"] == 2300
    assert [k["time"] for k in track["keys"]] == [0.0, 1.0]
    np.testing.assert_allclose([k["value"][2] for k in track["keys"]],
                               [up[2], -up[2]], atol=1e-12)


def test_trajectory_animation_keys_follow_the_poses(robot, circle):
    t, poses, forces = circle
    fps = 20.0
    scene = hviz.hexapod_trajectory_scene(robot, t, poses, actuator_forces=forces, fps=fps,
                                         force_scale=0.02)
    (anim,) = [c for c in scene.commands if c["type"] == "set_animation"]
    assert anim["options"]["play"] is True
    clips = {a["path"]: a["clip"] for a in anim["animations"]}
    assert not any("rail" in p for p in clips)          # static parts are not animated
    tracks = {tr["name"]: tr for tr in clips["/meshcat/hexapod/platform_0"]["tracks"]}
    times = np.array([k["time"] for k in tracks[".position"]["keys"]])
    np.testing.assert_allclose(times, np.arange(41) / fps, atol=1e-12)   # samples at k / fps
    rows = np.rint(times * 1000).astype(int)
    np.testing.assert_allclose([k["value"] for k in tracks[".position"]["keys"]],
                               poses[rows, :3], atol=1e-12)
    for key, row in zip(tracks[".quaternion"]["keys"], rows):
        x, y, z, w = key["value"]
        np.testing.assert_allclose(Rotation.from_quat([x, y, z, w]).as_matrix(),
                                   rotation(poses[row, 3:]), atol=1e-12)
    arrow = {tr["name"]: tr for tr in clips["/meshcat/hexapod/overlays/actuator_1"]["tracks"]}
    np.testing.assert_allclose([k["value"][1] for k in arrow[".scale"]["keys"]],
                               0.02 * np.abs(forces[rows, 1]), rtol=1e-12)


def test_simulation_scene_reads_a_trajectory_object(robot, circle):
    t, _, forces = circle

    class Trajectory:  # the attributes the simulation's result carries
        times, actuator_forces = t[:200], forces[:200]
        poses = circle[1][:200]
        q = np.array([robot.inverse_kinematics(p) for p in circle[1][:200]])

    scene = hviz.simulation_scene(robot, Trajectory(), fps=50)
    (anim,) = [c for c in scene.commands if c["type"] == "set_animation"]
    assert any(a["path"].endswith("overlays/actuator_0") for a in anim["animations"])
    with pytest.raises(hp.InputError):
        hviz.simulation_scene(robot, object())


def test_hexapod_configurations_follow_the_carriages_branch(robot):
    pose = robot.home_pose + np.array([0.0, 0.0, -0.05, 0.0, 0.0, 0.0])
    branch = np.array([1.0, 1.0, -1.0, -1.0, -1.0, 1.0])
    wanted = robot.inverse_kinematics(pose, branch=branch, check_limits=False)
    (q_tree,) = hviz.hexapod_configurations(robot, pose, carriages=wanted)
    np.testing.assert_allclose(q_tree[robot.indices.carriage_q], wanted, atol=1e-12)
    assert np.abs(robot.model.residual(q_tree)).max() < 1e-12


def test_generic_robot_from_its_urdf_file(tmp_path):
    """Any tree with visuals: a bare pin.Model plus its URDF, with an STL mesh."""
    stl = tmp_path / "tetra.stl"
    tri = np.array([[[0, 0, 0], [1, 0, 0], [0, 1, 0]], [[0, 0, 0], [0, 0, 1], [1, 0, 0]],
                    [[0, 0, 0], [0, 1, 0], [0, 0, 1]], [[1, 0, 0], [0, 0, 1], [0, 1, 0]]],
                   dtype=np.float32) * 0.1
    header = b"tetra".ljust(80, b" ") + np.uint32(4).tobytes()
    body = b"".join(np.zeros(3, np.float32).tobytes() + t.tobytes() + b"\0\0" for t in tri)
    stl.write_bytes(header + body)
    urdf = f"""<robot name="arm">
      <link name="base"><visual><geometry><mesh filename="{stl}"/></geometry>
        <material name="m"><color rgba="0.1 0.8 0.2 1"/></material></visual></link>
      <joint name="j" type="revolute"><parent link="base"/><child link="arm"/>
        <axis xyz="0 0 1"/><limit lower="-3" upper="3" effort="1" velocity="1"/></joint>
      <link name="arm"><visual><origin xyz="0.2 0 0"/><geometry><cylinder radius="0.02"
        length="0.3"/></geometry></visual></link></robot>"""
    model = pin.buildModelFromXML(urdf)
    scene = viz.pose_scene(model, np.array([0.3]), urdf=urdf, frames=("arm",))
    objects = [c for c in scene.commands if c["type"] == "set_object"]
    mesh = next(c for c in objects if c["path"] == "/meshcat/arm/base_0")
    assert mesh["object"]["geometries"][0]["format"] == "stl"
    assert mesh["object"]["materials"][0]["color"] == as_int([0.1, 0.8, 0.2])
    m = matrix_of(scene.commands, "/meshcat/arm/arm_0")
    np.testing.assert_allclose(m[:3, 3], 0.2 * np.array([np.cos(0.3), np.sin(0.3), 0]),
                               atol=1e-12)
    with pytest.raises(hp.InputError, match="bare tree"):
        viz.pose_scene(model, np.array([0.3]), urdf=urdf, actuator_forces=[1.0])


def test_another_closed_loop_robot_draws_from_its_own_urdf():
    """The planar 3-PRR (another ClosedLoopModel): sliders' forces along their rails."""
    planar = pytest.importorskip("hexapod_pin.planar.robot", reason="planar robot not present")
    robot = planar.Planar3PRR.default()
    visual = viz.robot_visual(robot)
    q = robot.home_configuration
    scene = viz.pose_scene(robot, q, actuator_forces=[1.0, -2.0, 0.5], force_scale=0.1,
                           frames=())
    n_arrows = 3 * 2
    assert scene.count("set_object") == visual.visual_model.ngeoms + n_arrows
    data = visual.model.createData()
    pin.forwardKinematics(visual.model, data, q)
    for i, (name, tau) in enumerate(zip(robot.model.actuated_joints, [1.0, -2.0, 0.5])):
        jid = visual.model.getJointId(name)
        axis = data.oMi[jid].rotation[:, 0]          # the sliders move along their local x
        m = matrix_of(scene.commands, f"/meshcat/{visual.name}/overlays/actuator_{i}")
        np.testing.assert_allclose(m[:3, 1], 0.1 * tau * axis, atol=1e-12)


def test_other_primitives_and_a_bounding_box_for_other_shapes():
    """Capsules, cones, ellipsoids; a mesh without a file as its bounding box."""
    import coal

    model = pin.Model()
    visuals = pin.GeometryModel()
    cloud = coal.BVHModelOBBRSS()   # a mesh held in memory, no file to draw it from
    cloud.beginModel(4, 4)
    for point in ([0, 0, 0], [0.1, 0, 0], [0, 0.2, 0], [0, 0, 0.3]):
        cloud.addVertex(np.array(point, dtype=float))
    cloud.endModel()
    shapes = {"capsule": coal.Capsule(0.02, 0.3), "cone": coal.Cone(0.05, 0.2),
              "ellipsoid": coal.Ellipsoid(0.1, 0.2, 0.3), "hull": cloud}
    for name, shape in shapes.items():
        visuals.addGeometryObject(pin.GeometryObject(name, 0, pin.SE3.Identity(), shape))
    visual = viz.RobotVisual(model, visuals, None, "shapes")
    scene = viz.pose_scene(visual, np.zeros(0), frames=())
    objects = {c["path"]: c["object"] for c in scene.commands if c["type"] == "set_object"}
    assert {"/meshcat/shapes/capsule/body", "/meshcat/shapes/capsule/cap_top",
            "/meshcat/shapes/capsule/cap_bottom"} <= set(objects)
    cone = objects["/meshcat/shapes/cone"]["geometries"][0]
    assert (cone["radiusTop"], cone["radiusBottom"], cone["height"]) == (0.0, 0.05, 0.2)
    hull = objects["/meshcat/shapes/hull"]
    assert hull["geometries"][0]["type"] == "BoxGeometry"
    np.testing.assert_allclose([hull["geometries"][0][k] for k in ("width", "height", "depth")],
                               [0.1, 0.2, 0.3], atol=1e-12)
    np.testing.assert_allclose(np.array(hull["object"]["matrix"]).reshape(4, 4).T[:3, 3],
                               [0.05, 0.1, 0.15], atol=1e-12)


def test_errors_name_the_bad_input(robot):
    q = robot.home_configuration
    with pytest.raises(hp.InputError, match="configuration"):
        viz.pose_scene(robot, q[:-1])
    with pytest.raises(hp.InputError, match="actuator_forces"):
        viz.pose_scene(robot, q, actuator_forces=[1.0, 2.0])
    with pytest.raises(hp.InputError, match="closure_forces"):
        viz.pose_scene(robot, q, closure_forces=np.zeros((3, 3)))
    with pytest.raises(hp.InputError, match="frames"):
        viz.pose_scene(robot, q, frames=["no_such_frame"])
    with pytest.raises(hp.InputError, match="force_scale"):
        viz.pose_scene(robot, q, actuator_forces=np.ones(6), force_scale=-1.0)
    with pytest.raises(hp.InputError, match="layout"):
        viz.modes_scene(robot, [q], layout="spiral")
    with pytest.raises(hp.InputError, match="increasing"):
        viz.trajectory_scene(robot, [0.0, 0.0], [q, q])
    with pytest.raises(hp.InputError, match="urdf"):
        viz.robot_visual(robot.model.model)
    with pytest.raises(hp.UnreachablePoseError):
        hviz.hexapod_configurations(robot, robot.home_pose + [0, 0, 1.0, 0, 0, 0])
    with pytest.raises(hp.InputError, match="folder"):
        viz.write_pose_html("/no/such/dir/x.html", robot, q)


def test_writing_starts_no_process(robot, tmp_path, monkeypatch, circle):
    """No meshcat server: nothing is spawned, and no child process is left behind."""
    before = child_pids()

    def refuse(*args, **kwargs):
        raise AssertionError("visualize tried to start a process")

    monkeypatch.setattr(subprocess.Popen, "__init__", refuse)
    t, poses, _ = circle
    viz.write_pose_html(tmp_path / "a.html", robot, robot.home_configuration)
    hviz.write_hexapod_trajectory_html(tmp_path / "b.html", robot, t[:300], poses[:300], fps=10)
    monkeypatch.undo()
    assert child_pids() - before == set()


def test_page_is_self_contained(robot, tmp_path):
    text = viz.write_pose_html(tmp_path / "p.html", robot, robot.home_configuration).read_text()
    assert "MeshCat.Viewer" in text and "handle_command_bytearray" in text
    assert not re.search(r"""<script[^>]+src=|<link[^>]+href=|https?://[^\s"']+\.js""", text)
    assert oct((tmp_path / "p.html").stat().st_mode & 0o777) != "0o600"


# -- what a browser shows ----------------------------------------------------------------
@needs_chromium
def test_browser_shows_the_home_pose(robot, tmp_path):
    path = viz.write_pose_html(tmp_path / "home.html", robot, robot.home_configuration,
                               actuator_forces=np.tile([1.65, -1.65], 3))
    image, status = render(path, tmp_path)
    assert status["ok"] == "true", status
    assert int(status["meshes"]) == N_VISUALS + 2 * 3 + 2 * 6   # visuals, triad, 6 arrows
    assert image.std() > 0.05                                    # not blank
    assert len(np.unique((image * 15).astype(int).reshape(-1, 3), axis=0)) > 20
    orange, blue = colour_pixels(image, ORANGE), colour_pixels(image, BLUE)
    assert orange > 300                                          # the carriages
    assert blue > 3000 and blue > 3 * orange                     # the platform, the largest


@needs_chromium
def test_browser_plays_the_trajectory_animation(robot, tmp_path, circle):
    t, poses, forces = circle
    path = hviz.write_hexapod_trajectory_html(tmp_path / "traj.html", robot, t, poses,
                                             actuator_forces=forces)
    first, status = render(path, tmp_path, "#t=0")
    assert status["ok"] == "true", status
    assert float(status["animation-duration"]) == pytest.approx(2.0)
    assert int(status["animation-actions"]) >= 18 + 1 + 6        # moving visuals, triad, arrows
    later, _ = render(path, tmp_path, "#t=1.0")
    moved = np.abs(first - later).sum(axis=2) > 0.1
    assert moved.mean() > 0.005, "the robot did not move between t = 0 and t = 1 s"
    assert colour_pixels(later, BLUE) > 3000


@needs_chromium
def test_browser_shows_every_mode(robot, tmp_path):
    up = robot.home_pose
    qs = hviz.hexapod_configurations(robot, [up, up * [1, 1, -1, 1, 1, 1]],
                                    carriages=[robot.home_q] * 2)
    path = viz.write_modes_html(tmp_path / "modes.html", robot, qs)
    image, status = render(path, tmp_path)
    assert int(status["meshes"]) == 2 * (N_VISUALS + 6)
    left, right = image[:, :400], image[:, 400:]
    assert colour_pixels(left, BLUE) > 1000 and colour_pixels(right, BLUE) > 1000


def test_a_robot_without_visuals_is_a_clear_error(tmp_path):
    urdf = tmp_path / "bare.urdf"
    urdf.write_text('<?xml version="1.0"?><robot name="bare"><link name="base"/>'
                    '<link name="arm"><inertial><mass value="1"/><inertia ixx="1e-3" ixy="0" '
                    'ixz="0" iyy="1e-3" iyz="0" izz="1e-3"/></inertial></link>'
                    '<joint name="j" type="revolute"><parent link="base"/><child link="arm"/>'
                    '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/>'
                    '</joint></robot>')
    loops = tmp_path / "bare.loops.yaml"
    loops.write_text("closures: []\nactuated: [j]\n")
    model = hp.ClosedLoopModel.from_files(urdf, loops)
    with pytest.raises(hp.InputError, match="no visual geometry"):
        viz.pose_scene(model, np.zeros(model.nq))


# -- views: labels beside the copies, the platform's path, the legend ----------------------
def _label_box(commands, index):
    """The world corners (8, 3) of label ``index``'s sign (its box and transform)."""
    (obj,) = [c["object"] for c in commands if c["type"] == "set_object"
              and c["path"] == f"/meshcat/labels/{index}"]
    width, height, depth = obj["geometries"][0]["width"], obj["geometries"][0]["height"], \
        obj["geometries"][0]["depth"]
    half = np.array([width, height, depth]) / 2
    corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    mat = matrix_of(commands, f"/meshcat/labels/{index}")
    return (corners * half) @ mat[:3, :3].T + mat[:3, 3]


def _overlap(a, b):
    """Whether two axis-aligned boxes (2, 3) overlap."""
    return bool(np.all(a[0] < b[1]) and np.all(b[0] < a[1]))


def test_mode_labels_stand_beside_their_copies_and_overlap_nothing(robot):
    from hexapod_pin.viz.drawing import draw_robot, robot_visual
    from hexapod_pin.viz.meshcat_scene import Scene

    modes = robot.assembly_modes(robot.home_actuators)
    qs = hviz.hexapod_configurations(robot, modes, carriages=[robot.home_q] * len(modes))
    labels = [f"mode {i} at pose {np.round(m[:3], 3)}" for i, m in enumerate(modes)]
    scene = viz.modes_scene(robot, qs, labels=labels)
    visual = robot_visual(robot)
    step = None
    copies = []
    for index, q in enumerate(qs):
        offset = matrix_of(scene.commands, f"/meshcat/hexapod_{index}")[:3, 3]
        pts = np.array(draw_robot(Scene(), visual, q, "/x", offset).points)   # box corners
        copies.append(np.array([pts.min(axis=0), pts.max(axis=0)]))
        if index == 1:
            step = offset[0]
    signs = []
    for index in range(len(qs)):
        corners = _label_box(scene.commands, index)
        signs.append(np.array([corners.min(axis=0), corners.max(axis=0)]))
        # beside its own copy: below it, centred under it, nearer to it than to any other
        mid = (copies[index][0] + copies[index][1]) / 2
        np.testing.assert_allclose(signs[index].mean(axis=0)[:2], mid[:2], atol=1e-9)
        assert signs[index][1, 2] < copies[index][0, 2]
        gaps = [np.linalg.norm(signs[index].mean(axis=0) - (c[0] + c[1]) / 2) for c in copies]
        assert int(np.argmin(gaps)) == index
    for i, sign in enumerate(signs):
        assert not any(_overlap(sign, copy) for copy in copies), i
        assert not any(_overlap(sign, other) for j, other in enumerate(signs) if j != i), i
        assert sign[1, 0] - sign[0, 0] <= step                     # narrower than the spacing
    assert "sign below each" in " ".join(scene.legend)
    assert any("red x, green y, blue z" in line for line in scene.legend)


def test_trajectory_view_traces_the_platform_origin(robot, circle):
    t, poses, forces = circle
    scene = hviz.hexapod_trajectory_scene(robot, t, poses, actuator_forces=forces, fps=20.0)
    (line,) = [c["object"] for c in scene.commands if c["type"] == "set_object"
               and c["path"] == "/meshcat/hexapod/path"]
    assert line["object"]["type"] == "Line"
    (geometry,) = line["geometries"]
    packed = geometry["data"]["attributes"]["position"]["array"]      # a float32 array
    points = np.frombuffer(packed.data, dtype=np.float32).astype(float).reshape(-1, 3)
    # one vertex per configuration drawn (the hexapod's helper thins the poses to the key
    # frames k / fps first), at the pose's position: the platform origin
    rows = np.rint(np.arange(41) / 20.0 * 1000).astype(int)
    np.testing.assert_allclose(points, poses[rows, :3], atol=1e-6)   # float32 in the page
    # the generic scene traces every sample it is given, not only its key frames
    qs = np.array([robot.configuration(p) for p in poses[:200:5]])
    dense = viz.trajectory_scene(robot, t[:200:5], qs, fps=5.0)
    (line,) = [c["object"] for c in dense.commands if c["type"] == "set_object"
               and c["path"] == "/meshcat/hexapod/path"]
    packed = line["geometries"][0]["data"]["attributes"]["position"]["array"]
    np.testing.assert_allclose(np.frombuffer(packed.data, dtype=np.float32).reshape(-1, 3),
                               poses[:200:5, :3], atol=1e-6)
    assert any("path of the platform origin" in line for line in scene.legend)
    assert any("red x, green y, blue z" in line for line in scene.legend)
    html = scene.html()
    assert "path of the platform origin" in html and "red x, green y, blue z" in html


def test_the_pose_view_legend_explains_the_triad(robot):
    scene = viz.pose_scene(robot, robot.home_configuration)
    assert scene.legend == [line for line in scene.legend if "arrow" not in line]
    assert any("platform frame: red x, green y, blue z" in line for line in scene.legend)
    assert viz.pose_scene(robot, robot.home_configuration, frames=()).legend == []
