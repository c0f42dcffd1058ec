"""The cost of the joint and drive effects (``hexapod_pin.core.effects``) in the generic tree
routes.

Per call of ``forward_dynamics_tree`` ("pinocchio" route) and ``inverse_dynamics_tree``
("kkt") on the Stewart platform of ``tests/data`` (24 velocity coordinates, 6 closures) and
the hexapod's tree (closed form not used here), for: the rigid model; armature only;
armature + damping + springs; all of them with Coulomb friction while every coordinate
slides; and Coulomb friction at rest (forward dynamics solves the stick / slip box QP). The
"FD of ID" column is the max relative error of ``forward(inverse(a)) = a`` (moving states;
the smoke run exits 1 above 1e-9).

    python benchmarks/bench_effects.py            # the table (~1 min)
    python benchmarks/bench_effects.py --smoke    # what the tests run (seconds)
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import numpy as np

import bench_common as bc
import hexapod_pin as hp
from hexapod_pin.core.dynamics import forward_dynamics_tree, inverse_dynamics_tree

DATA = Path(__file__).resolve().parents[1] / "tests" / "data"


def models():
    """(name, rigid ClosedLoopModel, home configuration) of the table."""
    stewart = hp.load_robot(DATA / "stewart" / "stewart.urdf")
    hexapod = hp.Hexapod.default()
    return [("Stewart 6-UPS", stewart.model, stewart.kinematics.home_q),
            ("hexapod tree", hexapod.model, hexapod.home_configuration)]


def variants(clm, rng):
    """The effect sets of the table, as models."""
    nv = clm.nv
    arm = rng.uniform(0.01, 0.1, nv)
    damp = rng.uniform(0.1, 1.0, nv)
    stiff = rng.uniform(1.0, 10.0, nv)
    fric = rng.uniform(0.05, 0.2, nv)
    return [("rigid", clm),
            ("armature", clm.with_effects(armature=arm)),
            ("armature+damping+springs", clm.with_effects(armature=arm, damping=damp,
                                                          stiffness=stiff)),
            ("all, sliding", clm.with_effects(armature=arm, damping=damp, stiffness=stiff,
                                              coulomb=fric))]


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="few repeats (for the tests)")
    args = parser.parse_args()
    repeats = 1 if args.smoke else 7
    bc.print_machine_info()
    rows, worst = [], 0.0
    for name, clm, q in models():
        rng = np.random.default_rng(0)
        v = clm.velocity_from_actuated(q, rng.normal(size=clm.n_actuated))
        u = rng.normal(size=clm.n_actuated)
        cases = variants(clm, rng)
        cases.append(("all, at rest (stick/slip QP)", cases[-1][1]))
        for label, model in cases:
            vel = np.zeros(clm.nv) if "at rest" in label else v
            acc = forward_dynamics_tree(model, q, vel, u).a
            fd = bc.measure(lambda m=model, w=vel: forward_dynamics_tree(m, q, w, u),
                            repeats=repeats)
            inv = bc.measure(lambda m=model, w=vel, a=acc: inverse_dynamics_tree(
                m, q, w, a, method="kkt"), repeats=repeats)
            if "at rest" in label:
                err = "-"
            else:
                back = inverse_dynamics_tree(model, q, vel, acc, method="kkt").actuator_forces
                again = forward_dynamics_tree(model, q, vel, back).a
                rel = float(np.max(np.abs(again - acc)) / max(1.0, np.max(np.abs(acc))))
                worst = max(worst, rel)
                err = f"{rel:.1e}"
            rows.append([name, label, bc.fmt_us(fd), bc.fmt_us(inv), err])
    print(bc.table(["model", "effects", "forward (pinocchio)", "inverse (kkt)", "FD of ID"],
                   rows, title="Joint and drive effects in the tree routes, per call"))
    return 0 if worst <= 1e-9 else 1


if __name__ == "__main__":
    sys.exit(main())
