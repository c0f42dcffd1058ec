"""Test robots of each hard class for the generic closed-loop core, built in code.

Each :class:`StressRobot` is a :class:`~hexapod_pin.core.closed_loop.ClosedLoopModel`
built from URDF text plus a loops description, and a sampler of closure-consistent
states ``(q, v)`` (seeded). The classes:

* ``five_bar_stiff``: the planar five-bar of ``tests/data/parallel/five_bar_6d`` closed by a
  6-D weld (6 rows, rank 3: redundant rows) with link masses spanning five orders of
  magnitude (1e-3 .. 1e2 kg; mass-matrix entries up to ~1e1..1e2 kg m^2);
* ``five_bar_massless``: the same five-bar with the closing pin link massless (its joint
  has a zero column in ``M``: ``M`` positive semi-definite, positive on the closures' null
  space);
* ``delta_weld``: the delta of ``tests/data/parallel/delta``, two legs welded (6-D) to the
  platform (12 rows, rank 6: many redundant rows), masses spanning 1e-2 .. 1e2;
* ``delta_massless``: the delta with massless wrist bodies;
* ``ladder_mixed``: a ladder of spatial four-bars (point closures, independent rows) with
  bar and coupler masses alternating over five orders of magnitude;
* ``ladder_massless``: the ladder with massless couplers;
* ``planar_ladder_weld``: a planar ladder of parallelograms each closed by a 6-D weld
  (30 rows, rank 15: many redundant rows), masses over five orders of magnitude;
* ``ladder_long``: a long chain of 24 loops.

The ladder is the mechanism of ``benchmarks/ladder.py`` written here again with per-link
masses (tests do not import the benchmarks).
"""

from __future__ import annotations

import re
import shutil
import tempfile
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from hexapod_pin.core.closed_loop import ClosedLoopModel
from hexapod_pin.core.description import build_model, parse_loops
from hexapod_pin.loaders.parallel_robots import load_parallel_robot

DATA = Path(__file__).parent / "data" / "parallel"


@dataclass
class StressRobot:
    """A hard-class test robot: its model and a sampler of consistent states."""

    name: str
    clm: ClosedLoopModel
    sample: Callable[[np.random.Generator], tuple[np.ndarray, np.ndarray]]


# ------------------------------------------------------------------------ URDF editing
def scale_inertials(urdf: str, factors: dict[str, float]) -> str:
    """URDF text with the mass and inertia of each named link multiplied by its factor."""
    def link(match: re.Match) -> str:
        name, body = match.group(1), match.group(2)
        if name not in factors:
            return match.group(0)
        k = factors[name]

        def num(m: re.Match) -> str:
            return f'{m.group(1)}="{float(m.group(2)) * k!r}"'

        inertial = re.sub(r'(mass value|ixx|ixy|ixz|iyy|iyz|izz)="([^"]+)"', num, body)
        return f'<link name="{name}">{inertial}</link>'

    return re.sub(r'<link name="([^"]+)">(.*?)</link>', link, urdf, flags=re.DOTALL)


def _parallel_robot(folder: str, factors: dict[str, float]) -> ClosedLoopModel:
    src = DATA / folder
    with tempfile.TemporaryDirectory() as tmp:
        dst = Path(tmp) / folder
        dst.mkdir()
        shutil.copy(src / "robot.yaml", dst / "robot.yaml")
        (dst / "robot.urdf").write_text(scale_inertials((src / "robot.urdf").read_text(),
                                                        factors))
        return load_parallel_robot(dst)


# ------------------------------------------------------------------------------ ladder
def _f(x: float) -> str:
    return repr(float(x))


