"""Estimation of the base parameters from measured states and actuator forces.

Weighted least squares (Gautier's method):

1. the full regressor ``W`` (N n_act, n) of the states (:mod:`.regressor`) and its base
   columns ``W_b`` (the robot's :func:`~.base.base_parameters`, found on random states,
   or given); the data must determine every base parameter: the numerical rank of
   ``W_b`` with unit-norm columns (singular values above :data:`DATA_RTOL` of the
   largest) must be ``r``, else :class:`~hexapod_pin.errors.IdentifiabilityError` names
   the base parameters of the undetermined directions;
2. per-actuator noise ``sigma_i``: given (``noise_std``), or from the least-squares
   residuals of each actuator, ``sigma_i^2 = |e_i|^2 / (N - r / n_act)``: ordinary least
   squares first, then re-weighted with the estimate (:data:`NOISE_ITERATIONS` solves in
   all: a noisy actuator's residual leaks into the others' through the fit);
3. the rows of actuator ``i`` divided by ``sigma_i``: ``beta = argmin |W_w beta - u_w|``
   (column-scaled, by SVD), solved on the data reduced once per actuator
   (:class:`ActuatorFactors`: the QR ``W_i = Q_i R_i`` of actuator ``i``'s rows, in chunks,
   and ``c_i = Q_i^T u_i``; ``|W_w beta - u_w|^2 = sum_i (|R_i beta - c_i|^2 + rho_i^2) /
   sigma_i^2``, so every solve and the covariance below use the (n_act r, r) stack
   ``[R_i / sigma_i]`` and give what the full (N n_act, r) matrix gives), covariance ``s^2 (W_w^T W_w)^-1`` with ``s^2 = |e_w|^2 /
   (N n_act - r)`` (the weights' scale re-estimated: standard errors stay right when the
   given noise levels are off by a common factor), standard errors its diagonal's roots;
4. the physically consistent estimate of the full parameters (:mod:`.consistent`) on
   the same weighted data, started from the nominal robot, and verified: besides the
   fit's own checks, the identified robot's mass matrix in actuator coordinates at home,
   ``M_a = G^T (M + diag(armature)) G`` (``G`` the actuated velocity map of
   :mod:`.regressor`), must be within a factor :data:`MASS_MATRIX_RATIO` of the nominal
   robot's in every direction (every generalised eigenvalue of the pair in
   ``[1 / ratio, ratio]``), else :class:`~hexapod_pin.errors.SolverError`. Its distance
   from the least-squares base parameters (``consistent_gap`` of the result, in standard
   errors) above :data:`GAP_WARNING` is logged as a warning (logger
   ``hexapod_pin.identification.estimate``).

With the states' noise (``state_noise``, :class:`~.input_noise.StateNoise`: states
differentiated from noisy positions) three steps change (:mod:`.input_noise`): the rows
inside the Coulomb deadband are left out (steps 2 - 4 count the rows kept); the solve
of step 3 is bias-compensated, ``(W_w^T W_w - B) beta = W_w^T u_w``, its inverse taken
from the generalised eigenvectors of ``(B, W_w^T W_w)``; and the covariance is the
sandwich ``H^-1 S H^-1`` with the long-run covariance ``S`` of the per-sample scores,
which needs no noise level (the weights only set the efficiency). The consistent fit of
step 4 then uses ``H`` in place of ``W_w^T W_w``.

:func:`identify` runs the same on a :class:`~.motion_data.MotionData` (positions and
forces in time) after :func:`~.motion_data.states_from_motion`, with the states' noise
of the position noise, given or estimated (:func:`identify`).
"""

from __future__ import annotations

import dataclasses
import logging
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import pinocchio as pin
import scipy.linalg

from ..core.checks import as_array, bounds, count, flag, real_number
from ..errors import IdentifiabilityError, InputError, SolverError
from .base import BaseParameters, base_parameters
from .consistent import PRIOR_WEIGHT, consistent_fit
from .input_noise import (
    ATTENUATION_WARNING,
    COMPENSATION_CAP,
    COMPENSATION_WARNING,
    StateNoise,
    acceleration_sensitivities,
    actuator_velocities,
    attenuation_terms,
    coulomb_rows,
    long_run_covariance,
    position_noise,
    score_correction,
    sensitivity_rows,
)
from .motion_data import (
    DEFAULT_TRIM,
    check_motion,
    derivative_noise_gain,
    position_noise_estimate,
    resolve_cutoff,
    resolve_trim,
    states_from_motion,
)
from .parameters import DEFAULT_DRIVE, nominal_parameters, tree_with_parameters
from .regressor import ClosedLoopRegressor
from .results import ForceResiduals, IdentificationResult

