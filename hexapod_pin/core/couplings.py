"""Joint couplings: holonomic rows ``q1 = f(q2)`` between two 1-DoF joints of the tree.

A :class:`JointCoupling` ties the coordinate ``q1`` of a revolute or prismatic joint to
the coordinate ``q2`` of another by a quartic polynomial (MuJoCo's ``<equality><joint>``,
a gear pair, a cam)::

    q1 = f(q2) = c0 + c1 q2 + c2 q2^2 + c3 q2^3 + c4 q2^4      (m or rad)

and, without a second joint, ``q1 = c0`` (a joint held at a value). Each coupling is one
constraint row appended after the closure rows of a
:class:`~hexapod_pin.core.closed_loop.ClosedLoopModel` (``clm.couplings``), with the
conventions of those rows:

* residual ``r = q1 - f(q2)`` (m or rad);
* Jacobian row (along ``pin.integrate``, which for these joints is plain addition):
  ``+1`` on ``v1``, ``-f'(q2)`` on ``v2``;
* drift ``gamma = -f''(q2) v2^2`` (``J a + gamma = d^2 r / dt^2``);
* the multiplier is the generalised force the coupling exerts on ``q1`` (N or N m; on
  ``q2`` it exerts ``-f'(q2)`` times it).

:class:`CouplingRows` evaluates all the couplings of a model at once, in one place, for
every route (residual, Jacobian, drift and their derivatives in ``q``).
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import pinocchio as pin

from ..errors import DescriptionError

#: the number of polynomial coefficients (a quartic, as MuJoCo's ``polycoef``)
N_COEFFICIENTS = 5
#: Pinocchio joint types a coupling can join (one coordinate, ``q`` a plain number)
_SCALAR_JOINTS = ("JointModelRX", "JointModelRY", "JointModelRZ", "JointModelRevoluteUnaligned",
                  "JointModelPX", "JointModelPY", "JointModelPZ", "JointModelPrismaticUnaligned")


@dataclass(frozen=True)
class JointCoupling:
    """One joint coupling ``q1 = c0 + c1 q2 + ... + c4 q2^4`` (see the module docstring).

    Attributes:
        name: a label for messages (unique among a model's couplings).
        joint1: the driven joint (its coordinate is the polynomial's value).
        joint2: the driving joint, or None for ``q1 = c0``.
        polycoef: ``(c0, c1, c2, c3, c4)`` (units of ``q1`` per power of ``q2``'s).
    """

    name: str
    joint1: str
    joint2: str | None
    polycoef: tuple[float, float, float, float, float]

    def __post_init__(self) -> None:
        coef = tuple(float(c) for c in self.polycoef)
        if len(coef) > N_COEFFICIENTS or not all(np.isfinite(coef)):
            raise DescriptionError(self.name, f"polycoef must be up to {N_COEFFICIENTS} finite "
                                              f"numbers, got {self.polycoef!r}", "polycoef")
        coef = coef + (0.0,) * (N_COEFFICIENTS - len(coef))
        object.__setattr__(self, "polycoef", coef)
        if self.joint2 == self.joint1:
            raise DescriptionError(self.name, f"joint {self.joint1!r} coupled to itself",
                                   self.joint1)

    @staticmethod
    def shifted(name: str, joint1: str, joint2: str | None, polycoef: Sequence[float],
                ref1: float, ref2: float) -> JointCoupling:
        """The coupling ``q1 - ref1 = f(q2 - ref2)`` (MuJoCo's form, relative to the
        reference positions ``qpos0``) written with absolute coordinates."""
        coef = np.zeros(N_COEFFICIENTS)
        coef[:len(polycoef)] = polycoef
        if joint2 is None:
            return JointCoupling(name, joint1, None, (coef[0] + ref1, 0.0, 0.0, 0.0, 0.0))
        # f(x - ref2) expanded in powers of x
        poly = np.polynomial.Polynomial(coef)(np.polynomial.Polynomial([-ref2, 1.0]))
        out = np.zeros(N_COEFFICIENTS)
        out[:poly.coef.size] = poly.coef[:N_COEFFICIENTS]
        out[0] += ref1
        c0, c1, c2, c3, c4 = (float(c) for c in out)
        return JointCoupling(name, joint1, joint2, (c0, c1, c2, c3, c4))


class CouplingRows:
    """The rows of a model's couplings, evaluated together.

    Args:
        model: the Pinocchio tree.
        couplings: the couplings, in row order.
        source: a label for messages.

    Raises:
        DescriptionError: a joint that is not in the tree or not a revolute / prismatic
            joint with one plain coordinate, or two couplings with one name.
    """

    def __init__(self, model: pin.Model, couplings: Sequence[JointCoupling],
                 source: str = "model") -> None:
        self.couplings = tuple(couplings)
        names = [c.name for c in self.couplings]
        if len(set(names)) != len(names):
            raise DescriptionError(source, "two couplings share a name", str(names))
        self.n_rows = len(self.couplings)
        self.nv = model.nv
        iq1, iv1, iq2, iv2 = [], [], [], []
        for c in self.couplings:
            q1, v1 = _scalar_joint(model, c.joint1, c.name, source)
            iq1.append(q1)
            iv1.append(v1)
            q2, v2 = (0, 0) if c.joint2 is None else _scalar_joint(model, c.joint2, c.name,
                                                                    source)
            iq2.append(q2)
            iv2.append(v2)
        self.iq1, self.iv1 = np.array(iq1, dtype=int), np.array(iv1, dtype=int)
        self.iq2, self.iv2 = np.array(iq2, dtype=int), np.array(iv2, dtype=int)
        #: (n, 5) polynomial coefficients, zero for a coupling without joint2 but c0
        self.coef = np.array([c.polycoef for c in self.couplings], dtype=float).reshape(-1, 5)
        #: whether each coupling has a driving joint
        self.driven = np.array([c.joint2 is not None for c in self.couplings], dtype=bool)
        self._d1 = self.coef[:, 1:] * np.arange(1, 5)           # f' coefficients (n, 4)
        self._d2 = self._d1[:, 1:] * np.arange(1, 4)            # f'' coefficients (n, 3)
        self._d3 = self._d2[:, 1:] * np.arange(1, 3)            # f''' coefficients (n, 2)
        self._rows = np.arange(self.n_rows)

    def _x(self, q: np.ndarray) -> np.ndarray:
        return np.where(self.driven, q[self.iq2], 0.0)

    @staticmethod
    def _poly(coef: np.ndarray, x: np.ndarray) -> np.ndarray:
        out = np.zeros(x.shape)
        for k in range(coef.shape[1] - 1, -1, -1):      # Horner
            out = out * x + coef[:, k]
        return out

    def derivatives(self, q: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """``(f'(q2), f''(q2), f'''(q2))`` of each coupling (zero without joint2)."""
        x = self._x(q)
        return self._poly(self._d1, x), self._poly(self._d2, x), self._poly(self._d3, x)

    def residual(self, q: np.ndarray) -> np.ndarray:
        """``q1 - f(q2)`` (n_rows,) at ``q`` (nq,)."""
        return q[self.iq1] - self._poly(self.coef, self._x(q))

    def jacobian(self, q: np.ndarray) -> np.ndarray:
        """The rows (n_rows, nv): ``+1`` on ``v1``, ``-f'(q2)`` on ``v2``."""
        out = np.zeros((self.n_rows, self.nv))
        out[self._rows, self.iv1] = 1.0
        slope = self._poly(self._d1, self._x(q))
        out[self._rows[self.driven], self.iv2[self.driven]] -= slope[self.driven]
        return out

    def drift(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``gamma = -f''(q2) v2^2`` (n_rows,)."""
        v2 = np.where(self.driven, v[self.iv2], 0.0)
        return -self._poly(self._d2, self._x(q)) * v2 * v2

    def jacobian_velocity_dq(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``d(J v)/dq`` (n_rows, nv): ``-f''(q2) v2`` on ``v2``."""
        out = np.zeros((self.n_rows, self.nv))
        v2 = np.where(self.driven, v[self.iv2], 0.0)
        val = -self._poly(self._d2, self._x(q)) * v2
        out[self._rows[self.driven], self.iv2[self.driven]] = val[self.driven]
        return out

    def drift_dq(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``d gamma/dq`` (n_rows, nv): ``-f'''(q2) v2^2`` on ``v2``."""
        out = np.zeros((self.n_rows, self.nv))
        v2 = np.where(self.driven, v[self.iv2], 0.0)
        val = -self._poly(self._d3, self._x(q)) * v2 * v2
        out[self._rows[self.driven], self.iv2[self.driven]] = val[self.driven]
        return out

    def drift_dv(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """``d gamma/dv`` (n_rows, nv): ``-2 f''(q2) v2`` on ``v2``."""
        return 2.0 * self.jacobian_velocity_dq(q, v)

    def transpose_force_dq(self, q: np.ndarray, y: np.ndarray) -> np.ndarray:
        """``d(J^T y)/dq`` (nv, nv) for multipliers ``y`` (n_rows,) held: ``-f''(q2) y`` at
        ``(v2, v2)``, summed over the couplings."""
        out = np.zeros((self.nv, self.nv))
        val = -self._poly(self._d2, self._x(q)) * y
        idx = self.iv2[self.driven]
        np.add.at(out, (idx, idx), val[self.driven])
        return out


def _scalar_joint(model: pin.Model, joint: str, coupling: str, source: str) -> tuple[int, int]:
    """``(idx_q, idx_v)`` of a coupled joint; DescriptionError unless it is a revolute or
    prismatic joint of the tree with one plain coordinate."""
    if not model.existJointName(joint):
        raise DescriptionError(source, f"coupling {coupling!r}: joint {joint!r} is not in the "
                                       "tree", joint)
    jmodel = model.joints[model.getJointId(joint)]
    if jmodel.shortname() not in _SCALAR_JOINTS:
        raise DescriptionError(source, f"coupling {coupling!r}: joint {joint!r} is a "
                                       f"{jmodel.shortname()}; only revolute and prismatic "
                                       "joints with one coordinate can be coupled", joint)
    return jmodel.idx_q, jmodel.idx_v
