"""Dynamics of closed-loop mechanisms (generic) and of the hexapod (mixin).

Being written: see issue 5. Generic functions take a
:class:`hexapod_pin.closed_loop.ClosedLoopModel`; :class:`HexapodDynamics` adds
the hexapod's pose/twist-level API to :class:`hexapod_pin.Hexapod`.
"""

from __future__ import annotations


class HexapodDynamics:
    """Dynamics methods of :class:`hexapod_pin.Hexapod` (a mixin)."""
