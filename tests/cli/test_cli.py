"""The hexapod-pin command line: outputs checked against independent computations, exit
codes, one-line errors, files written."""

from __future__ import annotations

import base64
import functools
import json
import re
import subprocess
import sys

import numpy as np
import pytest
from rich.console import Console
from scipy.spatial.transform import Rotation
from typer.testing import CliRunner

from conftest import one_line_error as cli_error

import hexapod_pin as hp
from hexapod_pin import files
from hexapod_pin import motion as motions
from hexapod_pin.cli import app, common
from hexapod_pin.viz import workspace_plots
from hexapod_pin.viz.workspace_plots import CONDITION_LABEL

RUN = CliRunner()
HOME_STATIC_FORCE = 1.651   # N, the number for the defaults at home


def invoke(*args):
    return RUN.invoke(app, [str(a) for a in args])


def ok_json(*args):
    result = invoke(*args, "--json")
    assert result.exit_code == 0, result.output
    assert result.stderr == ""                        # --json writes nothing else
    return json.loads(result.stdout)


def one_line_error(result, *words):
    """:func:`conftest.one_line_error` with exit code 1."""
    return cli_error(result, 1, *words)


def independent_ik(geometry, pose):
    """Carriage positions on the home branch, from the geometry alone (scipy rotation)."""
    a = np.pi / 2 + 2 * np.pi / 3 * np.arange(3)
    mids = geometry.rail_radius * np.stack([np.cos(a), np.sin(a), np.zeros(3)], 1)
    dirs = np.stack([-np.sin(a), np.cos(a), np.zeros(3)], 1)
    pts = geometry.platform_radius * np.stack([np.cos(a), np.sin(a), np.zeros(3)], 1)
    rot = Rotation.from_euler("ZYX", pose[3:][::-1]).as_matrix()
    q = []
    for i in range(6):
        k = i // 2
        d = pose[:3] + rot @ pts[k] - mids[k]
        along = d @ dirs[k]
        q.append(along + (-1) ** (i + 1) * np.sqrt(geometry.leg_length ** 2 - d @ d + along ** 2))
    return np.array(q)


def fd_jacobian(geometry, pose, eps=1e-6):
    cols = []
    for j in range(6):
        out = []
        for sign in (1.0, -1.0):
            d = np.zeros(6)
            d[j] = sign * eps
            rot = Rotation.from_rotvec(d[3:]).as_matrix() @ Rotation.from_euler(
                "ZYX", pose[3:][::-1]).as_matrix()
            rpy = Rotation.from_matrix(rot).as_euler("ZYX")[::-1]
            out.append(independent_ik(geometry, np.r_[pose[:3] + d[:3], rpy]))
        cols.append((out[0] - out[1]) / (2 * eps))
    return np.array(cols).T


def decode_commands(html: str) -> list[dict]:
    import umsgpack

    blobs = json.loads(re.search(r"var hexapodPinCommands = (\[.*?\]);", html, re.DOTALL).group(1))
    return [umsgpack.unpackb(base64.b64decode(b)) for b in blobs]


def count(html_path, kind="set_object") -> int:
    return sum(c["type"] == kind for c in decode_commands(html_path.read_text()))


def write_csv(path, t, poses, extra=None):
    header = ["t", "x", "y", "z", "roll", "pitch", "yaw"] + list(extra or {})
    cols = [t[:, None], poses] + [np.asarray(v)[:, None] for v in (extra or {}).values()]
    rows = np.hstack(cols)
    path.write_text("# a motion\n" + ",".join(header) + "\n"
                    + "\n".join(",".join(repr(float(v)) for v in r) for r in rows) + "\n")
    return path


# -- kinematics ---------------------------------------------------------------------------
def test_ik_matches_the_geometry_in_radians_and_degrees(robot):
    pose = np.array([0.01, -0.02, 0.33, 0.05, -0.04, 0.1])
    expected = independent_ik(robot.geometry, pose)
    out = ok_json("ik", *pose)
    np.testing.assert_allclose(out["q"], expected, atol=1e-12)
    text = ",".join(repr(float(v)) for v in np.r_[pose[:3], np.degrees(pose[3:])])
    out = ok_json("ik", text, "--degrees")
    np.testing.assert_allclose(out["q"], expected, atol=1e-12)
    table = invoke("ik", *pose)
    assert table.exit_code == 0 and f"{expected[3]:+.6f}" in table.stdout


