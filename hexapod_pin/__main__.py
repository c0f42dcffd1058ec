"""``python -m hexapod_pin`` runs the command line."""

from .cli import app

app(prog_name="hexapod-pin")
