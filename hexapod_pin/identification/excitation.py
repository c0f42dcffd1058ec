"""Excitation trajectories for dynamic identification: a finite Fourier series in the
robot's pose space, optimised for the condition number of the base regressor within the
robot's limits.

The motion (Swevers et al. 1997), per pose component ``j`` (m or rad), with ``w = 2 pi
f0`` and ``H`` harmonics::

    pose_j(t) = centre_j + sum_k a_jk sin(k w t) + b_jk (cos(k w t) - 1),   k = 1 .. H

periodic with period ``1 / f0``. It starts and ends at the centre pose, and at rest:
``sum_k k a_jk = 0`` (velocity) and ``sum_k k^2 b_jk = 0`` (acceleration) hold by
construction (the coefficients are ``Z x``, ``Z`` an orthonormal basis of the null space
of those two rows; ``H >= 2``). Twists are world-axis: ``v = d(x, y, z)/dt`` and, for a
pose with all three angles, ``w = E(rpy) d(rpy)/dt`` with ``E`` of
:func:`hexapod_pin.core.pose.euler_rates_matrix` (``dw/dt = E d2(rpy)/dt2 + dE/dt
d(rpy)/dt``); a single angle's rate otherwise.

The optimisation (:func:`optimise_excitation`, ``scipy.optimize.minimize``, SLSQP with
finite-difference gradients, step :data:`FD_STEP`): minimise ``log10 cond(W_b D^-1)``,
the condition number of the stacked base regressor (:mod:`.regressor`, :mod:`.base`) at
``samples`` equally spaced times of one period (``(i + 1/2) / (samples f0)``: none at the
rest points, where the Coulomb column ``sign(qd)`` jumps), with unit-norm columns (``D`` the column norms: a condition number
free of the parameters' units), subject to, at every sample:

* the pose reached, regularly (the regressor's tree state exists) and within the strokes
  (``robot.stroke_violations`` of the actuator positions);
* both singularity measures (``robot.singularity``) at least ``singularity_margin``
  times the robot's own thresholds;
* the actuator forces of the nominal robot (``W pi_nominal``, its inverse dynamics with
  its drive effects, :mod:`.regressor`) within ``force_margin`` of the robot's force
  bounds (:func:`hexapod_pin.core.workspace_maps.actuator_force_bounds`);

the coefficients within ``+- amplitude`` (scaled per component, linear / angular).
The reach and stroke condition is not smooth: the constraint is -1 at a sample that
fails it, and the line search steps back.

Verification before it is returned: the optimised series is sampled at
``check_factor`` (default 10) times the optimisation's rate and checked by the
library's feasibility check (:func:`hexapod_pin.planning.feasibility.check_feasibility`:
forces and strokes) and the singularity measures (at least the robot's own thresholds).
Where the denser check fails, the coefficients are scaled down by :data:`SHRINK` until it
passes (the result says how often); a start that fails it is refused
(:class:`~hexapod_pin.errors.SolverError`).
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
import numpy.typing as npt
import scipy.linalg
import scipy.optimize

from ..core.checks import as_array, count, real_number
from ..core.pose import euler_rates_matrix
from ..core.robot_api import ParallelRobot, pose_layout
from ..core.workspace_maps import Progress, actuator_force_bounds
from ..errors import ArgumentTypeError, HexapodPinError, InputError, SolverError
from ..motion import Motion, write_motion
from ..planning.feasibility import check_feasibility
from ..planning.limits import Limits
from .base import BaseParameters, base_parameters
from .parameters import DEFAULT_DRIVE, nominal_parameters
from .regressor import ClosedLoopRegressor

#: the coefficients are scaled by this factor while the denser check fails
SHRINK = 0.8
#: the most shrinks before the optimisation is refused
MAX_SHRINKS = 30
#: finite-difference step of the gradients, in the coefficients scaled by ``amplitude``
FD_STEP = 1e-6


@dataclass(frozen=True)
class FourierSeries:
    """A pose-space Fourier series (module docstring).

    Attributes:
        centre: (dim,) the centre pose (m, rad), the robot's pose axes.
        base_frequency: ``f0`` (Hz); the period is ``1 / f0``.
        sine: (H, dim) ``a_jk`` (row ``k - 1``) (m, rad).
        cosine: (H, dim) ``b_jk`` (m, rad).
        full_rotation: the pose has roll, pitch and yaw (twists through ``E(rpy)``).
        angular: (dim,) bool, the angular components.
    """

    centre: np.ndarray
    base_frequency: float
    sine: np.ndarray
    cosine: np.ndarray
    full_rotation: bool
    angular: np.ndarray

    @property
    def period(self) -> float:
        """One period (s)."""
        return 1.0 / self.base_frequency

    def evaluate(self, times: npt.ArrayLike) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(poses, twists, twist_dots)`` (N, dim) each at ``times`` (N,) (s)."""
        t = np.asarray(times, dtype=float).reshape(-1)
        w = 2.0 * np.pi * self.base_frequency
        k = np.arange(1, self.sine.shape[0] + 1)
        phase = np.outer(t, k * w)
        s, c = np.sin(phase), np.cos(phase)
        kw = k * w
        pos = self.centre + s @ self.sine + (c - 1.0) @ self.cosine
        vel = (c * kw) @ self.sine - (s * kw) @ self.cosine
        acc = -(s * kw ** 2) @ self.sine - (c * kw ** 2) @ self.cosine
        if not self.full_rotation:
            return pos, vel, acc
        ang = np.flatnonzero(self.angular)
        rpy, rates, rates_dot = pos[:, ang], vel[:, ang], acc[:, ang]
        emat = euler_rates_matrix(rpy)
        twist, twist_dot = vel.copy(), acc.copy()
        twist[:, ang] = np.einsum("nij,nj->ni", emat, rates)
        twist_dot[:, ang] = np.einsum("nij,nj->ni", emat, rates_dot) + \
            np.einsum("nij,nj->ni", _euler_rates_derivative(rpy, rates), rates)
        return pos, twist, twist_dot


