"""Errors in the variables: what noise on the measured actuator positions does to an
identification, and the estimate and standard errors that account for it.

The states of :func:`~.motion_data.states_from_motion` come from filtered, twice
differentiated positions, so white position noise ``s_p`` (m or rad, per actuator)
becomes noise on the states' actuator velocities and accelerations, ``s_v = g_v s_p`` and
``s_a = g_a s_p`` (:func:`~.motion_data.derivative_noise_gain`), correlated in time over
a few periods of the cut-off. The regressor is then measured with an error, ``W^ = W +
Delta``, while the forces ``u = W beta + e`` are not, and three things follow (measured
in docs/tutorials/identification.md):

1. **Coulomb sign errors.** Where an actuator's velocity crosses zero slowly, the sign of
   the filtered velocity (the Coulomb column) is wrong on several samples in a row: an
   error of twice the Coulomb force, where the force noise is a small fraction of it. The
   rows of actuator ``i`` with ``|qd_i| < DEADBAND s_v,i`` are left out
   (:func:`coulomb_rows`: a kept row's sign is wrong with probability below
   ``Phi(-DEADBAND)``, 3e-5).
2. **Attenuation bias.** ``E[W^T W_w W^] = W^T W_w W + B`` (``W_w`` the weights ``1 /
   sigma_i^2`` of actuator ``i``'s rows), so least squares shrinks ``beta`` by ``-A^-1 B
   beta`` along the accelerations' columns, with::

       B = sum_k sum_i sum_j s_a,j^2 g_kij g_kij^T / sigma_i^2,   g_kij = dW_ki / dqdd_j

   (``W_ki`` the base-regressor row of actuator ``i`` at sample ``k``; independent noise
   per actuator). The regressor is affine in the accelerations, so ``g_kij`` is the
   difference of the rows at the tree acceleration moved by actuator ``j``'s unit
   acceleration and at the sample's own (:func:`acceleration_sensitivities`, exact), and
   ``E[W^T W_w W^] = A + B`` holds exactly for the acceleration noise: the compensation
   is not a linearisation. The bias-compensated estimate (Stoica and Soderstrom's
   bias-compensated least squares) solves ``(A - B) beta = W^T W_w u``, ``A = W^T W_w
   W``. ``B`` is a sum of smooth functions of the configuration: it is summed over every
   ``stride``-th sample and scaled (the states vary slower than the cut-off; ``stride``
   samples at four times the cut-off, and at most :data:`SENSITIVITY_SAMPLES` samples in
   all). The velocity noise's part (the damping and Coriolis columns) is left out:
   smaller by ``(g_v / g_a)^2`` (2e-5 at 500 Hz and a 50 Hz cut-off).

   The compensation is as right as the noise given (``B`` grows as its square: 10 % off
   in the noise leaves 20 % of the bias); :func:`~.estimate.identify` warns when it moves
   an estimate by more than :data:`COMPENSATION_WARNING` standard errors. In the
   directions ``v`` of ``B v = l A^ v`` (``A^`` from the noisy data), ``l`` is the
   noise's share of the data's energy, and compensating divides by ``1 - l``. Where the
   motion barely excites a combination, the noise can make most of it (on the hexapod at
   1 um and the default cut-off: 0.16 with the tests' excitation, condition number 450;
   0.7 - 0.8 with one of condition number 833; 0.85 - 1.0 with one that passes near a
   singularity), and as ``l`` nears 1 the division amplifies that component's noise
   without bound (``A^ - B`` is not even positive definite on some noise draws). So ``l``
   is capped at :data:`COMPENSATION_CAP` (the component's estimate and standard error at
   most 20 times the plain ones; a component that weakly excited is within a few
   standard errors of zero, so what the cap leaves of its bias is small against them),
   the largest ``l`` is the result's ``attenuation``, and ``identify`` warns above
   :data:`ATTENUATION_WARNING` with the cut-off that brings it there (``B`` falls as the
   cut-off's fifth power). A cap of 0.5 was measured to leave the bias and shrink the
   standard errors: 4 - 6 standard errors off on the hexapod.
3. **Correlated residuals.** The residual ``e - Delta beta`` is correlated in time (the
   filter), and ``Delta^T e`` and ``Delta^T Delta beta`` add spread that the classical
   covariance ``s^2 A^-1`` does not see; and it counts the position noise's part of the
   residual as white force noise, too much for its high-frequency part (the regressor's
   columns are smooth and barely see it). The covariance is the sandwich ``H^-1 S H^-1``
   (``H = A - B``) with ``S`` the long-run covariance of the per-sample scores ``psi_k =
   sum_i W_ki (u_ki - W_ki beta) / sigma_i^2 + B_k beta`` (they sum to zero at the
   estimate; ``B_k`` the sample's part of ``B``, put at the samples where ``B`` is
   summed), estimated from their low frequencies (:func:`long_run_covariance`: the
   equal-weight cosine estimator, Lazarus, Lewis, Stock and Watson 2018: ``S = N / K
   sum_k c_k c_k^T`` over the first ``K`` coefficients of the scores' orthonormal
   cosine transform, ``k = 1 .. K``, the frequencies up to :data:`LONG_RUN_BAND` of the
   cut-off, and at least ``r + 1`` of them so that ``S`` has full rank). There the
   position noise's part of the residual, which lives near the cut-off, is absent and
   the spectrum is flat; the constant (``k = 0``, zero at the estimate) is left out, so
   the estimate is unbiased where a Bartlett window's is not (measured: Newey-West over
   8 periods of the cut-off 9 % narrow with white noise, 10 % wide at 30 um). It
   assumes nothing about where the correlation comes from: unmodelled dynamics that
   vary slower than the band are covered too.

Units: the actuators' (m or rad, N or N m); the base parameters' own.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.fft

from ..core.checks import bounds
from ..errors import HexapodPinError, InputError, MotionSampleError
from .base import BaseParameters
from .motion_data import derivative_noise_gain
from .regressor import ClosedLoopRegressor

#: rows where an actuator's speed is below this many velocity-noise deviations are left
#: out of the fit when the drive has Coulomb friction (module docstring, item 1)
DEADBAND = 4.0
#: the long-run covariance uses the scores' frequencies up to this fraction of the
#: cut-off (item 3)
LONG_RUN_BAND = 0.25
#: the attenuation bias is summed over at most this many samples (item 2)
SENSITIVITY_SAMPLES = 4000
#: :func:`~.estimate.identify` warns when the compensation moves an estimate by more than
#: this many standard errors (it is then as uncertain as the position noise given)
COMPENSATION_WARNING = 2.0
#: the noise's share of the data's energy is compensated up to this in any direction
#: (item 2: the compensation multiplies a component by at most ``1 / (1 - cap)``)
COMPENSATION_CAP = 0.95
#: :func:`~.estimate.identify` warns when the noise's share of the data's energy exceeds
#: this in some direction (that component's estimate is then mostly noise)
ATTENUATION_WARNING = 0.9


@dataclass(frozen=True)
class StateNoise:
    """The noise of a motion's states (module docstring), as
    :func:`~.estimate.identify_from_states` takes it.

    Attributes:
        position_std: (n_act,) white noise on the measured actuator positions (m or rad).
        velocity_std: (n_act,) on the states' actuator velocities (m/s or rad/s).
        acceleration_std: (n_act,) on their accelerations (m/s^2 or rad/s^2).
        band: the long-run covariance's band, as a fraction of the Nyquist frequency
            (0 < band <= 1): ``floor(N band)`` cosine terms for N samples.
        stride: the attenuation bias is summed over every ``stride``-th sample (>= 1).
        compensate: compensate the attenuation bias (the noise is known); False (the
            noise estimated from the data, an upper bound): the Coulomb deadband and the
            long-run covariance of the plain estimate, the compensation only computed
            (its shift estimates the bias).
    """

    position_std: np.ndarray
    velocity_std: np.ndarray
    acceleration_std: np.ndarray
    band: float
    stride: int
    compensate: bool

    @classmethod
    def of_filter(cls, times: np.ndarray, cutoff: float, position_std: np.ndarray,
                  compensate: bool = True) -> StateNoise:
        """The state noise that white position noise ``position_std`` ((n_act,), m or
        rad, >= 0) leaves through :func:`~.motion_data.filtered_derivatives` of samples
        at ``times`` cut at ``cutoff`` Hz: the gains of
        :func:`~.motion_data.derivative_noise_gain`, the band of
        :data:`LONG_RUN_BAND` of the cut-off, the stride of four samples per period of
        the cut-off (module docstring).

        Raises:
            InputError: a cut-off at or above the Nyquist frequency, too few samples.
        """
        std = np.asarray(position_std, dtype=float)
        gain_v, gain_a = derivative_noise_gain(times, cutoff)
        rate = (times.size - 1) / (times[-1] - times[0])
        return cls(std, gain_v * std, gain_a * std,
                   min(1.0, LONG_RUN_BAND * cutoff / (0.5 * rate)),
                   max(1, int(rate / (4.0 * cutoff))), bool(compensate))


def position_noise(value: npt.ArrayLike, n_act: int) -> np.ndarray:
    """A given position noise (scalar or (n_act,), m or rad) as (n_act,).

    Raises:
        InputError: a noise that is not positive and finite, or of the wrong length.
    """
    std = bounds(value, n_act, "position_noise_std")
    if not np.all(np.isfinite(std)):
        raise InputError("position_noise_std", value, "must be finite")
    return std


def coulomb_rows(velocities: np.ndarray, noise: StateNoise, drive: tuple[str, ...]
                 ) -> np.ndarray:
    """``keep`` (N, n_act) bool: the rows of the fit (module docstring, item 1); every row
    when the drive has no Coulomb friction."""
    if "coulomb" not in drive:
        return np.ones(velocities.shape, dtype=bool)
    return np.abs(velocities) >= DEADBAND * noise.velocity_std


def actuator_velocities(robot: object, poses: np.ndarray, twists: np.ndarray,
                        times: np.ndarray) -> np.ndarray:
    """The actuator velocities ``J twist`` (N, n_act) at the states (the robot's
    ``jacobian_batch``).

    Raises:
        MotionSampleError: a state whose Jacobian is not regular (its index and time).
    """
    batch = getattr(robot, "jacobian_batch")(poses)
    bad = np.flatnonzero(~np.asarray(batch.ok))
    if bad.size:
        k = int(bad[0])
        raise MotionSampleError(k, float(times[k]), InputError(
            "poses", poses[k], "unreachable, or a singular Jacobian"))
    return np.einsum("kij,kj->ki", np.asarray(batch.jacobian), twists)


def sensitivity_rows(n: int, noise: StateNoise) -> np.ndarray:
    """The samples (indices into N) where the attenuation bias is summed: every
    ``stride``-th, at most :data:`SENSITIVITY_SAMPLES`."""
    stride = max(noise.stride, int(np.ceil(n / SENSITIVITY_SAMPLES)))
    return np.arange(0, n, stride)


def acceleration_sensitivities(reg: ClosedLoopRegressor, base: BaseParameters,
                               poses: np.ndarray, twists: np.ndarray,
                               twist_dots: np.ndarray, times: np.ndarray) -> np.ndarray:
    """``g`` (M, n_act, n_act, r): ``g[m, i, j] = dW_i / dqdd_j`` at the M states
    (module docstring, item 2): on the tree state of each
    (:meth:`~.regressor.ClosedLoopRegressor.tree_motion`), the base-regressor rows at
    the acceleration ``a + G e_j`` minus those at ``a`` (``G`` the actuated velocity map:
    ``S G = I`` moves actuator ``j``'s acceleration by one, ``J_c G = 0`` keeps the
    closures; the rows are affine in ``a``: exact).

    Raises:
        MotionSampleError: a state fails (its index and ``times`` entry; the cause as
            :meth:`~.regressor.ClosedLoopRegressor.batch`).
    """
    n_act, m = reg.n_actuators, poses.shape[0]
    out = np.empty((m, n_act, n_act, base.count))
    for k in range(m):
        try:
            motion = reg.tree_motion(poses[k], twists[k], twist_dots[k])
        except HexapodPinError as exc:
            raise MotionSampleError(k, float(times[k]), exc) from exc
        own = reg.rows_of(motion)
        for j in range(n_act):
            moved = reg.rows_of(motion._replace(a=motion.a + motion.actuated_map[:, j]))
            out[k, :, j] = base.regressor(moved - own)
    return out


def attenuation_terms(sens: np.ndarray, keep: np.ndarray, noise: StateNoise,
                      scale: float) -> np.ndarray:
    """``B_i`` (n_act, r, r), actuator ``i``'s part of ``B`` before the weight ``1 /
    sigma_i^2`` (module docstring, item 2): ``scale sum_m keep_mi sum_j s_a,j^2 g_mij
    g_mij^T`` over the M sensitivity samples (``keep`` (M, n_act) their rows of the fit;
    ``scale`` the samples per sensitivity sample)."""
    m, n_act, _, r = sens.shape
    out = np.empty((n_act, r, r))
    for i in range(n_act):
        weight = np.sqrt(keep[:, i, None] * noise.acceleration_std ** 2)     # (M, n_act)
        rows = (sens[:, i] * weight[:, :, None]).reshape(m * n_act, r)
        out[i] = rows.T @ rows
    return scale * out


def score_correction(sens: np.ndarray, keep: np.ndarray, noise: StateNoise, scale: float,
                     beta: np.ndarray, sigma: np.ndarray) -> np.ndarray:
    """``B_k beta`` (M, r) at the sensitivity samples (module docstring, item 3), each
    carrying the ``scale`` samples it stands for: their sum is ``B beta``."""
    mass = np.einsum("mijp,p->mij", sens, beta)           # the actuator-space mass matrix
    return scale * np.einsum("mi,mijp,mij,j,i->mp", keep, sens, mass,
                             noise.acceleration_std ** 2, sigma ** -2.0, optimize=True)


def long_run_covariance(scores: np.ndarray, terms: int) -> np.ndarray:
    """The long-run covariance (r, r) of the per-sample scores (N, r), the covariance of
    their sum (module docstring, item 3): ``N / K sum_k c_k c_k^T`` over the
    coefficients ``k = 1 .. K`` (``K = min(terms, N - 1)``) of their orthonormal cosine
    transform (DCT-II, ``c_k = sqrt(2 / N) sum_t psi_t cos(pi k (t + 1/2) / N)``; the
    frequency of term ``k`` is ``k / (2 N)`` of the sampling rate). For white scores of
    covariance ``C`` each ``c_k`` has covariance ``C`` and the sum ``N C``."""
    n = scores.shape[0]
    k = max(1, min(int(terms), n - 1))
    coef = scipy.fft.dct(scores, type=2, axis=0, norm="ortho")[1:k + 1]
    return n * (coef.T @ coef) / k
