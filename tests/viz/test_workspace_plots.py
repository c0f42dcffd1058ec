"""Workspace figures and the workspace point cloud, looked at as a person would."""

import numpy as np
import pytest
from test_scenes import needs_chromium, render

from hexapod_pin.errors import InputError, MissingDependencyError
from hexapod_pin.hexapod import sweeps
from hexapod_pin.hexapod import workspace as ws
from hexapod_pin.viz import scenes as viz
from hexapod_pin.viz import workspace_plots


def test_colormap_orders_low_to_high():
    colors = viz.colormap([0.0, 0.5, 1.0, np.inf])
    assert colors.shape == (4, 3)
    np.testing.assert_allclose(colors[0], viz.COLORMAP[0])
    np.testing.assert_allclose(colors[2], viz.COLORMAP[-1])
    np.testing.assert_allclose(colors[3], viz.COLORMAP[-1])
    # brightness (sum of RGB) increases along viridis
    assert colors[0].sum() < colors[1].sum() < colors[2].sum()


def test_workspace_cloud_holds_every_point_with_its_colour(robot):
    poses = ws.constant_orientation_grid(robot.home_pose[:3], [0.08, 0.08, 0.06], 9)
    m = ws.evaluate(robot, poses, singularity=False, statics=False)
    pts, cond = poses[m.ok, :3], np.log10(m.condition_number[m.ok])
    scene = viz.workspace_scene(robot, pts, cond)
    cloud = [c for c in scene.commands if c["type"] == "set_object" and c["path"].endswith("/workspace")]
    assert len(cloud) == 1
    attrs = cloud[0]["object"]["geometries"][0]["data"]["attributes"]
    position = np.frombuffer(attrs["position"]["array"].data, dtype=np.float32).reshape(-1, 3)
    np.testing.assert_allclose(position, pts, atol=1e-7)
    color = np.frombuffer(attrs["color"]["array"].data, dtype=np.float32).reshape(-1, 3)
    np.testing.assert_allclose(color[np.argmin(cond)], viz.COLORMAP[0], atol=1e-6)
    np.testing.assert_allclose(color[np.argmax(cond)], viz.COLORMAP[-1], atol=1e-6)
    with pytest.raises(InputError):
        viz.workspace_scene(robot, pts, cond[:-1])
    with pytest.raises(InputError):
        viz.workspace_scene(robot, np.full((3, 3), np.nan))


@needs_chromium
def test_browser_shows_the_workspace_cloud(robot, tmp_path):
    poses = ws.constant_orientation_grid(robot.home_pose[:3], [0.1, 0.1, 0.08], 21)
    m = ws.evaluate(robot, poses, singularity=False, statics=False)
    scene = viz.workspace_scene(robot, poses[m.ok, :3], np.log10(m.condition_number[m.ok]))
    with_cloud = scene.write(tmp_path / "cloud.html")
    image, status = render(with_cloud, tmp_path, "#a")
    assert status["ok"] == "true", status
    assert image.std() > 0.05
    # the same scene without the cloud object: the cloud must change enough pixels
    scene._commands = [c for c in scene._commands if not c.get("path", "").endswith("/workspace")]
    bare, _ = render(scene.write(tmp_path / "bare.html"), tmp_path, "#b")
    changed = np.abs(image - bare).sum(axis=2) > 0.15
    assert changed.sum() > 500


def test_force_capability_map_matches_the_workspace_call(robot, tmp_path):
    fig = workspace_plots.plot_force_capability_slice(robot, resolution=21,
                                                      path=tmp_path / "fc.png")
    assert (tmp_path / "fc.png").stat().st_size > 5000
    image = fig.axes[0].images[0].get_array()
    poses = ws.constant_orientation_grid([0, 0, robot.home_pose[2]], [0.12, 0.12, 1.0], (21, 21, 1))
    cap = ws.force_capability(robot, poses, [0, 0, -robot.geometry.gravity, 0, 0, 0])
    expected = np.where(cap.ok & cap.feasible_without_payload, cap.scale, np.nan).reshape(21, 21).T
    np.testing.assert_allclose(np.ma.filled(image, np.nan), expected, equal_nan=True)


