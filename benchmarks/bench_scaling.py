"""Scaling of the closed-loop dynamics: time against batch size and against closures.

Prints (Markdown tables):

1. hexapod, microseconds per state against the batch size N = 1 ... 10^6 for inverse and
   forward dynamics and one simulation step (ours, raw Pinocchio, MuJoCo, numpy);
2. microseconds per call against the number of closures, on the tree level (generic
   ``ClosedLoopModel``): the planar 3-PRR (3 point closures, 9 rows of rank 6), the
   hexapod (6 closures, 18 rows) and ladders of n spatial four-bars (n closures, 3 n rows,
   ``3 n + 1`` dofs; see ladder.py), each route checked against the others;
3. the planar 3-PRR against its MuJoCo twin (mjcf_planar.py) at the task level, with a
   platform wrench: the MJCF checked against our Pinocchio model (kinematics, inertia),
   then inverse / forward dynamics and one step, MuJoCo vs ``Planar3PRR``'s own routes,
   raw Pinocchio and our integrator.

Usage (from the repository root)::

    python benchmarks/bench_scaling.py            # full run
    python benchmarks/bench_scaling.py --smoke    # seconds; exit 1 when routes disagree
    python benchmarks/bench_scaling.py --only-planar   # the planar rows and section only
"""

from __future__ import annotations

import os

# tiny dense matrices: BLAS threads only add contention (set before numpy loads)
os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")
os.environ.setdefault("OMP_NUM_THREADS", "1")

import argparse  # noqa: E402
import sys  # noqa: E402
from dataclasses import dataclass, field  # noqa: E402

import numpy as np  # noqa: E402

import hexapod_pin as hp  # noqa: E402
import hexapod_pin.core.dynamics as hpd  # noqa: E402
import ladder as lad_mod  # noqa: E402
import pinocchio_raw as pr  # noqa: E402
from bench_common import MIN_SAMPLE, NO_ROUTE, fmt_us, measure, print_machine_info, table  # noqa: E402
from bench_peers import DT, RIGID_TOL, HexapodPeers, time_route  # noqa: E402

try:
    import mujoco

    import mjcf
    import mjcf_planar
except ImportError:
    mujoco = None

#: MuJoCo's refined (rigid) forward dynamics: its floor grows with the conditioning of
#: MuJoCo's soft problem (1e-10 for one loop, 2.6e-8 for 64 loops)
MUJOCO_REFINED_TOL = 1e-7
#: sanity bound on MuJoCo's soft forward dynamics of the planar 3-PRR (m/s^2, rad/s^2):
#: measured up to 1.1e-2 over 1000 states (the regulariser R ~ 1e-4 A_ii, see mjcf.py)
PLANAR_SOFT_BOUND = 0.1


# -- 1. batch size -------------------------------------------------------------------------
BATCH_ROUTES = {
    "inverse dynamics": ["ours inverse_dynamics kkt, no joint wrenches",
                         "ours fast.inverse_dynamics (numba)",
                         "ours inverse_dynamics_batch",
                         "raw Pinocchio rnea + solve (tree state given)",
                         "MuJoCo mj_inverse + reduction (tree state given)",
                         "numpy Newton-Euler"],
    "forward dynamics": ["ours forward_dynamics pinocchio", "ours forward_dynamics_batch",
                         "ours fast.forward_dynamics_full (numba)",
                         "raw Pinocchio constraintDynamics (tree state given)",
                         "MuJoCo mj_forward (soft closures, tree state given)",
                         "numpy Newton-Euler"],
    "simulation step": ["ours ClosedLoopIntegrator.step rk4 (tree state given)",
                        "ours ClosedLoopIntegrator.step semi_implicit_euler (tree state given)",
                        "raw Pinocchio constraintDynamics + integrate",
                        "MuJoCo mj_step (Euler, soft closures, tree state given)",
                        "numpy semi-implicit Euler"],
}


