"""Measurement files of the calibration (CSV).

One measurement per row, a header row naming the columns (any order), ``#`` lines are
comments:

* the actuator readings ``q0 .. q5`` (m), always;
* either the measured target pose ``x, y, z, roll, pitch, yaw`` in the instrument frame
  (m, rad; degrees with ``degrees=True``),
* or the measured target points ``p0_x, p0_y, p0_z`` (then ``p1_*``, ``p2_*`` for more
  points; m, instrument frame), whose coordinates in the target frame are given apart
  (``target_points``, the command line's ``--target-point``).

Example::

    x,y,z,roll,pitch,yaw,q0,q1,q2,q3,q4,q5
    0.0012,-0.0003,0.3571,0.0021,-0.0010,0.0005,-0.1502,0.1497,-0.1511,0.1503,-0.1499,0.1508
"""

from __future__ import annotations

import csv
import io
import os
from pathlib import Path

import numpy as np
import numpy.typing as npt

from ..core.checks import MAX_MAGNITUDE
from ..core.text_formats import check_columns
from ..errors import DescriptionError, InputError
from ..files import read_text, write_text_atomic
from .problem import Measurements

ACTUATOR_COLUMNS = tuple(f"q{i}" for i in range(6))
POSE_COLUMNS = ("x", "y", "z", "roll", "pitch", "yaw")


def point_columns(count: int) -> tuple[str, ...]:
    """Column names of ``count`` target points: ``p0_x, p0_y, p0_z, p1_x, ...``."""
    return tuple(f"p{j}_{a}" for j in range(count) for a in "xyz")


def read_measurements(path: str | os.PathLike, target_points: npt.ArrayLike | None = None,
                      degrees: bool = False) -> Measurements:
    """Measurements from a CSV file (see the module doc).

    Args:
        path: the CSV file.
        target_points: (M, 3) target-frame coordinates of the measured points (m), for
            files of points.
        degrees: the pose angles of the file are in degrees.

    Returns:
        checked :class:`~hexapod_pin.calibration.problem.Measurements`.

    Raises:
        MissingFileError: the file does not exist.
        DescriptionError: unreadable file, no header, unknown or missing
            columns, a row of another length, a value that is not a number (row and
            column named).
        InputError: inconsistent measurements (see ``Measurements.checked``).
    """
    lines = [ln for ln in read_text(path, "measurement file").splitlines()
             if ln.strip() and not ln.lstrip().startswith("#")]
    rows = list(csv.reader(lines))
    if not rows:
        raise DescriptionError(str(path), "no header row")
    header = check_columns(rows[0], str(path))
    n_points = sum(1 for h in header if h.startswith("p") and h.endswith("_x"))
    known = set(ACTUATOR_COLUMNS) | set(POSE_COLUMNS) | set(point_columns(n_points))
    unknown = [h for h in header if h not in known]
    if unknown:
        raise DescriptionError(str(path), f"unknown columns {unknown}; expected q0..q5 with "
                               "x, y, z, roll, pitch, yaw or p0_x, p0_y, p0_z, ...")
    wanted = ACTUATOR_COLUMNS + (POSE_COLUMNS if n_points == 0 else point_columns(n_points))
    missing = [h for h in wanted if h not in header]
    if missing:
        raise DescriptionError(str(path), f"missing columns {missing}")
    values = np.empty((len(rows) - 1, len(header)))
    for r, row in enumerate(rows[1:], start=2):
        if len(row) != len(header):
            raise DescriptionError(str(path), f"{len(row)} values, {len(header)} columns",
                                   f"row {r}")
        for c, text in enumerate(row):
            try:
                values[r - 2, c] = float(text)
            except ValueError:
                raise DescriptionError(str(path), f"not a number: {text!r}",
                                       f"row {r}, column {header[c]}") from None
            if not abs(values[r - 2, c]) <= MAX_MAGNITUDE:     # NaN, inf, 1e200
                raise DescriptionError(str(path), f"{text.strip()!r} is not a finite number "
                                       f"within {MAX_MAGNITUDE:g}",
                                       f"row {r}, column {header[c]}")
    col = {h: k for k, h in enumerate(header)}
    q = values[:, [col[h] for h in ACTUATOR_COLUMNS]]
    if n_points == 0:
        poses = values[:, [col[h] for h in POSE_COLUMNS]]
        if degrees:
            poses[:, 3:] = np.radians(poses[:, 3:])
        return Measurements.checked(q, poses=poses)
    pts = values[:, [col[h] for h in point_columns(n_points)]].reshape(-1, n_points, 3)
    if target_points is None:
        raise InputError("target_points", None, f"the file has {n_points} point(s): give "
                         "their target-frame coordinates (the command line's "
                         "--target-point x,y,z, once per point)")
    return Measurements.checked(q, points=pts, target_points=target_points)


def measurements_csv(actuators: npt.ArrayLike, poses: npt.ArrayLike | None = None,
                     points: npt.ArrayLike | None = None) -> str:
    """CSV text of measurements (the format of :func:`read_measurements`, angles in rad,
    numbers as their shortest exact decimal)."""
    data = Measurements.checked(actuators, poses, points,
                                None if points is None else np.zeros((np.shape(points)[1], 3)))
    if data.poses is not None:
        header, body = POSE_COLUMNS, data.poses
    else:
        points = data.point_arrays()[0]
        header = point_columns(points.shape[1])
        body = points.reshape(data.count, -1)
    out = io.StringIO()
    writer = csv.writer(out, lineterminator="\n")
    writer.writerow(header + ACTUATOR_COLUMNS)
    for row in np.hstack([body, data.actuators]):
        writer.writerow([repr(float(v)) for v in row])
    return out.getvalue()


def write_measurements(path: str | os.PathLike, actuators: npt.ArrayLike,
                       poses: npt.ArrayLike | None = None, points: npt.ArrayLike | None = None) -> Path:
    """Write measurements to a CSV file (atomically); returns the path.

    Raises:
        InputError: malformed measurements, or a folder that does not exist.
    """
    return write_text_atomic(path, measurements_csv(actuators, poses, points))