def _euler_rates_derivative(rpy: np.ndarray, rates: np.ndarray) -> np.ndarray:
    """``dE/dt`` (N, 3, 3) of :func:`~hexapod_pin.core.pose.euler_rates_matrix`."""
    cp, sp = np.cos(rpy[:, 1]), np.sin(rpy[:, 1])
    cy, sy = np.cos(rpy[:, 2]), np.sin(rpy[:, 2])
    dp, dy = rates[:, 1], rates[:, 2]
    out = np.zeros((rpy.shape[0], 3, 3))
    out[:, 0, 0] = -sy * dy * cp - cy * sp * dp
    out[:, 1, 0] = cy * dy * cp - sy * sp * dp
    out[:, 2, 0] = -cp * dp
    out[:, 0, 1] = -cy * dy
    out[:, 1, 1] = -sy * dy
    return out


@dataclass(frozen=True)
class Excitation:
    """An optimised excitation trajectory (module docstring), sampled at the rate of the
    optimisation.

    Attributes:
        robot: the robot it was optimised for (the nominal model).
        series: the :class:`FourierSeries`.
        times: (N,) the samples of one period (s), ``(i + 1/2) / (N f0)``.
        poses: (N, dim) platform poses (m, rad).
        twists: (N, dim) their twists (world axes, m/s, rad/s).
        twist_dots: (N, dim) the twists' time derivatives.
        actuator_positions: (N, n_act) (m or rad).
        actuator_forces: (N, n_act) of the nominal robot (N or N m).
        condition_number: of the base regressor at the samples (unit-norm columns).
        initial_condition_number: the same at the start of the optimisation.
        iterations: SLSQP iterations.
        shrinks: how often the coefficients were scaled down by :data:`SHRINK` for the
            denser check.
        check_factor: the denser check's rate, a multiple of the samples'.
        base: the base parameters used.
    """

    robot: object
    series: FourierSeries
    times: np.ndarray
    poses: np.ndarray
    twists: np.ndarray
    twist_dots: np.ndarray
    actuator_positions: np.ndarray
    actuator_forces: np.ndarray
    condition_number: float
    initial_condition_number: float
    iterations: int
    shrinks: int
    check_factor: int
    base: BaseParameters

    def motion(self, rate_factor: int = 1, periods: int = 1) -> Motion:
        """The trajectory as a :class:`~hexapod_pin.motion.Motion` (poses, twists, their
        derivatives, actuator positions and nominal forces) sampled at ``rate_factor``
        times the samples' rate over ``periods`` periods, from rest at ``t = 0`` to rest
        at the end (both ends included).

        Raises:
            InputError: bad ``rate_factor`` or ``periods``.
        """
        rate_factor = count(rate_factor, "rate_factor")
        periods = count(periods, "periods")
        n = self.times.size * rate_factor * periods
        t = np.arange(n + 1) * (self.series.period / (self.times.size * rate_factor))
        return sampled_motion(self.robot, self.series, t)

    def write(self, path: str | Path, rate_factor: int = 1, periods: int = 1) -> Path:
        """Write :meth:`motion` as a motion file (.csv or .json,
        :func:`hexapod_pin.motion.write_motion`); returns the path."""
        return write_motion(path, self.motion(rate_factor, periods),
                            self.robot)   # type: ignore[arg-type]


