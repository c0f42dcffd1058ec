"""Strict file readers and extreme magnitudes (issue 31, "Reliability, second pass", items 2
and 3): every reader of the package refuses a duplicate key, a duplicate column, binary
content, a folder, keys outside the geometry table and out-of-range numbers with a library
error naming the file; the command line turns each into its one ``error:`` line; the
planning options are checked by name and the planned forces never exceed their bound.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from conftest import one_line_error
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from typer.testing import CliRunner

import hexapod_pin as hp
from hexapod_pin import planning
from hexapod_pin.calibration import read_measurements
from hexapod_pin.cli import app
from hexapod_pin.core.checks import MAX_MAGNITUDE
from hexapod_pin.core.description import read_effects_file
from hexapod_pin.errors import DescriptionError, GeometryError, HexapodPinError, InputError
from hexapod_pin.files import load_geometry, save_geometry, write_text_atomic
from hexapod_pin.motion import read_motion
from hexapod_pin.planning import read_waypoints

HEADER = "t,x,y,z,roll,pitch,yaw"
#: a reader by file suffix: each takes a path
READERS = {
    "geometry.toml": load_geometry, "geometry.yaml": load_geometry,
    "geometry.json": load_geometry, "loops.yaml": hp.load_loops,
    "motion.csv": read_motion, "motion.json": read_motion,
    "waypoints.csv": read_waypoints, "waypoints.json": read_waypoints,
    "measurements.csv": read_measurements,
    "effects.yaml": read_effects_file,
}


@pytest.fixture(scope="module")
def hexapod():
    return hp.Hexapod.default()


# -- duplicate keys and columns -----------------------------------------------------------
@pytest.mark.parametrize("name, text, key, lines", [
    ("g.yaml", "geometry:\n  leg_length: 0.5\n  leg_length: 0.6\n", "geometry.leg_length",
     "lines 2 and 3"),
    ("g.json", '{"geometry": {"leg_length": 0.5,\n "leg_length": 0.6}}', "leg_length",
     "lines 1 and 2"),
    ("g.toml", "[geometry]\nleg_length = 0.5\nleg_length = 0.6\n", "leg_length", "line 3"),
])
def test_a_geometry_key_written_twice_is_refused_with_its_lines(tmp_path, name, text, key,
                                                                lines):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(DescriptionError, match=key) as info:
        load_geometry(path)
    assert lines in str(info.value) and info.value.source == str(path)


def test_a_loops_key_written_twice_is_refused(tmp_path):
    path = tmp_path / "l.yaml"
    path.write_text("closures: []\nactuated: [a]\nactuated: [b]\n")
    with pytest.raises(DescriptionError, match="actuated is written twice .lines 2 and 3.") \
            as info:
        hp.load_loops(path)
    assert info.value.culprit == "actuated (line 3)"


@pytest.mark.parametrize("reader, header", [
    (read_motion, HEADER + ",x"), (read_waypoints, "x,y,z,roll,pitch,yaw,y"),
    (read_measurements, "q0,q1,q2,q3,q4,q5,q0,x,y,z,roll,pitch,yaw"),
])
def test_a_csv_column_given_twice_is_refused(tmp_path, reader, header):
    path = tmp_path / "f.csv"
    width = len(header.split(","))
    path.write_text(header + "\n" + ",".join(["0"] * width) + "\n")
    with pytest.raises(DescriptionError, match="duplicate column") as info:
        reader(path)
    assert info.value.source == str(path)


def test_json_duplicate_keys_of_a_motion_are_refused(tmp_path):
    path = tmp_path / "m.json"
    path.write_text('{"t": [0, 1], "pose": [[0,0,0,0,0,0],[0,0,0,0,0,0]], "t": [0, 2]}')
    with pytest.raises(DescriptionError, match="t is written twice"):
        read_motion(path)


# -- keys outside the geometry table, numbers out of range ---------------------------------
@pytest.mark.parametrize("name, text", [
    ("g.toml", "leg_lenght = 0.5\n[geometry]\nrail_radius = 0.4\n"),
    ("g.yaml", "geometry:\n  rail_radius: 0.4\nleg_lenght: 0.5\n"),
])
def test_a_key_outside_the_geometry_table_is_refused_with_a_suggestion(tmp_path, name, text):
    path = tmp_path / name
    path.write_text(text)
    with pytest.raises(DescriptionError, match="leg_lenght.*outside.*did you mean 'leg_length'"):
        load_geometry(path)


def test_an_unknown_geometry_field_gets_a_suggestion(tmp_path):
    path = tmp_path / "g.toml"
    path.write_text("[geometry]\nleg_lenght = 0.5\n")
    with pytest.raises(GeometryError, match="did you mean 'leg_length'"):
        load_geometry(path)


@pytest.mark.parametrize("value", ["1e200", "-1e200", "1e400", "nan"])
def test_geometry_numbers_are_range_checked_like_the_api(tmp_path, value):
    path = tmp_path / "g.toml"
    path.write_text(f"[geometry]\nleg_length = {value}\n")
    with pytest.raises(GeometryError, match="leg_length"):
        load_geometry(path)
    with pytest.raises(GeometryError, match="leg_length"):
        hp.HexapodGeometry(leg_length=float(value))


@pytest.mark.parametrize("reader, text, words", [
    (read_motion, HEADER + "\n0,0,0,0.35,0,0,0\n1,1e200,0,0.35,0,0,0\n", "pose has a value beyond"),
    (read_waypoints, "x,y,z,roll,pitch,yaw\n0,0,0.35,0,0,0\n0,0,0.35,0,-1e200,0\n",
     "waypoint 2 has a value that is not finite or beyond"),
    (read_measurements, "q0,q1,q2,q3,q4,q5,x,y,z,roll,pitch,yaw\n" + "1e200," + "0," * 10 + "0\n",
     r"row 2, column q0.*'1e200' is not a finite number"),
    (read_measurements, "q0,q1,q2,q3,q4,q5,x,y,z,roll,pitch,yaw\n" + "0," * 7 + "nan,0,0,0,0\n",
     r"row 2, column y.*'nan' is not a finite number"),
])
def test_file_numbers_are_range_checked_like_the_api(tmp_path, reader, text, words):
    path = tmp_path / "f.csv"
    path.write_text(text)
    with pytest.raises(HexapodPinError, match=words):
        reader(path)


# -- binary content, folders, non-paths ----------------------------------------------------
@pytest.mark.parametrize("name", sorted(READERS))
def test_binary_content_and_folders_are_refused_by_every_reader(tmp_path, name):
    reader = READERS[name]
    path = tmp_path / name
    path.write_bytes(b"\x00\x01\xff\xfe\x80 not text")
    with pytest.raises(DescriptionError, match="not UTF-8") as info:
        reader(path)
    assert info.value.source == str(path)
    folder = tmp_path / ("dir_" + name)
    folder.mkdir()
    with pytest.raises(DescriptionError, match="is a folder"):
        reader(folder)


@pytest.mark.parametrize("path", [None, 3, True, ["a.toml"], ""])
def test_a_path_that_is_not_a_path_is_refused_by_name(path):
    for reader in (load_geometry, hp.load_loops, read_motion, read_waypoints,
                   read_measurements):
        if path is None and reader is load_geometry:
            continue                    # None: the default geometry
        with pytest.raises(InputError, match="path"):
            reader(path)


def test_writing_onto_a_folder_is_refused(tmp_path):
    with pytest.raises(InputError, match="is a folder"):
        write_text_atomic(tmp_path, "x")
    (tmp_path / "d.toml").mkdir()
    with pytest.raises(InputError, match="is a folder"):
        save_geometry(hp.HexapodGeometry(), tmp_path / "d.toml")


# -- malformed files, generated ---------------------------------------------------------------
FRAGMENTS = st.sampled_from([
    "geometry:", "[geometry]", "leg_length", " = ", ": ", "0.5", "1e200", "nan", "-inf",
    "\n", "  ", ",", "{", "}", "[", "]", '"', "x,y,z", "t", HEADER, "\x00", "\xff",
    "leg_length: 1\nleg_length: 2\n", "closures:", "- a", "pose", '{"t": [0], "pose": [[0]]}',
    "q0,q1,q2,q3,q4,q5,x,y,z,roll,pitch,yaw", "effects:", "joints:", "#", "0,0,0,0,0,0",
])


@settings(max_examples=60, deadline=None,
          suppress_health_check=[HealthCheck.function_scoped_fixture])
@given(name=st.sampled_from(sorted(READERS)), parts=st.lists(FRAGMENTS, max_size=12),
       raw=st.binary(max_size=40), binary=st.booleans())
def test_malformed_files_raise_library_errors_only(tmp_path, name, parts, raw, binary):
    """Generated malformed files (fragments of every format, or random bytes): a reader
    returns or raises a library error; nothing else escapes."""
    path = tmp_path / name
    if binary:
        path.write_bytes(raw)
    else:
        path.write_text("".join(parts), encoding="utf-8", errors="surrogateescape")
    try:
        READERS[name](path)
    except HexapodPinError:
        pass


# -- the command line: one error line each ----------------------------------------------------
def test_the_cli_reports_each_file_problem_on_one_line(tmp_path):
    run = CliRunner()
    dup = tmp_path / "g.yaml"
    dup.write_text("geometry:\n  leg_length: 0.5\n  leg_length: 0.6\n")
    outside = tmp_path / "o.toml"
    outside.write_text("leg_lenght = 0.5\n[geometry]\nrail_radius = 0.35\n")
    huge = tmp_path / "h.toml"
    huge.write_text("[geometry]\nleg_length = 1e200\n")
    motion = tmp_path / "m.csv"
    motion.write_text(HEADER + ",t\n0,0,0,0.35,0,0,0,0\n")
    for args, words in (
            (["ik", "0", "0", "0.35", "0", "0", "0", "--geometry", str(dup)],
             ("written twice", "lines 2 and 3")),
            (["ik", "0", "0", "0.35", "0", "0", "0", "--geometry", str(outside)],
             ("outside", "leg_length")),
            (["ik", "0", "0", "0.35", "0", "0", "0", "--geometry", str(huge)],
             ("leg_length",)),
            (["ik", "0", "0", "0.35", "0", "0", "0", "--geometry", str(tmp_path)],
             ("is a folder",)),
            (["id", str(motion)], ("duplicate column", "'t'"))):
        one_line_error(run.invoke(app, args), 1, *words)


# -- planning options and extreme magnitudes (item 3) ------------------------------------------
def _waypoints(robot):
    home = robot.home_pose
    return np.array([home, home + [0.01, 0.0, 0.0, 0.0, 0.0, 0.02]])


@pytest.mark.parametrize("call, name", [
    (lambda r, wp: planning.time_optimal(None, wp), "robot"),
    (lambda r, wp: planning.time_optimal(r, wp, limits="fast"), "limits"),
    (lambda r, wp: planning.time_optimal(r, wp, payload=3.0), "payload"),
    (lambda r, wp: planning.time_optimal(r, wp, start_speed=1e300), "start_speed"),
    (lambda r, wp: planning.time_optimal(r, wp, end_speed=True), "end_speed"),
    (lambda r, wp: planning.time_optimal(r, wp, grid_points=2.0), "grid_points"),
    (lambda r, wp: planning.Payload(mass="1"), "mass"),
    (lambda r, wp: planning.Payload(mass=-1.0), "mass"),
    (lambda r, wp: planning.Payload(wrench=[[1.0, 2.0], [3.0]]), "wrench"),
    (lambda r, wp: planning.Limits(actuator_force=1e200), "actuator_force"),
    (lambda r, wp: planning.Limits(actuator_force="fast"), "actuator_force"),
    (lambda r, wp: planning.Limits(linear_speed=-1.0), "linear_speed"),
    (lambda r, wp: planning.Limits(strokes="no"), "strokes"),
    (lambda r, wp: planning.Limits(margin=1.0), "margin"),
])
def test_planning_options_are_checked_by_name(hexapod, call, name):
    with pytest.raises(InputError) as info:
        call(hexapod, _waypoints(hexapod))
    assert info.value.name == name


@pytest.mark.parametrize("bound", [1e3, 1e100, MAX_MAGNITUDE])
def test_planned_forces_never_exceed_their_bound(hexapod, bound):
    """Up to MAX_MAGNITUDE the plan keeps the bound (to check_feasibility's relative
    tolerance, round-off); above it the bound is refused (it cannot be certified)."""
    plan = planning.time_optimal(hexapod, _waypoints(hexapod),
                                 limits=planning.Limits(actuator_force=bound), grid_points=40)
    assert np.isfinite(plan.actuator_forces).all()
    assert np.abs(plan.actuator_forces).max() <= bound * (1.0 + 1e-9)
    assert np.abs(plan.actuator_forces).max() >= 0.5 * bound       # the bound was used


def test_resample_refuses_an_absurd_rate(hexapod):
    plan = planning.time_optimal(hexapod, _waypoints(hexapod), grid_points=20)
    for rate in (1e300, math.inf, "100", True, 0.0):
        with pytest.raises(InputError, match="rate"):
            plan.resample(rate)


def test_batches_refuse_a_row_of_huge_magnitude_and_qddot_needs_twist_dot(hexapod):
    poses = np.array([hexapod.home_pose, hexapod.home_pose])
    poses[1, 0] = 1e300
    for call in (hexapod.inverse_kinematics_batch, hexapod.jacobian_batch):
        with pytest.raises(InputError, match="poses"):
            call(poses)
    with pytest.raises(InputError, match="twist_dot"):
        hexapod.qddot(hexapod.home_pose, np.zeros(6), None)
