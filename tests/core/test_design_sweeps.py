"""``hexapod_pin.core.sweeps``: design sweeps of any robot, against references written here.

* the planar 3-PRR (``GeometryFactory``) over its link length: the reachable share of a box
  of positions against the chains' closed form on a fine grid (``|P_k - c_k| = L`` with
  the slider on its rail within the stroke), its payload against virtual power with a
  Jacobian written here;
* the Stewart platform loaded from a URDF written per design (its stroke): the reachable
  share of a box of heights against the leg-length closed form, its payload at home
  against the symmetric leg forces;
* the wrench of gravity in each robot's selection, the four-bar's missing payload;
* bad input raises typed errors naming the value; designs that cannot be built are rows.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pandas as pd
import pytest

import hexapod_pin as hp
import robot_registry
from hexapod_pin.core import sweeps
from hexapod_pin.errors import ArgumentTypeError, InputError

DATA = Path(__file__).resolve().parents[1] / "data"
# the Stewart platform (tests/data/stewart/README.md): base and platform points, legs
ALPHA = np.radians([-15, 15, 105, 135, 225, 255])
BETA = np.radians([-45, 45, 75, 165, 195, 285])
BASE = 0.5 * np.stack([np.cos(ALPHA), np.sin(ALPHA)], 1)
PLATFORM = 0.3 * np.stack([np.cos(BETA), np.sin(BETA)], 1)
LEG_OFFSET, HOME_Z, G = 0.65, 0.6, 9.81


def within(estimate: float, expected: float, n: int, slack: float = 0.0) -> bool:
    """A sampled fraction within four binomial standard errors (plus ``slack``)."""
    sigma = np.sqrt(max(expected * (1 - expected), 1e-4) / n)
    return abs(estimate - expected) <= 4 * sigma + slack


# -- the planar 3-PRR ---------------------------------------------------------------------
def planar_chains(g: hp.PlanarGeometry, yaw: float = 0.0):
    """Rail midpoints, directions and rotated platform points (planar/geometry.py)."""
    a = np.pi / 2 + 2 * np.pi / 3 * np.arange(3)
    mids = g.rail_radius * np.stack([np.cos(a), np.sin(a)], 1)
    dirs = np.stack([-np.sin(a), np.cos(a)], 1)
    pts = g.platform_radius * np.stack([np.cos(a + yaw), np.sin(a + yaw)], 1)
    return mids, dirs, pts


def planar_reachable_share(g: hp.PlanarGeometry, half: float, n: int = 201) -> float:
    """Share of the square ``|x|, |y| <= half`` (yaw 0) where every link reaches its rail
    with its slider (larger root) within the stroke, on an n x n grid."""
    mids, dirs, pts = planar_chains(g)
    xs = np.linspace(-half, half, n)
    grid = np.stack(np.meshgrid(xs, xs), -1)
    ok = np.ones(grid.shape[:2], dtype=bool)
    for k in range(3):
        d = grid + pts[k] - mids[k]
        along = d @ dirs[k]
        disc = g.link_length ** 2 - (np.einsum("...i,...i", d, d) - along ** 2)
        slider = along + np.sqrt(np.maximum(disc, 0.0))
        ok &= (disc >= 0) & (np.abs(slider) <= g.rail_half_length)
    return float(ok.mean())


def test_planar_sweep_reachable_share_is_the_closed_form():
    base = hp.PlanarGeometry()
    designs = sweeps.design_grid({"link_length": [0.2, 0.26, 0.3, 0.34]}, hp.PlanarGeometry)
    settings = sweeps.SweepSettings(n_samples=3000, payload_samples=5,
                                    half_extent={"x": 0.1, "y": 0.1})
    seen = []
    table = sweeps.design_sweep(sweeps.GeometryFactory(hp.Planar3PRR, base), designs,
                                settings, progress=lambda d, t: seen.append((d, t)))
    assert seen == [(1, 4), (2, 4), (3, 4), (4, 4)]
    assert list(table.columns) == ["link_length", *sweeps.SUMMARY_COLUMNS]
    # 0.2 < rail_radius - platform_radius: no home, a row that says why
    assert list(table["valid"]) == [False, True, True, True]
    assert "link_length" in table["error"][0] and pd.isna(table["reachable_volume"][0])
    box = 0.2 * 0.2                                           # m^2: x and y sampled
    for i, length in enumerate([0.26, 0.3, 0.34], start=1):
        expected = planar_reachable_share(base.replace(link_length=length), 0.1)
        share = table["reachable_volume"][i] / box
        assert within(share, expected, 3000, slack=0.005), (length, share, expected)
        assert table["well_conditioned_volume"][i] <= table["reachable_volume"][i]
    assert 0.1 < table["reachable_volume"][1] / box < table["reachable_volume"][2] / box
    # no force bound on the default planar robot: any payload is held
    assert table["median_payload_kg"][2] == np.inf


def test_planar_payload_is_virtual_power_with_an_own_jacobian():
    g = hp.PlanarGeometry(max_actuator_force=40.0)
    pose = np.array([0.02, -0.03, 0.1])
    mids, dirs, pts = planar_chains(g, pose[2])
    rows = []
    for k in range(3):                   # ds_k = n_k . (v + w z x r_k) / (n_k . u_k)
        tip = pose[:2] + pts[k]
        d = tip - mids[k]
        along = d @ dirs[k]
        slider = along + np.sqrt(g.link_length ** 2 - d @ d + along ** 2)
        n = tip - (mids[k] + slider * dirs[k])
        rows.append(np.r_[n, n @ [-pts[k, 1], pts[k, 0]]] / (n @ dirs[k]))
    per_kg = -np.linalg.solve(np.array(rows).T, [0.0, -G, 0.0])   # J^T tau = -w
    robot = hp.Planar3PRR(g)
    rest = robot.static_forces(pose)
    bound = np.where(per_kg > 0, (40.0 - rest) / per_kg, (-40.0 - rest) / per_kg).min()
    settings = sweeps.SweepSettings(n_samples=8, payload_samples=8, half_extent={"x": 1e-9},
                                    center=dict(zip(("x", "y", "yaw"), pose)))
    row = sweeps.evaluate_design(sweeps.GeometryFactory(hp.Planar3PRR, g), {}, settings)
    assert row["valid"] and row["error"] == ""
    assert row["median_payload_kg"] == pytest.approx(bound, rel=1e-6)
    assert row["min_payload_kg"] == pytest.approx(bound, rel=1e-6)
    assert row["reachable_volume"] == pytest.approx(2e-9)      # the box, all of it reached


# -- a robot loaded from a description written per design ----------------------------------
def stewart_factory(folder: Path):
    """Load the Stewart platform with the stroke ``+-params["stroke"]`` (m), its URDF
    written into ``folder`` (a sweep over a loaded robot's description)."""
    source = (DATA / "stewart" / "stewart.urdf").read_text(encoding="utf-8")
    assert source.count('lower="-0.15" upper="0.15"') == 6

    def make(params: dict) -> hp.ClosedLoopRobot:
        s = params["stroke"]
        here = folder / f"stroke_{s:+.3f}"
        here.mkdir(exist_ok=True)
        (here / "stewart.urdf").write_text(
            source.replace('lower="-0.15" upper="0.15"', f'lower="{-s!r}" upper="{s!r}"'),
            encoding="utf-8")
        shutil.copy(DATA / "stewart" / "stewart.loops.yaml", here)
        return hp.load_robot(here / "stewart.urdf")

    return make


def test_stewart_sweep_over_its_stroke_is_the_leg_length_closed_form(tmp_path):
    offset2 = np.sum((PLATFORM - BASE) ** 2, axis=1)     # |b_i - a_i|^2, level platform
    np.testing.assert_allclose(offset2, offset2[0], rtol=1e-12)
    half, n = 0.25, 600
    settings = sweeps.SweepSettings(n_samples=n, payload_samples=4, half_extent={"z": half})
    table = sweeps.design_sweep(stewart_factory(tmp_path),
                                sweeps.design_grid({"stroke": [-0.1, 0.05, 0.15]}), settings)
    assert list(table["valid"]) == [False, True, True]
    assert "lower <= upper" in table["error"][0]               # the description refused
    for i, s in ((1, 0.05), (2, 0.15)):
        # x = y = 0, level: every leg sqrt(z^2 + |b - a|^2) in [0.65 - s, 0.65 + s]
        low = np.sqrt((LEG_OFFSET - s) ** 2 - offset2[0])
        high = np.sqrt((LEG_OFFSET + s) ** 2 - offset2[0])
        expected = (min(high, HOME_Z + half) - max(low, HOME_Z - half)) / (2 * half)
        share = table["reachable_volume"][i] / (2 * half)     # m: z sampled alone
        assert within(share, expected, n), (s, share, expected)


def test_stewart_payload_at_home_is_the_symmetric_leg_force(tmp_path):
    make = stewart_factory(tmp_path)
    robot = make({"stroke": 0.15})
    leg = np.sqrt(HOME_Z ** 2 + np.sum((PLATFORM[0] - BASE[0]) ** 2))
    per_kg = G * leg / (6 * HOME_Z)           # six equal legs carry 1 kg: 6 tau dz/dl = g
    rest = robot.static_forces(robot.home_pose)
    np.testing.assert_allclose(rest, rest[0], rtol=1e-9)      # the symmetric pose
    bound = (2000.0 - rest[0]) / per_kg                        # effort limit 2000 N
    settings = sweeps.SweepSettings(n_samples=4, payload_samples=4, half_extent={"z": 1e-9})
    row = sweeps.evaluate_design(make, {"stroke": 0.15}, settings)
    assert row["median_payload_kg"] == pytest.approx(bound, rel=1e-6)


# -- gravity in each robot's wrench selection ----------------------------------------------
@pytest.mark.parametrize("name, expected", [
    ("hexapod", [0, 0, -G, 0, 0, 0]), ("planar", [0, -G, 0]), ("stewart", [0, 0, -G, 0, 0, 0]),
    ("five-bar", [0, -G]), ("delta", [0, 0, -G]), ("four-bar", None)])
def test_gravity_wrench_is_the_weight_in_the_pose_axes(name, expected):
    wrench = sweeps.gravity_wrench(robot_registry.get(name), mass=2.0)
    if expected is None:                # the four-bar's pose is x alone, gravity along -z
        assert wrench is None
    else:
        np.testing.assert_allclose(wrench, 2.0 * np.array(expected), atol=1e-12)


def test_a_pose_without_gravity_has_no_payload_column():
    robot = robot_registry.get("four-bar")
    settings = sweeps.SweepSettings(n_samples=6, payload_samples=6, half_extent={"x": 1e-4})
    row = sweeps.evaluate_design(lambda params: robot, {}, settings)
    assert row["valid"] and row["reachable_volume"] == pytest.approx(2e-4)
    assert row["median_payload_kg"] is None and row["min_payload_kg"] is None
    assert row["median_condition"] > 0


# -- input checks ---------------------------------------------------------------------------
def test_settings_refuse_bad_values_by_name():
    for kwargs, word in ((dict(half_extent={"q": 0.1}), "'q'"),
                         (dict(half_extent={"x": 0.0}), "half_extent['x']"),
                         (dict(half_extent={}), "names no pose axis"),
                         (dict(half_extent=[0.1]), "mapping"),
                         (dict(center={"yaw": np.nan}), "center['yaw']"),
                         (dict(n_samples=0), "n_samples"), (dict(n_samples=2.5), "n_samples"),
                         (dict(payload_samples=-1), "payload_samples"),
                         (dict(max_condition=1.0), "max_condition"), (dict(seed=-1), "seed")):
        with pytest.raises(InputError, match=word.replace("[", r"\[")):
            sweeps.SweepSettings(**kwargs)


def test_a_box_axis_the_robot_has_not_is_an_error():
    make = sweeps.GeometryFactory(hp.Planar3PRR, hp.PlanarGeometry())
    for settings, word in ((sweeps.SweepSettings(n_samples=5, half_extent={"z": 0.1}), "'z'"),
                           (sweeps.SweepSettings(n_samples=5, center={"roll": 0.1}),
                            "'roll'")):
        with pytest.raises(InputError, match=word) as info:
            sweeps.evaluate_design(make, {}, settings)
        assert "('x', 'y', 'yaw')" in str(info.value)


def test_grids_factories_and_designs_refuse_bad_input():
    grid = sweeps.design_grid({"rail_radius": [0.35, 0.4], "link_length": np.array([0.3])})
    assert grid == [{"rail_radius": 0.35, "link_length": 0.3},
                    {"rail_radius": 0.4, "link_length": 0.3}]
    with pytest.raises(InputError, match="not a PlanarGeometry field"):
        sweeps.design_grid({"leg_length": [0.3]}, hp.PlanarGeometry)
    with pytest.raises(InputError, match="list of values"):
        sweeps.design_grid({"link_length": 0.3})
    with pytest.raises(InputError, match="at least one value"):
        sweeps.design_grid({"link_length": []})
    with pytest.raises(ArgumentTypeError, match="dataclass"):
        sweeps.design_grid({"link_length": [0.3]}, dict)
    make = sweeps.GeometryFactory(hp.Planar3PRR, hp.PlanarGeometry())
    small = sweeps.SweepSettings(n_samples=5, payload_samples=0)
    # a misspelt field raises (a sweep of typos is not a table of invalid designs)
    with pytest.raises(ArgumentTypeError, match="link_lenght"):
        sweeps.design_sweep(make, [{"link_lenght": 0.3}], small)
    with pytest.raises(ArgumentTypeError, match="parallel robot"):
        sweeps.evaluate_design(lambda params: "robot", {}, small)
    with pytest.raises(ArgumentTypeError, match="make_robot"):
        sweeps.design_sweep("planar", [{}], small)
    with pytest.raises(ArgumentTypeError, match="SweepSettings"):
        sweeps.design_sweep(make, [{}], {"n_samples": 5})
    with pytest.raises(InputError, match="at least one design"):
        sweeps.design_sweep(make, [], small)
    with pytest.raises(InputError, match="'valid'"):
        sweeps.design_sweep(make, [{"valid": 1.0}], small)
    with pytest.raises(InputError, match="summary column"):
        sweeps.Sweep(make, small, {"error": len})
    with pytest.raises(ArgumentTypeError, match="base"):
        sweeps.GeometryFactory(hp.Planar3PRR, hp.PlanarGeometry)


def test_extra_columns_are_read_from_each_robot():
    make = sweeps.GeometryFactory(hp.Planar3PRR, hp.PlanarGeometry())
    table = sweeps.design_sweep(
        make, sweeps.design_grid({"link_length": [0.28, 0.32]}),
        sweeps.SweepSettings(n_samples=20, payload_samples=0),
        columns={"home_slider": lambda robot: robot.geometry.home_slider})
    assert list(table.columns)[:4] == ["link_length", "valid", "error", "home_slider"]
    expected = [np.sqrt(length ** 2 - (0.35 - 0.12) ** 2) for length in (0.28, 0.32)]
    np.testing.assert_allclose(table["home_slider"].to_numpy(dtype=float), expected)
    assert table["median_payload_kg"].isna().all()             # payload_samples=0
