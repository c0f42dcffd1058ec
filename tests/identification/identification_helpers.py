"""Shared helpers of the identification tests: random physically consistent parameters and
synthetic data of a perturbed robot (a module of its own, not the conftest: the tests'
``from conftest import ...`` means tests/conftest.py)."""

from __future__ import annotations

import numpy as np
import pinocchio as pin

from hexapod_pin.identification import ClosedLoopRegressor, nominal_parameters

#: the robots of the issue's checks
ROBOTS = ("hexapod", "planar", "stewart")


def random_consistent(robot, drive, rng, layout=None) -> np.ndarray:
    """A random physically consistent full parameter vector: every body a random mass
    (0.1 - 2 kg), centre of mass (+-0.1 m) and positive-definite inertia about it with the
    triangle inequalities (principal moments from random positive semi-axes, rotated);
    drive parameters positive, offsets signed. ``layout``: given (a model without a
    platform, e.g. Cassie's), else the robot's."""
    layout = ClosedLoopRegressor(robot, drive).layout if layout is None else layout
    out = np.empty(layout.size)
    for b in range(len(layout.bodies)):
        mass = rng.uniform(0.1, 2.0)
        axes = rng.uniform(0.02, 0.2, 3) ** 2         # a solid ellipsoid's a^2, b^2, c^2
        moments = mass / 5.0 * np.array([axes[1] + axes[2], axes[0] + axes[2],
                                         axes[0] + axes[1]])
        rot = pin.Quaternion(rng.normal(size=4)).normalized().matrix()
        inertia = pin.Inertia(mass, rng.uniform(-0.1, 0.1, 3), rot @ np.diag(moments) @ rot.T)
        out[10 * b:10 * b + 10] = inertia.toDynamicParameters()
    out[layout.n_inertial:] = rng.uniform(0.2, 3.0, layout.n_drive)
    if "offset" in layout.drive:
        out[layout.drive_slice("offset")] = rng.uniform(-2.0, 2.0, len(layout.actuators))
    return out


def perturbed(robot, drive, rng) -> np.ndarray:
    """The robot's nominal parameters with every massive body's mass and rotational
    inertia (about the centre of mass) off by 10-30 % (random sign), the centre of mass
    moved by up to 1 cm, and drive friction on (viscous 1-5, Coulomb 0.5-2, offsets
    +-1)."""
    layout = ClosedLoopRegressor(robot, drive).layout
    out = nominal_parameters(robot, drive)
    for b in range(len(layout.bodies)):
        nominal = pin.Inertia.FromDynamicParameters(out[10 * b:10 * b + 10])
        if nominal.mass <= 0.0:
            continue
        factor = lambda: 1.0 + rng.choice([-1.0, 1.0]) * rng.uniform(0.1, 0.3)
        out[10 * b:10 * b + 10] = pin.Inertia(
            nominal.mass * factor(), nominal.lever + rng.uniform(-0.01, 0.01, 3),
            nominal.inertia * factor()).toDynamicParameters()
    n_act = len(layout.actuators)
    values = {"viscous": (1.0, 5.0), "coulomb": (0.5, 2.0), "offset": (-1.0, 1.0),
              "armature": (0.01, 0.1)}
    for kind in layout.drive:
        out[layout.drive_slice(kind)] = rng.uniform(*values[kind], n_act)
    return out
