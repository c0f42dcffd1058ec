"""Generic closed-loop core: every route on every robot class, against raw Pinocchio,
MuJoCo (the exported model) and an independent null-space reference.

For each robot (upstream-style parallel robots of tests/data, the hard classes of
tests/stress_robots.py, Cassie, Solo-12, the ladder with 1 / 16 / 64 loops) and a few
closure-consistent states:

* forward dynamics, routes "pinocchio", "kkt", "qp": us per call; the raw
  ``pin.constraintDynamics`` with the same constraint models and the settings of our
  "pinocchio" route (mu = 0, one iteration; for redundant rows the route's mu, 1e-8 / max(1,
  max M_ii), 2 iterations),
  and for redundant rows also with mu = 1e-6, 5 iterations (an extra row); MuJoCo's
  ``mj_forward`` on :func:`hexapod_pin.core.mujoco_export.to_mujoco`'s model;
* inverse dynamics, routes "kkt", "qp" (bounded at 10x the needed forces): us per call;
  raw ``pin.rnea`` + ``computeJointJacobians`` + ``getConstraintsJacobian`` + a least-squares
  solve of ``[S J^T] x = rhs``;
* agreement: max relative error of ``a`` against a null-space reference computed here
  with numpy's SVD (forward), and of the reference's acceleration for the returned
  actuator forces against the motion asked for (inverse); failures: states where a route
  raised.

Batches (N = 64): per-state cost of ``forward_dynamics_tree_batch`` /
``inverse_dynamics_tree_batch`` against a loop of single calls. Simulation: one step of
the tree integrator (semi-implicit Euler and RK4) against ``mj_step`` (MuJoCo's Euler
and RK4 integrators) on Cassie and the one-loop ladder.

Run ``python benchmarks/bench_generic.py`` (``--smoke``: two robots, short samples; a
test runs it; ``--integrators``: the integrator table only). Prints Markdown tables;
exits 1 when a route failed a solve or disagreed with the reference by more than
``AGREEMENT``.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from importlib import metadata
from pathlib import Path

import numpy as np
import pinocchio as pin

HERE = Path(__file__).resolve().parent
sys.path.insert(0, str(HERE))
sys.path.insert(0, str(HERE.parent / "tests"))

import ladder
import stress_robots

from hexapod_pin.core.effects import passive_forces
from hexapod_pin.core.dynamics import (
    PIN_PROX_ITERS,
    dynamics_of,
    forward_dynamics_tree,
    inverse_dynamics_tree,
)
from hexapod_pin.core.linear_kernels import kkt_residuals
from hexapod_pin.core.simulation import ClosedLoopIntegrator
from hexapod_pin.core.tree_batch import forward_dynamics_tree_batch, inverse_dynamics_tree_batch
from hexapod_pin.errors import HexapodPinError, InputError
from hexapod_pin.loaders import robots
from hexapod_pin.loaders.parallel_robots import load_parallel_robot

try:
    import mujoco

    from hexapod_pin.core.mujoco_export import mujoco_state, to_mujoco
except ImportError:  # pragma: no cover - the bench extra installs it
    mujoco = None

SAMPLE = {"seconds": 0.05}
#: largest relative error against the null-space reference before the run fails
AGREEMENT = 1e-8


#: the clock of every timing: CPU time of the calling thread (time spent descheduled by
#: other jobs on a shared machine is not counted; every timed call runs on this thread)
CLOCK = time.thread_time


def timing(fn) -> float:
    """Seconds per call: the minimum over 5 samples of at least SAMPLE seconds each."""
    fn()
    t0 = CLOCK()
    fn()
    k = max(1, int(SAMPLE["seconds"] / max(CLOCK() - t0, 1e-6)))
    best = np.inf
    for _ in range(5):
        t0 = CLOCK()
        for _ in range(k):
            fn()
        best = min(best, (CLOCK() - t0) / k)
    return best


def paired(fa, fb, samples: int = 9) -> tuple[float, float]:
    """Seconds per call of ``fa`` and ``fb``, timed in alternating samples (both see the
    same machine load), the minimum over ``samples`` each."""
    k = []
    for fn in (fa, fb):
        fn()
        t0 = CLOCK()
        fn()
        k.append(max(1, int(SAMPLE["seconds"] / max(CLOCK() - t0, 1e-6))))
    best = [np.inf, np.inf]
    for _ in range(samples):
        for i, fn in enumerate((fa, fb)):
            t0 = CLOCK()
            for _ in range(k[i]):
                fn()
            best[i] = min(best[i], (CLOCK() - t0) / k[i])
    return best[0], best[1]


# ----------------------------------------------------------------------------- robots
def _cassie():
    clm = robots.cassie()
    rng = np.random.default_rng(7)

    def sample(rng):
        dq = np.zeros(clm.nv)
        dq[clm.actuated_v] = 0.1 * rng.normal(size=clm.n_actuated)
        q = clm.assemble(pin.integrate(clm.model, pin.neutral(clm.model), dq)).q
        return q, _null_velocity(clm, q, rng)
    del rng
    return "cassie", clm, sample


def _solo():
    clm = robots.solo12()

    def sample(rng):
        q = robots.solo12_stand(clm, [0.01, -0.005, 0.20] + 0.01 * rng.normal(size=3),
                                0.05 * rng.normal(size=3)).q
        return q, _null_velocity(clm, q, rng)
    return "solo12", clm, sample


def _ladder(loops):
    lad = ladder.Ladder(loops)
    clm = ladder.ladder_model(lad)

    def sample(rng):
        q = ladder.configuration(clm, lad, rng.uniform(-0.8, 0.8))
        return q, _null_velocity(clm, q, rng)
    return f"ladder_{loops}", clm, sample


def _parallel(folder):
    clm = load_parallel_robot(HERE.parent / "tests" / "data" / "parallel" / folder)
    robot = stress_robots.build({"five_bar_6d": "five_bar_stiff", "delta": "delta_weld"}[folder])
    home = robot.clm  # same tree, other masses: reuse its sampler's assembly from home

    def sample(rng):
        q, _ = robot.sample(rng)
        return q, _null_velocity(clm, q, rng)
    del home
    return folder, clm, sample


def _stress(name):
    robot = stress_robots.build(name)
    return name, robot.clm, robot.sample


def _null_velocity(clm, q, rng):
    _, sv, vt = np.linalg.svd(clm.constraint_jacobian(q))
    basis = vt[int(np.sum(sv > 1e-10 * sv[0])):].T
    return 0.5 * basis @ rng.normal(size=basis.shape[1])


def _with_drives(entry):
    """A robot of the list with drive effects on every coordinate: armature, damping,
    springs relaxed at a sampled state, Coulomb friction (the states slide)."""
    name, clm, sample = entry
    nv = clm.nv
    ramp = 1.0 + np.arange(nv) / nv
    driven = clm.with_effects(armature=0.02 * ramp, damping=0.5 * ramp, coulomb=0.1 * ramp,
                              stiffness=20.0 * ramp,
                              spring_reference=sample(np.random.default_rng(99))[0])
    return f"{name}+drives", driven, sample


def robot_list(smoke: bool):
    if smoke:
        return [_parallel("five_bar_6d"), _with_drives(_parallel("five_bar_6d")), _ladder(1)]
    return [_parallel("five_bar_6d"), _with_drives(_parallel("five_bar_6d")),
            _parallel("delta"), _with_drives(_parallel("delta")), _stress("five_bar_stiff"),
            _stress("delta_massless"), _stress("planar_ladder_weld"), _stress("ladder_mixed"),
            _cassie(), _solo(), _ladder(1), _ladder(16), _ladder(64)]


# -------------------------------------------------------------------------- reference
def reference(clm, q, v, tau):
    """The acceleration of the null-space method, numpy SVD, with the drive effects
    written here: ``M + diag(armature)`` (on a copy of the tree without Pinocchio's
    armature) and ``tau - D v - K (q - q_ref) - c sign(v)`` (every coordinate of the
    robots here is a vector-space joint; the states slide)."""
    model = pin.Model(clm.model)
    model.armature[:] = 0.0
    data = model.createData()
    eff = clm.effects
    mass = pin.crba(model, data, q) + np.diag(eff.armature)
    mass = np.triu(mass) + np.triu(mass, 1).T
    bias = pin.nonLinearEffects(model, data, q, v)
    tau = tau - eff.damping * v - eff.stiffness * pin.difference(model, eff.spring_reference, q) \
        - eff.coulomb * np.sign(v)
    jac, gamma = clm.constraint_jacobian(q), clm.constraint_drift(q, v)
    _, sv, vt = np.linalg.svd(jac)
    r = int(np.sum(sv > 1e-10 * sv[0]))
    a_p = np.linalg.pinv(jac, rcond=1e-10) @ -gamma
    basis = vt[r:].T
    z = np.linalg.solve(basis.T @ mass @ basis, basis.T @ (tau - bias - mass @ a_p))
    return a_p + basis @ z


def rel(x, ref):
    return float(np.max(np.abs(x - ref)) / max(np.max(np.abs(ref)), 1e-300))


# ------------------------------------------------------------------------------- rows
def make_states(clm, sample, n_states: int):
    """``n_states`` closure-consistent states ``(q, v, u, tau, a_ref)`` (seeded)."""
    rng = np.random.default_rng(0)
    states = []
    for _ in range(n_states):
        q, v = sample(rng)
        u = rng.normal(size=clm.n_actuated)
        tau = np.zeros(clm.nv)
        tau[clm.actuated_v] = u
        states.append((q, v, u, tau, reference(clm, q, v, tau)))
    return states


class PinocchioCalls:
    """The forward-dynamics calls compared with our "pinocchio" route, cycling over
    ``states``: ``raw`` (``pin.constraintDynamics`` on its own model, data and constraint
    models, with the settings of our route: mu = 0 and one iteration, or the route's mu
    (1e-8 / max(1, max M_ii)) and 2 iterations when the rows are redundant), ``raw_user`` (mu = 1e-6, 5 iterations, the
    settings of the issue's first measurements), ``floor`` (the raw call plus what our
    route needs to verify it: ``getConstraintsJacobian`` and the compiled residual kernel,
    no other Python) and ``ours`` (``forward_dynamics_tree``)."""

    def __init__(self, clm, states, redundant: bool):
        self.clm, self.states, self.k = clm, states, 0
        self.model = model = pin.Model(clm.model)
        self.data = data = model.createData()
        self.cms, self.cds = cms, cds = clm.pinocchio_constraints()
        pin.initConstraintDynamics(model, data, cms, cds)
        self.prox = pin.ProximalSettings(1e-13, dynamics_of(clm).redundant_mu if redundant
                                         else 0.0, PIN_PROX_ITERS if redundant else 1)
        self.prox_user = pin.ProximalSettings(1e-13, 1e-6, 5)
        # Pinocchio's buffers, as our route reads them (live views, bound once)
        self.views = (data.M, data.nle, data.primal_rhs_contact[:clm.n_rows], data.lambda_c,
                      np.empty(2))

    def nxt(self):
        self.k = (self.k + 1) % len(self.states)
        return self.states[self.k]

    def raw(self):
        s = self.nxt()
        pin.constraintDynamics(self.model, self.data, s[0], s[1], s[3], self.cms, self.cds,
                               self.prox)

    def raw_user(self):
        s = self.nxt()
        pin.constraintDynamics(self.model, self.data, s[0], s[1], s[3], self.cms, self.cds,
                               self.prox_user)

    def floor(self):
        s = self.nxt()
        model, data, cms, cds = self.model, self.data, self.cms, self.cds
        acc = pin.constraintDynamics(model, data, s[0], s[1], s[3], cms, cds, self.prox)
        jac = pin.getConstraintsJacobian(model, data, cms, cds)
        mass, nle, rhs, lam, out = self.views
        kkt_residuals(mass, nle, s[3], jac, rhs, acc, lam, out)

    def ours(self):
        s = self.nxt()
        forward_dynamics_tree(self.clm, s[0], s[1], s[2])


def bench_robot(name, clm, sample, n_states: int):
    states = make_states(clm, sample, n_states)
    dyn = dynamics_of(clm)
    rank = clm.rank(states[0][0]).rank
    redundant = rank < clm.n_rows
    calls = PinocchioCalls(clm, states, redundant)
    model, data, cms, cds = calls.model, calls.data, calls.cms, calls.cds
    nxt, raw_fd = calls.nxt, calls.raw
    mj = None
    if mujoco is not None:
        try:
            mjm = to_mujoco(clm)
            mjd = mujoco.MjData(mjm)
            mj_states = [mujoco_state(clm, s[0], s[1]) for s in states]

            def mj_fwd():
                s = nxt()
                st = mj_states[calls.k]
                mjd.qpos[:], mjd.qvel[:], mjd.ctrl[:] = st.qpos, st.qvel, s[2]
                mujoco.mj_forward(mjm, mjd)
            mj = timing(mj_fwd)
        except InputError:
            mj = None
    rows = []
    for method in ("pinocchio", "kkt", "qp"):
        fails, err = 0, 0.0
        for q, v, u, _, a_ref in states:
            try:
                res = forward_dynamics_tree(clm, q, v, u, method=method)
                err = max(err, rel(res.a, a_ref))
            except HexapodPinError:
                fails += 1

        def call(method=method):
            s = nxt()
            try:
                forward_dynamics_tree(clm, s[0], s[1], s[2], method=method)
            except HexapodPinError:
                pass
        t, raw = paired(call, raw_fd)
        rows.append((name, clm.nv, f"{clm.n_rows}/{rank}", f"FD {method}", t, raw, mj, err,
                     fails, n_states))
        if method == "pinocchio":
            t_floor, raw = paired(calls.floor, raw_fd)
            rows.append((name, clm.nv, f"{clm.n_rows}/{rank}",
                         "raw + its verification (no other Python)", t_floor, raw, mj, None,
                         0, n_states))
        if method == "pinocchio" and redundant:
            t_user, raw = paired(calls.raw_user, raw_fd)
            rows.append((name, clm.nv, f"{clm.n_rows}/{rank}", "raw, mu 1e-6, 5 iterations",
                         t_user, raw, mj, None, 0, n_states))
    # inverse dynamics
    sel = np.zeros((clm.nv, clm.n_actuated))
    sel[clm.actuated_v, np.arange(clm.n_actuated)] = 1.0

    def raw_id():
        q, v, _, _, a = nxt()
        rhs = pin.rnea(model, data, q, v, a)
        pin.computeJointJacobians(model, data, q)
        jac = pin.getConstraintsJacobian(model, data, cms, cds)
        np.linalg.lstsq(np.hstack([sel, jac.T]), rhs, rcond=None)
    for method, bounded in (("kkt", False), ("qp", True)):
        fails, err = 0, 0.0
        for q, v, u, _, a_ref in states:
            try:
                res = inverse_dynamics_tree(clm, q, v, a_ref, method=method,
                                            bounds=10 * np.abs(u).max() if bounded else None)
                # the reference forward dynamics of the returned forces gives the motion back
                # (u itself is not unique on a redundantly actuated robot such as Solo-12)
                tau = np.zeros(clm.nv)
                tau[clm.actuated_v] = res.actuator_forces
                err = max(err, rel(reference(clm, q, v, tau), a_ref))
            except HexapodPinError:
                fails += 1

        def call(method=method, bounded=bounded):
            q, v, u, _, a = nxt()
            try:
                inverse_dynamics_tree(clm, q, v, a, method=method,
                                      bounds=10 * np.abs(u).max() if bounded else None)
            except HexapodPinError:
                pass
        t, raw = paired(call, raw_id)
        rows.append((name, clm.nv, f"{clm.n_rows}/{rank}",
                     f"ID {method}" + (" (bounded)" if bounded else ""), t, raw, None, err,
                     fails, n_states))
    return rows, states, dyn


def bench_batch(name, clm, states, n: int = 64):
    q = np.array([states[i % len(states)][0] for i in range(n)])
    v = np.array([states[i % len(states)][1] for i in range(n)])
    u = np.array([states[i % len(states)][2] for i in range(n)])
    a = np.array([states[i % len(states)][4] for i in range(n)])
    t_fb = timing(lambda: forward_dynamics_tree_batch(clm, q, v, u)) / n
    t_fl = timing(lambda: [forward_dynamics_tree(clm, q[i], v[i], u[i]) for i in range(n)]) / n
    t_ib = timing(lambda: inverse_dynamics_tree_batch(clm, q, v, a, method="kkt")) / n
    t_il = timing(lambda: [inverse_dynamics_tree(clm, q[i], v[i], a[i], method="kkt")
                           for i in range(n)]) / n
    return name, n, t_fb, t_fl, t_ib, t_il


def bench_step(name, clm, states, dt: float = 1e-3):
    """One step from the same state (a falling robot would leave its workspace): us per
    step of each integrator and of ``mj_step`` (MuJoCo's Euler and RK4 integrators; each
    integrator timed in alternating samples with its MuJoCo counterpart, so that both see
    the same machine load), and the largest closure residual after the step, checked here
    with ``ClosedLoopModel.residual`` (m / rad)."""
    out = {}
    q0, v0 = states[0][0], states[0][1]
    tau = np.zeros(clm.nv)
    for integ, mj_integ, key in (("semi_implicit_euler", "mjINT_EULER", "mj_step"),
                                 ("rk4", "mjINT_RK4", "mj_step_rk4")):
        sim = ClosedLoopIntegrator(clm, integrator=integ)
        residual = max(float(np.max(np.abs(clm.residual(sim.step(q0, v0, tau, dt)[0]))))
                       for _ in range(3))

        def step(sim=sim):
            sim.step(q0, v0, tau, dt)
        if mujoco is None:
            out[integ] = (timing(step), residual)
            continue
        mjm = to_mujoco(clm, timestep=dt)
        mjm.opt.integrator = getattr(mujoco.mjtIntegrator, mj_integ)
        mjd = mujoco.MjData(mjm)
        st = mujoco_state(clm, q0, v0)

        def mj_step(mjm=mjm, mjd=mjd, st=st):
            mjd.qpos[:], mjd.qvel[:] = st.qpos, st.qvel
            mujoco.mj_step(mjm, mjd)
        t_ours, t_mj = paired(step, mj_step)
        out[integ] = (t_ours, residual)
        out[key] = (t_mj, float("nan"))
    return name, out


def bench_overhead(name, clm, sample, runs: int = 7):
    """Our "pinocchio" route and the floor of a verified call against the raw call, each
    pair timed :func:`paired` ``runs`` times (states cycled): the median ratio and its
    range over the runs, and the smallest us per call of each."""
    states = make_states(clm, sample, 5)
    calls = PinocchioCalls(clm, states, clm.rank(states[0][0]).rank < clm.n_rows)
    ratios: dict[str, list[float]] = {"ours": [], "floor": []}
    best = {"ours": np.inf, "floor": np.inf, "raw": np.inf}
    for _ in range(runs):
        for key in ("ours", "floor"):
            t, raw = paired(getattr(calls, key), calls.raw)
            ratios[key].append(t / raw)
            best[key], best["raw"] = min(best[key], t), min(best["raw"], raw)
    return name, clm.nv, {k: (float(np.median(r)), min(r), max(r)) for k, r in ratios.items()}, best


def print_overhead() -> None:
    """The table of ``--overhead``: our route and the verification floor against raw."""
    print("| robot | nv | raw us | ours us | ours / raw: median (range) | floor us | "
          "floor / raw: median (range) | ours - raw us |")
    print("|---|---|---|---|---|---|---|---|")
    for name, clm, sample in robot_list(False):
        if name in ("delta_massless", "ladder_64"):     # exact route / minutes per run
            continue
        _, nv, rat, best = bench_overhead(name, clm, sample)
        (om, olo, ohi), (fm, flo, fhi) = rat["ours"], rat["floor"]
        print(f"| {name} | {nv} | {_us(best['raw'])} | {_us(best['ours'])} | {om:.2f} "
              f"({olo:.2f}-{ohi:.2f}) | {_us(best['floor'])} | {fm:.2f} ({flo:.2f}-{fhi:.2f}) "
              f"| {_us(best['ours'] - best['raw'])} |")


# ------------------------------------------------------------------------------ report
def mujoco_effects_agreement(clm, states) -> tuple[float, float] | None:
    """Max relative errors of MuJoCo's ``mj_fullM`` (armature included) and
    ``qfrc_passive`` (damping, springs) on the exported model against ours (the tree's
    mass matrix plus the armature, :func:`~hexapod_pin.core.effects.passive_forces`) over
    ``states``; None without MuJoCo, on a tree with ball / free joints (other velocity
    conventions) or when the export is refused."""
    if mujoco is None or clm.model.nq != clm.model.nv:
        return None
    try:
        mjm = to_mujoco(clm)
    except InputError:
        return None
    mjd = mujoco.MjData(mjm)
    err_m = err_p = 0.0
    for q, v, *_ in states:
        st = mujoco_state(clm, q, v)
        mjd.qpos[:], mjd.qvel[:] = st.qpos, st.qvel
        mujoco.mj_forward(mjm, mjd)
        full = np.zeros((mjm.nv, mjm.nv))
        mujoco.mj_fullM(mjm, mjd, full)
        ours_m = pin.crba(clm.model, clm.model.createData(), q)
        ours_m = np.triu(ours_m) + np.triu(ours_m, 1).T
        err_m = max(err_m, rel(full, ours_m))
        ours_p = passive_forces(clm.model, clm.effects, q, v)
        if np.abs(ours_p).max() > 0:
            err_p = max(err_p, rel(np.asarray(mjd.qfrc_passive), ours_p))
    return err_m, err_p


def print_mujoco_effects(kept, bad) -> None:
    print("\n| robot (MuJoCo export) | armature, damping, springs | mj_fullM vs M + armature | "
          "qfrc_passive vs -D v - K dq |")
    print("|---|---|---|---|")
    for name, clm, states in kept:
        got = mujoco_effects_agreement(clm, states)
        if got is None:
            continue
        eff = clm.effects
        what = ", ".join(k for k, x in (("armature", eff.armature), ("damping", eff.damping),
                                        ("springs", eff.stiffness)) if np.any(x)) or "none"
        print(f"| {name} | {what} | {got[0]:.1e} | {got[1]:.1e} |")
        # the export pads point masses with tiny inertias (core.mujoco_export): 1e-9
        if not max(got) <= 1e-9:
            bad.append(f"{name} MuJoCo export: mass matrix {got[0]:.1e}, passive {got[1]:.1e}")


def print_steps(kept) -> None:
    """The integrator table: one step on Cassie and the one-loop ladder (of ``kept``,
    ``(name, clm, states)`` triples) against ``mj_step``."""
    print("\n| robot | semi-implicit Euler us/step | mj_step (Euler) us | ratio | RK4 us/step | "
          "mj_step (RK4) us | ratio | max closure residual |")
    print("|---|---|---|---|---|---|---|---|")
    for name, clm, states in kept:
        if name not in ("cassie", "ladder_1"):
            continue
        _, out = bench_step(name, clm, states)
        mj = out.get("mj_step", (None, 0.0))[0]
        mj4 = out.get("mj_step_rk4", (None, 0.0))[0]
        sie, rk4 = out["semi_implicit_euler"][0], out["rk4"][0]
        res = max(out["semi_implicit_euler"][1], out["rk4"][1])
        print(f"| {name} | {_us(sie)} | {_us(mj)} | {_ratio(sie, mj)} | {_us(rk4)} | "
              f"{_us(mj4)} | {_ratio(rk4, mj4)} | {res:.1e} |")


def machine() -> str:
    versions = ", ".join(f"{p} {metadata.version(p)}" for p in
                         ("pin", "proxsuite", "numpy", "numba", "mujoco")
                         if _has(p))
    return (f"{platform.processor() or platform.machine()}, {os.cpu_count()} cores, "
            f"Python {platform.python_version()}, {versions}, "
            f"OPENBLAS_NUM_THREADS={os.environ.get('OPENBLAS_NUM_THREADS', 'unset')}")


def _has(package: str) -> bool:
    try:
        metadata.version(package)
        return True
    except metadata.PackageNotFoundError:
        return False


def _us(x):
    return "-" if x is None else f"{1e6 * x:.1f}"


def _ratio(x, ref):
    return "-" if ref is None else f"{x / ref:.2f}"


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="two robots, short samples")
    parser.add_argument("--integrators", action="store_true",
                        help="the integrator table only (Cassie and the one-loop ladder)")
    parser.add_argument("--overhead", action="store_true",
                        help="the forward-dynamics overhead table only: our 'pinocchio' "
                             "route and the verification floor against the raw call, seven "
                             "paired runs per robot")
    args = parser.parse_args(argv)
    if args.smoke:
        SAMPLE["seconds"] = 0.002
    n_states = 2 if args.smoke else 5
    print(f"machine: {machine()}\n")
    if args.overhead:
        print_overhead()
        return 0
    if args.integrators:
        kept = []
        for name, clm, sample in (_cassie(), _ladder(1)):
            q, v = sample(np.random.default_rng(0))    # the first state of bench_robot
            kept.append((name, clm, [(q, v)]))
        print_steps(kept)
        return 0
    print("| robot | nv | rows/rank | route | us/call | raw Pinocchio us | ratio | "
          "mj_forward us | ratio to mj | max rel. error vs null-space | failed |")
    print("|---|---|---|---|---|---|---|---|---|---|---|")
    kept = []
    bad = []
    for name, clm, sample in robot_list(args.smoke):
        rows, states, _ = bench_robot(name, clm, sample, n_states)
        kept.append((name, clm, states))
        for (rname, nv, rr, route, t, raw, mj, err, fails, n) in rows:
            if fails or (err is not None and not err <= AGREEMENT):
                bad.append(f"{rname} {route}: {fails} failed, error {err:.1e}")
            ratio_mj = "-" if mj is None or not route.startswith("FD") else f"{t / mj:.2f}"
            print(f"| {rname} | {nv} | {rr} | {route} | {_us(t)} | {_us(raw)} | "
                  f"{t / raw:.2f} | {_us(mj) if route.startswith('FD') else '-'} | {ratio_mj} | "
                  f"{'-' if err is None else f'{err:.1e}'} | {fails}/{n} |")
    print("\n| robot | N | FD batch us/state | FD loop us/state | ID batch us/state | "
          "ID loop us/state |")
    print("|---|---|---|---|---|---|")
    for name, clm, states in kept[-2:] if args.smoke else kept:
        if name not in ("cassie", "ladder_16", "planar_ladder_weld", "ladder_1", "five_bar_6d"):
            continue
        _, n, fb, fl, ib, il = bench_batch(name, clm, states, 8 if args.smoke else 64)
        print(f"| {name} | {n} | {_us(fb)} | {_us(fl)} | {_us(ib)} | {_us(il)} |")
    print_mujoco_effects(kept, bad)
    print_steps(kept)
    if bad:
        print("\nDISAGREEMENT OR FAILED SOLVES:\n" + "\n".join(bad))
        return 1
    return 0


if __name__ == "__main__":
    sys.exit(main())