def test_ik_branch_picks_the_other_root(robot):
    pose = robot.home_pose
    out = ok_json("ik", *pose, "--branch", "+-+-+-", "--no-limits")
    home = independent_ik(robot.geometry, pose)
    # the other root is mirrored about the foot of the perpendicular: q' = 2 (u . d) - q
    np.testing.assert_allclose(out["q"], -home, atol=1e-12)


def test_geometry_from_toml_yaml_and_flags(tmp_path):
    toml = tmp_path / "g.toml"
    toml.write_text("[geometry]\nleg_length = 0.5\ncarriage_home = 0.12\n"
                    "platform_inertia = [0.005, 0.005, 0.009]\n")
    yaml = tmp_path / "g.yaml"
    yaml.write_text("leg_length: 0.5\ncarriage_home: 0.12\n")
    geometry = hp.HexapodGeometry(leg_length=0.5, carriage_home=0.12)
    pose = geometry.home_pose
    for extra in (["--geometry", toml], ["--geometry", yaml],
                  ["--set", "leg_length=0.5", "--set", "carriage_home=0.12"]):
        out = ok_json("ik", *pose, *extra)
        np.testing.assert_allclose(out["q"], [-0.12, 0.12] * 3, atol=1e-12)
    assert files.load_geometry(toml).platform_inertia == (0.005, 0.005, 0.009)


def test_bad_input_is_one_line_nonzero_and_names_the_cause(tmp_path, robot):
    cli_error(invoke("ik", 0, 0, 0.35, 0, 0), 2, "expected 6 values", "got 5")   # usage
    one_line_error(invoke("ik", 0, 0, "zz", 0, 0, 0), "not a number", "zz")
    one_line_error(invoke("ik", 0, 0, 0.9, 0, 0, 0), "unreachable", "carriage")
    one_line_error(invoke("ik", 0.0, 0.0, 0.2, 0, 0, 0), "stroke")
    one_line_error(invoke("ik", *robot.home_pose, "--branch", "++"), "branch")
    bad = tmp_path / "bad.toml"
    bad.write_text("leg_length = = 0.5\n")
    one_line_error(invoke("ik", *robot.home_pose, "--geometry", bad), "malformed", "bad.toml")
    one_line_error(invoke("ik", *robot.home_pose, "--set", "legs=3"), "legs", "unknown field")
    one_line_error(invoke("ik", *robot.home_pose, "--set", "leg_length=-1"), "leg_length")
    one_line_error(invoke("ik", *robot.home_pose, "--geometry", tmp_path / "none.yaml"),
                   "not found")
    one_line_error(invoke("plot", "spiral"), "kind")
    assert invoke("ik", "--no-such-option-value").exit_code == 2   # a usage error


def test_subprocess_error_has_no_traceback():
    proc = subprocess.run([sys.executable, "-m", "hexapod_pin", "ik", "0", "0", "1", "0", "0",
                           "0"], capture_output=True, text=True, timeout=120, check=False)
    assert proc.returncode == 1 and "Traceback" not in proc.stderr
    assert proc.stderr.startswith("error: pose unreachable")


def test_jacobian_matches_finite_differences(robot):
    pose = robot.home_pose + np.array([0.01, 0.0, -0.02, 0.03, 0.02, -0.05])
    out = ok_json("jacobian", *pose)
    np.testing.assert_allclose(out["jacobian"], fd_jacobian(robot.geometry, pose), atol=1e-6)
    sv = np.linalg.svd(np.array(out["jacobian"]), compute_uv=False)
    assert out["condition_number"] == pytest.approx(sv[0] / sv[-1], rel=1e-12)
    # the one condition number of the library, printed under its label
    assert out["condition_number"] == pytest.approx(robot.singularity(pose).condition_number,
                                                    rel=1e-12)
    lines = invoke("jacobian", *pose).stdout.splitlines()     # a table row: label | value
    assert any(CONDITION_LABEL in line and f" {out['condition_number']:.6g} " in line
               for line in lines)


