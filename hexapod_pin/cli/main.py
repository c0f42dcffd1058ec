"""Command line interface: ``hexapod-pin`` (also ``python -m hexapod_pin``).

Commands (``hexapod-pin COMMAND --help`` for each), each a thin layer over library
functions:

* ``demo`` (:mod:`.demo`);
* ``ik``, ``fk``, ``modes``, ``jacobian`` (:mod:`.kinematics`);
* ``statics``, ``id``, ``simulate`` (:mod:`.dynamics`);
* ``view``, ``plot`` (:mod:`.views`);
* ``retime``, ``check`` (:mod:`.planning`).

Common options (:mod:`.common`):

* ``--geometry FILE``: a TOML, YAML or JSON file of :class:`HexapodGeometry` fields
  (at the top level or under a ``geometry`` table), e.g. ``leg_length = 0.5``;
  ``--set FIELD=VALUE`` (repeatable) overrides one field. Default: the defaults
  (:func:`hexapod_pin.files.load_geometry`).
* ``--json``: machine-readable output on stdout (nothing else is written then).
* ``--quiet``: no progress bars or notes (results are still printed).
* ``--degrees``: angles of poses in degrees, in and out (default rad).

Numbers are given as separate arguments or comma-separated (``0 0 0.35 0 0 0`` or
``0,0,0.35,0,0,0``); negative numbers need no ``--``.

Motion files (``id``, ``view --trajectory``, ``plot``; written by ``simulate --out``):
CSV or JSON, see :mod:`hexapod_pin.motion`.

Every measure printed is the library's and says what it is: the condition number is
``cond(J)`` of the unscaled workspace Jacobian (columns m/s and rad/s), as
``Hexapod.singularity`` and ``hexapod_pin.hexapod.workspace.evaluate`` report it.

Errors of the library or of the input end the command with a one-line message
on stderr and exit code 1 (usage errors: exit code 2).
"""

from __future__ import annotations

import typer

from . import demo, dynamics, kinematics, planning, views
from .common import NUMBERS

app = typer.Typer(help="Kinematics and dynamics of the rail-driven hexapod.", no_args_is_help=True,
                  pretty_exceptions_enable=False, add_completion=False,
                  rich_markup_mode="markdown")


@app.callback()
def _root() -> None:
    """hexapod_pin command line (see each command's --help)."""


app.command()(demo.demo)
app.command(context_settings=NUMBERS)(kinematics.ik)
app.command(context_settings=NUMBERS)(kinematics.fk)
app.command(context_settings=NUMBERS)(kinematics.modes)
app.command(context_settings=NUMBERS)(kinematics.jacobian)
app.command(context_settings=NUMBERS)(dynamics.statics)
app.command("id")(dynamics.inverse_dynamics)
app.command()(dynamics.simulate)
app.command(context_settings=NUMBERS)(views.view)
app.command()(views.plot)
app.command()(planning.retime)
app.command()(planning.check)


def main() -> None:  # pragma: no cover - console entry point
    """Run the command line (``hexapod-pin``)."""
    app(prog_name="hexapod-pin")