def ladder_urdf(loops: int, bar_masses, coupler_masses, spacing: float = 0.3,
                bar_length: float = 0.2, radius: float = 0.01) -> str:
    """URDF of a ladder of ``loops`` spatial parallelogram four-bars (see benchmarks/ladder.py):
    bars hinged to the ground about y at ``(j spacing, 0, 0)``, couplers hanging from the bar
    tips by a universal joint; closure j puts the tip of coupler j on the tip of bar j+1."""
    def rod(mass, length):
        if mass == 0.0:
            return 0.0, 0.0
        return mass * length ** 2 / 12 + mass * radius ** 2 / 4, mass * radius ** 2 / 2

    lines = ['<?xml version="1.0"?>', '<robot name="ladder">', '  <link name="world"/>']
    for j in range(loops + 1):
        mb = bar_masses[j]
        it_b, ia_b = rod(mb, bar_length)
        lines += [
            (f'  <joint name="bar_{j}" type="revolute"><parent link="world"/>'
            f'<child link="bar_{j}"/><origin xyz="{_f(j * spacing)} 0 0"/><axis xyz="0 1 0"/>'
            '<limit lower="-3.2" upper="3.2" effort="100" velocity="100"/></joint>'),
            (f'  <link name="bar_{j}"><inertial><origin xyz="0 0 {_f(bar_length / 2)}"/>'
            f'<mass value="{_f(mb)}"/><inertia ixx="{_f(it_b)}" ixy="0" ixz="0" '
            f'iyy="{_f(it_b)}" iyz="0" izz="{_f(ia_b)}"/></inertial></link>'),
            (f'  <joint name="bar_{j}_tip_mount" type="fixed"><parent link="bar_{j}"/>'
            f'<child link="bar_{j}_tip"/><origin xyz="0 0 {_f(bar_length)}"/></joint>'),
            f'  <link name="bar_{j}_tip"/>',
        ]
        if j == loops:
            continue
        mc = coupler_masses[j]
        it_c, ia_c = rod(mc, spacing)
        lines += [
            (f'  <joint name="coupler_{j}_a" type="revolute"><parent link="bar_{j}"/>'
            f'<child link="cross_{j}"/><origin xyz="0 0 {_f(bar_length)}"/><axis xyz="0 1 0"/>'
            '<limit lower="-3.2" upper="3.2" effort="0" velocity="100"/></joint>'),
            f'  <link name="cross_{j}"/>',
            (f'  <joint name="coupler_{j}_b" type="revolute"><parent link="cross_{j}"/>'
            f'<child link="coupler_{j}"/><origin xyz="0 0 0"/><axis xyz="0 0 1"/>'
            '<limit lower="-3.2" upper="3.2" effort="0" velocity="100"/></joint>'),
            (f'  <link name="coupler_{j}"><inertial><origin xyz="{_f(spacing / 2)} 0 0"/>'
            f'<mass value="{_f(mc)}"/><inertia ixx="{_f(ia_c)}" ixy="0" ixz="0" '
            f'iyy="{_f(it_c)}" iyz="0" izz="{_f(it_c)}"/></inertial></link>'),
            (f'  <joint name="coupler_{j}_tip_mount" type="fixed"><parent link="coupler_{j}"/>'
            f'<child link="coupler_{j}_tip"/><origin xyz="{_f(spacing)} 0 0"/></joint>'),
            f'  <link name="coupler_{j}_tip"/>',
        ]
    lines.append('</robot>')
    return "\n".join(lines) + "\n"


def planar_ladder_urdf(loops: int, masses) -> str:
    """URDF of a planar ladder of parallelograms in the x-z plane (every hinge about y):
    bar j hinged to the ground at ``(0.3 j, 0, 0)``, coupler j hinged at the tip of bar j,
    and a small ``pin_j`` link hinged at the tip of coupler j, welded (6-D) to the tip of
    bar j+1 by the loops description (6 rows per loop, 3 of them redundant)."""
    spacing, length = 0.3, 0.2

    def link(name, mass, com, lx):
        it = mass * lx ** 2 / 12 + mass * 1e-4 / 4 if mass else 0.0
        ia = mass * 1e-4 / 2 if mass else 0.0
        return (f'  <link name="{name}"><inertial><origin xyz="{com}"/><mass value="{_f(mass)}"/>'
                f'<inertia ixx="{_f(it)}" ixy="0" ixz="0" iyy="{_f(it)}" iyz="0" '
                f'izz="{_f(ia)}"/></inertial></link>')

    def hinge(name, parent, child, xyz):
        return (f'  <joint name="{name}" type="revolute"><parent link="{parent}"/>'
                f'<child link="{child}"/><origin xyz="{xyz}"/><axis xyz="0 1 0"/>'
                '<limit lower="-3.2" upper="3.2" effort="100" velocity="100"/></joint>')

    lines = ['<?xml version="1.0"?>', '<robot name="planar_ladder">', '  <link name="world"/>']
    k = 0
    for j in range(loops + 1):
        lines += [hinge(f"bar_{j}", "world", f"bar_{j}", f"{_f(j * spacing)} 0 0"),
                  link(f"bar_{j}", masses[k % len(masses)], f"0 0 {_f(length / 2)}", length),
                  (f'  <joint name="bar_{j}_tip_mount" type="fixed"><parent link="bar_{j}"/>'
                  f'<child link="bar_{j}_tip"/><origin xyz="0 0 {_f(length)}"/></joint>'),
                  f'  <link name="bar_{j}_tip"/>']
        k += 1
        if j == loops:
            continue
        lines += [hinge(f"coupler_{j}", f"bar_{j}", f"coupler_{j}", f"0 0 {_f(length)}"),
                  link(f"coupler_{j}", masses[k % len(masses)], f"{_f(spacing / 2)} 0 0",
                       spacing),
                  hinge(f"pin_{j}", f"coupler_{j}", f"pin_{j}", f"{_f(spacing)} 0 0"),
                  link(f"pin_{j}", masses[(k + 1) % len(masses)], "0 0 0", 0.02)]
        k += 2
    lines.append('</robot>')
    return "\n".join(lines) + "\n"