def sampled_motion(robot: object, series: FourierSeries, times: np.ndarray) -> Motion:
    """The series at ``times`` as a :class:`~hexapod_pin.motion.Motion` with the actuator
    positions and the nominal robot's forces (``bounded=False``).

    Raises:
        BatchUnreachablePoseError: a pose out of reach (the robot's batch error).
        BatchSingularityError: a singular pose (the robot's batch error).
    """
    bot: ParallelRobot = robot   # type: ignore[assignment]
    poses, twists, twist_dots = series.evaluate(times)
    q = bot.inverse_kinematics_batch(poses).actuator_positions
    forces = bot.inverse_dynamics_batch(poses, twists, twist_dots,
                                        bounded=False).actuator_forces
    return Motion(times, poses, twists, twist_dots, q=q, actuator_forces=forces)


def _null_basis(harmonics: int) -> np.ndarray:
    """``Z`` (2H, 2H - 2): the coefficient vectors ``(a_1..a_H, b_1..b_H)`` with zero
    velocity and acceleration at ``t = 0``."""
    k = np.arange(1, harmonics + 1, dtype=float)
    rows = np.zeros((2, 2 * harmonics))
    rows[0, :harmonics] = k
    rows[1, harmonics:] = k ** 2
    return scipy.linalg.null_space(rows)


