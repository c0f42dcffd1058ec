"""Exit codes and usage errors. An unknown option is a usage error (exit code 2, "No such
option" with the close matches), never read as a bad number; negative numbers and comma
lists still pass as values; a missing required option or argument and a wrong number of
values are usage errors (2); a computed failure (saturation, a singular or unreachable
pose) and bad input exit with 1 (the table of docs/tutorials/cli.md)."""

from __future__ import annotations

import json

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


# -- exit codes: 0 success, 1 a computed failure or bad input, 2 a usage error -------------
def test_a_missing_required_option_or_argument_is_a_usage_error():
    from conftest import one_line_error

    one_line_error(RUN.invoke(app, ["stiffness"]), 2, "Missing option '--actuator-stiffness'")
    one_line_error(RUN.invoke(app, ["id"]), 2, "Missing argument")
    one_line_error(RUN.invoke(app, ["retime"]), 2, "Missing argument")


def test_a_wrong_number_of_values_is_a_usage_error():
    from conftest import one_line_error

    one_line_error(RUN.invoke(app, ["ik", "0", "0", "0.35"]), 2, "expected 6 values", "got 3")
    one_line_error(RUN.invoke(app, ["statics", "--wrench", "1,2"]), 2, "expected 6 values")
    result = RUN.invoke(app, ["ik", "0", "0", "0.35", "--json"])
    assert result.exit_code == 2
    assert json.loads(result.stdout)["error"]["type"] == "ValueCountError"
    # a value that is not a number stays bad input (exit code 1)
    one_line_error(RUN.invoke(app, ["ik", "0", "0", "zz", "0", "0", "0"]), 1, "not a number")


def test_a_saturated_simulation_exits_1_unless_allowed():
    result = RUN.invoke(app, ["simulate", "--duration", "1", "--dt", "0.01"])
    assert result.exit_code == 1, result.output
    assert "saturated" in result.stdout and "warning" in result.stderr
    allowed = RUN.invoke(app, ["simulate", "--duration", "1", "--dt", "0.01",
                               "--allow-saturation"])
    assert allowed.exit_code == 0, allowed.output
    assert "saturated" in allowed.stdout and "warning" in allowed.stderr
    misspelt = RUN.invoke(app, ["simulate", "--allow-saturaton"])
    assert misspelt.exit_code == 2
    assert "No such option: --allow-saturaton" in misspelt.stderr
    assert "--allow-saturation" in misspelt.stderr


def test_a_missing_motion_file_says_file_not_found(tmp_path):
    from conftest import one_line_error

    missing = tmp_path / "nope.csv"
    one_line_error(RUN.invoke(app, ["id", str(missing)]), 1, str(missing), "file not found")
    result = RUN.invoke(app, ["id", str(missing), "--json"])
    assert json.loads(result.stdout)["error"]["type"] == "MissingFileError"


def _type_one_pose():
    """The home pose raised until a leg is perpendicular to its rail (bisection on the
    reach: a type-I singularity of the default hexapod)."""
    import hexapod_pin as hp

    robot = hp.Hexapod.default()
    low, high = robot.home_pose[2], 1.0
    for _ in range(60):
        pose = robot.home_pose.copy()
        pose[2] = mid = 0.5 * (low + high)
        try:
            robot.inverse_kinematics(pose, check_limits=False)
            low = mid
        except hp.UnreachablePoseError:
            high = mid
        except hp.SingularityError:
            low = mid
    pose[2] = low
    assert robot.singularity(pose).type_one < 1e-6
    return pose


def test_jacobian_at_a_type_one_singularity_exits_1_and_prints_no_inf():
    from conftest import one_line_error

    pose = [str(v) for v in _type_one_pose()]
    line = one_line_error(RUN.invoke(app, ["jacobian", *pose]), 1, "type-I singularity")
    assert "inf" not in line.lower()
    # the measure is a |cos|, not a singular value
    assert "|cos| of the leg and its rail" in line and "singular value" not in line
    result = RUN.invoke(app, ["jacobian", *pose, "--json"])
    assert result.exit_code == 1 and "Infinity" not in result.stdout
    assert json.loads(result.stdout)["error"]["type"] == "SingularityError"


def test_no_singularity_message_calls_another_measure_a_singular_value():
    import re
    from pathlib import Path

    package = Path(__file__).resolve().parents[2] / "hexapod_pin"
    for path in package.rglob("*.py"):
        text = path.read_text(encoding="utf-8")
        assert "is singular (smallest singular value" not in text, path
        # every SingularityError raised with a value of 0 names its measure
        for call in re.findall(r"SingularityError\(([^()]*(?:\([^()]*\)[^()]*)*)\)", text):
            if re.search(r",\s*0\.0\s*$", call):
                raise AssertionError(f"{path}: SingularityError({call}) names no measure")