def batch_scaling(sizes, repeats, budget, mem_limit) -> str:
    peers = HexapodPeers(hp.HexapodGeometry(), max(sizes), n_tree=64)
    out = []
    history: dict = {}
    for op in peers.operations():
        key = op.name.split(" (")[0]
        if key not in BATCH_ROUTES:
            continue
        rows = []
        for route in op.routes:
            if route.name not in BATCH_ROUTES[key]:
                continue
            cells = [time_route(route, peers, n, repeats if n < 10 ** 5 else max(3, repeats // 2),
                                budget, mem_limit, history) for n in sizes]
            kind = "batch" if route.batch is not None else "loop"
            rows.append([f"{route.name} ({kind})"] + [fmt_us(c) for c in cells])
        out.append(table(["route"] + [f"N = {_n(n)}" for n in sizes], rows,
                         title=f"### {op.name}: us per state against N"))
    return "\n".join(out)


def _n(n: int) -> str:
    return f"10^{int(np.log10(n))}" if n >= 1000 else str(n)


# -- 2. closures ---------------------------------------------------------------------------
@dataclass
class Mechanism:
    """A closed-loop model, a pool of consistent tree states, and its MuJoCo twin."""

    name: str
    clm: hp.ClosedLoopModel
    states: list                      # (q, v, a) Pinocchio tree states
    mj_model: object = None
    mj_states: list = field(default_factory=list)   # (qpos, qvel, qacc)
    mj_dofs: np.ndarray | None = None  # MuJoCo dof of each 1-DoF Pinocchio joint's v index
    pin_dofs: np.ndarray | None = None

    def __post_init__(self):
        self.raw = pr.RawPinocchio(self.clm)
        rank = self.clm.rank(self.states[0][0]).rank
        self.rank = rank
        self.raw.set_redundant(rank < self.clm.n_rows)
        self.forces = [self.raw.inverse(*s) for s in self.states]
        if self.mj_model is not None:
            m = self.mj_model
            self.mj_data = mujoco.MjData(m)
            self.mj_selection = np.zeros((m.nv, self.clm.n_actuated))
            for k, joint in enumerate(self.clm.actuated_joints):
                self.mj_selection[m.joint(joint).dofadr[0], k] = 1.0

    @property
    def label(self) -> str:
        return (f"{self.name} ({len(self.clm.closures)} closures, {self.clm.n_rows} rows"
                f"{'' if self.rank == self.clm.n_rows else f' rank {self.rank}'}, "
                f"nv {self.clm.nv})")

    def routes(self) -> dict[str, tuple[str, callable]]:
        """name -> (kind "id" / "fd", fn(i)) ; fd returns the tree acceleration (Pinocchio
        v order, 1-DoF joints only for MuJoCo)."""
        clm, raw, st, f = self.clm, self.raw, self.states, self.forces

        out = {
            "ours FD pinocchio": ("fd", lambda i: hpd.forward_dynamics_tree(
                clm, st[i][0], st[i][1], f[i], method="pinocchio").a),
            "ours FD kkt": ("fd", lambda i: hpd.forward_dynamics_tree(
                clm, st[i][0], st[i][1], f[i], method="kkt").a),
            "ours FD qp": ("fd", lambda i: hpd.forward_dynamics_tree(
                clm, st[i][0], st[i][1], f[i], method="qp").a),
            "raw constraintDynamics": ("fd", lambda i: raw.forward(st[i][0], st[i][1], f[i])),
            "raw crba+KKT": ("fd", lambda i: raw.forward_kkt(st[i][0], st[i][1], f[i])),
            "ours ID kkt": ("id", lambda i: hpd.inverse_dynamics_tree(
                clm, *st[i], method="kkt").actuator_forces),
            "ours ID qp": ("id", lambda i: hpd.inverse_dynamics_tree(
                clm, *st[i], method="qp").actuator_forces),
            "raw rnea+solve": ("id", lambda i: raw.inverse(*st[i])),
        }
        if self.mj_model is not None:
            m, d = self.mj_model, self.mj_data

            def mj_fd(i, refine=False):
                d.qpos[:], d.qvel[:] = self.mj_states[i][0], self.mj_states[i][1]
                d.ctrl[:] = f[i]
                mujoco.mj_forward(m, d)
                if refine:
                    mjcf.refine_forward(m, d)
                acc = np.full(clm.nv, np.nan)
                acc[self.pin_dofs] = d.qacc[self.mj_dofs]
                return acc

            def mj_id(i):
                d.qpos[:], d.qvel[:], d.qacc[:] = self.mj_states[i]
                mujoco.mj_inverse(m, d)
                return mjcf.reduce_to_actuators(self.mj_selection, d.qfrc_inverse,
                                                d.efc_J.reshape(d.nefc, m.nv))
            out["MuJoCo mj_forward"] = ("fd", mj_fd)
            out["MuJoCo refined"] = ("fd", lambda i: mj_fd(i, True))
            out["MuJoCo mj_inverse+reduce"] = ("id", mj_id)
        return out


def _one_dof_maps(clm, mj_model):
    pin_dofs, mj_dofs = [], []
    model = clm.model
    for j in range(1, model.njoints):
        joint = model.joints[j]
        if joint.nv == 1:
            pin_dofs.append(joint.idx_v)
            mj_dofs.append(mj_model.joint(model.names[j]).dofadr[0])
    return np.array(pin_dofs), np.array(mj_dofs)


def ladder_mechanism(n_loops: int, n_states: int, seed: int = 0) -> Mechanism:
    lad = lad_mod.Ladder(n_loops)
    clm = lad_mod.ladder_model(lad)
    rng = np.random.default_rng(seed)
    states = []
    mj_model = mujoco.MjModel.from_xml_string(lad_mod.ladder_mjcf(lad)) if mujoco else None
    mj_states = []
    for _ in range(n_states):
        theta = rng.uniform(0.2, 0.6)
        q = lad_mod.configuration(clm, lad, theta)
        v = clm.complete_velocity(q, clm.actuated_v, rng.uniform(-1, 1, 1))
        a = clm.complete_acceleration(q, v, clm.actuated_v, rng.uniform(-2, 2, 1))
        states.append((q, v, a))
        if mj_model is not None:
            qpos = np.zeros(mj_model.nq)
            qvel, qacc = np.zeros(mj_model.nv), np.zeros(mj_model.nv)
            for name, value in lad_mod.joint_values(lad, theta).items():
                jid = clm.model.getJointId(name)
                iv = clm.model.joints[jid].idx_v
                qpos[mj_model.joint(name).qposadr[0]] = value
                qvel[mj_model.joint(name).dofadr[0]] = v[iv]
                qacc[mj_model.joint(name).dofadr[0]] = a[iv]
            mj_states.append((qpos, qvel, qacc))
    mech = Mechanism(f"ladder n={n_loops}", clm, states, mj_model, mj_states)
    if mj_model is not None:
        mech.pin_dofs, mech.mj_dofs = _one_dof_maps(clm, mj_model)
    return mech


def hexapod_mechanism(n_states: int) -> Mechanism:
    peers = HexapodPeers(hp.HexapodGeometry(), n_states, n_tree=n_states)
    zero = np.zeros(6)
    states = [peers.raw.tree_state(peers.poses[i], peers.twists[i], peers.twist_dots[i])
              for i in range(n_states)]
    mj_states = []
    mj_model = None
    if peers.mj is not None:
        mj_model = peers.mj.model
        mj_states = [peers.mj.set_task_state(peers.poses[i], peers.twists[i],
                                             peers.twist_dots[i]) for i in range(n_states)]
    del zero
    mech = Mechanism("hexapod", peers.robot.model, states, mj_model, mj_states)
    if mj_model is not None:
        mech.pin_dofs, mech.mj_dofs = _one_dof_maps(peers.robot.model, mj_model)
    return mech


def planar_states(robot, n_states: int, seed: int = 0):
    """n random planar states ``(pose, twist, twist_dot, wrench)``, each (3,), near home
    (+-2 cm, +-0.1 rad; twist +-0.1 m/s, +-0.5 rad/s; twist_dot +-1 m/s^2, +-3 rad/s^2;
    wrench +-5 N, +-0.3 N m), reachable (rejection sampling)."""
    rng = np.random.default_rng(seed)
    out = []
    while len(out) < n_states:
        pose = robot.home_pose + rng.uniform(-1, 1, 3) * np.array([0.02, 0.02, 0.1])
        twist = rng.uniform(-1, 1, 3) * np.array([0.1, 0.1, 0.5])
        twist_dot = rng.uniform(-1, 1, 3) * np.array([1.0, 1.0, 3.0])
        wrench = rng.uniform(-1, 1, 3) * np.array([5.0, 5.0, 0.3])
        try:
            robot.jacobian(pose)
        except hp.HexapodPinError:
            continue
        out.append((pose, twist, twist_dot, wrench))
    return out


def planar_mechanism(n_states: int, seed: int = 0) -> Mechanism | None:
    try:
        from hexapod_pin.planar.robot import Planar3PRR
    except ImportError:
        return None
    robot = Planar3PRR.default()
    samples = planar_states(robot, n_states, seed)
    states = [(robot.configuration(p), robot.velocity(p, t), robot.acceleration(p, t, td))
              for p, t, td, _ in samples]
    mj = mjcf_planar.MujocoPlanar(robot.geometry, timestep=DT) if mujoco else None
    mech = Mechanism("planar 3-PRR", robot.model, states,
                     None if mj is None else mj.model,
                     [] if mj is None else [mj.set_task_state(*s[:3]) for s in samples])
    if mj is not None:
        mech.pin_dofs, mech.mj_dofs = _one_dof_maps(robot.model, mj.model)
    return mech


def closure_scaling(ladders, n_states, repeats, check: bool, hexapod: bool = True):
    """Accuracy and timing tables against closures; returns (text, failures)."""
    mechs = []
    planar = planar_mechanism(n_states)
    if planar is not None:
        mechs.append(planar)
    if hexapod:
        mechs.append(hexapod_mechanism(n_states))
    mechs += [ladder_mechanism(n, n_states) for n in ladders]
    names = list(dict.fromkeys(k for m in mechs for k in m.routes()))
    acc_rows, time_rows, failures = [], [], []
    for mech in mechs:
        routes = mech.routes()
        acc_row, time_row = [mech.label], [mech.label]
        for name in names:
            if name not in routes:
                acc_row.append(NO_ROUTE)
                time_row.append(NO_ROUTE)
                continue
            kind, fn = routes[name]
            worst = 0.0
            for i in range(len(mech.states)):
                if kind == "id":
                    diff = np.abs(fn(i) - mech.forces[i])
                else:
                    acc = fn(i)
                    diff = np.abs(acc - mech.states[i][2])[np.isfinite(acc)]
                worst = max(worst, float(np.max(diff)))
            # MuJoCo's soft answer is reported, not asserted (its error grows with the
            # number of loops: 8 rad/s^2 for 64); the refined one has a conditioning floor
            tol = {"MuJoCo mj_forward": np.inf, "MuJoCo refined": MUJOCO_REFINED_TOL}.get(
                name, RIGID_TOL)
            flag = "" if worst <= tol else " FAIL"
            if flag:
                failures.append(f"{mech.name} {name}: {worst:.2e} > {tol:g}")
            acc_row.append(f"{worst:.1e}{flag}")
            counter, pool = iter(range(10 ** 12)), len(mech.states)
            time_row.append(fmt_us(measure(
                lambda fn=fn, counter=counter, pool=pool: fn(next(counter) % pool),
                repeats=repeats)))
        acc_rows.append(acc_row)
        time_rows.append(time_row)
    text = table(["mechanism"] + names, acc_rows,
                 title="### accuracy against the reference (ID: raw rnea+solve forces, N or "
                       "N m; FD: the sampled tree acceleration), max abs over the states")
    text += "\n" + table(["mechanism"] + names, time_rows,
                         title="### us per call (one state), median [inter-quartile range]")
    return text, failures


# -- 3. the planar 3-PRR against MuJoCo, task level ----------------------------------------
class RawPlanar(pr.RawPinocchio):
    """:class:`pinocchio_raw.RawPinocchio` on the planar tree, with its platform wrench.

    The platform chain's joints are world x, world y and z through the platform origin, so
    the generalised force of a wrench ``(fx, fy, mz)`` (world axes, moment about the
    origin) is the wrench itself on those three dofs.
    """

    def __init__(self, robot):
        super().__init__(robot.model)
        self.set_redundant(True)
        self.platform_v = robot.indices.platform

    def wrench_generalised(self, wrench) -> np.ndarray:
        out = np.zeros(self.nv)
        if wrench is not None:
            out[self.platform_v] = wrench
        return out


@dataclass
class PlanarRoute:
    """One route of the planar task-level comparison."""

    name: str
    output: str                 # "forces", "acceleration" or "step"
    fn: callable                # i -> array, Pinocchio order (forces: slider order)
    tol: float
    note: str = "rigid"


def planar_routes(n_states: int, seed: int = 0):
    """The planar routes, their reference outputs, and the MJCF check (dict or None)."""
    from hexapod_pin.planar.robot import Planar3PRR
    from hexapod_pin.hexapod.simulation import ClosedLoopIntegrator

    robot = Planar3PRR.default()
    raw = RawPlanar(robot)
    samples = planar_states(robot, n_states, seed)
    tree = [(robot.configuration(p), robot.velocity(p, t), robot.acceleration(p, t, td))
            for p, t, td, _ in samples]
    wrenches = [s[3] for s in samples]
    forces = [raw.inverse(*tree[i], wrenches[i]) for i in range(n_states)]
    # semi-implicit Euler of the sampled motion (1-DoF joints: q+ = q + dt v+)
    steps = [np.concatenate([q + DT * (v + DT * a), v + DT * a]) for q, v, a in tree]
    ref = {"forces": forces, "acceleration": [t[2] for t in tree], "step": steps}
    integ = ClosedLoopIntegrator(robot.model, "pinocchio", "semi_implicit_euler")
    idx = robot.indices

    def tree_tau(i):
        tau = np.zeros(robot.model.nv)
        tau[idx.slider], tau[idx.platform] = forces[i], wrenches[i]
        return tau

    def ours_step(i):
        q1, v1, _ = integ.step(tree[i][0], tree[i][1], tree_tau(i), DT)
        return np.concatenate([q1, v1])

    # the projection onto the closures moves (q, v) by O(dt^2) (closure residual of
    # q + dt v+, and J(q+) v+): measured 5.8e-6 over 1000 states with max |a| = 8
    scheme_tol = 10 * DT ** 2 * max(np.max(np.abs(a)) for _, _, a in tree) + RIGID_TOL
    routes = []
    for method in ("kkt", "qp"):
        routes.append(PlanarRoute(
            f"ours Planar3PRR.inverse_dynamics {method}", "forces",
            lambda i, m=method: robot.inverse_dynamics(*samples[i], method=m).actuator_forces,
            RIGID_TOL))
    routes.append(PlanarRoute("raw Pinocchio rnea + lstsq (tree state given) [reference]",
                              "forces", lambda i: raw.inverse(*tree[i], wrenches[i]),
                              RIGID_TOL))
    for method in ("nullspace", "qp", "pinocchio"):
        routes.append(PlanarRoute(
            f"ours Planar3PRR.forward_dynamics {method}", "acceleration",
            lambda i, m=method: robot.forward_dynamics(
                *samples[i][:2], forces[i], samples[i][3], method=m).tree_acceleration,
            RIGID_TOL))
    routes.append(PlanarRoute("raw Pinocchio constraintDynamics mu=1e-2 (tree state given)",
                              "acceleration",
                              lambda i: raw.forward(*tree[i][:2], forces[i], wrenches[i]),
                              RIGID_TOL))
    routes.append(PlanarRoute("raw Pinocchio constraintDynamics + integrate", "step",
                              lambda i: np.concatenate(raw.step(*tree[i][:2], forces[i], DT,
                                                                wrenches[i])), RIGID_TOL))
    routes.append(PlanarRoute("ours ClosedLoopIntegrator.step semi_implicit_euler "
                              "(tree state given)", "step", ours_step, scheme_tol,
                              "projection onto the closures, O(dt^2)"))
    check = None
    if mujoco is not None:
        mj = mjcf_planar.MujocoPlanar(robot.geometry, timestep=DT)
        perm = mjcf_planar.dof_permutation(mj, robot.model.model)
        check = mjcf_planar.model_check(robot, mj, *zip(*(s[:3] for s in samples[:20])))
        mj_state = [mj.set_task_state(*s[:3]) for s in samples]

        def mj_step(i, refine):
            qpos, qvel = mj.step(*mj_state[i][:2], forces[i], wrenches[i], refine=refine)
            return np.concatenate([qpos[perm], qvel[perm]])

        routes += [
            PlanarRoute("MuJoCo mj_inverse + reduction, in-plane rows, solve (tree state "
                        "given)", "forces",
                        lambda i: mj.inverse_tree_state(*mj_state[i], wrenches[i]),
                        RIGID_TOL),
            PlanarRoute("MuJoCo mj_inverse + reduction, all 9 rows, lstsq (tree state given)",
                        "forces", lambda i: mj.inverse_tree_state(*mj_state[i], wrenches[i],
                                                                  rows="all"), RIGID_TOL),
            PlanarRoute("MuJoCo incl. closed-form qpos + completion", "forces",
                        lambda i: mj.inverse_task(*samples[i]), RIGID_TOL),
            PlanarRoute("MuJoCo mj_forward (soft closures, tree state given)",
                        "acceleration", lambda i: mj.forward(
                            *mj_state[i][:2], forces[i], wrenches[i])[perm],
                        PLANAR_SOFT_BOUND, "soft: sanity bound only"),
            PlanarRoute("MuJoCo + proximal refinement (rigid, tree state given)",
                        "acceleration", lambda i: mj.forward(
                            *mj_state[i][:2], forces[i], wrenches[i], refine=True)[perm],
                        MUJOCO_REFINED_TOL, "rigid, conditioning floor"),
            PlanarRoute("MuJoCo mj_step (Euler, soft closures, tree state given)", "step",
                        lambda i: mj_step(i, False), DT * PLANAR_SOFT_BOUND,
                        "soft: sanity bound only"),
            PlanarRoute("MuJoCo refined + mj_Euler (rigid, tree state given)", "step",
                        lambda i: mj_step(i, True), MUJOCO_REFINED_TOL,
                        "rigid, conditioning floor"),
        ]
    order = {"forces": 0, "acceleration": 1, "step": 2}
    routes.sort(key=lambda r: order[r.output])
    return routes, ref, check


PLANAR_OUTPUTS = {
    "forces": "inverse dynamics: actuator forces (N); reference raw Pinocchio rnea + lstsq",
    "acceleration": "forward dynamics of the reference forces: tree acceleration (m/s^2, "
                    "rad/s^2); reference the sampled one",
    "step": f"one step dt = {DT:g} s: tree (q, v) (m, rad, m/s, rad/s); reference semi-"
            "implicit Euler of the sampled acceleration",
}


def planar_vs_mujoco(n_states: int, repeats: int, timing: bool = True):
    """Planar task-level tables (MJCF check, accuracy and us per call); (text, failures)."""
    try:
        routes, ref, check = planar_routes(n_states)
    except ImportError:
        return "planar model not available", []
    failures, text = [], []
    if check is None:
        text.append("mujoco is not installed: MuJoCo rows are skipped")
    else:
        rows = [[mjcf_planar.CHECKS[k][0], f"{v:.1e}", mjcf_planar.CHECKS[k][1]]
                for k, v in check.items()]
        text.append(table(["MJCF check (max over states)", "max abs", "unit"], rows,
                          title="### planar MJCF vs our Pinocchio model"))
        failures += [f"planar MJCF check {k}: {v:.2e}" for k, v in check.items()
                     if v > RIGID_TOL]
    rows = []
    for route in routes:
        worst = max(float(np.max(np.abs(route.fn(i) - ref[route.output][i])))
                    for i in range(n_states))
        flag = "" if worst <= route.tol else " FAIL"
        if flag:
            failures.append(f"planar {route.name}: {worst:.2e} > {route.tol:g}")
        cell = NO_ROUTE
        if timing:
            counter = iter(range(10 ** 12))
            cell = fmt_us(measure(lambda fn=route.fn, counter=counter: fn(next(counter) % n_states),
                                  repeats=repeats))
        rows.append([route.name, route.output, route.note, f"{route.tol:.0e}",
                     f"{worst:.1e}{flag}", cell])
    text.append(table(["route", "output", "kind", "tolerance", "max abs diff",
                       "us per call"], rows,
                      title=f"### accuracy over {n_states} states (max abs difference "
                            "against the reference of each output) and us per call"))
    text.append("\n" + "\n".join(f"- {k}: {v}" for k, v in PLANAR_OUTPUTS.items()))
    return "\n".join(text), failures


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--smoke", action="store_true")
    parser.add_argument("--sizes", default="1,10,100,1000,10000,100000,1000000")
    parser.add_argument("--ladders", default="1,2,4,8,16,32,64")
    parser.add_argument("--states", type=int, default=16, help="states per mechanism")
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--budget", type=float, default=30.0)
    parser.add_argument("--mem-limit", type=float, default=4.0, help="GiB")
    parser.add_argument("--planar-states", type=int, default=1000,
                        help="states of the planar task-level accuracy table")
    parser.add_argument("--only-planar", action="store_true",
                        help="only the planar rows of the closure table and its section")
    args = parser.parse_args(argv)
    if args.smoke:
        args.sizes, args.ladders, args.states, args.repeats, args.budget = \
            "1,10", "1,3", 3, 2, 2.0
        args.planar_states = 8
        MIN_SAMPLE["seconds"] = 1e-3
    print_machine_info()
    sizes = [int(float(x)) for x in args.sizes.split(",")]
    ladders = [] if args.only_planar else [int(x) for x in args.ladders.split(",")]
    if not args.only_planar:
        print("\n## Time against batch size (hexapod)")
        print(batch_scaling(sizes, args.repeats, args.budget, args.mem_limit * 2 ** 30))
    print("\n## Time against the number of closures (tree level, generic ClosedLoopModel)")
    text, failures = closure_scaling(ladders, args.states, args.repeats, check=args.smoke,
                                     hexapod=not args.only_planar)
    print(text)
    print("\n## The planar 3-PRR against MuJoCo (task level, with a platform wrench)")
    text, planar_failures = planar_vs_mujoco(args.planar_states, args.repeats)
    print(text)
    failures += planar_failures
    if failures:
        print("\nDISAGREEMENT:\n" + "\n".join(failures))
        return 1
    print("\nall routes agree within their tolerances")
    return 0


if __name__ == "__main__":
    sys.exit(main())
