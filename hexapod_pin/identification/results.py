"""What a dynamic identification gives: the base-parameter estimates with their standard
errors, the residuals before and after, the physically consistent estimate and the
identified robot, and the validation on held-out data.

Residuals are actuator forces (N or N m): measured minus predicted, ``rms`` over every
sample and actuator, ``rms_per_actuator`` per actuator. "Before": the nominal robot's
parameters (:func:`~.parameters.nominal_parameters`, offsets 0); "after": the
least-squares base parameters.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np
import numpy.typing as npt

from ..core.checks import as_array
from ..core.robot import ClosedLoopRobot
from ..errors import InputError
from .base import BaseParameters
from .consistent import ConsistentFit
from .input_noise import StateNoise
from .motion_data import DEFAULT_TRIM, states_from_motion
from .parameters import robot_with_parameters
from .regressor import ClosedLoopRegressor


@dataclass(frozen=True)
class ForceResiduals:
    """Actuator-force residuals (measured - predicted, N or N m).

    Attributes:
        rms: root mean square over every sample and actuator.
        rms_per_actuator: (n_act,).
        max: largest absolute residual.
        count: number of samples.
    """

    rms: float
    rms_per_actuator: np.ndarray
    max: float
    count: int

    @classmethod
    def of(cls, residual: np.ndarray) -> ForceResiduals:
        """The summary of residuals shaped (N, n_act)."""
        return cls(float(np.sqrt(np.mean(residual ** 2))),
                   np.sqrt(np.mean(residual ** 2, axis=0)),
                   float(np.max(np.abs(residual), initial=0.0)), int(residual.shape[0]))


@dataclass(frozen=True)
class ValidationReport:
    """Predicted against measured actuator forces on held-out data.

    Attributes:
        identified: residuals of the identified base parameters.
        consistent: residuals of the physically consistent estimate (None without one).
        nominal: residuals of the nominal robot.
    """

    identified: ForceResiduals
    consistent: ForceResiduals | None
    nominal: ForceResiduals


@dataclass(frozen=True)
class IdentificationResult:
    """A dynamic identification (:func:`~.estimate.identify_from_states`).

    Attributes:
        robot: the robot identified (its nominal parameters: the "before").
        base: the :class:`~.base.BaseParameters` (structure, names, regrouping).
        values: weighted least-squares estimates of the base parameters (r,)
            (bias-compensated when ``state_noise.compensate``).
        std_errors: their standard errors (r,): square roots of the diagonal of
            ``covariance``.
        covariance: (r, r) for exact states ``s^2 (W_w^T W_w)^-1``, ``W_w`` the weighted
            base regressor, ``s^2`` the weighted residual variance (about 1 when the noise
            model is right); with ``state_noise`` the long-run sandwich of
            :mod:`.input_noise` (item 3).
        noise_std: the per-actuator force noise used as weights (n_act,) (N, N m): given,
            or estimated from the ordinary least-squares residuals.
        nominal_values: the nominal robot's base parameters (r,).
        before: residuals of the nominal robot on the data.
        after: residuals of the estimate on the data.
        condition_number: of the weighted base regressor with unit-norm columns.
        consistent: the physically consistent estimate (None when not asked for).
        cutoff: the filter cut-off used for motion data (Hz; None: the default, or
            states).
        trim: the samples dropped at each end of motion data (None: the default, or
            states).
        input_noise_force: (n_act,) (N, N m) the force errors that the position noise
            (given, or estimated from the data) makes through the filtered accelerations
            (:func:`~.estimate.identify`, :func:`~.estimate.input_noise_force`); None for
            states.
        state_noise: the states' noise used (:class:`~.input_noise.StateNoise`); None:
            exact states, the classical covariance.
        attenuation: the largest share of the weighted data's energy that the
            acceleration noise makes in one direction (:mod:`.input_noise`, item 2);
            None for exact states.
        compensation: (r,) the bias compensation's shift (compensated minus plain
            weighted least squares, the same weights): applied to ``values`` when
            ``state_noise.compensate``, else only the estimated bias of ``values``;
            None for exact states.
        deadband_rows: (n_act,) the rows of each actuator left out inside the Coulomb
            deadband (:mod:`.input_noise`, item 1); None for exact states.
    """

    robot: object
    base: BaseParameters
    values: np.ndarray
    std_errors: np.ndarray
    covariance: np.ndarray
    noise_std: np.ndarray
    nominal_values: np.ndarray
    before: ForceResiduals
    after: ForceResiduals
    condition_number: float
    consistent: ConsistentFit | None
    cutoff: float | None = None
    trim: int | None = DEFAULT_TRIM
    input_noise_force: np.ndarray | None = None
    state_noise: StateNoise | None = None
    attenuation: float | None = None
    compensation: np.ndarray | None = None
    deadband_rows: np.ndarray | None = None
    _cache: dict = field(default_factory=dict, repr=False, compare=False)

    @property
    def names(self) -> tuple[str, ...]:
        """The base parameters' names (:attr:`BaseParameters.names`)."""
        return self.base.names

    @property
    def consistent_values(self) -> np.ndarray | None:
        """The base parameters of the consistent estimate (r,), or None."""
        return None if self.consistent is None else self.base.values(
            self.consistent.parameters)

    @property
    def consistent_gap(self) -> float | None:
        """The largest difference between the consistent estimate's base parameters and
        the least-squares ones, in standard errors (None without a consistent estimate)."""
        cons = self.consistent_values
        if cons is None:
            return None
        return float(np.max(np.abs(cons - self.values) / self.std_errors))

    def table(self) -> str:
        """The estimates as text: name, nominal, estimate, standard error, consistent."""
        lines = [f"{'parameter':<28} {'nominal':>12} {'estimate':>12} {'std error':>10}"
                 + ("" if self.consistent is None else f" {'consistent':>12}")]
        cons = self.consistent_values
        for k, name in enumerate(self.names):
            line = (f"{name:<28} {self.nominal_values[k]:>12.5g} {self.values[k]:>12.5g} "
                    f"{self.std_errors[k]:>10.3g}")
            if cons is not None:
                line += f" {cons[k]:>12.5g}"
            lines.append(line)
        return "\n".join(lines)

    @cached_property
    def identified_robot(self) -> ClosedLoopRobot:
        """The robot with the physically consistent estimate
        (:func:`~.parameters.robot_with_parameters`: a ClosedLoopRobot on a copy of the
        tree, every route of the shared API; offsets are not part of a robot model).

        Raises:
            InputError: the identification had no consistent estimate.
        """
        if self.consistent is None:
            raise InputError("consistent", False, "no physically consistent estimate: "
                             "identify with consistent=True")
        return robot_with_parameters(self.robot, self.consistent.parameters,
                                     self.base.layout.drive)

    def predict(self, poses: npt.ArrayLike, twists: npt.ArrayLike,
                twist_dots: npt.ArrayLike) -> np.ndarray:
        """Actuator forces (N, n_act) of the estimated base parameters at N states."""
        full = ClosedLoopRegressor(self.robot, self.base.layout.drive).batch(
            poses, twists, twist_dots)
        return (self.base.regressor(full) @ self.values).reshape(-1, full.shape[0] //
                                                                 np.asarray(poses).shape[0])

    def validate_states(self, poses: npt.ArrayLike, twists: npt.ArrayLike,
                        twist_dots: npt.ArrayLike,
                        actuator_forces: npt.ArrayLike) -> ValidationReport:
        """Residuals of the estimates and of the nominal robot on held-out states
        (arguments as :func:`~.estimate.identify_from_states`)."""
        reg = ClosedLoopRegressor(self.robot, self.base.layout.drive)
        full = reg.batch(poses, twists, twist_dots)
        forces = as_array(actuator_forces, (reg.n_actuators,), "actuator_forces", batch=True)
        wb = self.base.regressor(full)
        n_act = reg.n_actuators

        def res(beta: np.ndarray) -> ForceResiduals:
            return ForceResiduals.of(forces - (wb @ beta).reshape(-1, n_act))

        cons = self.consistent_values
        return ValidationReport(res(self.values), None if cons is None else res(cons),
                                res(self.nominal_values))

    def validate(self, data: object) -> ValidationReport:
        """:meth:`validate_states` on a held-out :class:`~.motion_data.MotionData`,
        processed as the identification's data were (the same cut-off and trim)."""
        st = states_from_motion(self.robot, data, self.cutoff, self.trim)
        return self.validate_states(st.poses, st.twists, st.twist_dots, st.actuator_forces)
