"""Time integration of any closed-loop mechanism on its Pinocchio tree.

:class:`ClosedLoopIntegrator`, generic over a :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`
whose joints are 1-DoF revolute / prismatic, continuous (unbounded revolute), ball
(spherical, quaternion), ``SphericalZYX``, ``Translation``, planar or free-flyers:

* the state is the tree's ``(q, v)`` (Pinocchio conventions);
* classical fourth-order Runge-Kutta on ``q`` as a vector of ``R^nq`` and ``v``:
  ``qdot`` from ``v`` through the joint kinematics (vector-space coordinates
  ``qdot = v``; a continuous joint ``(cos, sin)' = (-sin, cos) v``; a ball joint
  ``Q' = 1/2 Q (x) (w_body, 0)``; a planar joint ``p' = R v_lin``,
  ``(cos, sin)' = (-sin, cos) w``; a free-flyer ``p' = R v_lin``, quaternion
  ``Q' = 1/2 Q (x) (w_body, 0)``; the unit quaternions and ``(cos, sin)`` pairs
  renormalised after every stage and step), ``vdot``
  from the constrained forward dynamics (``pin.constraintDynamics`` by default);
  the actuator forces and the wrench are held constant over a step (zero-order hold);
  with redundant closure rows the stage states are put back on the closures (one
  Gauss-Newton pass each) before their dynamics are solved;
* or semi-implicit Euler, ``v' = v + dt a(q, v)``, ``q' = q (+) dt v'`` (``pin.integrate``
  when a joint is not a vector space);
* or ``"stick_slip"``: semi-implicit Euler with the Coulomb friction of the step solved at
  velocity level (a time-stepping scheme): damping and springs explicit at ``(q, v)``,
  ``v_free = v + dt a(q, v, tau + passive)``, then the friction forces ``f`` of the
  coordinates with Coulomb friction (``|f_i| <= coulomb_i``) chosen so that each next
  velocity ``v'_i`` is zero (stick) or opposed by its friction (slip, ``f_i = -coulomb_i
  sign(v'_i)``): with ``G`` the response of those velocities to unit forces through the
  closures (``G = N_r (N^T M N)^-1 N_r^T``, ``N`` a basis of ``null(J_c)``), ``f``
  solves the box QP ``min 1/2 f^T G f + (v_free_r / dt)^T f``, ``-c <= f <= c``
  (ProxSuite, polished; its KKT conditions are exactly stick / slip), checked after the
  verified solve with ``tau + passive + f`` (:class:`~hexapod_pin.errors.SolverError`
  otherwise); ``v' = v + dt a``, the stuck velocities set to exactly zero and kept there
  by the velocity projection (minimum norm over the other coordinates);
* Coulomb friction and the integrators (:func:`resolve_integrator`): ``sign(v)`` is
  discontinuous, and RK4 or plain Euler steps across ``v = 0`` flip it every step (the
  velocity chatters about zero by ``dt c / m`` and a load below the friction never
  holds). So a model with Coulomb friction runs ``"stick_slip"`` (``"auto"`` picks it; an
  explicit ``"rk4"`` or ``"semi_implicit_euler"`` raises
  :class:`~hexapod_pin.errors.InputError`), unless ``friction_regularisation`` =
  ``v_eps`` (m/s or rad/s) replaces the friction by the smooth force ``-coulomb
  tanh(v / v_eps)`` (any integrator; an approximation: a joint under a load ``|u| <
  coulomb`` creeps at ``v_eps atanh(|u| / coulomb)`` instead of sticking; the force is
  stiff near ``v = 0``, with slope ``coulomb / v_eps``: RK4 is stable for ``dt`` below
  about ``2.8 m v_eps / coulomb``, ``m`` the joint's effective inertia, and chatters
  beyond);
* the energy dissipated by damping and friction over each step is left in
  :attr:`ClosedLoopIntegrator.dissipated` (J): for RK4, the RK4 quadrature of the
  dissipated power ``sum(damping v^2 + friction power)`` over the stage velocities (the
  same fourth order as the state); for the Euler schemes, the work of the dissipative
  forces held over the step along its displacement ``dt v'``, ``-dt (f_damping(v) +
  f_friction) . v'``;
* after each step, drift control by projection onto the constraint manifold: the
  quaternions are renormalised; when the closure residual ``r`` exceeds ``projection_tol``
  (default 1e-10 m), ``q`` gets Gauss-Newton corrections ``q <- q (+) (-J_c^+ r)``
  (minimum norm over all coordinates); the velocity is projected at the returned ``q``,
  ``v <- v - J_c^+ J_c v``. All closures at once: one Pinocchio kinematic pass per
  Gauss-Newton step gives the stacked errors (read from live views of the constraint
  datas, :class:`~hexapod_pin.core.constraint_views.ConstraintErrors`) and constraint
  Jacobian (Pinocchio's LOCAL constraint rows), and one compiled kernel solves the step
  and the velocity projection on the independent rows with one factorisation. The Euler
  step's first correction, while the closures drift, is taken with the constraint
  Jacobian of its verified dynamics call (at the step's start, ``dt |v|`` away: no
  Jacobian pass at the predicted ``q``); the pass at the corrected ``q`` verifies the
  closures and projects the velocity. Every returned state has its closure residual
  measured at the returned ``q`` (at most ``projection_tol``, or
  :class:`~hexapod_pin.errors.AssemblyError`).

:meth:`ClosedLoopIntegrator.step` checks its inputs (``dt`` and ``projection_tol`` real,
finite, > 0; ``q`` (nq,), ``v`` (nv,), ``tau`` (nv,) real and finite: else
:class:`~hexapod_pin.errors.InputError`). Its stage states are off the closures by
O(dt^2) and go through the unchecked dynamics paths (not the closure check of the public
routes of :mod:`~hexapod_pin.core.dynamics`); the step's start state is not checked
against the closures either (the returned state is projected onto them).
"""


