"""Usage errors of the numeric commands: an unknown option is a usage error (exit code 2,
"No such option" with the close matches), never read as a bad number; negative numbers and
comma lists still pass as values."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from hexapod_pin.cli import app

RUN = CliRunner()
HOME = ["0", "0", "0.3868", "0", "0", "0"]


@pytest.mark.parametrize("command, option, close", [
    ("statics", "--no-limits", None),
    ("ik", "--jsn", "--json"),
    ("jacobian", "--degres", "--degrees"),
    ("fk", "-z", None),
])
def test_an_unknown_option_is_a_usage_error_naming_it(command, option, close):
    result = RUN.invoke(app, [command, *HOME, option])
    assert result.exit_code == 2, result.output
    line = result.stderr.strip().splitlines()[-1]
    assert f"No such option: {option}" in line and "not a number" not in line
    if close:
        assert close in line


def test_negative_numbers_and_comma_lists_are_values():
    result = RUN.invoke(app, ["ik", "0", "0", "0.35", "-0.01", "0", "-0.02", "--json"])
    assert result.exit_code == 0, result.output
    result = RUN.invoke(app, ["ik", "0,0,0.35,-0.01,0,-0.02", "--json"])
    assert result.exit_code == 0, result.output
    result = RUN.invoke(app, ["ik", "--json", "--", "0", "0", "0.35", "-0.01", "0", "0"])
    assert result.exit_code == 0, result.output
