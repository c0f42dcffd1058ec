"""Dynamic identification of closed-loop robots: the closed-loop regressor, the base
parameters, least-squares and physically consistent estimates.

* :mod:`.parameters`: the ten inertial parameters per body (Pinocchio's convention) and
  the drive parameters per actuator, their names, the nominal values of a robot and the
  robot rebuilt with other values;
* :mod:`.regressor`: ``u = Y pi + Y_d pi_d`` at closure-consistent states
  (:func:`regressor`, :func:`regressor_batch`, :class:`ClosedLoopRegressor`), and at a
  tree state of any closed-loop model (:func:`closed_loop_regressor_tree`);
* :mod:`.base`: :func:`base_parameters` (count, names, regrouping rules);
* :mod:`.estimate`: :func:`identify_from_states`, :func:`identify` (weighted least squares,
  standard errors, the physically consistent fit of :mod:`.consistent`);
* :mod:`.motion_data`: :class:`MotionData` and its zero-phase filtering;
* :mod:`.input_noise`: errors in the variables (position noise through the
  differentiated states): :class:`StateNoise`, the Coulomb deadband, the bias
  compensation and the long-run sandwich covariance;
* :mod:`.excitation`: :func:`optimise_excitation`, a pose-space Fourier series optimised
  for the base regressor's condition number within the robot's limits;
* :mod:`.results`: :class:`IdentificationResult`, :class:`ValidationReport`.

Units: SI (kg, m, s, N, N m); poses, twists and actuator conventions of the robot API.
"""

from ..errors import IdentifiabilityError
from .base import BaseParameters, base_from_regressor, base_parameters, random_states
from .consistent import ConsistentFit
from .estimate import identify, identify_from_states
from .excitation import Excitation, FourierSeries, optimise_excitation
from .input_noise import StateNoise
from .motion_data import MotionData, MotionStates, states_from_motion
from .parameters import (
    DEFAULT_DRIVE,
    DRIVE_KINDS,
    ParameterLayout,
    model_with_parameters,
    nominal_parameters,
    robot_with_parameters,
)
from .regressor import (
    ClosedLoopRegressor,
    TreeMotion,
    TreeRegressorRows,
    closed_loop_regressor_tree,
    regressor,
    regressor_batch,
)
from .results import ForceResiduals, IdentificationResult, ValidationReport

__all__ = [
    "DEFAULT_DRIVE", "DRIVE_KINDS", "BaseParameters", "ClosedLoopRegressor", "ConsistentFit",
    "Excitation", "FourierSeries", "optimise_excitation",
    "ForceResiduals", "IdentifiabilityError", "IdentificationResult", "MotionData",
    "MotionStates", "ParameterLayout", "StateNoise", "TreeMotion", "TreeRegressorRows", "ValidationReport",
    "base_from_regressor", "closed_loop_regressor_tree", "model_with_parameters",
    "base_parameters", "identify", "identify_from_states", "nominal_parameters",
    "random_states", "regressor", "regressor_batch", "robot_with_parameters",
    "states_from_motion",
]