#: estimates of the per-actuator noise: ordinary least squares, then re-weighted
NOISE_ITERATIONS = 3
#: relative singular-value threshold of the data's base regressor (unit-norm columns)
DATA_RTOL = 1e-10
#: a consistent estimate farther than this from the least-squares one (in standard errors
#: of a base parameter) is logged as a warning (the least-squares estimate is then not
#: physically consistent, or the data do not fit the model)
GAP_WARNING = 3.0
LOGGER = logging.getLogger(__name__)
#: :func:`identify` warns, when the position noise is not given, where the force errors
#: that the estimated noise makes exceed this fraction of the force noise (the
#: acceleration noise grows as ``cutoff^2.5``: 0.2 kept the plain estimates' bias within
#: their standard errors in the measured cases of docs/tutorials/identification.md)
INPUT_NOISE_WARNING = 0.2
#: :func:`identify` warns, when the position noise is not given, where the bias that the
#: estimated noise makes (the shift its compensation would make) exceeds this many
#: standard errors of an estimate
BIAS_WARNING = 1.0
#: :func:`identify` warns when the positions' content above the cut-off exceeds the
#: position noise given by this factor
NOISE_MISMATCH = 1.5
#: rows per QR of :class:`ActuatorFactors` (bounds its memory)
CHUNK_ROWS = 20_000
#: the identified robot's actuator-space mass matrix must be within this factor of the
#: nominal one in every direction (module docstring, step 4)
MASS_MATRIX_RATIO = 100.0


def _check_base(base: object, reg: ClosedLoopRegressor) -> BaseParameters:
    if not isinstance(base, BaseParameters):
        raise InputError("base", base, "expected BaseParameters (base_parameters(robot))")
    if base.layout != reg.layout:
        raise InputError("base", base, f"its layout {base.layout.drive} does not match "
                         f"the robot and drive {reg.layout.drive}")
    return base


