"""Base parameters: the independent combinations of the dynamic parameters that the
actuator forces determine, found numerically, with the regrouping rules by name.

Method (Gautier 1990, numerical): stack the closed-loop regressor ``W`` (:mod:`.regressor`)
over random closure-consistent states (:func:`random_states`: poses around home reached
by the robot's own inverse kinematics, so every closure holds to 1e-12, random twists and
twist derivatives; seeded), scale each column to unit norm (``W_s = W D^-1``), and factor
``W_s P = Q R`` by QR with column pivoting (``scipy.linalg.qr(pivoting=True)``). The
numerical rank ``r`` counts the diagonal entries with ``|R_ii| > rtol |R_00|``
(:data:`RANK_RTOL` = 1e-8: the dependent columns of the library's robots fall below
1e-12, the independent ones stay above 1e-6 with the default sampling). The first ``r``
pivoted columns are the base columns ``b``, the others ``d`` are combinations of them:
``W_d = W_b K`` with ``K = D_b^-1 R_11^-1 R_12 D_d``, so::

    W pi = W_b beta,    beta = pi_b + K pi_d    (the regrouping, beta = regrouping @ pi)

and ``beta`` is what data can identify. Each base parameter is printed as its rule
(``beta_k = Izz_platform + 0.04 m_leg_0 + ...``, coefficients below
:data:`COEFFICIENT_TOL` relative to the largest dropped).

Which parameters merge (measured, ``tests/identification/test_base.py``; the counts are
tree / closed loop / + armature / + viscous and Coulomb / + armature, viscous and Coulomb
/ + all four drive kinds):

=========== ======== ====== ==== ==== ==== ==== ====
robot       standard tree   loop +a   +vc  +avc +avco
=========== ======== ====== ==== ==== ==== ==== ====
hexapod     190      76     46   46   58   58   64
Stewart     190      94     88   94   100  106  112
planar 3PRR 90       17     14   16   20   22   23
=========== ======== ====== ==== ==== ==== ==== ====

* viscous and Coulomb columns (``qd_i``, ``sign(qd_i)``) are never combinations of the
  inertial ones: each adds one base parameter per actuator;
* armature (``qdd_i``): on a HORIZONTAL rail the carriage moves along the rail only and
  gravity has no component along it, so the mass column of the carriage and everything
  that translates with it is ``qdd_i`` too: the armature merges with that mass
  (``m_carriage_0 + m_u_0_a + m_u_0_b - 2.222 mz_u_0_b + Ia_carriage_0``): the
  hexapod's six, the planar robot's slider 0. On an INCLINED rail the mass column is
  ``qdd_i + g sin(alpha_i)``, so the armature is separate (the planar robot's sliders 1
  and 2), and on a Stewart leg the actuated body also turns with the leg: separate;
* offset (``1``): separate on a horizontal rail (the hexapod's six, planar slider 0) and
  on a Stewart leg; on an inclined rail with armature asked for, the constant is already
  spanned by the mass column ``qdd_i + g sin(alpha_i)`` and the armature's ``qdd_i``, so
  the offset merges (planar sliders 1 and 2).

The issue's "with viscous, Coulomb and offset terms" counts (58 / 106 / 22) are those
of ``drive=("armature", "viscous", "coulomb")``.

The structure depends only on the robot, not on the samples, when the samples are rich
enough; data that are not (too few states, motions in a subspace) are detected in
:mod:`.estimate` by the rank of the base regressor of the data.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import numpy.typing as npt
import scipy.linalg

from ..core.checks import count, real_number
from ..errors import HexapodPinError, IdentifiabilityError
from .parameters import DEFAULT_DRIVE, ParameterLayout
from .regressor import ClosedLoopRegressor

#: relative threshold on ``|R_ii| / |R_00|`` of the pivoted QR of the column-scaled
#: regressor: below it a column is a combination of the previous ones
RANK_RTOL = 1e-8
#: a coefficient of a regrouping rule smaller than this is not printed (and, in
#: :attr:`BaseParameters.regrouping`, set to exactly 0)
COEFFICIENT_TOL = 1e-9
#: default number of random states of :func:`base_parameters`
DEFAULT_STATES = 60


@dataclass(frozen=True)
class BaseParameters:
    """The base parameters of a robot (module docstring).

    Attributes:
        layout: the full parameter vector's :class:`~.parameters.ParameterLayout`.
        base_index: indices (r,) into the full vector of the base columns (``b``).
        regrouping: (r, n) matrix, ``beta = regrouping @ pi`` (``[I | K]`` in the
            columns ``(b, d)``).
        diagonal: ``|R_ii| / |R_00|`` of the pivoted QR (n,), in pivot order: the gap
            between ``diagonal[r - 1]`` and ``diagonal[r]`` is the margin of the rank.
        rtol: the rank threshold used.
    """

    layout: ParameterLayout
    base_index: np.ndarray
    regrouping: np.ndarray
    diagonal: np.ndarray
    rtol: float

    @property
    def count(self) -> int:
        """Number of base parameters ``r``."""
        return int(self.base_index.size)

    @property
    def names(self) -> tuple[str, ...]:
        """The base parameters' names: each is named after its base column (the full
        parameter it starts from; :meth:`rules` gives what it also contains)."""
        full = self.layout.names
        return tuple(full[i] for i in self.base_index)

    @property
    def dependent_index(self) -> np.ndarray:
        """Indices into the full vector of the parameters that are not base columns."""
        mask = np.ones(self.layout.size, dtype=bool)
        mask[self.base_index] = False
        return np.flatnonzero(mask)

    def values(self, parameters: npt.ArrayLike) -> np.ndarray:
        """``beta = regrouping @ pi`` (r,) of a full parameter vector (n,)."""
        return self.regrouping @ np.asarray(parameters, dtype=float)

    def rules(self, precision: int = 4) -> tuple[str, ...]:
        """One rule per base parameter, e.g. ``"m_carriage_0 = m_carriage_0 + m_u_0_a -
        2.222 mz_u_0_b + ..."`` (coefficients with ``precision`` significant digits; terms whose
        coefficient is below :data:`COEFFICIENT_TOL` times the largest are left out)."""
        full = self.layout.names
        out = []
        for k, row in enumerate(self.regrouping):
            big = float(np.max(np.abs(row)))
            terms = []
            for j in np.flatnonzero(np.abs(row) > COEFFICIENT_TOL * big):
                coef = row[j]
                sign = "-" if coef < 0 else "+"
                text = full[j] if abs(abs(coef) - 1.0) < 1e-9 else f"{abs(coef):.{precision}g} {full[j]}"
                terms.append(f"{sign} {text}")
            body = " ".join(terms)
            body = body.removeprefix("+ ")
            out.append(f"{full[self.base_index[k]]} = {body}")
        return tuple(out)

    def regressor(self, full: np.ndarray) -> np.ndarray:
        """The base regressor ``W_b`` (rows, r): the base columns of a full regressor."""
        return np.asarray(full)[:, self.base_index]


def random_states(robot: object, n: int, seed: int = 0,
                  amplitude: tuple[float, float] = (0.02, 0.1),
                  speed: tuple[float, float] = (0.2, 1.0),
                  acceleration: tuple[float, float] = (2.0, 10.0)
                  ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """``n`` random platform states ``(poses, twists, twist_dots)`` (n, dim) each, seeded:
    poses uniform within ``+- amplitude`` (m, rad: linear, angular) of home that the robot
    reaches regularly (the regressor's own test: :meth:`ClosedLoopRegressor.tree_motion`
    succeeds; others are drawn again, with the amplitude halved after 20 misses
    in a row), twists normal with standard deviations ``speed`` (m/s, rad/s) and twist
    derivatives with ``acceleration`` (m/s^2, rad/s^2). The twist's angular components are
    scaled like the pose's.

    Raises:
        InputError: bad ``n`` or seed.
        IdentifiabilityError: no reachable pose found (the amplitude fell below 1e-9).
    """
    n = count(n, "n")
    rng = np.random.default_rng(count(seed, "seed", minimum=0))
    layout = getattr(robot, "pose_layout", None)
    dim = int(getattr(robot, "pose_dim"))
    home = np.asarray(getattr(robot, "home_pose"), dtype=float)
    angular = np.zeros(dim, dtype=bool)
    if layout is not None:
        angular[np.asarray(layout.angular, dtype=int)] = True

    def scale(pair: tuple[float, float]) -> np.ndarray:
        return np.where(angular, float(pair[1]), float(pair[0]))

    amp = scale(amplitude)
    reg = ClosedLoopRegressor(robot, ())
    rest = np.zeros(dim)
    poses = np.empty((n, dim))
    misses = 0
    k = 0
    while k < n:
        pose = home + rng.uniform(-1.0, 1.0, dim) * amp
        try:
            reg.tree_motion(pose, rest, rest)
        except HexapodPinError:
            misses += 1
            if misses >= 20:
                amp = 0.5 * amp
                misses = 0
                if float(np.max(amp)) < 1e-9:
                    raise IdentifiabilityError("no pose near home is reachable", n, 0)
            continue
        poses[k] = pose
        k += 1
        misses = 0
    twists = rng.normal(size=(n, dim)) * scale(speed)
    twist_dots = rng.normal(size=(n, dim)) * scale(acceleration)
    return poses, twists, twist_dots


def base_from_regressor(full: npt.ArrayLike, layout: ParameterLayout,
                        rtol: float = RANK_RTOL) -> BaseParameters:
    """The base parameters of a stacked full regressor (rows, layout.size) (module
    docstring).

    Raises:
        InputError: bad ``rtol``.
        IdentifiabilityError: the regressor is zero (nothing is identifiable).
    """
    rtol = real_number(rtol, "rtol", minimum=0.0)
    mat = np.asarray(full, dtype=float)
    norms = np.linalg.norm(mat, axis=0)
    live = norms > 0.0
    if not live.any():
        raise IdentifiabilityError("the regressor is zero", layout.size, 0)
    scale = np.where(live, norms, 1.0)
    _, r_mat, perm = scipy.linalg.qr(mat / scale, mode="economic", pivoting=True)
    diag = np.abs(np.diag(r_mat))
    diagonal = np.zeros(layout.size)
    diagonal[:diag.size] = diag / diag[0]
    rank = int(np.sum(diagonal > rtol))
    base, dep = perm[:rank], perm[rank:]
    k_scaled = scipy.linalg.solve_triangular(r_mat[:rank, :rank], r_mat[:rank, rank:])
    k_mat = k_scaled / scale[base][:, None] * scale[dep][None, :]
    regroup = np.zeros((rank, layout.size))
    regroup[np.arange(rank), base] = 1.0
    regroup[:, dep] = k_mat
    big = np.max(np.abs(regroup), axis=1, keepdims=True)
    regroup[np.abs(regroup) <= COEFFICIENT_TOL * big] = 0.0
    order = np.argsort(base, kind="stable")          # base parameters in layout order
    return BaseParameters(layout, base[order], regroup[order], diagonal, rtol)


def base_parameters(robot: object, drive: object = DEFAULT_DRIVE, *,
                    n_states: int = DEFAULT_STATES, seed: int = 0,
                    rtol: float = RANK_RTOL) -> BaseParameters:
    """The base parameters of a robot with the drive parameters ``drive`` (module
    docstring): from ``n_states`` random states (:func:`random_states`, seeded).

    Args:
        robot: a robot of the library.
        drive: the drive kinds (:data:`~.parameters.DRIVE_KINDS`); ``()`` for the
            inertial parameters alone.
        n_states: random states stacked (>= 1; the rows ``n_states n_act`` should exceed
            the parameters severalfold).
        seed: the random generator's seed.
        rtol: the rank threshold (:data:`RANK_RTOL`).

    Raises:
        ArgumentTypeError: not a robot of the library.
        InputError: bad ``drive``, ``n_states``, ``seed`` or ``rtol``.
        DescriptionError: a redundantly actuated robot.
        IdentifiabilityError: nothing identifiable.
    """
    reg = ClosedLoopRegressor(robot, drive)
    poses, twists, twist_dots = random_states(robot, n_states, seed)
    return base_from_regressor(reg.batch(poses, twists, twist_dots), reg.layout, rtol)