def test_fk_inverts_ik(robot):
    pose = robot.home_pose + np.array([0.01, -0.015, -0.02, 0.04, -0.03, 0.08])
    q = independent_ik(robot.geometry, pose)
    out = ok_json("fk", *q)
    np.testing.assert_allclose(out["pose"], pose, atol=1e-9)


def test_modes_of_home_q_and_their_html(tmp_path, robot):
    html = tmp_path / "modes.html"
    out = ok_json("modes", "--html", html)
    modes = np.array(out["modes"])
    assert len(modes) == 8 and (modes[:, 2] > 0).sum() == 4
    for pose in modes:     # every mode puts the carriages at home q
        np.testing.assert_allclose(independent_ik_any_branch(robot.geometry, pose),
                                   robot.home_q, atol=1e-8)
    assert count(html) == 8 * (25 + 6) + 8              # 8 copies and their 8 labels
    labels = [c for c in decode_commands(html.read_text())
              if c["type"] == "set_object" and "/labels/" in c["path"]]
    assert [c["object"]["textures"][0]["text"] for c in labels] == [
        f"{n}: z = {pose[2]:+.3f} m" for n, pose in enumerate(modes)]


def independent_ik_any_branch(geometry, pose):
    """The root of each carriage nearest to home q (modes may use either root)."""
    a = np.pi / 2 + 2 * np.pi / 3 * np.arange(3)
    mids = geometry.rail_radius * np.stack([np.cos(a), np.sin(a), np.zeros(3)], 1)
    dirs = np.stack([-np.sin(a), np.cos(a), np.zeros(3)], 1)
    pts = geometry.platform_radius * np.stack([np.cos(a), np.sin(a), np.zeros(3)], 1)
    rot = Rotation.from_euler("ZYX", pose[3:][::-1]).as_matrix()
    out = []
    for i in range(6):
        k = i // 2
        d = pose[:3] + rot @ pts[k] - mids[k]
        along = d @ dirs[k]
        root = np.sqrt(max(geometry.leg_length ** 2 - d @ d + along ** 2, 0.0))
        home = geometry.home_q[i]
        out.append(min((along + root, along - root), key=lambda v: abs(v - home)))
    return np.array(out)


# -- dynamics -------------------------------------------------------------------------------
def test_statics_home_value_and_load_by_virtual_work(robot):
    out = ok_json("statics")
    np.testing.assert_allclose(out["actuator_forces"], HOME_STATIC_FORCE * np.tile([1, -1], 3),
                               atol=1e-3)
    wrench = np.array([1.0, -2.0, -10.0, 0.1, 0.2, -0.3])
    loaded = ok_json("statics", "--wrench", ",".join(map(str, wrench)))
    # virtual work: tau . qdot + wrench . twist = 0 for the extra load -> J^T dtau = -wrench
    jac = fd_jacobian(robot.geometry, robot.home_pose)
    dtau = np.array(loaded["actuator_forces"]) - np.array(out["actuator_forces"])
    np.testing.assert_allclose(jac.T @ dtau, -wrench, atol=1e-5)


def test_id_at_rest_from_poses_only_equals_statics(tmp_path, robot):
    t = np.linspace(0.0, 0.1, 11)
    path = write_csv(tmp_path / "rest.csv", t, np.tile(robot.home_pose, (11, 1)))
    out = ok_json("id", path, "--out", tmp_path / "with_forces.json")
    np.testing.assert_allclose(out["actuator_forces"],
                               np.tile(HOME_STATIC_FORCE * np.tile([1, -1], 3), (11, 1)),
                               atol=1e-3)
    back = motions.read_motion(tmp_path / "with_forces.json")
    np.testing.assert_allclose(back.actuator_forces, out["actuator_forces"])
    np.testing.assert_allclose(back.twists, 0.0, atol=1e-12)