@dataclass(frozen=True)
class ActuatorFactors:
    """The data of least squares reduced per actuator (module docstring, step 3): the
    economic QR ``W_i = Q_i R_i`` of actuator ``i``'s rows of the base regressor (its
    rows ``i, i + n_act, ...``), with ``c_i = Q_i^T u_i`` and ``rho_i^2 = |u_i - Q_i
    c_i|^2``, so that ``|W_i beta - u_i|^2 = |R_i beta - c_i|^2 + rho_i^2`` for every
    ``beta``. Every weighted solve then works on the ``(n_act r, r)`` stack.

    Attributes:
        r: (n_act, r, r) the triangular factors.
        c: (n_act, r) the projected forces.
        rho2: (n_act,) the squared residuals outside the columns' span.
        rows: the number of rows of the full problem (``N n_act`` less those left out).
        counts: (n_act,) the rows of each actuator.
    """

    r: np.ndarray
    c: np.ndarray
    rho2: np.ndarray
    rows: int
    counts: np.ndarray

    @classmethod
    def of(cls, wb: np.ndarray, u: np.ndarray, n_act: int,
           keep: np.ndarray | None = None) -> ActuatorFactors:
        """The factors of the base regressor ``wb`` (N n_act, r) and forces ``u`` (N n_act,),
        sample-major, one actuator at a time in chunks of :data:`CHUNK_ROWS` rows (the
        factor of ``[R; next chunk]`` at each step: memory of one chunk); only the rows
        where ``keep`` (N, n_act) is True, when given."""
        r = wb.shape[1]
        facs, cs, rho2 = np.zeros((n_act, r, r)), np.zeros((n_act, r)), np.zeros(n_act)
        counts = np.zeros(n_act, dtype=int)
        for i in range(n_act):
            rows_i, u_i = wb[i::n_act], u[i::n_act]
            if keep is not None:
                rows_i, u_i = rows_i[keep[:, i]], u_i[keep[:, i]]
            counts[i] = rows_i.shape[0]
            for start in range(0, rows_i.shape[0], CHUNK_ROWS):
                block = np.vstack([facs[i], rows_i[start:start + CHUNK_ROWS]])
                rhs = np.concatenate([cs[i], u_i[start:start + CHUNK_ROWS]])
                q_mat, facs[i] = scipy.linalg.qr(block, mode="economic")  # block: >= r rows
                cs[i] = q_mat.T @ rhs
                rho2[i] += float(np.sum((rhs - q_mat @ cs[i]) ** 2))
        return cls(facs, cs, rho2, int(np.sum(counts)), counts)

    def stacked(self, sigma: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """``([R_i / sigma_i], [c_i / sigma_i])`` ((n_act r, r), (n_act r,)): the weighted
        problem, reduced."""
        return ((self.r / sigma[:, None, None]).reshape(-1, self.r.shape[2]),
                (self.c / sigma[:, None]).reshape(-1))

    def residuals2(self, beta: np.ndarray) -> np.ndarray:
        """``|W_i beta - u_i|^2`` (n_act,) per actuator."""
        return np.sum((self.r @ beta - self.c) ** 2, axis=1) + self.rho2


def _data_rank(factors: ActuatorFactors, names: tuple[str, ...]) -> None:
    mat = factors.stacked(np.ones(factors.r.shape[0]))[0]
    scaled = mat / np.maximum(np.linalg.norm(mat, axis=0), np.finfo(float).tiny)
    _, sv, vt = np.linalg.svd(scaled, full_matrices=False)
    rank = int(np.sum(sv > DATA_RTOL * sv[0])) if sv.size else 0
    if rank < mat.shape[1]:
        combos = []
        for row in vt[rank:][:5]:
            top = np.argsort(-np.abs(row))[:3]
            combos.append(" ".join(f"{row[j]:+.2g} {names[j]}" for j in top))
        raise IdentifiabilityError("the data do not excite every base parameter "
                                   "(too few samples or too little motion)", mat.shape[1],
                                   rank, combos)


def actuator_mass_matrix(reg: ClosedLoopRegressor, parameters: np.ndarray) -> np.ndarray:
    """``M_a = G^T (M + diag(armature)) G`` (n_act, n_act) (kg or kg m^2) at the robot's
    home pose of the robot with the full parameters ``parameters`` (layout of ``reg``;
    the model's armature on the actuated coordinates replaced by the parameters' when
    the layout has armature)."""
    clm = reg.clm
    home = np.asarray(getattr(reg.robot, "home_pose"), dtype=float)
    rest = np.zeros(reg.dim)
    motion = reg.tree_motion(home, rest, rest)
    tree = tree_with_parameters(clm, parameters)
    mass = np.array(pin.crba(tree, tree.createData(), motion.q))
    mass = np.triu(mass) + np.triu(mass, 1).T
    armature = np.array(clm.effects.armature, dtype=float)
    if "armature" in reg.layout.drive:
        armature[clm.actuated_v] = parameters[reg.layout.drive_slice("armature")]
    gmap = motion.actuated_map
    return gmap.T @ (mass + np.diag(armature)) @ gmap


def _verify_mass_matrix(reg: ClosedLoopRegressor, nominal: np.ndarray,
                        identified: np.ndarray) -> None:
    ratios = scipy.linalg.eigvalsh(actuator_mass_matrix(reg, identified),
                                   actuator_mass_matrix(reg, nominal))
    if not (np.all(np.isfinite(ratios)) and ratios[0] >= 1.0 / MASS_MATRIX_RATIO
            and ratios[-1] <= MASS_MATRIX_RATIO):
        raise SolverError("consistent fit", "unverified", "the identified robot's mass "
                          "matrix at home is off the nominal one by the factors "
                          f"{ratios[0]:.3g} .. {ratios[-1]:.3g} (allowed "
                          f"{1.0 / MASS_MATRIX_RATIO:g} .. {MASS_MATRIX_RATIO:g})")


def _solve(mat: np.ndarray, rhs: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """``(x, (A^T A)^-1, condition)`` of column-scaled least squares (``A`` the reduced
    stack of :meth:`ActuatorFactors.stacked`: the same normal matrix as the full one)."""
    norms = np.linalg.norm(mat, axis=0)
    u_mat, sv, vt = np.linalg.svd(mat / norms, full_matrices=False)
    y = vt.T @ ((u_mat.T @ rhs) / sv)
    inv = (vt.T / sv ** 2) @ vt
    return y / norms, inv / np.outer(norms, norms), float(sv[0] / sv[-1])


def _solve_compensated(mat: np.ndarray, rhs: np.ndarray, correction: np.ndarray
                       ) -> tuple[np.ndarray, np.ndarray, np.ndarray, float]:
    """``(x, H^-1, H, attenuation)`` of the bias-compensated normal equations ``H x = A^T
    rhs`` (:mod:`.input_noise`, item 2), column-scaled: with ``B V = A^T A V diag(l)``,
    ``V^T A^T A V = I`` (``l`` the shares of the noise in the data's energy), ``H = A^T A
    - B_c``, ``B_c`` = ``B`` with ``l`` capped at
    :data:`~.input_noise.COMPENSATION_CAP`, so ``H^-1 = V diag(1 / (1 - min(l, cap)))
    V^T``; the attenuation is ``max(l)``."""
    normal = mat.T @ mat
    norms = np.sqrt(np.diag(normal))
    outer = np.outer(norms, norms)
    try:
        shares, vec = scipy.linalg.eigh(correction / outer, normal / outer)
    except (np.linalg.LinAlgError, ValueError) as exc:
        raise IdentifiabilityError(f"the normal matrix of the compensated fit is not "
                                   f"positive definite ({exc}): the data do not excite "
                                   "every base parameter", mat.shape[1],
                                   int(np.linalg.matrix_rank(mat))) from None
    kept = 1.0 - np.minimum(shares, COMPENSATION_CAP)
    inv = (vec / kept) @ vec.T
    back = np.linalg.inv(vec)                    # H = V^-T diag(kept) V^-1
    h = (back.T * kept) @ back
    return ((inv @ ((mat.T @ rhs) / norms)) / norms, inv / outer, h * outer,
            float(shares[-1]))


@dataclass(frozen=True)
class _Fit:
    """One weighted solve: the estimate and the inverse of its normal matrix (``H^-1``
    when compensated), the plain estimate (the same weights, no compensation), the
    condition number, and with the attenuation terms: the compensated estimate, the
    attenuation and ``H``."""

    beta: np.ndarray
    inv: np.ndarray
    plain: np.ndarray
    condition: float
    compensated: np.ndarray | None = None
    attenuation: float | None = None
    normal: np.ndarray | None = None


def _weighted_fit(factors: ActuatorFactors, sigma: np.ndarray, parts: np.ndarray | None,
                  compensate: bool) -> _Fit:
    """Weighted least squares with the weights ``1 / sigma_i^2``; with ``parts``
    (:func:`~.input_noise.attenuation_terms`) also bias-compensated by ``B = sum_i
    parts_i / sigma_i^2`` (:func:`_solve_compensated`), the estimate when
    ``compensate``."""
    rw, cw = factors.stacked(sigma)
    beta, inv, cond = _solve(rw, cw)
    if parts is None:
        return _Fit(beta, inv, beta, cond)
    comp, inv_h, normal, attenuation = _solve_compensated(
        rw, cw, np.einsum("ipq,i->pq", parts, sigma ** -2.0))
    if compensate:
        return _Fit(comp, inv_h, beta, cond, comp, attenuation, normal)
    return _Fit(beta, inv, beta, cond, comp, attenuation)


def _noise_levels(factors: ActuatorFactors, parts: np.ndarray | None, compensate: bool,
                  u: np.ndarray) -> np.ndarray:
    """The per-actuator noise ``sigma_i`` from the residuals (module docstring, step 2),
    each fit compensated when ``compensate``."""
    n_act, r = factors.r.shape[0], factors.r.shape[1]
    sigma = np.ones(n_act)
    for _ in range(NOISE_ITERATIONS):       # OLS, then re-weighted
        beta_it = _weighted_fit(factors, sigma, parts, compensate).beta
        sigma = np.sqrt(factors.residuals2(beta_it)
                        / np.maximum(factors.counts - r / n_act, 1.0))
        sigma = np.maximum(sigma, 1e-12 * max(float(np.max(np.abs(u))), 1e-300))
    return sigma


def _check_state_noise(value: object, n_act: int) -> StateNoise:
    if not isinstance(value, StateNoise):
        raise InputError("state_noise", value, "expected a StateNoise (or None)")
    for name in ("position_std", "velocity_std", "acceleration_std"):
        arr = np.asarray(getattr(value, name), dtype=float)
        if arr.shape != (n_act,) or not np.all(np.isfinite(arr) & (arr >= 0)):
            raise InputError(f"state_noise.{name}", arr, f"expected {n_act} finite values "
                             ">= 0")
    band = real_number(value.band, "state_noise.band", minimum=0.0)
    if band > 1.0:
        raise InputError("state_noise.band", band, "expected 0 < band <= 1")
    count(value.stride, "state_noise.stride")
    return value


@dataclass(frozen=True)
class _NoiseTerms:
    """What the states' noise adds to a fit (:mod:`.input_noise`): the rows outside the
    Coulomb deadband ``keep`` (N, n_act), the sensitivity samples ``rows`` (M,), their
    sensitivities (M, n_act, n_act, r) and the attenuation terms ``parts`` (n_act, r,
    r)."""

    noise: StateNoise
    keep: np.ndarray
    rows: np.ndarray
    sens: np.ndarray
    parts: np.ndarray

    @classmethod
    def of(cls, reg: ClosedLoopRegressor, base: BaseParameters, noise: StateNoise,
           poses: npt.ArrayLike, twists: npt.ArrayLike, twist_dots: npt.ArrayLike,
           times: npt.ArrayLike | None) -> _NoiseTerms:
        """The terms at the states (checked already by the regressor's batch)."""
        pos, tw, td = (as_array(x, (reg.dim,), name, batch=True) for x, name in
                       ((poses, "poses"), (twists, "twists"), (twist_dots, "twist_dots")))
        n = pos.shape[0]
        stamp = np.arange(n, dtype=float) if times is None else np.asarray(times, float)
        keep = coulomb_rows(actuator_velocities(reg.robot, pos, tw, stamp), noise,
                            reg.layout.drive)
        rows = sensitivity_rows(n, noise)
        sens = acceleration_sensitivities(reg, base, pos[rows], tw[rows], td[rows],
                                          stamp[rows])
        return cls(noise, keep, rows, sens,
                   attenuation_terms(sens, keep[rows], noise, n / rows.size))

    def long_run(self, wb: np.ndarray, u: np.ndarray, beta: np.ndarray,
                 sigma: np.ndarray) -> np.ndarray:
        """The long-run covariance of the fit's per-sample scores (:mod:`.input_noise`,
        item 3) at the estimate ``beta`` with the weights ``1 / sigma^2``: the
        compensated one's scores when ``noise.compensate``, else the plain one's (no
        ``B_k beta``: the spread about the plain estimate's biased limit)."""
        n, n_act = self.keep.shape
        r = beta.size
        residual = (u - wb @ beta).reshape(n, n_act) * self.keep
        scores = np.einsum("kip,ki->kp", wb.reshape(n, n_act, r), residual / sigma ** 2)
        if self.noise.compensate:
            scores[self.rows] += score_correction(self.sens, self.keep[self.rows],
                                                  self.noise, n / self.rows.size, beta,
                                                  sigma)
        return long_run_covariance(scores, max(int(self.noise.band * n), r + 1))


def identify_from_states(robot: object, poses: npt.ArrayLike, twists: npt.ArrayLike,
                         twist_dots: npt.ArrayLike, actuator_forces: npt.ArrayLike, *,
                         drive: object = DEFAULT_DRIVE, base: BaseParameters | None = None,
                         noise_std: npt.ArrayLike | None = None, consistent: bool = True,
                         prior: float = PRIOR_WEIGHT, times: npt.ArrayLike | None = None,
                         state_noise: StateNoise | None = None) -> IdentificationResult:
    """Identify the base parameters (and a physically consistent robot) from platform
    states and measured actuator forces (module docstring).

    Args:
        robot: a robot of the library, the nominal model.
        poses: (N, dim) platform poses (m, rad).
        twists: (N, dim) their twists (world axes, m/s, rad/s).
        twist_dots: (N, dim) the twists' time derivatives (m/s^2, rad/s^2).
        actuator_forces: (N, n_act) measured (N, N m).
        drive: the drive parameters (:data:`~.parameters.DRIVE_KINDS`).
        base: the base parameters (default: :func:`~.base.base_parameters` of the robot).
        noise_std: force noise per actuator (scalar or (n_act,), > 0); None: estimated.
        consistent: also fit the physically consistent full parameters.
        prior: the consistent fit's prior weight (> 0).
        times: (N,) the samples' times, for error messages.
        state_noise: the states' noise, consecutive samples of one motion in time order
            (:class:`~.input_noise.StateNoise`, :func:`identify` makes it): the Coulomb
            deadband, the bias compensation (``compensate``) and the long-run sandwich
            covariance of :mod:`.input_noise`; None: exact states, the classical
            covariance.

    Raises:
        ArgumentTypeError: not a robot of the library.
        InputError: bad shapes, lengths, NaN / inf, bad options.
        MotionSampleError: a state out of reach or singular (its row).
        IdentifiabilityError: the data do not determine every base parameter (with the
            rank and the undetermined combinations), or fewer rows than parameters.
        SolverError: the consistent fit failed its checks (step 4 and
            :mod:`.consistent`).
    """
    reg = ClosedLoopRegressor(robot, drive)
    n_act = reg.n_actuators
    full = reg.batch(poses, twists, twist_dots, times)
    n = full.shape[0] // n_act
    forces = as_array(actuator_forces, (n_act,), "actuator_forces", batch=True)
    if forces.shape[0] != n:
        raise InputError("actuator_forces", actuator_forces, f"expected {n} rows (one per "
                         f"pose), got {forces.shape[0]}")
    base = base_parameters(robot, reg.layout.drive) if base is None \
        else _check_base(base, reg)
    consistent = flag(consistent, "consistent")
    prior = real_number(prior, "prior", minimum=0.0)
    noise = None if state_noise is None else _check_state_noise(state_noise, n_act)
    r = base.count
    if full.shape[0] <= r:
        raise IdentifiabilityError(f"{full.shape[0]} force rows for {r} base parameters",
                                   r, full.shape[0])
    wb = base.regressor(full)
    u = forces.reshape(-1)
    terms = None if noise is None else _NoiseTerms.of(reg, base, noise, poses, twists,
                                                       twist_dots, times)
    keep = None if terms is None else terms.keep
    parts = None if terms is None else terms.parts
    compensate = noise is not None and noise.compensate
    if not np.any(u):
        raise InputError("actuator_forces", "all zero", "no force was measured: nothing "
                         "to identify the parameters from")
    factors = ActuatorFactors.of(wb, u, n_act, keep)
    if factors.rows <= r:
        raise IdentifiabilityError(f"{factors.rows} force rows outside the Coulomb "
                                   f"deadband for {r} base parameters", r, factors.rows)
    still = np.flatnonzero(factors.counts == 0)
    if still.size:
        raise IdentifiabilityError(
            f"actuator(s) {still.tolist()} have no sample outside the Coulomb deadband "
            "(their speed stays under 4 velocity-noise deviations): their friction cannot "
            "be identified; move them faster or leave 'coulomb' out of drive", r,
            factors.rows)
    if terms is not None and n < r + 2:
        raise IdentifiabilityError(f"{n} samples for the long-run covariance of {r} base "
                                   f"parameters (at least {r + 2} needed)", r, n)
    _data_rank(factors, base.names)
    if noise_std is None:
        sigma = _noise_levels(factors, parts, compensate, u)
    else:
        sigma = bounds(noise_std, n_act, "noise_std")
        if not np.all(np.isfinite(sigma)):
            raise InputError("noise_std", noise_std, "must be finite")
    fit = _weighted_fit(factors, sigma, parts, compensate)
    beta = fit.beta
    if terms is None:
        s2 = float(np.sum(factors.residuals2(beta) / sigma ** 2)) / (factors.rows - r)
        cov = s2 * fit.inv
    else:
        cov = fit.inv @ terms.long_run(wb, u, beta, sigma) @ fit.inv
    cov = 0.5 * (cov + cov.T)
    nominal = nominal_parameters(robot, reg.layout.drive)
    beta_nom = base.values(nominal)
    fitted = None
    if consistent:
        rw = factors.stacked(sigma)[0]
        information = scipy.linalg.qr(rw, mode="r")[0][:r] if fit.normal is None \
            else scipy.linalg.cholesky(fit.normal)                      # H = R^T R
        by_sample = full.reshape(n, n_act, -1)
        scale = np.sqrt(np.einsum("kij,kij,i->j", by_sample, by_sample, sigma ** -2.0))
        fitted = consistent_fit(reg.layout, information, base.regrouping, beta, scale,
                                nominal, prior)
        _verify_mass_matrix(reg, nominal, fitted.parameters)
    result = IdentificationResult(
        robot, base, beta, np.sqrt(np.diag(cov)), cov, sigma, beta_nom,
        ForceResiduals.of((u - wb @ beta_nom).reshape(n, n_act)),
        ForceResiduals.of((u - wb @ beta).reshape(n, n_act)), fit.condition, fitted,
        state_noise=noise, attenuation=fit.attenuation,
        compensation=None if fit.compensated is None else fit.compensated - fit.plain,
        deadband_rows=None if keep is None else n - np.sum(keep, axis=0))
    gap = result.consistent_gap
    if gap is not None and gap > GAP_WARNING:
        LOGGER.warning("the consistent estimate is %.3g standard errors from the "
                       "least-squares one (above %g): the least-squares estimate is not "
                       "physically consistent, or the data do not fit the model", gap,
                       GAP_WARNING)
    return result


def _induced_force(reg: ClosedLoopRegressor, times: np.ndarray, cutoff: float,
                   sigma: np.ndarray) -> np.ndarray:
    """:func:`input_noise_force` for a checked position noise ``sigma`` (n_act,)."""
    gain = derivative_noise_gain(times, cutoff)[1]
    mass = actuator_mass_matrix(reg, nominal_parameters(reg.robot, reg.layout.drive))
    return np.sqrt((mass ** 2) @ (gain * sigma) ** 2)


def input_noise_force(robot: object, times: np.ndarray, cutoff: float,
                      position_noise_std: npt.ArrayLike,
                      drive: object = DEFAULT_DRIVE) -> np.ndarray:
    """The force errors (n_act,) (N, N m) that white actuator-position noise makes through
    the filtered, twice differentiated positions (errors in the variables): ``sqrt(diag(M_a
    diag(s_a^2) M_a))`` with ``s_a = gain * position_noise_std`` the acceleration noise
    (:func:`~.motion_data.derivative_noise_gain`) and ``M_a`` the nominal robot's mass
    matrix in actuator coordinates at home (:func:`actuator_mass_matrix`). The velocity
    noise's part (through damping and Coulomb steps) is left out: smaller by the ratio
    of the two gains, ``cutoff`` times over.

    Raises:
        InputError: a position noise that is not positive and finite (scalar or (n_act,)).
    """
    reg = ClosedLoopRegressor(robot, drive)
    return _induced_force(reg, times, cutoff, position_noise(position_noise_std,
                                                             reg.n_actuators))


def _warn_input_noise(result: IdentificationResult, induced: np.ndarray,
                      sigma_p: np.ndarray, given: bool, cut: float) -> None:
    """The warnings of :func:`identify` about the position noise (its docstring); each
    names the cut-off that would bring its number to the threshold (the bias and ``B``
    fall as the cut-off's fifth power, the force errors as its 2.5th)."""
    if result.compensation is None or result.attenuation is None:
        return
    shift = float(np.max(np.abs(result.compensation) / result.std_errors))
    ratio = float(np.max(induced / result.noise_std))
    if not given and (shift > BIAS_WARNING or ratio > INPUT_NOISE_WARNING):
        better = cut * min((BIAS_WARNING / shift) ** 0.2 if shift > BIAS_WARNING else 1.0,
                           (INPUT_NOISE_WARNING / ratio) ** 0.4
                           if ratio > INPUT_NOISE_WARNING else 1.0)
        LOGGER.warning("the actuator positions' noise, estimated at %s from the data above "
                       "the cut-off, biases the estimates by up to %.3g standard errors "
                       "(errors in the variables; its force errors up to %.3g of the force "
                       "noise) through the accelerations filtered at %.4g Hz, and the "
                       "standard errors do not cover it: give position_noise_std (the "
                       "sensors' noise) to compensate it, or use a cut-off of %.3g Hz",
                       np.array2string(sigma_p, precision=2), shift, ratio, cut, better)
    share = result.attenuation
    if given and share > ATTENUATION_WARNING:
        # the share at a cut-off c': l' = l x / (1 - l + l x), x = (c' / c)^5
        low = min(share, 0.999)
        ratio = ATTENUATION_WARNING * (1.0 - low) / (low * (1.0 - ATTENUATION_WARNING))
        LOGGER.warning("the position noise makes up to %.3g of the data's energy in a "
                       "direction that the motion barely excites, through the "
                       "accelerations filtered at %.4g Hz (above %g): the estimates of "
                       "that combination are mostly noise (compensated up to %g); a "
                       "cut-off of %.3g Hz would bring it to %g, or excite it more", share,
                       cut, ATTENUATION_WARNING, COMPENSATION_CAP, cut * ratio ** 0.2,
                       ATTENUATION_WARNING)
    if given and shift > COMPENSATION_WARNING:
        LOGGER.warning("the position noise biased the plain estimates by up to %.3g "
                       "standard errors through the accelerations filtered at %.4g Hz "
                       "(errors in the variables; above %g): compensated, but only as "
                       "well as position_noise_std is known (10%% off in it leaves 20%% "
                       "of the bias); a cut-off of %.3g Hz would bring it to %g", shift,
                       cut, COMPENSATION_WARNING,
                       cut * (COMPENSATION_WARNING / shift) ** 0.2, COMPENSATION_WARNING)


def identify(robot: object, data: object, *, cutoff: float | None = None,
             trim: int | None = DEFAULT_TRIM, position_noise_std: npt.ArrayLike | None = None,
             **options: object) -> IdentificationResult:
    """Identify from a measured motion (:class:`~.motion_data.MotionData`): its states
    by :func:`~.motion_data.states_from_motion` (zero-phase Butterworth at ``cutoff`` Hz,
    default a fifth of the Nyquist frequency; ``trim`` samples dropped at each end,
    default three periods of the cut-off), then :func:`identify_from_states` with
    ``options`` (``drive``, ``base``, ``noise_std``, ``consistent``, ``prior``) and the
    states' noise (:class:`~.input_noise.StateNoise.of_filter`): errors as both.

    The actuator positions' noise makes errors in the variables (:mod:`.input_noise`):

    * ``position_noise_std`` given (the sensors' white noise, m or rad, scalar or
      (n_act,)): the rows inside the Coulomb deadband are left out, the attenuation bias
      is compensated, and the covariance is the long-run sandwich. Warnings: the
      compensation moves an estimate by more than
      :data:`~.input_noise.COMPENSATION_WARNING` standard errors (the result then leans
      on the noise given; the cut-off that would bring it there is named); the noise
      makes more than :data:`~.input_noise.ATTENUATION_WARNING` of the data's energy in
      some direction (that combination is mostly noise; the cut-off named); the
      positions carry more than :data:`NOISE_MISMATCH` times the given noise above the
      cut-off (a noise given too small, or a motion faster than the cut-off).
    * None: the noise is estimated from the positions' content above the cut-off
      (:func:`~.motion_data.position_noise_estimate`: an upper bound, vibration reads as
      noise) and used for the deadband and the sandwich covariance; the compensation is
      computed but not applied (it would follow an overestimate): its shift, the
      result's ``compensation``, estimates the bias. When that exceeds
      :data:`BIAS_WARNING` standard errors, or the force errors that the noise makes
      (``input_noise_force`` of the result, :func:`input_noise_force`) exceed
      :data:`INPUT_NOISE_WARNING` of an actuator's force noise, a warning says what to
      do: give ``position_noise_std``, or lower the cut-off (it must stay well above the
      motion's bandwidth) to the value it names.
    """
    reg = ClosedLoopRegressor(robot, options.get("drive", DEFAULT_DRIVE))
    n_act = reg.n_actuators
    checked = check_motion(data, n_act, reg.dim)
    times = checked.times
    cut = resolve_cutoff(times, cutoff)
    st = states_from_motion(robot, checked, cutoff, trim)
    seen = position_noise_estimate(times, checked.actuator_positions, cut,
                                   resolve_trim(times, cut, trim))
    given = position_noise_std is not None
    sigma_p = seen if position_noise_std is None else \
        position_noise(position_noise_std, n_act)
    if given and np.any(seen > NOISE_MISMATCH * sigma_p):
        LOGGER.warning("the actuator positions carry %s above the cut-off of %.4g Hz, more "
                       "than %g times the noise given (%s): the noise is larger than given "
                       "(then the bias compensation falls short), or the motion has "
                       "content above the cut-off that the filter distorts (a fast "
                       "reversal near a singularity): check the noise, raise the cut-off "
                       "or slow the motion", np.array2string(seen, precision=2), cut,
                       NOISE_MISMATCH, np.array2string(sigma_p, precision=2))
    noise = StateNoise.of_filter(times, cut, sigma_p, compensate=given)
    result = identify_from_states(robot, st.poses, st.twists, st.twist_dots,
                                  st.actuator_forces, times=st.times, state_noise=noise,
                                  **options)   # type: ignore[arg-type]
    induced = _induced_force(reg, times, cut, sigma_p)
    _warn_input_noise(result, induced, sigma_p, given, cut)
    return dataclasses.replace(result, cutoff=cutoff, trim=trim, input_noise_force=induced)