from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from ..errors import AssemblyError, InputError, SolverError
from .checks import as_array, real_number
from .closed_loop import ClosedLoopModel
from .constraint_views import ConstraintErrors, gather_negated
from .dynamics import FORWARD_METHODS, box_qp, dynamics_of, independent_rows
from .effects import STICK_MARGIN, dissipated_power, passive_forces, check_stick_slip
from .integrator_kernels import (
    FREE_FLYER,
    PLANAR,
    SPHERICAL,
    UNBOUNDED,
    VECTOR,
    configuration_rate,
    errors_gauss_newton_pass,
    euler_update,
    finite_state,
    gauss_newton_pass,
    normalise_pairs,
    rk4_combine,
    rk4_stage,
)

#: closure residual above which a step is projected back onto the closures (m)
PROJECTION_TOL = 1e-10
_SUPPORTED_1DOF = {"JointModelRX", "JointModelRY", "JointModelRZ", "JointModelPX",
                   "JointModelPY", "JointModelPZ", "JointModelRevoluteUnaligned",
                   "JointModelPrismaticUnaligned"}
#: joints whose configuration is a vector space of dimension nv (``qdot = v``)
_VECTOR_JOINTS = _SUPPORTED_1DOF | {"JointModelSphericalZYX", "JointModelTranslation"}
#: the other supported joints, by kind of the compiled joint table
_LIE_JOINTS = {"JointModelFreeFlyer": FREE_FLYER, "JointModelRUBX": UNBOUNDED,
               "JointModelRUBY": UNBOUNDED, "JointModelRUBZ": UNBOUNDED,
               "JointModelRevoluteUnboundedUnaligned": UNBOUNDED,
               "JointModelSpherical": SPHERICAL, "JointModelPlanar": PLANAR}
_INF = math.inf
_F64 = np.dtype(np.float64)
#: the integrators (:func:`resolve_integrator`: "auto" picks one by the model's effects)
INTEGRATORS = ("auto", "rk4", "semi_implicit_euler", "stick_slip")
STATUSES = ("completed", "stroke_limit", "carriage_gap", "failed")


# --------------------------------------------------------------------------------------
# generic integrator
# --------------------------------------------------------------------------------------
def resolve_integrator(clm: ClosedLoopModel, integrator: str = "auto",
                       friction_regularisation: float | None = None) -> str:
    """The integrator a run of ``clm`` uses (see the module docstring).

    Args:
        clm: the closed-loop model (its :attr:`~ClosedLoopModel.effects`).
        integrator: one of :data:`INTEGRATORS`. "auto": "stick_slip" when the model has
            Coulomb friction and no ``friction_regularisation`` is given, else "rk4".
        friction_regularisation: ``v_eps`` (m/s or rad/s) of the smooth friction
            ``-coulomb tanh(v / v_eps)``, or None for the exact (set-valued) friction.

    Returns:
        "rk4", "semi_implicit_euler" or "stick_slip".

    Raises:
        InputError: an unknown integrator; "rk4" or "semi_implicit_euler" for a model with
            exact Coulomb friction (they chatter: use "stick_slip", "auto" or a
            ``friction_regularisation``); "stick_slip" with a ``friction_regularisation``
            (choose one friction model).
    """
    if not (isinstance(integrator, str) and integrator in INTEGRATORS):
        raise InputError("integrator", integrator, f"expected one of {INTEGRATORS}")
    exact = clm.effects.has_coulomb and friction_regularisation is None
    if integrator == "auto":
        return "stick_slip" if exact else "rk4"
    if exact and integrator != "stick_slip":
        coords = np.flatnonzero(clm.effects.coulomb).tolist()
        raise InputError("integrator", integrator, f"the model has Coulomb friction on the "
                         f"velocity coordinates {coords}: {integrator} steps across v = 0 "
                         "flip sign(v) and chatter; use 'stick_slip' (or 'auto': exact "
                         "stick-slip at velocity level) or friction_regularisation=v_eps "
                         "(smooth approximation, any integrator)")
    if integrator == "stick_slip" and friction_regularisation is not None:
        raise InputError("friction_regularisation", friction_regularisation,
                         "'stick_slip' solves the exact Coulomb friction: give no "
                         "regularisation, or another integrator")
    return integrator


