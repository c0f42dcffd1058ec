"""Robots and description formats from elsewhere: example-parallel-robots folders, SDF,
MJCF (compiled by MuJoCo), example-robot-data's Solo-12 and Cassie, each loaded as a
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`.
"""
