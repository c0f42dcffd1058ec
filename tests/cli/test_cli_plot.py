"""``hexapod-pin plot KIND --robot PATH``: the figures of any closed-loop robot, on the
Gough-Stewart platform (``tests/data/stewart``), a five-bar and a four-bar, checked against
the Stewart platform's closed forms (leg lengths ``|p + R b_i - a_i|`` within the stroke,
the Jacobian of unit leg vectors), and the data the figures draw against the files given."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest

import hexapod_pin as hp
from hexapod_pin.viz import plotting
from hexapod_pin.viz import workspace_plots as wpl
from test_cli_any_robot import BASE, LEG_OFFSET, PLATFORM, invoke, one_line_error, stewart_ik

DATA = Path(__file__).resolve().parents[1] / "data"
STEWART = ["--robot", str(DATA / "stewart" / "stewart.urdf")]
FOUR_BAR = ["--robot", str(DATA / "four_bar" / "four_bar.urdf")]
FIVE_BAR = ["--robot", str(DATA / "parallel" / "five_bar_3d"), "--platform", "end_1",
            "--pose-axes", "x,z"]
#: the Stewart platform's stroke (tests/data/stewart/README.md), |q_i| <= 0.15 m
STROKE = 0.15


def ok_json(*args: object) -> dict:
    result = invoke(*args, "--json")
    assert result.exit_code == 0, result.output
    assert result.stderr == ""
    return json.loads(result.stdout)


def is_png(path: Path) -> bool:
    return path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and path.stat().st_size > 8000


def level_legs(xyz: np.ndarray) -> np.ndarray:
    """Leg vectors (..., 6, 3) of a level platform at positions (..., 3)."""
    return xyz[..., None, :] + PLATFORM - BASE


@pytest.fixture(scope="module")
def stewart() -> hp.ClosedLoopRobot:
    return hp.load_robot(DATA / "stewart" / "stewart.urdf")


@pytest.fixture
def figures(monkeypatch) -> list:
    """The figures the command draws (the library's return values, kept; the command
    imports these modules on first use, so they are patched in place)."""
    drawn: list = []
    for name in ("plot_trajectory", "plot_closure_residual"):
        original = getattr(plotting, name)
        monkeypatch.setattr(plotting, name,
                            lambda *a, _f=original, **k: drawn.append(_f(*a, **k)) or drawn[-1])
    for name in ("plot_conditioning", "plot_workspace_slice"):
        original = getattr(wpl, name)
        monkeypatch.setattr(wpl, name,
                            lambda *a, _f=original, **k: drawn.append(_f(*a, **k)) or drawn[-1])
    return drawn


def write_motion(path: Path, t: np.ndarray, poses: np.ndarray, extra: dict | None = None) -> Path:
    names = ["t", "x", "y", "z", "roll", "pitch", "yaw", *(extra or {})]
    cols = [t[:, None], poses, *(np.asarray(v)[:, None] for v in (extra or {}).values())]
    np.savetxt(path, np.hstack(cols), delimiter=",", header=",".join(names), comments="")
    return path


# -- workspace ------------------------------------------------------------------------------
def test_workspace_slice_of_the_stewart_platform_is_its_stroke(tmp_path, figures):
    out = ok_json("plot", "workspace", *STEWART, "--half-width", 0.25, "--resolution", 11,
                  "-o", tmp_path / "w.png")
    assert out["axes"] == ["x", "y"] and out["pose_axes"][0] == "x"
    assert out["actuators"][0] == "leg_0_prismatic" and is_png(tmp_path / "w.png")
    # the grid: x, y = +-0.25 m around home (0, 0), level at z = 0.6
    xs = np.linspace(-0.25, 0.25, 11)
    gx, gy = np.meshgrid(xs, xs)
    legs = np.linalg.norm(level_legs(np.stack([gx, gy, np.full_like(gx, 0.6)], -1)), axis=-1)
    inside = np.all(np.abs(legs - LEG_OFFSET) <= STROKE, axis=-1)
    assert 0.1 < inside.mean() < 0.9
    assert out["reachable_fraction"] == pytest.approx(inside.mean())
    # the image: cond(J) where the legs are within the stroke, nothing elsewhere
    shown = np.ma.filled(figures[-1].axes[0].images[1].get_array(), np.nan)
    np.testing.assert_array_equal(np.isfinite(shown), inside)
    ax = figures[-1].axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x (m)", "y (m)")
    assert "z = 0.600 m" in ax.get_title()


def test_workspace_slice_over_chosen_axes_through_a_chosen_pose(tmp_path, stewart):
    at = "0.02,0,0.6,0,0,10"                      # yaw 10 deg
    out = ok_json("plot", "workspace", *STEWART, "--axes", "x,z", "--at", at, "--degrees",
                  "--half-width", "0.1,0.2", "--resolution", 9, "-o", tmp_path / "w.svg")
    assert out["axes"] == ["x", "z"]
    ws = wpl.workspace_slice(stewart, axes=("x", "z"), half_width=[0.1, 0.2], resolution=9,
                             center=[0.02, 0, 0.6, 0, 0, np.radians(10)])
    np.testing.assert_allclose(ws.x, 0.02 + np.linspace(-0.1, 0.1, 9), atol=1e-15)
    np.testing.assert_allclose(ws.y, 0.6 + np.linspace(-0.2, 0.2, 9), atol=1e-15)
    for iz, zv in enumerate(ws.y):
        for ix, xv in enumerate(ws.x):
            ok = np.all(np.abs(stewart_ik(np.array([xv, 0, zv, 0, 0, np.radians(10)])))
                        <= STROKE)
            assert (ws.status[iz, ix] == wpl.REACHABLE) == ok, (xv, zv)
    assert out["reachable_fraction"] == pytest.approx(ws.reachable_fraction)


def test_workspace_of_a_planar_mechanism_takes_its_two_position_axes(tmp_path, figures):
    out = ok_json("plot", "workspace", *FIVE_BAR, "--half-width", 0.45, "--at", "0,0",
                  "--resolution", 13, "-o", tmp_path / "f.png")
    assert out["axes"] == ["x", "z"] and out["pose_axes"] == ["x", "z"]
    ax = figures[-1].axes[0]
    assert (ax.get_xlabel(), ax.get_ylabel()) == ("x (m)", "z (m)")
    assert 0.0 < out["reachable_fraction"] < 1.0


def test_the_default_figure_is_named_after_the_robot(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    out = ok_json("plot", "workspace", *STEWART, "--half-width", 0.1, "--resolution", 5)
    assert out["figure"] == "stewart.png" and is_png(tmp_path / "stewart.png")


# -- conditioning ---------------------------------------------------------------------------
def test_conditioning_sweep_is_the_closed_form_jacobian(tmp_path, figures, stewart):
    ok_json("plot", "conditioning", *STEWART, "--axes", "z", "--half-width", 0.1,
            "-o", tmp_path / "c.png")
    line = figures[-1].axes[0].lines[0]
    zs, cond = line.get_xdata(), line.get_ydata()
    np.testing.assert_allclose(zs, 0.6 + np.linspace(-0.1, 0.1, 200), atol=1e-15)
    for k in (0, 77, 199):                          # q_dot_i = e_i . (v + w x R b_i)
        legs = level_legs(np.array([0.0, 0.0, zs[k]]))
        e = legs / np.linalg.norm(legs, axis=1)[:, None]
        jac = np.hstack([e, np.cross(PLATFORM, e)])
        sv = np.linalg.svd(jac, compute_uv=False)
        assert cond[k] == pytest.approx(sv[0] / sv[-1], rel=1e-8)
    assert figures[-1].axes[1].get_xlabel() == "z (m)"


def test_conditioning_along_a_motion_file_and_of_a_one_axis_robot(tmp_path, figures, stewart):
    t = np.linspace(0.0, 1.0, 11)
    poses = np.tile(stewart.home_pose, (11, 1))
    poses[:, 0] = 0.05 * t
    path = write_motion(tmp_path / "m.csv", t, poses)
    ok_json("plot", "conditioning", path, *STEWART, "-o", tmp_path / "c.png")
    np.testing.assert_allclose(figures[-1].axes[0].lines[0].get_xdata(), t)
    one_line_error(invoke("plot", "conditioning", path, *STEWART, "--axes", "z", "-o",
                          tmp_path / "c.png"), 2, "the poses are the file's")
    # the four-bar: a pose of x alone, its sweep along x
    ok_json("plot", "conditioning", *FOUR_BAR, "-o", tmp_path / "fb.png")
    assert figures[-1].axes[1].get_xlabel() == "x (m)" and is_png(tmp_path / "fb.png")


# -- along a motion -------------------------------------------------------------------------
def test_trajectory_of_a_loaded_robot_names_its_actuators(tmp_path, figures):
    t = np.linspace(0.0, 0.4, 9)
    poses = np.tile([0.0, 0.0, 0.6, 0.0, 0.0, 0.0], (9, 1))
    poses[:, 2] += 0.05 * t
    poses[:, 5] = 0.2 * t
    path = write_motion(tmp_path / "m.csv", t, poses, {"residual": 1e-13 * (1 + t)})
    out = ok_json("plot", "trajectory", path, *STEWART, "--forces", "-o", tmp_path / "t.png")
    assert out["kind"] == "trajectory" and is_png(tmp_path / "t.png")
    fig = figures[-1]
    assert [ax.get_ylabel() for ax in fig.axes] == ["actuator position q (m)",
                                                   "actuator force tau (N)"]
    lines = fig.axes[0].lines
    assert [ln.get_label() for ln in lines] == [f"leg_{i}_prismatic" for i in range(6)]
    for n in (0, 8):                                 # q_i = |p + R b_i - a_i| - 0.65
        np.testing.assert_allclose([ln.get_ydata()[n] for ln in lines], stewart_ik(poses[n]),
                                   atol=1e-10)
    ok_json("plot", "residual", path, *STEWART, "-o", tmp_path / "r.png")
    np.testing.assert_allclose(figures[-1].axes[0].lines[0].get_ydata(), 1e-13 * (1 + t))


def test_trajectory_units_follow_the_joints(tmp_path, figures):
    t = np.linspace(0.0, 0.2, 5)
    x = 0.12086005 + 0.002 * t
    path = tmp_path / "fb.csv"
    np.savetxt(path, np.c_[t, x], delimiter=",", header="t,x", comments="")
    ok_json("plot", "trajectory", path, *FOUR_BAR, "-o", tmp_path / "fb.png")
    ax = figures[-1].axes[0]
    assert ax.get_ylabel() == "actuator position q (rad)"
    assert [ln.get_label() for ln in ax.lines] == ["crank"]
    # a hexapod motion file is not the four-bar's: the columns expected are named
    hexapod_file = write_motion(tmp_path / "h.csv", t, np.tile(np.eye(6)[2], (5, 1)))
    one_line_error(invoke("plot", "trajectory", hexapod_file, *FOUR_BAR, "-o",
                          tmp_path / "x.png"), 1, "expected columns t, x")


# -- errors and help ------------------------------------------------------------------------
@pytest.mark.parametrize("args, words", [
    (("workspace", *FOUR_BAR), ("two pose axes", "one (x)")),
    (("workspace", *STEWART, "--axes", "x,q"), ("axes", "x,q")),
    (("workspace", *STEWART, "--axes", "x,x"), ("two distinct",)),
    (("workspace", *FIVE_BAR, "--rpy", "0,0,0.1"), ("yaw is not a pose axis",)),
    (("workspace", *FIVE_BAR, "--z", "9", "--half-width", "0.01", "--resolution", "3"),
     ("no platform position",)),
    (("workspace", *STEWART, "--half-width", "0,1"), ("half-width", "> 0")),
    (("workspace", *STEWART, "--at", "0,0,0.6"), ("at", "6 values")),
    (("conditioning", *STEWART, "--axes", "q"), ("axis swept",)),
])
def test_bad_plot_options_are_one_line_errors(args, words, tmp_path):
    code = 2 if "6 values" in words else 1            # a wrong number of values: usage
    one_line_error(invoke("plot", *args, "-o", tmp_path / "x.png"), code, *words)
    assert not (tmp_path / "x.png").exists()


def test_robot_options_need_a_robot_and_the_help_shows_them():
    one_line_error(invoke("plot", "workspace", "--platform", "tip"), 2, "--robot")
    text = invoke("plot", "--help").stdout
    for option in ("--robot", "--platform", "--pose-axes", "--axes", "--at", "--half-width"):
        assert option in text, option