def test_motion_rates_from_poses_match_the_exact_circle(robot):
    exact = motions.circle_motion(robot, radius=0.02, period=1.0, rate=2000.0)
    estimated = motions.Motion(exact.t, exact.poses)
    twists, dots = motions.motion_rates(estimated)
    np.testing.assert_allclose(twists, exact.twists, atol=1e-5)
    np.testing.assert_allclose(dots[5:-5], exact.twist_dots[5:-5], atol=1e-3)
    spin = motions.Motion(exact.t, exact.poses * [1, 1, 1, 0, 0, 0]
                      + np.outer(exact.t, [0, 0, 0, 0.1, 0.2, 0.3]))
    w, _ = motions.motion_rates(spin)
    # w = E(rpy) rpy_dot: compare with the rotation's own rate (scipy, central difference)
    n, h = 500, exact.t[1] - exact.t[0]
    rots = [Rotation.from_euler("ZYX", spin.poses[m, 3:][::-1]) for m in (n - 1, n + 1)]
    omega = (rots[1] * rots[0].inv()).as_rotvec() / (2 * h)
    np.testing.assert_allclose(w[n, 3:], omega, atol=1e-6)


def test_malformed_motion_files_are_one_line_errors(tmp_path):
    missing = tmp_path / "m.csv"
    missing.write_text("t,x,y,z\n0,0,0,0.3\n")
    one_line_error(invoke("id", missing), "missing columns")
    decreasing = write_csv(tmp_path / "d.csv", np.array([0.0, 0.2, 0.1]), np.zeros((3, 6)))
    one_line_error(invoke("id", decreasing), "increasing")
    broken = tmp_path / "b.json"
    broken.write_text('{"t": [0, 1], "pose": [[0, 0, 0.3, 0, 0]]}')
    one_line_error(invoke("view", "--trajectory", broken), "pose", "shape")
    one_line_error(invoke("id", tmp_path / "absent.csv"), "not found")


def test_simulate_writes_files_and_reports(tmp_path):
    paths = {"out": tmp_path / "sim.json", "html": tmp_path / "sim.html",
             "plot": tmp_path / "sim.png"}
    out = ok_json("simulate", "--duration", 0.1, "--controller", "computed-torque",
                  "--radius", 0.01, "--period", 0.5,
                  *[a for k, v in paths.items() for a in (f"--{k}", v)])
    assert out["status"] == "completed" and out["samples"] == 101
    assert out["max_closure_residual_m"] < 1e-9 and out["max_tracking_error_m"] < 1e-3
    motion = motions.read_motion(paths["out"])
    assert motion.q.shape == (101, 6) and motion.actuator_forces.shape == (101, 6)
    assert "set_animation" in {c["type"] for c in decode_commands(paths["html"].read_text())}
    assert paths["plot"].stat().st_size > 10000


def test_simulate_stop_at_a_stroke_limit_is_a_failure_exit():
    result = invoke("simulate", "--controller", "none", "--duration", 0.5, "--json")
    assert result.exit_code == 0       # --json reports, the status says what happened
    assert json.loads(result.stdout)["status"] == "stroke_limit"
    result = invoke("simulate", "--controller", "none", "--duration", 0.5)
    assert result.exit_code == 1 and "stroke_limit" in result.stdout


# -- view, plot, demo ---------------------------------------------------------------------------
def test_view_writes_pose_modes_and_animation_files(tmp_path, robot):
    home = tmp_path / "home.html"
    out = ok_json("view", "-o", home)
    assert out["kind"] == "pose" and count(home) == 25 + 6
    pose = robot.home_pose + np.array([0.0, 0.01, 0.0, 0.0, 0.0, 0.2])
    tilted = tmp_path / "tilted.html"
    ok_json("view", *pose, "-o", tilted)
    platform = [c for c in decode_commands(tilted.read_text())
                if c["type"] == "set_transform" and c["path"].endswith("platform_0")]
    np.testing.assert_allclose(np.array(platform[0]["matrix"]).reshape(4, 4).T[:3, 3],
                               pose[:3], atol=1e-12)
    circle = tmp_path / "circle.html"
    out = ok_json("view", "--circle", 0.02, "--period", 1.0, "-o", circle)
    assert out["kind"] == "trajectory" and count(circle, "set_animation") == 1
    one_line_error(invoke("view", "-o", tmp_path / "x.png"), ".html")
    one_line_error(invoke("view", "0", "0", "0.3", "0", "0", "0", "--circle", "0.01"),
                   "one of")


