"""Pictures: meshcat scenes of any closed-loop model (self-contained HTML) and
matplotlib figures.

* :mod:`~hexapod_pin.viz.meshcat_scene`: the recorded meshcat scene and its HTML page;
  shapes, arrows, animation clips, camera.
* :mod:`~hexapod_pin.viz.drawing`: a robot's URDF visuals and force / frame overlays
  drawn into a scene.
* :mod:`~hexapod_pin.viz.scenes`: pose, assembly-mode, trajectory and workspace scenes
  of any robot, and their ``write_*_html`` functions.
* :mod:`~hexapod_pin.viz.hexapod_scenes`: the hexapod's scenes from platform poses and
  simulation results.
* :mod:`~hexapod_pin.viz.plotting`: matplotlib figures along a motion (the ``plot``
  extra) and the figure helpers.
* :mod:`~hexapod_pin.viz.workspace_plots`: workspace figures: cond(J) along a path,
  slices, force capability, design sweeps.
* :mod:`~hexapod_pin.viz.stiffness_plots`: maps of the weakest stiffness and the lowest
  natural frequency over a slice.
* :mod:`~hexapod_pin.viz.identification_plots`: dynamic identification: measured
  against predicted forces, parameter estimates with error bars.
"""
