"""Robot-agnostic closed-loop mechanics: any Pinocchio tree plus loop closures.

Imports no robot, no viewer and no command line: description (xacro -> URDF ->
``pin.Model``, loops files), :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`,
dynamics on the tree (forward, inverse, their results) and time integration.
"""
