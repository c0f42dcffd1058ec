"""A generic chain with many loops: a ladder of n spatial parallelogram four-bars.

Used by ``bench_scaling.py`` to time the closed-loop dynamics against the number of
closures, with the same mechanism as URDF + loops YAML (read by hexapod_pin's generic
``ClosedLoopModel``) and as MJCF (MuJoCo).

The mechanism, in the vertical x-z plane (gravity ``-g z`` acts in the plane):

* n + 1 bars ``bar_j`` (j = 0..n) hinged to the ground about the world y axis at
  ``(j d, 0, 0)``, each a rod of length ``l`` along its local +z; ``bar_0`` is actuated;
* n couplers ``coupler_j`` (j = 0..n-1) hanging from the tip of ``bar_j`` by a universal
  joint (hinge ``coupler_j_a`` about y, then ``coupler_j_b`` about the rotated z), each a
  rod of length ``d`` along its local +x;
* closure j (point, 3 rows): the tip of ``coupler_j`` on the tip of ``bar_{j+1}``.

Tree: ``3 n + 1`` dofs; ``3 n`` closure rows, all independent (the universal joint's
second hinge gives the out-of-plane row a non-zero column); mobility 1. Assembled in
closed form: every bar at the same angle ``theta``, couplers horizontal
(``coupler_j_a = -theta``, ``coupler_j_b = 0``).
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

import numpy as np


@dataclass(frozen=True)
class Ladder:
    """Dimensions and inertia of the ladder (SI units).

    Rods have the inertia of thin cylinders of radius ``radius`` (axial ``m r^2 / 2``,
    transverse ``m L^2 / 12 + m r^2 / 4``), identical in URDF and MJCF.
    """

    loops: int
    spacing: float = 0.3        # d: pivot spacing = coupler length (m)
    bar_length: float = 0.2     # l (m)
    bar_mass: float = 0.2       # (kg)
    coupler_mass: float = 0.1   # (kg)
    radius: float = 0.01        # (m)
    gravity: float = 9.81       # (m/s^2)

    def rod_inertia(self, mass: float, length: float) -> tuple[float, float]:
        """(transverse, axial) moments of a rod about its centre (kg m^2)."""
        return mass * length ** 2 / 12 + mass * self.radius ** 2 / 4, mass * self.radius ** 2 / 2


def _f(x: float) -> str:
    return repr(float(x))


def ladder_urdf(lad: Ladder) -> str:
    """URDF text of the ladder's tree."""
    it_b, ia_b = lad.rod_inertia(lad.bar_mass, lad.bar_length)
    it_c, ia_c = lad.rod_inertia(lad.coupler_mass, lad.spacing)
    lines = ['<?xml version="1.0"?>', '<robot name="ladder">', '  <link name="world"/>']
    for j in range(lad.loops + 1):
        lines += [
            f'  <joint name="bar_{j}" type="revolute">',
            f'    <parent link="world"/><child link="bar_{j}"/>',
            f'    <origin xyz="{_f(j * lad.spacing)} 0 0" rpy="0 0 0"/><axis xyz="0 1 0"/>',
            '    <limit lower="-3.2" upper="3.2" effort="100" velocity="100"/>',
            '  </joint>',
            f'  <link name="bar_{j}"><inertial><origin xyz="0 0 {_f(lad.bar_length / 2)}"/>'
            f'<mass value="{_f(lad.bar_mass)}"/><inertia ixx="{_f(it_b)}" ixy="0" ixz="0" '
            f'iyy="{_f(it_b)}" iyz="0" izz="{_f(ia_b)}"/></inertial></link>',
            f'  <joint name="bar_{j}_tip_mount" type="fixed"><parent link="bar_{j}"/>'
            f'<child link="bar_{j}_tip"/><origin xyz="0 0 {_f(lad.bar_length)}"/></joint>',
            f'  <link name="bar_{j}_tip"/>',
        ]
        if j == lad.loops:
            continue
        lines += [
            f'  <joint name="coupler_{j}_a" type="revolute">',
            f'    <parent link="bar_{j}"/><child link="cross_{j}"/>',
            f'    <origin xyz="0 0 {_f(lad.bar_length)}"/><axis xyz="0 1 0"/>',
            '    <limit lower="-3.2" upper="3.2" effort="0" velocity="100"/>',
            '  </joint>',
            f'  <link name="cross_{j}"/>',
            f'  <joint name="coupler_{j}_b" type="revolute">',
            f'    <parent link="cross_{j}"/><child link="coupler_{j}"/>',
            '    <origin xyz="0 0 0"/><axis xyz="0 0 1"/>',
            '    <limit lower="-3.2" upper="3.2" effort="0" velocity="100"/>',
            '  </joint>',
            f'  <link name="coupler_{j}"><inertial><origin xyz="{_f(lad.spacing / 2)} 0 0"/>'
            f'<mass value="{_f(lad.coupler_mass)}"/><inertia ixx="{_f(ia_c)}" ixy="0" ixz="0" '
            f'iyy="{_f(it_c)}" iyz="0" izz="{_f(it_c)}"/></inertial></link>',
            f'  <joint name="coupler_{j}_tip_mount" type="fixed"><parent link="coupler_{j}"/>'
            f'<child link="coupler_{j}_tip"/><origin xyz="{_f(lad.spacing)} 0 0"/></joint>',
            f'  <link name="coupler_{j}_tip"/>',
        ]
    lines.append('</robot>')
    return "\n".join(lines) + "\n"


