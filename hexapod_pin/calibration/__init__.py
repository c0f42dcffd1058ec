"""Kinematic calibration of the as-built hexapod.

* :func:`calibrate`: identify the per-chain geometry (lines, sensor zeros, leg lengths,
  platform joints) and the instrument and target frames from measured poses or target
  points and the actuator readings (:mod:`.identify`; the models in :mod:`.model`, the
  parameters in :mod:`.parameters`, the result and its validation in :mod:`.results`);
* identifiability: rank, singular values, the base parameter set and the combinations no
  data can separate (:mod:`.identifiability`; :class:`~hexapod_pin.errors.IdentifiabilityError`
  when the data cannot give what is asked);
* :func:`select_poses`: measurement poses maximising an observability index
  (:mod:`.selection`);
* :func:`synthetic_measurements`: data of a perturbed robot, :func:`random_as_built` a
  random perturbed robot (:mod:`.synthetic`);
* a first guess of the instrument frame by rigid registration (:mod:`.registration`);
* measurement files (CSV) and the identified geometry file (:mod:`.files`);
* figures (:mod:`.plots`, matplotlib optional).

Units: m, rad; poses ``(x, y, z, roll, pitch, yaw)`` with ``R = Rz Ry Rx``.
"""

from ..errors import IdentifiabilityError
from .identifiability import IdentifiabilityReport
from .identify import calibrate
from .measurements import read_measurements, write_measurements
from .parameters import DEFAULT_IDENTIFY, GROUPS, NAMES, ParameterModel
from .problem import Measurements, reference_poses
from .results import (
    CalibrationResult,
    ModelErrors,
    ParameterEstimate,
    ResidualSummary,
    ValidationReport,
)
from .selection import PoseSelection, select_measurements, select_poses
from .synthetic import SyntheticData, random_as_built, synthetic_measurements

__all__ = [
    "DEFAULT_IDENTIFY", "GROUPS", "NAMES", "CalibrationResult", "IdentifiabilityError",
    "IdentifiabilityReport", "Measurements", "ModelErrors", "ParameterEstimate",
    "ParameterModel", "PoseSelection", "ResidualSummary", "SyntheticData", "ValidationReport",
    "calibrate", "read_measurements", "reference_poses", "select_measurements",
    "random_as_built", "select_poses", "synthetic_measurements", "write_measurements",
]
