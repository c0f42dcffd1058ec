"""Command line interface: ``hexapod-pin``.

Output goes to the terminal through rich; ``--json`` gives machine-readable output.
Errors of the library end the command with a one-line message and exit code 1.
"""

from __future__ import annotations

import json
from typing import Optional

import numpy as np
import typer
from rich.console import Console
from rich.table import Table

from .errors import HexapodPinError
from .geometry import HexapodGeometry
from .hexapod import Hexapod

app = typer.Typer(help="Kinematics and dynamics of the rail-driven hexapod.", no_args_is_help=True,
                  pretty_exceptions_enable=False)
console = Console()


@app.callback()
def _root() -> None:
    """hexapod_pin command line (see each command's --help)."""


def _fail(exc: Exception) -> None:
    Console(stderr=True).print(f"[bold red]error:[/] {exc}", highlight=False)
    raise typer.Exit(code=1)


@app.command()
def demo(as_json: bool = typer.Option(False, "--json", help="machine-readable output"),
         leg_length: Optional[float] = typer.Option(None, help="override leg_length (m)")) -> None:
    """Load the default hexapod, assemble its home pose and report the closures."""
    try:
        geometry = HexapodGeometry() if leg_length is None else HexapodGeometry(
            leg_length=leg_length)
        robot = Hexapod(geometry)
        q = robot.home_configuration
        residual = float(np.max(np.abs(robot.model.residual(q))))
        result = {
            "home_pose": robot.home_pose.tolist(),
            "home_q": robot.home_q.tolist(),
            "closure_rows": robot.model.n_rows,
            "closure_residual_max_abs_m": residual,
            "constraint_rank": robot.model.rank(q).rank,
            "mobility": robot.model.mobility(q),
        }
    except HexapodPinError as exc:
        _fail(exc)
        return
    if as_json:
        typer.echo(json.dumps(result))
        return
    table = Table(title="hexapod_pin demo: default hexapod at home")
    table.add_column("quantity")
    table.add_column("value", justify="right")
    table.add_row("home pose (x, y, z) (m)", " ".join(f"{v:.6f}" for v in result["home_pose"][:3]))
    table.add_row("home pose (roll, pitch, yaw) (rad)",
                  " ".join(f"{v:.3f}" for v in result["home_pose"][3:]))
    table.add_row("carriages q (m)", " ".join(f"{v:+.3f}" for v in result["home_q"]))
    table.add_row("closure rows / rank", f"{result['closure_rows']} / {result['constraint_rank']}")
    table.add_row("mobility of the closed chain", str(result["mobility"]))
    table.add_row("max closure residual (m)", f"{residual:.2e}")
    console.print(table)
