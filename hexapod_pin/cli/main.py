"""Command line interface: ``hexapod-pin`` (also ``python -m hexapod_pin``).

Commands (``hexapod-pin COMMAND --help`` for each), each a thin layer over library
functions:

* ``demo``, ``warmup`` (:mod:`.demo`);
* ``ik``, ``fk``, ``modes``, ``jacobian`` (:mod:`.kinematics`);
* ``statics``, ``fd``, ``id``, ``simulate`` (:mod:`.dynamics`);
* ``view``, ``plot`` (:mod:`.views`);
* ``urdf``, ``mjcf`` (:mod:`.export`);
* ``retime``, ``check`` (:mod:`.planning`);
* ``workspace`` (:mod:`.workspace`);
* ``stiffness`` (:mod:`.stiffness`);
* ``calibrate`` (:mod:`.calibrate`);
* ``excite``, ``identify`` (:mod:`.identification`).

Common options (:mod:`.common`):

* ``--geometry FILE``: a TOML, YAML or JSON file of :class:`HexapodGeometry` fields
  (at the top level or under a ``geometry`` table), e.g. ``leg_length = 0.5``;
  ``--set FIELD=VALUE`` (repeatable) overrides one field. Default: the defaults
  (:func:`hexapod_pin.files.load_geometry`).
* ``--robot PATH [--platform FRAME] [--pose-axes x,z]`` (``ik``, ``fk``, ``modes``,
  ``jacobian``, ``statics``, ``fd``, ``simulate``, ``view``, ``mjcf``, ``excite``,
  ``identify``): any closed-loop
  robot instead of the hexapod (:func:`hexapod_pin.load_robot`: a URDF with
  ``<name>.loops.yaml`` beside it, an SDF, or a folder; platform and pose axes default to
  the loops file's ``robot:`` section). Poses then have the robot's pose axes, actuator
  values its actuated joints; ``--robot`` with ``--geometry`` / ``--set`` or a hexapod
  option (``--branch``, ``--radius``, ...) is a usage error (exit code 2).
* ``--effects FILE`` (``statics``, ``fd``, ``id``, ``simulate``, ``stiffness``): joint and
  drive effects (armature, damping, Coulomb friction, springs, gears) over the robot's own,
  from a YAML or TOML file in the format of a loops file's ``effects:`` section
  (:func:`hexapod_pin.core.description.read_effects_file`); the output says which are on.
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

Exit codes (:data:`.common.EXIT_CODES`): 0 success; 1 a computed failure (saturation, a
singular or unreachable pose, ...) or bad input (a value that is not a number, a missing
or malformed file); 2 a usage error (an unknown option, a missing required option or
argument, a wrong number of values). Every error is a one-line message on stderr, or with
``--json`` a JSON object on stdout (:mod:`.common`).

``hexapod-pin --version`` prints the package version.
"""

from __future__ import annotations

from typing import Annotated

import typer

from .. import __version__
from . import (calibrate, demo, dynamics, export, identification, kinematics, planning,
               stiffness, views, workspace)
from .common import NUMBERS, Command, Group

app = typer.Typer(help="Kinematics and dynamics of the rail-driven hexapod.", no_args_is_help=True,
                  pretty_exceptions_enable=False, add_completion=False,
                  rich_markup_mode="markdown", cls=Group)


def print_version(value: bool) -> None:
    """``--version``: print ``hexapod-pin <version>`` and exit."""
    if value:
        typer.echo(f"hexapod-pin {__version__}")
        raise typer.Exit()


@app.callback()
def root(version: Annotated[bool, typer.Option(
        "--version", help="print the version and exit", callback=print_version,
        is_eager=True)] = False) -> None:
    """hexapod_pin command line (see each command's --help)."""


app.command(cls=Command)(demo.demo)
app.command(cls=Command)(demo.warmup)
app.command(cls=Command, context_settings=NUMBERS)(kinematics.ik)
app.command(cls=Command, context_settings=NUMBERS)(kinematics.fk)
app.command(cls=Command, context_settings=NUMBERS)(kinematics.modes)
app.command(cls=Command, context_settings=NUMBERS)(kinematics.jacobian)
app.command(cls=Command, context_settings=NUMBERS)(dynamics.statics)
app.command(cls=Command, context_settings=NUMBERS)(dynamics.fd)
app.command("id", cls=Command)(dynamics.inverse_dynamics)
app.command(cls=Command)(dynamics.simulate)
app.command(cls=Command, context_settings=NUMBERS)(views.view)
app.command(cls=Command)(views.plot)
app.command(cls=Command)(export.urdf)
app.command(cls=Command)(export.mjcf)
app.command(cls=Command)(planning.retime)
app.command(cls=Command)(planning.check)
app.command(cls=Command)(workspace.workspace)
app.command(cls=Command, context_settings=NUMBERS)(stiffness.stiffness)
app.command(cls=Command, context_settings=NUMBERS)(calibrate.calibrate)
app.command(cls=Command)(identification.excite)
app.command(cls=Command)(identification.identify)


def main() -> None:  # pragma: no cover - console entry point
    """Run the command line (``hexapod-pin``)."""
    app(prog_name="hexapod-pin")