def test_view_with_forces_draws_arrows(tmp_path):
    path = tmp_path / "f.html"
    ok_json("view", "--forces", "-o", path)
    paths = {c["path"] for c in decode_commands(path.read_text()) if c["type"] == "set_object"}
    assert sum("/overlays/actuator_" in p for p in paths) == 12    # 6 arrows, 2 meshes each
    assert sum("/overlays/closure_" in p for p in paths) == 12


def test_plot_kinds_write_files(tmp_path, robot):
    t = np.linspace(0, 1, 21)
    poses = np.tile(robot.home_pose, (21, 1))
    poses[:, 2] -= 0.02 * t
    extra = {f"q{i}": np.zeros(21) + i for i in range(6)} | {"residual": 1e-12 * (1 + t)}
    motion = write_csv(tmp_path / "m.csv", t, poses, extra)
    for kind, args in (("trajectory", [motion]), ("residual", [motion]),
                       ("conditioning", []), ("workspace", ["--resolution", 9])):
        target = tmp_path / f"{kind}.png"
        out = ok_json("plot", kind, *args, "-o", target)
        assert out["kind"] == kind and target.stat().st_size > 8000, kind
    one_line_error(invoke("plot", "residual", write_csv(tmp_path / "n.csv", t, poses)),
                   "residual")


def test_demo_json_keeps_its_keys_and_writes_html(tmp_path):
    html = tmp_path / "demo.html"
    out = ok_json("demo", "--html", html)
    assert out["mobility"] == 6 and out["closure_residual_max_abs_m"] <= 1e-12
    assert out["html"] == str(html) and count(html) >= 25
    assert out["round_trip"]["error"] < 1e-9
    np.testing.assert_allclose(np.abs(out["statics"]["actuator_forces"]),
                               HOME_STATIC_FORCE, atol=1e-3)
    assert out["simulation"]["status"] == "completed"


def test_progress_bars_show_in_a_terminal_and_quiet_silences_them(tmp_path, monkeypatch):
    terminal = functools.partial(Console, force_terminal=True, width=100)
    monkeypatch.setattr(common, "Console", terminal)
    t = np.linspace(0.0, 0.05, 6)
    path = write_csv(tmp_path / "rest.csv", t, np.tile(hp.HexapodGeometry().home_pose, (6, 1)))
    noisy = invoke("id", path)
    assert noisy.exit_code == 0 and "inverse dynamics" in noisy.stderr
    quiet = invoke("id", path, "--quiet")
    assert quiet.exit_code == 0 and quiet.stderr == ""
    loud = invoke("view", "-o", tmp_path / "v.html")
    assert "wrote" in loud.stderr
    assert invoke("view", "-o", tmp_path / "v.html", "-q").stderr == ""


# -- the first hour of a new user: messages, errors, version, export -----------------------
NO_ASSEMBLY_Q = [-0.3, 0.3, 0.25, 0.3, -0.3, -0.25]   # within the strokes, no assembly mode


def test_brackets_in_messages_survive(monkeypatch, tmp_path):
    line = one_line_error(invoke("statics", 0, 0, 0, 0, 0, 0), "singular")
    assert "[e_i, (r_k x e_i) / platform_radius]" in line

    def no_matplotlib(*args, **kwargs):
        raise hp.errors.MissingDependencyError("matplotlib", "plot")

    monkeypatch.setattr(workspace_plots, "figure_class", no_matplotlib)
    line = one_line_error(invoke("plot", "conditioning", "-o", tmp_path / "c.png"),
                          "matplotlib")
    assert 'pip install "hexapod-pin[plot]"' in line