def test_design_sweep_heat_map(tmp_path):
    table = sweeps.design_sweep(sweeps.design_grid(rail_radius=[0.33, 0.37], leg_length=[0.25, 0.45]),
                                sweeps.SweepSettings(n_samples=1000, payload_samples=20),
                                use_dask=False)
    fig = workspace_plots.plot_design_sweep(table, "rail_radius", "leg_length",
                                            path=tmp_path / "s.svg")
    assert (tmp_path / "s.svg").stat().st_size > 2000
    mesh = fig.axes[0].collections[0].get_array()
    assert np.ma.count_masked(mesh) == 2 or np.isnan(np.ma.filled(mesh, np.nan)).sum() == 2
    with pytest.raises(InputError):
        workspace_plots.plot_design_sweep(table, "rail_radius", "nope")


def test_point_cloud_has_a_colour_bar_and_no_empty_caption_box(robot):
    values = np.array([1.0, 2.0, 3.0])
    scene = viz.workspace_scene(robot, robot.home_pose[:3] + np.zeros((3, 3)), values,
                                value_label="log10 cond(J)")
    assert scene.colorbar == (1.0, 3.0, "log10 cond(J)")
    page = scene.html()
    assert 'id="hexapod-pin-colorbar"' in page and "log10 cond(J)" in page
    assert '<div id="hexapod-pin-caption"></div>' in page       # empty: hidden by CSS
    assert "#hexapod-pin-caption:empty { display: none; }" in page
    assert "3 points, coloured by log10 cond(J)" in page


def test_force_arrows_come_with_their_length_scale(robot):
    pose = robot.home_pose
    rest = robot.inverse_dynamics(pose, np.zeros(6), np.zeros(6))
    scene = viz.pose_scene(robot, robot.home_configuration,
                           actuator_forces=rest.actuator_forces,
                           closure_forces=rest.closure_forces)
    # the largest force is drawn DEFAULT_ARROW_LENGTH long
    biggest = max(np.abs(rest.actuator_forces).max(),
                  np.linalg.norm(rest.closure_forces, axis=1).max())
    per_decimetre = 0.1 * biggest / viz.DEFAULT_ARROW_LENGTH
    assert f"arrow length: 0.1 m = {per_decimetre:.4g} N" in " ".join(scene.legend)
    assert 'id="hexapod-pin-legend"' in scene.html()
    plain = viz.pose_scene(robot, robot.home_configuration).legend      # the triad's line only
    assert not any("arrow" in line for line in plain) and len(plain) == 1


def test_scenes_show_inline_in_jupyter(robot):
    scene = viz.pose_scene(robot, robot.home_configuration, caption="a <b> & c")
    inline = scene._repr_html_()
    assert inline.startswith("<iframe") and 'srcdoc="' in inline
    assert "&lt;!DOCTYPE html&gt;" in inline and "<!DOCTYPE" not in inline


def test_design_sweep_axes_have_units_and_readable_numbers(tmp_path):
    import pandas as pd

    table = pd.DataFrame({"rail_radius": [0.3, 0.3, 0.4, 0.4],
                          "leg_length": [0.4, 0.5, 0.4, 0.5],
                          "reachable_volume": [0.0, 1.0, 2.0, 3.0]})
    fig = workspace_plots.plot_design_sweep(table, "rail_radius", "leg_length")
    ax = fig.axes[0]
    assert ax.get_xlabel() == "rail_radius (m)" and ax.get_ylabel() == "leg_length (m)"
    assert fig.axes[1].get_ylabel() == "reachable_volume (m³)"
    colours = {t.get_text(): t.get_color() for t in ax.texts}
    assert colours["0"] == "white" and colours["3"] == "black"   # viridis: dark to yellow


def test_design_sweep_is_serial_below_the_dask_size_and_hints_the_extra(monkeypatch):
    def no_dask(*args, **kwargs):
        raise AssertionError("a small sweep must not start Dask")

    monkeypatch.setattr(sweeps, "_dask_rows", no_dask)
    designs = sweeps.design_grid(rail_radius=[0.33, 0.37])
    settings = sweeps.SweepSettings(n_samples=200, payload_samples=5)
    assert len(designs) < sweeps.DASK_MIN_DESIGNS
    assert len(sweeps.design_sweep(designs, settings)) == 2
    monkeypatch.setitem(__import__("sys").modules, "pandas", None)
    with pytest.raises(MissingDependencyError, match=r'pip install "hexapod-pin\[sweep\]"'):
        sweeps.design_sweep(designs, settings)