class ClosedLoopIntegrator:
    """Fixed-step integrator of a closed-loop tree with projection onto the closures.

    Args:
        clm: the closed-loop model (joints: 1-DoF revolute / prismatic, continuous
            (unbounded revolute), ball (spherical), ``SphericalZYX``, ``Translation``,
            planar, free-flyer).
        method: forward-dynamics route, "pinocchio" (default), "qp" or "kkt".
        integrator: "auto" (default: "stick_slip" for a model with exact Coulomb friction,
            else "rk4"), "rk4" (classical Runge-Kutta, four dynamics calls per step),
            "semi_implicit_euler" (one call per step; fast, first order, energy not
            conserved to better than O(dt)) or "stick_slip" (semi-implicit Euler with
            exact stick-slip friction at velocity level: two dynamics calls and a box QP
            per step); see :func:`resolve_integrator`.
        residual: optional callable ``q -> max-abs closure residual`` (m) replacing the
            generic evaluation through Pinocchio's frames (e.g. the hexapod's closed form
            :meth:`~hexapod_pin.hexapod.kernels.ClosedForm.closure_residual`); it must
            return the same quantity as :meth:`ClosedLoopModel.residual`.
        friction_regularisation: ``v_eps`` (m/s or rad/s, > 0): Coulomb friction becomes
            the smooth ``-coulomb tanh(v / v_eps)`` (an approximation, any integrator);
            None (default): the exact friction.

    Raises:
        InputError: an unsupported joint type, method or integrator, an integrator that
            does not take the model's friction (:func:`resolve_integrator`), a
            ``friction_regularisation`` that is not a finite real number > 0.
    """

    def __init__(self, clm: ClosedLoopModel, method: str = "pinocchio", integrator: str = "auto",
                 residual: Callable[[np.ndarray], float] | None = None,
                 friction_regularisation: float | None = None) -> None:
        if method not in FORWARD_METHODS:
            raise InputError("method", method, f"expected one of {FORWARD_METHODS}")
        if friction_regularisation is not None:
            friction_regularisation = real_number(friction_regularisation,
                                                  "friction_regularisation", minimum=0.0)
        self.clm = clm
        self.dyn = dynamics_of(clm)
        self.method = method
        #: the integrator used ("auto" resolved)
        self.integrator = resolve_integrator(clm, integrator, friction_regularisation)
        #: ``v_eps`` of the smooth friction, or None (exact friction)
        self.friction_regularisation = friction_regularisation
        self._residual_fn = residual
        effects = self._effects = clm.effects
        #: the velocity coordinates with Coulomb friction
        self._friction = np.flatnonzero(effects.coulomb)
        self._dissipative = bool(effects.damping.any() or self._friction.size)
        #: the coordinates with friction that slipped at the last "stick_slip" step, with
        #: ``f = +coulomb`` and with ``f = -coulomb`` (the others stuck)
        self._slipping = (np.zeros(self._friction.size, dtype=bool),
                          np.zeros(self._friction.size, dtype=bool))
        #: the energy (J) dissipated by damping and friction over the last step (see the
        #: module docstring); 0 for a model without them
        self.dissipated = 0.0
        smooth = friction_regularisation is not None and self._friction.size
        self._acceleration = self._smooth_acceleration if smooth else \
            self._verified_acceleration
        model = clm.model
        rows: list[tuple[int, int, int]] = []     # (kind, idx_q, idx_v)
        quat: list[int] = []                      # starts of the unit quaternions in q
        pairs: list[int] = []                     # starts of the unit (cos, sin) pairs
        for jid in range(1, model.njoints):
            joint = model.joints[jid]
            name = joint.shortname()
            iq, iv = joint.idx_q, joint.idx_v
            if name in _VECTOR_JOINTS:
                rows += [(VECTOR, iq + k, iv + k) for k in range(joint.nv)]
                continue
            kind = _LIE_JOINTS.get(name)
            if kind is None:
                raise InputError("clm", name, "the integrator supports 1-DoF revolute / "
                                 "prismatic, continuous, ball (spherical), SphericalZYX, "
                                 "translation, planar and free-flyer joints only")
            rows.append((kind, iq, iv))
            if kind in (FREE_FLYER, SPHERICAL):
                quat.append(iq + 3 if kind == FREE_FLYER else iq)
            else:
                pairs.append(iq if kind == UNBOUNDED else iq + 2)
        #: start of each unit quaternion (x, y, z, w) in q: free-flyers' and ball joints'
        #: (RK4 stage kernels)
        self._quat = np.array(quat, dtype=np.int64)
        #: start of each unit (cos, sin) pair in q: continuous and planar joints'
        self._pairs = np.array(pairs, dtype=np.int64)
        #: whether a joint is not a vector space (the Euler step then uses pin.integrate)
        self._lie = bool(quat or pairs)
        #: (kind, idx_q, idx_v) of every joint (coordinate, for vector-space joints), kinds
        #: of :mod:`~hexapod_pin.core.integrator_kernels` (the compiled configuration rate
        #: and RK4 stage kernels)
        self._joints = np.array(rows, dtype=np.int64).reshape(-1, 3)
        self._shapes = ((model.nq,), (model.nv,))
        self._redundant: bool | None = None
        self._rows: np.ndarray | None = None     # independent closure rows (projection)
        # the projection's own Pinocchio data and constraint data (Pinocchio's LOCAL rows)
        self._data = model.createData()
        self._cms, self._cds = clm.pinocchio_constraints()
        self._err = np.empty(clm.n_rows)
        self._out = np.empty(1)
        self._nv = model.nv
        self._calcs = [(cm.calc, cd) for cm, cd in zip(self._cms, self._cds)]
        self._errors = ConstraintErrors(model, self._cms, self._cds, "local")
        #: the live views of the errors (None: read through ConstraintErrors.gather)
        self._views = self._errors.local_views
        # the Gauss-Newton steps of the projection (two buffers: the current and the next)
        self._steps = (np.empty(model.nv), np.empty(model.nv))
        #: the constraint Jacobian at the start of the current step (from the verified
        #: dynamics call), None when the dynamics did not give one
        self._jac0: np.ndarray | None = None
        #: whether the last Euler step needed a position correction (then the next one
        #: takes its first Gauss-Newton step without a Jacobian pass, see step)
        self._drifting = True
        self._model = model
        self.dyn.pinocchio_arguments()    # Pinocchio's constraint dynamics set up, then
        self._ddq = self.dyn.data.ddq     # its acceleration buffer (a live view)

    # -- kinematics of the configuration vector -------------------------------------------
    def qdot(self, q: np.ndarray, v: np.ndarray) -> np.ndarray:
        """Time derivative of ``q`` as a vector of ``R^nq`` for the velocity ``v`` (see the
        module docstring: vector coordinates ``qdot = v``; continuous joints
        ``(cos, sin)' = (-sin, cos) v``; ball joints ``Q' = 1/2 Q (x) (w_body, 0)``; planar
        joints and free-flyers ``p' = R v_lin`` and their rotation's rate)."""
        out = np.empty_like(q)
        configuration_rate(q, v, self._joints, out)
        return out

    # -- dynamics ---------------------------------------------------------------------------
    def acceleration(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray,
                     checked: bool = True) -> np.ndarray:
        """Tree acceleration (nv,) for the applied generalised force ``tau`` (nv,),
        verified; the joint effects added (damping, springs, Coulomb friction: sliding
        ``-coulomb sign(v)`` and the stick / slip of the coordinates at rest, or the
        smooth ``-coulomb tanh(v / v_eps)`` with a ``friction_regularisation``).

        Every answer satisfies the equation of motion and the closures at acceleration
        level to :data:`~hexapod_pin.core.dynamics.RESIDUAL_RTOL` (relative) or the
        route raises :class:`~hexapod_pin.errors.SolverError`. The "pinocchio" method
        runs one verified ``pin.constraintDynamics`` call and falls back to the exact
        KKT route when it is refused. ``checked`` is kept for callers; every call is
        checked.
        """
        acc = self._acceleration(q, v, tau)
        return acc.copy() if self.method == "pinocchio" else acc

    def _verified_acceleration(self, q, v, tau):
        """The verified tree acceleration (nv,) at ``(q, v)``: with the "pinocchio" method
        Pinocchio's own buffer (overwritten by the next call: read it, do not keep it),
        falling back to the exact KKT route when that answer is refused."""
        dyn = self.dyn
        if dyn.clm.effects.has_forces:   # the joint effects' force joins the applied one
            force, rest = dyn.effect_terms(q, v)
            if rest.size:                # Coulomb friction at rest: solved for
                self._jac0 = None
                return dyn.forward_unchecked(q, v, tau, self.method).a
            tau = tau + force
        return self._rigid_acceleration(q, v, tau)

    def _smooth_acceleration(self, q, v, tau):
        """:meth:`_verified_acceleration` with the smooth friction ``-coulomb tanh(v /
        v_eps)`` (``friction_regularisation``) in place of the exact one."""
        total = tau + passive_forces(self._model, self._effects, q, v)
        total[self._friction] += self._smooth_friction(v)
        return self._rigid_acceleration(q, v, total)

    def _smooth_friction(self, v: np.ndarray) -> np.ndarray:
        """``-coulomb tanh(v / v_eps)`` on the coordinates with friction."""
        idx = self._friction
        return -self._effects.coulomb[idx] * np.tanh(v[idx] / self.friction_regularisation)

    def _rigid_acceleration(self, q, v, tau):
        """The verified acceleration for a ``tau`` that already holds the effects' force
        (Pinocchio's buffer with the "pinocchio" method, see
        :meth:`_verified_acceleration`)."""
        dyn = self.dyn
        if self.method == "pinocchio":
            if dyn.pinocchio_verified(q, v, tau) is not None:      # the short path
                self._jac0 = dyn.last_jacobian
                return self._ddq
            redundant = self._redundant
            if redundant is None:
                redundant = self._redundant = dyn.closure_rank(q) < dyn.n_rows
            acc, _ = dyn.pinocchio_call(q, v, tau, redundant)
            if acc is not None:
                self._jac0 = dyn.last_jacobian
                return acc
        self._jac0 = None
        return dyn.forward_total(q, v, tau, self.method).a

    def step(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, dt: float,
             projection_tol: float = PROJECTION_TOL) -> tuple[np.ndarray, np.ndarray, float]:
        """One step of length ``dt`` (s) with ``tau`` (nv,) held; returns ``(q, v, residual)``.

        Args:
            q: tree configuration (nq,) (unit quaternions and ``(cos, sin)`` pairs).
            v: tree velocity (nv,).
            tau: generalised force (nv,) held over the step (N, N m).
            dt: step length (s), a real number, finite and > 0.
            projection_tol: closure residual above which the step is projected back onto
                the closures (m / rad), a real number, finite and > 0.

        ``residual`` is the max-abs closure residual after the projection (m).

        Raises:
            InputError: a ``dt`` or ``projection_tol`` that is not a finite real number
                > 0 (None, text, bool, NaN, inf, <= 0); a ``q``, ``v`` or ``tau`` of the
                wrong shape, not real, or with NaN / inf entries (naming the argument and
                its values).
            AssemblyError: the projection does not converge.
        """
        if not (type(dt) is float and 0.0 < dt < _INF):
            dt = real_number(dt, "dt", minimum=0.0)
        if projection_tol is not PROJECTION_TOL and not (
                type(projection_tol) is float and 0.0 < projection_tol < _INF):
            projection_tol = real_number(projection_tol, "projection_tol", minimum=0.0)
        nd, (shape_q, shape_v) = np.ndarray, self._shapes
        if not (type(q) is nd and type(v) is nd and type(tau) is nd and q.dtype == _F64
                and v.dtype == _F64 and tau.dtype == _F64
                and q.shape == shape_q and v.shape == shape_v and tau.shape == shape_v
                and q.flags.c_contiguous and v.flags.c_contiguous
                and tau.flags.c_contiguous and finite_state(q, v, tau)):
            q, v = as_array(q, shape_q, "q"), as_array(v, shape_v, "v")
            tau = as_array(tau, shape_v, "tau")
        return self.advance(q, v, tau, dt, projection_tol)

    def advance(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, dt: float,
                projection_tol: float = PROJECTION_TOL) -> tuple[np.ndarray, np.ndarray,
                                                                 float]:
        """:meth:`step` without its input checks (contiguous float64 ``q`` (nq,), ``v``
        (nv,), ``tau`` (nv,), finite; ``dt``, ``projection_tol`` finite floats > 0), for
        drivers that checked them once."""
        if self.integrator == "rk4":
            q_new, v_new = self._rk4(q, v, tau, dt, projection_tol)
            return self.project(q_new, v_new, projection_tol, velocity=True)
        if self.integrator == "stick_slip":
            return self._stick_slip(q, v, tau, dt, projection_tol)
        # semi-implicit Euler: v' = v + dt a(q, v), q' = q (+) dt v'
        model = self._model
        acc = self._acceleration(q, v, tau)
        if self._lie:                 # rotations, (cos, sin) pairs: the exponential map
            v_new = np.multiply(acc, dt)
            v_new += v
            q_new = pin.integrate(model, q, dt * v_new)
        else:                         # vector-space joints: q (+) dt v' = q + dt v'
            q_new, v_new = np.empty_like(q), np.empty_like(v)
            euler_update(q, v, acc, dt, q_new, v_new)
        if self._dissipative:
            friction = self._smooth_friction(v) if self.friction_regularisation else None
            self.dissipated = self._held_dissipation(v, v_new, dt, friction)
        jac0, rows = self._jac0, self._rows
        if jac0 is None or rows is None or self._residual_fn is not None \
                or not self._drifting:
            # one pass at q_new: the closures verified (corrected when they drifted) and
            # the velocity projected
            q_out, v_out, res = self.project(q_new, v_new, projection_tol, velocity=True)
            self._drifting = q_out is not q_new
            return q_out, v_out, res
        # the closures drifted at the last step: the first Gauss-Newton step with the
        # Jacobian at the start of the step (no Jacobian pass at q_new); the next pass
        # (project, at the corrected q) verifies the closures and projects the velocity
        if self._light_step(q_new, v_new, jac0, rows) > 1e-12:
            return self.project(q_new, v_new, projection_tol, velocity=True)
        if self._out[0] > projection_tol:
            q_new = pin.integrate(model, q_new, self._steps[0])
        else:
            self._drifting = False
        return self.project(q_new, v_new, projection_tol, velocity=True)

    def _light_step(self, q: np.ndarray, v: np.ndarray, jac: np.ndarray,
                    rows: np.ndarray) -> float:
        """A Gauss-Newton step at ``q`` taken with ``jac``, the constraint Jacobian at a
        nearby configuration (the start of the step: ``q`` is ``dt v`` away, and the error
        of that Jacobian slows the convergence by a factor of order ``dt |v|`` only): one
        kinematic pass for the closure errors at ``q`` and no Jacobian. The step is left
        in ``self._steps[0]``, the max-abs error at ``q`` in ``self._out[0]``; returns the
        miss of the solve (see :func:`gauss_newton_pass`)."""
        model, data = self._model, self._data
        pin.forwardKinematics(model, data, q)
        for calc, cd in self._calcs:
            calc(model, data, cd)
        views = self._views
        if views is None:
            return gauss_newton_pass(jac, self._errors.gather(self._err), rows, v,
                                     self._steps[0], self._steps[1], self._out)
        return errors_gauss_newton_pass(views, jac, self._err, rows, v, self._steps[0],
                                        self._steps[1], self._out)

    def _rk4(self, q, v, tau, dt, projection_tol=PROJECTION_TOL):
        """Classical RK4. With redundant closure rows (dependent on the others), each
        stage state is first put back on the closures (:meth:`_project_stage`): the drift
        of an unprojected stage can fall outside the range of the nearly redundant rows
        and the verified constrained dynamics then raise (Cassie at 1 ms). With
        independent rows every drift is in their range and the stages are left as RK4
        makes them."""
        if self._rows is None:
            self._rows = independent_rows(self._closure_pass(q))
        verified = self._acceleration
        if self._rows.size < self.clm.n_rows:
            project = self._project_stage

            def acc(qs, vs, first):
                """The stage's verified acceleration; a stage whose dynamics are refused
                (its drift outside the range of the nearly redundant rows: Cassie at
                18 m/s joint speeds) is projected to the trigger and solved again."""
                try:
                    return verified(qs, vs, tau), qs, vs
                except SolverError:
                    if first:
                        raise
                qs, vs, _ = self.project(qs, vs, projection_tol, velocity=True)
                return verified(qs, vs, tau), qs, vs
        else:
            def project(qs, vs, _):
                return qs, vs

            def acc(qs, vs, _):
                return verified(qs, vs, tau), qs, vs
        joints, quat, pairs, nq = self._joints, self._quat, self._pairs, q.shape[0]
        # the weighted sums of the stage rates, (qdot_1 + 2 qdot_2 + 2 qdot_3 + qdot_4,
        # a_1 + 2 a_2 + 2 a_3 + a_4), accumulated by the stage kernel
        rates = np.zeros(nq + v.shape[0])
        power = self.dissipated_power if self._dissipative else None
        dissipated = 0.0                  # the stage-weighted dissipated power
        qs, vs = q, v
        for h, w in ((0.5 * dt, 1.0), (0.5 * dt, 2.0), (dt, 2.0)):
            a_s, qs, vs = acc(qs, vs, qs is q)
            if power is not None:
                dissipated += w * power(vs)
            q_next, v_next = np.empty_like(q), np.empty_like(v)
            rk4_stage(q, v, qs, vs, a_s, h, w, joints, quat, q_next, v_next, rates)
            if pairs.size:
                normalise_pairs(q_next, pairs)
            qs, vs = project(q_next, v_next, projection_tol)
        a_s, qs, vs = acc(qs, vs, False)
        if power is not None:
            self.dissipated = dt / 6.0 * (dissipated + power(vs))
        q_new, v_new = np.empty_like(q), np.empty_like(v)
        rk4_stage(q, v, qs, vs, a_s, 0.0, 1.0, joints, quat, q_new, v_new, rates)
        rk4_combine(q, v, rates, dt / 6.0, quat, q_new, v_new)
        if pairs.size:
            normalise_pairs(q_new, pairs)
        return q_new, v_new

    # -- joint effects: dissipation and the stick-slip step ----------------------------------
    def dissipated_power(self, v: np.ndarray) -> float:
        """Power dissipated by damping and Coulomb friction at the velocity ``v`` (nv,) (W,
        >= 0): ``sum(damping v^2 + coulomb |v|)``, or ``coulomb v tanh(v / v_eps)`` for
        the friction with a ``friction_regularisation``."""
        eps = self.friction_regularisation
        if eps is None or not self._friction.size:
            return dissipated_power(self._effects, v)
        vf = v[self._friction]
        return float(np.dot(self._effects.damping * v, v)) - float(
            np.dot(self._smooth_friction(v), vf))

    def _held_dissipation(self, v: np.ndarray, v_new: np.ndarray, dt: float,
                          friction: np.ndarray | None) -> float:
        """``-dt (f_damping(v) + f_friction) . v'`` (J): the work against the dissipative
        forces held over an Euler step (``friction``: the forces on the coordinates with
        Coulomb friction, or None)."""
        out = float(np.dot(self._effects.damping * v, v_new))
        if friction is not None:
            out -= float(np.dot(friction, v_new[self._friction]))
        return dt * out

    def _stick_slip(self, q: np.ndarray, v: np.ndarray, tau: np.ndarray, dt: float,
                    projection_tol: float) -> tuple[np.ndarray, np.ndarray, float]:
        """One "stick_slip" step (module docstring): semi-implicit Euler with the Coulomb
        friction solved at velocity level, then the projection onto the closures that
        keeps the stuck coordinates at rest.

        Raises:
            SolverError: the friction forces miss stick / slip (or a dynamics solve fails).
            AssemblyError: the projection does not converge.
        """
        effects, idx = self._effects, self._friction
        force = tau + passive_forces(self._model, effects, q, v)
        friction = None
        stuck = idx[:0]
        if idx.size:
            a_free = np.array(self._rigid_acceleration(q, v, force))
            bound = effects.coulomb[idx]
            v_free = v[idx] + dt * a_free[idx]
            response = self.dyn.friction_response(q, idx)
            friction = self._friction_forces(response, v_free / dt, bound)
            force[idx] += friction
        acc = self._rigid_acceleration(q, v, force)
        v_new = v + dt * acc
        if friction is not None:
            # the velocity scale: the motion's and the change the friction can make
            scale = float(np.max(np.abs(v))) + dt * (float(np.max(np.abs(a_free))) + float(
                np.max(np.abs(response))) * float(np.max(bound)))
            stuck = idx[_stick_or_slip(friction, bound, v_new[idx], 1e-9 * scale)]
            v_new[stuck] = 0.0
        q_new = pin.integrate(self._model, q, dt * v_new)
        if self._dissipative:
            self.dissipated = self._held_dissipation(v, v_new, dt, friction)
        if not stuck.size:
            return self.project(q_new, v_new, projection_tol, velocity=True)
        q_out, _, res = self.project(q_new, v_new, projection_tol)
        return q_out, self._project_velocity_keeping(q_out, v_new, stuck), res

    def _friction_forces(self, response: np.ndarray, grad: np.ndarray,
                         bound: np.ndarray) -> np.ndarray:
        """The box QP ``min 1/2 f^T G f + g^T f``, ``-bound <= f <= bound``: first on the
        last step's active set (which coordinates stuck, which slipped each way: exact
        when its KKT conditions hold, the usual case), else ProxSuite
        (:func:`~hexapod_pin.core.dynamics.box_qp`). The active set found is kept for the
        next step."""
        upper, lower = self._slipping
        friction = _on_active_set(response, grad, bound, upper, lower)
        if friction is None:
            friction = box_qp(response, grad, bound)
        edge = bound * (1.0 - STICK_MARGIN)
        self._slipping = (friction >= edge, friction <= -edge)
        return friction

    def _project_velocity_keeping(self, q: np.ndarray, v: np.ndarray,
                                  fixed: np.ndarray) -> np.ndarray:
        """``v`` projected onto ``J_c(q) v = 0`` with the coordinates ``fixed`` left as
        they are (minimum-norm change of the others); the plain minimum-norm projection
        when the other coordinates cannot carry it (the fixed ones then move by the
        closures' drift only)."""
        if not self.clm.n_rows:
            return v
        jac = self._closure_pass(q)
        if self._rows is not None:
            jac = jac[self._rows]
        free = np.ones(v.size, dtype=bool)
        free[fixed] = False
        miss = jac @ v
        out = v.copy()
        out[free] -= _lstsq(jac[:, free], miss)
        scale = float(np.max(np.abs(jac), initial=0.0)) * float(np.max(np.abs(v))) + 1e-300
        if float(np.max(np.abs(jac @ out), initial=0.0)) > 1e-12 * scale:
            out = v - _lstsq(jac, miss)
        return out

    def _project_stage(self, q: np.ndarray, v: np.ndarray, trigger: float):
        """An RK4 stage state put back on the closures: when its closure residual exceeds
        ``trigger``, one Gauss-Newton pass of :meth:`project` (the step and the velocity
        projection from one kinematic pass at ``q``), leaving a residual of the order of
        the square of the stage's (no verifying pass: the step's end state is verified).
        The velocity is projected with the Jacobian at the stage's ``q``: left as RK4
        made it (off the closures' tangent space by O(dt^2)), Cassie's stage dynamics at
        1 ms missed the closure equation on its nearly redundant rows."""
        jac = self._closure_pass(q)
        rows = self._rows
        if rows is None:
            rows = self._rows = independent_rows(jac)
        step, v_new = self._steps[0], np.empty(self._nv)
        if self._solve_pass(jac, rows, v, step, v_new, q) <= trigger:
            return q, v
        return pin.integrate(self.clm.model, q, step), v_new

    def residual(self, q: np.ndarray) -> float:
        """Max-abs closure residual at ``q`` (m / rad): the ``residual`` callable when one was
        given, else the closure errors in Pinocchio's constraint rows (see :meth:`project`)."""
        if self._residual_fn is not None:
            return float(self._residual_fn(q))
        self._closure_pass(q)
        return float(np.max(np.abs(self._err), initial=0.0))

    def _closure_pass(self, q: np.ndarray) -> np.ndarray:
        """One kinematic pass at ``q``: the closure errors into ``self._err`` (n_rows,), and
        Pinocchio's constraint Jacobian ``J`` (n_rows, nv) returned.

        Rows of Pinocchio's LOCAL constraints (anchor-1 frame), in which ``J`` is the
        derivative of the errors along ``pin.integrate`` where they vanish: a point
        closure's error is ``R_1^T (p_1 - p_2)`` (the :meth:`ClosedLoopModel.residual`
        rows in anchor-1 axes: same Euclidean norm), a weld's ``log6(c2Mc1)`` (the same
        rows as :meth:`ClosedLoopModel.residual`). The joint couplings' rows
        (:mod:`~hexapod_pin.core.couplings`) follow the closure rows."""
        model, data, err = self.clm.model, self._data, self._err
        pin.computeJointJacobians(model, data, q)
        for calc, cd in self._calcs:
            calc(model, data, cd)                 # the anchor placements (J reads them)
        couplings = self.clm.coupling_rows
        if couplings is not None:
            ncl = self.clm.n_closure_rows
            self._errors.gather(err[:ncl])
            err[ncl:] = couplings.residual(q)
            return np.vstack([pin.getConstraintsJacobian(model, data, self._cms, self._cds)
                              if ncl else np.zeros((0, model.nv)), couplings.jacobian(q)])
        views = self._views
        if views is None:
            self._errors.gather(err)
        else:
            gather_negated(views, err)
        return pin.getConstraintsJacobian(model, data, self._cms, self._cds)

    def project(self, q: np.ndarray, v: np.ndarray, trigger: float = PROJECTION_TOL,
                max_iter: int = 8, velocity: bool = False) -> tuple[np.ndarray, np.ndarray,
                                                                    float]:
        """Project ``(q, v)`` onto the closures when the residual exceeds ``trigger``.

        All closures at once: one kinematic pass gives the stacked errors ``r`` and
        Pinocchio's constraint Jacobian ``J`` (rows of :meth:`_closure_pass`); Gauss-Newton
        steps ``q <- q (+) (-J_r^+ r_r)`` on the independent rows (rows dependent on the
        others, exactly or to 1e-8, are left out once and for all; ``J_r^+`` through the
        Gram matrix ``J_r J_r^T``, SVD least squares when that solve is inaccurate), one
        pass per step, until the residual stops decreasing tenfold or falls below
        ``1e-2 trigger``; then ``v <- v - J_r^+ J_r v`` with the Jacobian of the last pass
        (at the returned ``q``). The residual is the ``residual`` callable's when one was
        given, else the max-abs of ``r`` (m / rad). Returns ``(q, v, residual)``;
        untouched when the residual is below ``trigger``, except that with ``velocity``
        the velocity is then projected all the same (with the Jacobian at ``q``).

        Raises:
            AssemblyError: the residual stays above ``trigger`` after ``max_iter`` steps.
        """
        if not self.clm.n_rows:         # a tree without closures: nothing to project
            return q, v, 0.0 if self._residual_fn is None else float(self._residual_fn(q))
        model = self.clm.model
        jac = self._closure_pass(q)
        rows = self._rows
        if rows is None:
            rows = self._rows = independent_rows(jac)
        nv, steps = self._nv, self._steps
        step, v_new = steps[0], np.empty(nv)
        err = self._solve_pass(jac, rows, v, step, v_new, q)
        if err <= trigger:
            return q, v_new if velocity else v, err
        for _ in range(max_iter):
            if not math.isfinite(err):
                break
            q_new = pin.integrate(model, q, step)
            jac_new = self._closure_pass(q_new)
            step_new, v_next = steps[1] if step is steps[0] else steps[0], np.empty(nv)
            err_new = self._solve_pass(jac_new, rows, v, step_new, v_next, q_new)
            if not err_new < err:
                break
            q, err, err_old, step, v_new = q_new, err_new, err, step_new, v_next
            if err <= 1e-2 * trigger or err > 0.1 * err_old:
                break
        if not (err <= trigger):
            raise AssemblyError("projection onto the closures failed", err, max_iter, q)
        return q, v_new, err

    def _solve_pass(self, jac, rows, v, step, v_new, q) -> float:
        """After a :meth:`_closure_pass` at ``q``: the Gauss-Newton step
        ``-J_r^+ r_r`` into ``step`` and the projected velocity ``v - J_r^+ J_r v`` into
        ``v_new`` (one compiled Cholesky factorisation of ``J_r J_r^T`` for both; SVD least
        squares when that solve is singular or inaccurate). Returns the residual at ``q``."""
        out = self._out
        if not gauss_newton_pass(jac, self._err, rows, v, step, v_new, out) <= 1e-12:
            jac_r = jac[rows]
            step[:] = -_lstsq(jac_r, self._err[rows])
            v_new[:] = v - _lstsq(jac_r, jac_r @ v)
            out[0] = float(np.max(np.abs(self._err), initial=0.0))
        return float(out[0]) if self._residual_fn is None else float(self._residual_fn(q))