def test_json_errors_are_json_on_stdout():
    for args, kind in ((("ik", 0, 0, 9, 0, 0, 0), "UnreachablePoseError"),
                       (("simulate", "--duration", "abc"), "BadParameter"),
                       (("fk", *NO_ASSEMBLY_Q), "AssemblyError")):
        result = invoke(*args, "--json")
        assert result.exit_code == 1 and result.stderr == "", result.output
        error = json.loads(result.stdout)["error"]
        assert error["type"] == kind and "Traceback" not in result.output
        assert error["message"]


BAD_VALUES = [
    ("simulate", "--duration", "abc"), ("simulate", "--dt", "x"), ("simulate", "--dt", "-1"),
    ("simulate", "--period", "0"), ("simulate", "--radius", "-1"),
    ("simulate", "--controller", "lqr"), ("simulate", "--engine", "gpu"),
    ("simulate", "--engine", "fast", "--controller", "computed-torque"),
    ("view", "--fps", "fast"), ("view", "--circle", "nan"), ("view", "--layout", "x", "--modes"),
    ("plot", "workspace", "--resolution", "1.5"), ("plot", "workspace", "--z", "5"),
    ("modes", "--layout", "x", "--html", "m.html"), ("ik", "a", "b", "c", "d", "e", "f"),
    ("fk", *NO_ASSEMBLY_Q), ("modes", *NO_ASSEMBLY_Q), ("view", "--modes", *NO_ASSEMBLY_Q),
    ("urdf", "--robot", "delta"), ("urdf", "-o", "x.txt"), ("demo", "--set", "leg_length=x"),
    ("simulate", "--duration", "1e9"), ("simulate", "--dt", "1e-12"),
    ("view", "--circle", "0.02", "--fps", "0"), ("view", "--circle", "0.02", "--period", "0"),
]