def ladder_loops(loops: int, actuated=("bar_0",)) -> str:
    """Loops description of the ladder (point closures, ``actuated`` bars)."""
    lines = ["closures:"]
    lines += [f"  - {{name: rung_{j}, type: point, frame1: coupler_{j}_tip, "
              f"frame2: bar_{j + 1}_tip}}" for j in range(loops)]
    lines.append(f"actuated: [{', '.join(actuated)}]")
    return "\n".join(lines) + "\n"


def ladder_model(loops: int, bar_masses, coupler_masses, actuated=("bar_0",)
                 ) -> ClosedLoopModel:
    """The ladder as a ClosedLoopModel (URDF text + loops text)."""
    urdf = ladder_urdf(loops, bar_masses, coupler_masses)
    return ClosedLoopModel(build_model(urdf), parse_loops(ladder_loops(loops, actuated)),
                           name=f"ladder_{loops}", urdf_xml=urdf)


def planar_ladder_model(loops: int, masses, actuated=("bar_0",)) -> ClosedLoopModel:
    """The planar welded ladder as a ClosedLoopModel (``actuated`` bars)."""
    urdf = planar_ladder_urdf(loops, masses)
    text = "closures:\n" + "".join(
        f"  - {{name: weld_{j}, type: weld, frame1: pin_{j}, frame2: bar_{j + 1}_tip}}\n"
        for j in range(loops)) + f"actuated: [{', '.join(actuated)}]\n"
    return ClosedLoopModel(build_model(urdf), parse_loops(text), name=f"planar_ladder_{loops}",
                           urdf_xml=urdf)


def _ladder_sampler(clm: ClosedLoopModel, loops: int, against=("coupler_{j}_a",),
                    along=()):
    """Assembled states of a ladder of parallelograms: every bar at one angle theta, the
    joints named by ``against`` at -theta and those named by ``along`` at +theta (``{j}`` the
    loop), with a random closure-consistent velocity."""
    def sample(rng):
        theta = rng.uniform(-0.8, 0.8)
        q = clm.neutral()
        for j in range(loops + 1):
            q[clm.joint_q_index(f"bar_{j}")] = theta
        for j in range(loops):
            for name in against:
                q[clm.joint_q_index(name.format(j=j))] = -theta
            for name in along:
                q[clm.joint_q_index(name.format(j=j))] = theta
        return q, _velocity(clm, q, rng)
    return sample


# ------------------------------------------------------------------------ state sampling
def _velocity(clm: ClosedLoopModel, q: np.ndarray, rng, speed: float = 1.0) -> np.ndarray:
    """A random velocity in the null space of J_c (numpy SVD)."""
    _, sv, vt = np.linalg.svd(clm.constraint_jacobian(q))
    basis = vt[int(np.sum(sv > 1e-10 * sv[0])):].T
    return speed * basis @ rng.normal(size=basis.shape[1])


def _assembly_sampler(clm: ClosedLoopModel, q_home: np.ndarray, spread: float):
    def sample(rng):
        q0 = q_home.copy()
        q0[[clm.model.joints[clm.model.getJointId(j)].idx_q for j in clm.actuated_joints]] += \
            spread * rng.uniform(-1.0, 1.0, clm.n_actuated)
        q = clm.assemble(q0).q
        return q, _velocity(clm, q, rng)
    return sample


def _home(clm: ClosedLoopModel, values: dict[str, float]) -> np.ndarray:
    q0 = clm.neutral()
    for name, value in values.items():
        q0[clm.joint_q_index(name)] = value
    fixed = [clm.joint_v_index(name) for name in values if name in clm.actuated_joints]
    return clm.assemble(q0, fixed=fixed).q