def ladder_loops(lad: Ladder) -> str:
    """Loops YAML (hexapod_pin format) of the ladder."""
    lines = ["closures:"]
    lines += [f"  - {{name: rung_{j}, type: point, frame1: coupler_{j}_tip, "
              f"frame2: bar_{j + 1}_tip}}" for j in range(lad.loops)]
    lines.append("actuated: [bar_0]")
    return "\n".join(lines) + "\n"


def ladder_mjcf(lad: Ladder, timestep: float = 1e-3) -> str:
    """MJCF of the same ladder (site-based connect closures, stiffest solimp)."""
    it_b, ia_b = lad.rod_inertia(lad.bar_mass, lad.bar_length)
    it_c, ia_c = lad.rod_inertia(lad.coupler_mass, lad.spacing)
    solref = f"{_f(2 * timestep)} 1"
    lines = [
        '<mujoco model="ladder">',
        '  <compiler angle="radian" autolimits="true" inertiafromgeom="false"/>',
        f'  <option timestep="{_f(timestep)}" gravity="0 0 {_f(-lad.gravity)}" '
        'integrator="Euler" solver="Newton" tolerance="1e-15" iterations="100" '
        'jacobian="dense"><flag contact="disable"/></option>',
        '  <default><joint damping="0" armature="0" frictionloss="0" limited="false"/>',
        f'    <equality solref="{solref}" solimp="0.9999 0.9999 0.001 0.5 2"/>',
        '    <motor ctrllimited="false" forcelimited="false" gear="1"/></default>',
        '  <worldbody>',
    ]
    for j in range(lad.loops + 1):
        lines += [
            f'    <body name="bar_{j}" pos="{_f(j * lad.spacing)} 0 0">',
            f'      <joint name="bar_{j}" type="hinge" axis="0 1 0"/>',
            f'      <inertial pos="0 0 {_f(lad.bar_length / 2)}" mass="{_f(lad.bar_mass)}" '
            f'diaginertia="{_f(it_b)} {_f(it_b)} {_f(ia_b)}"/>',
            f'      <site name="bar_{j}_tip" pos="0 0 {_f(lad.bar_length)}"/>',
        ]
        if j < lad.loops:
            lines += [
                f'      <body name="coupler_{j}" pos="0 0 {_f(lad.bar_length)}">',
                f'        <joint name="coupler_{j}_a" type="hinge" axis="0 1 0"/>',
                f'        <joint name="coupler_{j}_b" type="hinge" axis="0 0 1"/>',
                f'        <inertial pos="{_f(lad.spacing / 2)} 0 0" '
                f'mass="{_f(lad.coupler_mass)}" diaginertia="{_f(ia_c)} {_f(it_c)} '
                f'{_f(it_c)}"/>',
                f'        <site name="coupler_{j}_tip" pos="{_f(lad.spacing)} 0 0"/>',
                '      </body>',
            ]
        lines.append('    </body>')
    lines += ['  </worldbody>', '  <equality>']
    lines += [f'    <connect name="rung_{j}" site1="coupler_{j}_tip" site2="bar_{j + 1}_tip"/>'
              for j in range(lad.loops)]
    lines += ['  </equality>', '  <actuator><motor name="bar_0" joint="bar_0"/></actuator>',
              '</mujoco>']
    return "\n".join(lines) + "\n"


def ladder_model(lad: Ladder):
    """The hexapod_pin ``ClosedLoopModel`` of the ladder, loaded from files in a temp dir."""
    from hexapod_pin import ClosedLoopModel

    with tempfile.TemporaryDirectory() as tmp:
        urdf = Path(tmp) / "ladder.urdf"
        loops = Path(tmp) / "ladder.loops.yaml"
        urdf.write_text(ladder_urdf(lad))
        loops.write_text(ladder_loops(lad))
        clm = ClosedLoopModel.from_files(urdf, loops)
    return clm


def joint_values(lad: Ladder, theta: float) -> dict[str, float]:
    """Closed-form assembled joint values for bar angle ``theta`` (rad)."""
    out = {f"bar_{j}": theta for j in range(lad.loops + 1)}
    for j in range(lad.loops):
        out[f"coupler_{j}_a"] = -theta
        out[f"coupler_{j}_b"] = 0.0
    return out


def configuration(clm, lad: Ladder, theta: float) -> np.ndarray:
    """Pinocchio q of the assembled ladder (every joint is 1-DoF)."""
    q = clm.neutral()
    for name, value in joint_values(lad, theta).items():
        q[clm.joint_q_index(name)] = value
    return q