@pytest.mark.parametrize("args", BAD_VALUES, ids=lambda a: " ".join(map(str, a)))
def test_no_traceback_for_any_bad_value(args, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    one_line_error(invoke(*args))


@pytest.mark.parametrize("args", [("plot", "workspace", "--rpy", "1,2"), ("jacobian", 0, 0, 0),
                                  ("statics", "--wrench", "1,2")],
                         ids=lambda a: " ".join(map(str, a)))
def test_a_wrong_number_of_values_is_one_line_and_exit_code_2(args):
    cli_error(invoke(*args), 2, "expected")


def test_errors_name_the_bad_argument():
    one_line_error(invoke("simulate", "--period", 0), "invalid period")
    one_line_error(invoke("view", "--circle", 0.02, "--period", 0), "invalid period")
    one_line_error(invoke("simulate", "--duration", "1e9"), "invalid duration", "steps")


def test_usage_errors_are_one_line_with_exit_code_2():
    result = invoke("simulate", "--no-such-option")
    assert result.exit_code == 2 and "Traceback" not in result.output
    lines = result.stderr.strip().splitlines()
    assert len(lines) == 1 and lines[0].startswith("error:") and "--no-such-option" in lines[0]
    assert "hexapod-pin simulate --help" in lines[0] or "simulate --help" in lines[0]


def test_version_and_help_without_type_noise():
    result = invoke("--version")
    assert result.exit_code == 0 and result.stdout.strip() == f"hexapod-pin {hp.__version__}"
    for command in ("view", "simulate", "demo"):
        text = invoke(command, "--help").stdout
        assert "--geometry" in text and "--set" in text and "<bool>" not in text, command


def test_piped_output_is_not_wrapped_at_80_columns():
    out = ok_json("jacobian")        # JSON: each measure once too
    assert "condition_number" not in out["singularity"]
    assert "jacobian_singular_values" not in out["singularity"]
    assert set(out["singularity"]) >= {"type_one", "type_two", "type_one_actuator"}
    text = invoke("jacobian").stdout
    assert max(len(line) for line in text.splitlines()) > 80
    # each measure on one line with its meaning; the singular values of J printed once
    assert any("type II: sigma_min(A_hat)" in line and "platform moves" in line
               for line in text.splitlines())
    assert text.count("singular values of J") == 1
    assert "[e_i, (r_i x e_i) / length]" in text


def test_commands_agree_when_no_configuration_exists(tmp_path, robot):
    for command in (("fk",), ("modes",), ("view", "--modes", "-o", tmp_path / "m.html")):
        one_line_error(invoke(*command, *NO_ASSEMBLY_Q), "assembly")
    assert not (tmp_path / "m.html").exists()
    # fk refuses carriage positions beyond the strokes, as ik refuses their pose
    pose = robot.home_pose + np.array([0.0, 0.0, -0.15, 0.0, 0.0, 0.0])
    one_line_error(invoke("ik", *pose), "stroke")
    q = ok_json("ik", *pose, "--no-limits")["q"]
    one_line_error(invoke("fk", *q), "stroke")
    np.testing.assert_allclose(ok_json("fk", *q, "--no-limits")["pose"], pose, atol=1e-9)
    one_line_error(invoke("plot", "workspace", "--z", 5, "-o", tmp_path / "w.png"),
                   "no platform position", "reachable")
    assert not (tmp_path / "w.png").exists()


def test_motion_file_errors_point_at_the_right_row(tmp_path, robot):
    t = np.linspace(0.0, 0.4, 5)
    poses = np.tile(robot.home_pose, (5, 1))
    poses[1, 2] = 1.0                                       # unreachable at row 1
    path = write_csv(tmp_path / "far.csv", t, poses)
    one_line_error(invoke("id", path), "row 1 ", "unreachable")
    one_line_error(invoke("plot", "trajectory", path, "-o", tmp_path / "t.png"), "row 1 ")
    ok = write_csv(tmp_path / "ok.csv", t, np.tile(robot.home_pose, (5, 1)))
    line = one_line_error(invoke("id", ok, "--method", "foo"), "method", "kkt")
    assert "row" not in line


def test_simulate_fast_by_default_and_tracking_loss_is_a_failure():
    out = ok_json("simulate", "--duration", 0.2, "--radius", 0.01, "--period", 0.5)
    assert out["engine"] == "fast" and out["status"] == "completed"
    assert out["max_tracking_error_m"] < 1e-3 and out["samples"] == 801
    slow = ok_json("simulate", "--duration", 0.05, "--engine", "python")
    assert slow["engine"] == "python" and slow["status"] == "completed"
    lost = invoke("simulate", "--duration", 1, "--dt", 0.01, "--radius", 0.005)
    assert lost.exit_code == 1 and "tracking_lost" in lost.stdout
    assert "completed" not in lost.stdout
    summary = ok_json("simulate", "--duration", 1, "--dt", 0.01, "--radius", 0.005)
    assert summary["status"] == "tracking_lost"
    assert summary["max_tracking_error_m"] > summary["tracking_tolerance_m"] == 0.005


def test_urdf_export_of_both_robots(tmp_path):
    import pinocchio as pin

    path = tmp_path / "hexapod.urdf"
    out = ok_json("urdf", "--set", "leg_length=0.5", "-o", path)
    assert out["out"] == str(path)
    robot = hp.Hexapod(hp.HexapodGeometry(leg_length=0.5))
    assert path.read_text() == robot.urdf() == robot.model.urdf_xml
    tree = pin.buildModelFromXML(path.read_text())
    # independent of the library: the leg tip sits leg_length along the leg's z axis
    tip = tree.frames[tree.getFrameId("leg_0_tip")].placement.translation
    np.testing.assert_allclose(np.abs(tip), [0.0, 0.0, 0.5], atol=1e-12)
    planar = tmp_path / "planar.urdf"
    ok_json("urdf", "--robot", "planar", "-o", planar)
    assert planar.read_text() == hp.Planar3PRR.default().urdf()
    assert invoke("urdf").stdout.lstrip().startswith("<?xml")


def test_demo_takes_the_common_geometry_options():
    out = ok_json("demo", "--set", "leg_length=0.5", "--no-html")
    expected = hp.HexapodGeometry(leg_length=0.5).home_pose
    np.testing.assert_allclose(out["home_pose"], expected, atol=1e-12)