class _Problem:
    """The optimisation's functions, sharing one pass over the samples per point: the
    regressor's tree state (it refuses a pose out of reach or singular), the actuator
    positions read from it (strokes), the singularity measures, and the nominal forces
    ``W pi_nominal`` (the robot's inverse dynamics, :mod:`.regressor`)."""

    def __init__(self, robot: ParallelRobot, reg: ClosedLoopRegressor, base: BaseParameters,
                 make: Callable[[np.ndarray], FourierSeries], times: np.ndarray,
                 singularity_margin: float, force_margin: float) -> None:
        self.robot, self.reg, self.base, self.make = robot, reg, base, make
        self.times = times
        self.sing_margin = singularity_margin
        self.bound = actuator_force_bounds(robot) * (1.0 - force_margin)
        self.nominal = nominal_parameters(robot, reg.layout.drive)
        self._key: bytes | None = None
        self._value: tuple[float, np.ndarray] = (0.0, np.zeros(0))

    def rows(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``(W, margins)``: the full regressor (N n_act, n) and per sample the smallest
        of the reach / stroke (-1 or 1), singularity (log10 of the measure over the
        margin times the threshold) and force (``1 - |u| / bound``) margins; ``W`` is
        empty when a sample fails the reach, stroke or singularity test."""
        poses, twists, twist_dots = self.make(x).evaluate(self.times)
        n, m = poses.shape[0], self.reg.n_actuators
        out = np.full(n, 1.0)
        full = np.empty((n * m, self.reg.layout.size))
        for i in range(n):
            try:
                motion = self.reg.tree_motion(poses[i], twists[i], twist_dots[i])
            except HexapodPinError:
                out[i] = -1.0
                continue
            if self.robot.stroke_violations(   # type: ignore[attr-defined]
                    self.robot.actuator_positions(motion.q)):
                out[i] = -1.0
                continue
            meas = self.robot.singularity(poses[i])
            for value, threshold in ((meas.type_one, meas.type_one_threshold),
                                     (meas.type_two, meas.type_two_threshold)):
                if threshold > 0:
                    out[i] = min(out[i], np.log10(max(value, 1e-300)
                                                  / (self.sing_margin * threshold)))
            full[i * m:(i + 1) * m] = self.reg.rows_of(motion)
        if np.any(out < 0):
            return np.zeros((0, self.reg.layout.size)), out
        finite = np.isfinite(self.bound)
        if np.any(finite):
            u = (full @ self.nominal).reshape(n, m)
            out = np.minimum(out, 1.0 - np.max(np.abs(u[:, finite]) / self.bound[finite],
                                               axis=1))
        return full, out

    def condition(self, full: np.ndarray) -> float:
        """Condition number of the base columns of ``full`` with unit-norm columns."""
        wb = self.base.regressor(full)
        norms = np.linalg.norm(wb, axis=0)
        sv = np.linalg.svd(wb / np.where(norms > 0, norms, 1.0), compute_uv=False)
        return float(sv[0] / sv[-1]) if sv[-1] > 0 else np.inf

    def evaluate(self, x: np.ndarray) -> tuple[float, np.ndarray]:
        """``(log10 condition number, margins)`` at ``x`` (the objective 10 where a
        margin fails)."""
        key = x.tobytes()
        if key != self._key:
            full, margins = self.rows(x)
            objective = float(np.log10(self.condition(full))) if full.size else 10.0
            self._key, self._value = key, (objective, margins)
        return self._value


def optimise_excitation(robot: object, *, harmonics: int = 3, base_frequency: float = 0.5,
                        samples: int = 60, amplitude: tuple[float, float] = (0.02, 0.1),
                        centre: npt.ArrayLike | None = None,
                        drive: object = DEFAULT_DRIVE, base: BaseParameters | None = None,
                        singularity_margin: float = 2.0, force_margin: float = 0.05,
                        check_factor: int = 10, max_iterations: int = 30, seed: int = 0,
                        progress: Progress | None = None) -> Excitation:
    """An excitation trajectory optimised for the base regressor's condition number
    within the robot's limits (module docstring).

    Args:
        robot: a robot of the library (the nominal model).
        harmonics: ``H`` (>= 2).
        base_frequency: ``f0`` (Hz, > 0).
        samples: samples per period of the optimisation (``samples n_act`` should exceed
            the base parameters severalfold).
        amplitude: bound of every coefficient, (linear m, angular rad).
        centre: (dim,) the centre pose (default: the robot's home pose).
        drive: the drive parameters of the regressor (:data:`~.parameters.DRIVE_KINDS`).
        base: the base parameters (default: :func:`~.base.base_parameters`).
        singularity_margin: both singularity measures at least this times the robot's
            thresholds at every sample (>= 1).
        force_margin: the forces within ``1 - force_margin`` of the force bounds at the
            samples (0 <= margin < 1; the denser check uses the full bounds).
        check_factor: the verification's rate, a multiple of the samples' (>= 1).
        max_iterations: SLSQP iterations at most.
        seed: the random start's seed (coefficients drawn, scaled down until feasible).
        progress: ``callable(fraction)`` called after each iteration and at the end.

    Raises:
        ArgumentTypeError: not a robot of the library; ``progress`` not callable.
        InputError: bad options or ``centre``.
        SolverError: no feasible start (the centre itself fails a limit), or the
            optimised trajectory fails the denser check even scaled down.
    """
    reg = ClosedLoopRegressor(robot, drive)
    bot: ParallelRobot = robot   # type: ignore[assignment]
    harmonics = count(harmonics, "harmonics", minimum=2)
    f0 = real_number(base_frequency, "base_frequency", minimum=0.0)
    samples = count(samples, "samples", minimum=2)
    check_factor = count(check_factor, "check_factor")
    max_iterations = count(max_iterations, "max_iterations")
    singularity_margin = real_number(singularity_margin, "singularity_margin", minimum=1.0,
                                     strict=False)
    force_margin = real_number(force_margin, "force_margin", minimum=0.0, strict=False)
    if not force_margin < 1.0:
        raise InputError("force_margin", force_margin, "expected 0 <= force_margin < 1")
    if progress is not None and not callable(progress):
        raise ArgumentTypeError("progress", progress, "expected a callable(fraction) or None")
    amp = as_array(amplitude, (2,), "amplitude")
    if not np.all(amp > 0):
        raise InputError("amplitude", amplitude, "expected two positive bounds")
    dim = reg.dim
    layout = pose_layout(bot)
    angular = np.zeros(dim, dtype=bool)
    angular[np.asarray(layout.angular, dtype=int)] = True
    centre_pose = np.asarray(bot.home_pose, dtype=float) if centre is None \
        else as_array(centre, (dim,), "centre")
    base = base_parameters(robot, reg.layout.drive) if base is None else base
    if not isinstance(base, BaseParameters) or base.layout != reg.layout:
        raise InputError("base", base, "expected the BaseParameters of this robot and drive")
    scale = np.where(angular, amp[1], amp[0])
    basis = _null_basis(harmonics)
    n_free = basis.shape[1]

    def make(x: np.ndarray) -> FourierSeries:
        coeffs = basis @ x.reshape(n_free, dim) * scale          # (2H, dim)
        return FourierSeries(centre_pose, f0, coeffs[:harmonics], coeffs[harmonics:],
                             layout.full_rotation, angular)

    times = (np.arange(samples) + 0.5) / (samples * f0)   # not at rest (t = 0): the
    # Coulomb column sign(qd) jumps there
    problem = _Problem(bot, reg, base, make, times, singularity_margin, force_margin)
    x0 = np.random.default_rng(count(seed, "seed", minimum=0)).uniform(-0.5, 0.5,
                                                                        n_free * dim)
    x0 = _feasible_start(problem, x0)
    initial = 10.0 ** problem.evaluate(x0)[0]
    state = {"iterations": 0}

    def step(_: np.ndarray) -> None:
        state["iterations"] += 1
        if progress is not None:
            progress(min(state["iterations"] / max_iterations, 1.0))

    sol = scipy.optimize.minimize(
        lambda x: problem.evaluate(x)[0], x0, method="SLSQP",
        bounds=[(-1.0, 1.0)] * x0.size,
        constraints=[{"type": "ineq", "fun": lambda x: problem.evaluate(x)[1]}],
        options={"maxiter": max_iterations, "ftol": 1e-4, "eps": FD_STEP}, callback=step)
    best = sol.x if np.all(problem.evaluate(sol.x)[1] >= 0) and \
        problem.evaluate(sol.x)[0] <= problem.evaluate(x0)[0] else x0
    dense = np.arange(samples * check_factor + 1) / (samples * check_factor * f0)
    shrinks = 0
    while not _dense_ok(bot, make(best), dense):
        if shrinks >= MAX_SHRINKS:
            raise SolverError("excitation", "infeasible", f"the trajectory fails the "
                              f"check at {check_factor}x the sampling rate even scaled by "
                              f"{SHRINK ** shrinks:.3g}")
        best, shrinks = best * SHRINK, shrinks + 1
    series = make(best)
    poses, twists, twist_dots = series.evaluate(times)
    motion = sampled_motion(bot, series, times)
    cond = problem.condition(reg.batch(poses, twists, twist_dots))
    if progress is not None:
        progress(1.0)
    return Excitation(robot, series, times, poses, twists, twist_dots, np.asarray(motion.q),
                      np.asarray(motion.actuator_forces), cond, float(initial),
                      int(state["iterations"]), shrinks, check_factor, base)


def _feasible_start(problem: _Problem, x0: np.ndarray) -> np.ndarray:
    """``x0`` scaled down by halves until every sample meets the limits."""
    for _ in range(40):
        if np.all(problem.evaluate(x0)[1] >= 0):
            return x0
        x0 = 0.5 * x0
    raise SolverError("excitation", "infeasible", "no feasible start: even a tiny motion "
                      "about the centre pose fails a limit (reach, stroke, singularity "
                      "margin or force)")


def _dense_ok(robot: ParallelRobot, series: FourierSeries, times: np.ndarray) -> bool:
    """The series at ``times`` passes the feasibility check (reach, strokes, force bounds)
    and the robot's own singularity thresholds."""
    poses, twists, twist_dots = series.evaluate(times)
    try:
        report = check_feasibility(robot, Motion(times, poses, twists, twist_dots),
                                   limits=Limits(strokes=True))
    except HexapodPinError:
        return False
    return report.feasible and all(robot.singularity(p).regular for p in poses)