# ------------------------------------------------------------------------------ robots
FIVE_BAR_MASSES = {"proximal_1": 1e2 / 0.3, "distal_1": 1e-3 / 0.4, "proximal_2": 1e-1 / 0.3,
                   "distal_2": 1e1 / 0.4, "pin": 1e-2 / 0.05}
DELTA_MASSES = {"upper_arm_0": 1e2, "forearm_0": 1e-1, "upper_arm_1": 1e-1, "forearm_1": 1e1,
                "upper_arm_2": 1.0, "forearm_2": 1e-2, "platform": 1e1}


def five_bar_stiff() -> StressRobot:
    clm = _parallel_robot("five_bar_6d", FIVE_BAR_MASSES)
    home = _home(clm, {"mot1": 1.2, "mot2": 1.9, "free1": -1.0, "free2": 1.0})
    return StressRobot("five_bar_stiff", clm, _assembly_sampler(clm, home, 0.15))


def five_bar_massless() -> StressRobot:
    clm = _parallel_robot("five_bar_6d", {"pin": 0.0})
    home = _home(clm, {"mot1": 1.2, "mot2": 1.9, "free1": -1.0, "free2": 1.0})
    return StressRobot("five_bar_massless", clm, _assembly_sampler(clm, home, 0.15))


def _delta_home(clm):
    values = {f"motor_{k}": 0.5 for k in range(3)}
    return _home(clm, values)


def delta_weld() -> StressRobot:
    clm = _parallel_robot("delta", DELTA_MASSES)
    return StressRobot("delta_weld", clm, _assembly_sampler(clm, _delta_home(clm), 0.2))


def delta_massless() -> StressRobot:
    clm = _parallel_robot("delta", {"wrist_1_body": 0.0, "wrist_2_body": 0.0})
    return StressRobot("delta_massless", clm, _assembly_sampler(clm, _delta_home(clm), 0.2))


def ladder_mixed(loops: int = 6, actuated=("bar_0",)) -> StressRobot:
    bars = [(1e2, 1e-3, 1.0, 1e-1, 1e1)[j % 5] for j in range(loops + 1)]
    couplers = [(1e-3, 1e1, 1e-2, 1e2, 1.0)[j % 5] for j in range(loops)]
    clm = ladder_model(loops, bars, couplers, actuated)
    return StressRobot("ladder_mixed", clm, _ladder_sampler(clm, loops))


def ladder_redundantly_actuated(loops: int = 6) -> StressRobot:
    """:func:`ladder_mixed` with three actuated bars for one degree of freedom: the
    actuator forces are not unique (the inverse-dynamics QP chooses them)."""
    robot = ladder_mixed(loops, ("bar_0", "bar_2", "bar_5"))
    return StressRobot("ladder_redundantly_actuated", robot.clm, robot.sample)


def ladder_massless(loops: int = 4) -> StressRobot:
    clm = ladder_model(loops, [0.2] * (loops + 1), [0.0] * loops)
    return StressRobot("ladder_massless", clm, _ladder_sampler(clm, loops))


def planar_ladder_weld(loops: int = 5, actuated=("bar_0",)) -> StressRobot:
    clm = planar_ladder_model(loops, (1e2, 1e-3, 1.0, 1e-1, 1e1, 1e-2), actuated)
    return StressRobot("planar_ladder_weld", clm, _ladder_sampler(clm, loops, ("coupler_{j}",), ("pin_{j}",)))


def planar_ladder_weld_redundantly_actuated(loops: int = 5) -> StressRobot:
    """:func:`planar_ladder_weld` (redundant weld rows) with three actuated bars for one
    degree of freedom: the actuator forces are not unique."""
    robot = planar_ladder_weld(loops, ("bar_0", "bar_2", "bar_4"))
    return StressRobot("planar_ladder_weld_redundantly_actuated", robot.clm, robot.sample)


def ladder_long(loops: int = 24) -> StressRobot:
    clm = ladder_model(loops, [0.2] * (loops + 1), [0.1] * loops)
    return StressRobot("ladder_long", clm, _ladder_sampler(clm, loops))


BUILDERS = {f.__name__: f for f in (five_bar_stiff, five_bar_massless, delta_weld,
                                     delta_massless, ladder_mixed, ladder_massless,
                                     planar_ladder_weld,
                                     ladder_long)}


def build(name: str) -> StressRobot:
    """The stress robot called ``name`` (one of ``BUILDERS``)."""
    return BUILDERS[name]()