def _on_active_set(hess: np.ndarray, grad: np.ndarray, bound: np.ndarray,
                   upper: np.ndarray, lower: np.ndarray) -> np.ndarray | None:
    """The minimiser of ``1/2 f^T H f + g^T f`` over ``-bound <= f <= bound`` when the
    active set is ``f = bound`` on ``upper``, ``f = -bound`` on ``lower`` (masks) and
    interior elsewhere: the interior part solves ``H_ff f_f = -(g_f + H_fb f_b)``. None
    unless that point satisfies the KKT conditions (interior inside the box, gradient
    ``H f + g`` <= 0 on ``upper`` and >= 0 on ``lower``, to 1e-12 of the scale of ``g``
    and ``H bound``) or the interior block is singular."""
    fixed = upper | lower
    free = ~fixed
    f = np.where(upper, bound, np.where(lower, -bound, 0.0))
    if free.any():
        rhs = -(grad[free] + hess[np.ix_(free, fixed)] @ f[fixed])
        try:
            f[free] = np.linalg.solve(hess[np.ix_(free, free)], rhs)
        except np.linalg.LinAlgError:
            return None
        if np.any(np.abs(f[free]) >= bound[free] * (1.0 - STICK_MARGIN)):
            return None
    gradient = hess @ f + grad
    tol = 1e-12 * (float(np.max(np.abs(grad))) + float(np.max(np.abs(hess))) *
                   float(np.max(bound)))
    if np.any(gradient[upper] > tol) or np.any(gradient[lower] < -tol):
        return None
    return f


def _stick_or_slip(friction: np.ndarray, bound: np.ndarray, v_new: np.ndarray,
                   tol: float) -> np.ndarray:
    """Mask of the coordinates at rest after the step (``|v'| <= tol``: those that stick,
    ``|f| < bound``, and those at the bound that the friction just holds), after checking
    that the others slip against their friction (``f = bound`` with ``v' <= tol``, ``f =
    -bound`` with ``v' >= -tol``).

    Raises:
        SolverError: a coordinate that neither sticks nor slips, naming its force, bound
            and velocity.
    """
    check_stick_slip(friction, bound, v_new, tol, "velocity-level Coulomb friction",
                     np.arange(friction.size), "next velocities (of the friction coordinates)")
    return np.abs(v_new) <= tol


def _lstsq(jac: np.ndarray, rhs: np.ndarray) -> np.ndarray:
    """``J^+ rhs`` by SVD least squares (minimum norm; any rank)."""
    sol, *_ = np.linalg.lstsq(jac, rhs, rcond=None)
    return sol
