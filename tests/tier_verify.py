"""Interpreted against compiled, kernel by kernel, over every kernel call of
``hp.warmup()``'s steps (run by ``tests/core/test_tiers.py`` in a fresh interpreter:
``python tier_verify.py OUT``).

Every kernel of the package gets, in place of its tiered-execution hook, a checker that
numba calls on EVERY call of the kernel (its machine code is never registered with it: a
twin dispatcher of the same source, loaded from the disk cache, holds it). The checker
runs the kernel's Python source (:func:`hexapod_pin.core.tiers.run_interpreted`) on the
arguments, keeps its result and the arguments it left, restores the arguments in place (so
arrays sharing memory keep sharing it), runs the machine code of the twin on them, and
compares: integers and booleans exactly, floats to ``RTOL`` times the largest magnitude of
the array, or times 1 below 1 (residuals and other round-off-sized arrays, whose scale is
that of the terms they cancel; NaN where NaN, infinities equal). The caller goes on with
the compiled result. An interpreted run calls the other kernels through their dispatchers,
so each kernel is checked on every branch warmup's inputs take and on the arguments its
callers really pass. ``OUT`` gets a JSON list: per kernel and argument types, the number of
calls, the first differences found and the exceptions the Python source raised.
"""

from __future__ import annotations

import json
import sys

import numba
import numpy as np
import robot_registry
from numba.core.dispatcher import Dispatcher

import hexapod_pin as hp
from hexapod_pin import precompile
from hexapod_pin.core import tiers
from hexapod_pin.hexapod.fast import simulate_fast

#: relative tolerance of a float (the largest magnitude of its array, at least 1, as scale)
RTOL = 1e-12


def _copy(value):
    if isinstance(value, np.ndarray):
        return value.copy()
    if isinstance(value, tuple):
        return tuple(_copy(v) for v in value)
    return value


def _put_back(value, saved) -> None:
    if isinstance(value, np.ndarray):
        if value.flags.writeable:
            value[...] = saved
    elif isinstance(value, tuple):
        for v, s in zip(value, saved):
            _put_back(v, s)


def differences(got, want, path: str = "") -> list[str]:
    """Where ``got`` (interpreted) differs from ``want`` (compiled)."""
    if isinstance(want, tuple) or isinstance(got, tuple):
        if not (isinstance(got, tuple) and isinstance(want, tuple) and len(got) == len(want)):
            return [f"{path}: {type(got).__name__} against {type(want).__name__}"]
        return [d for k, (g, w) in enumerate(zip(got, want))
                for d in differences(g, w, f"{path}[{k}]")]
    if type(got) is not type(want) and not (isinstance(want, np.ndarray)
                                             and isinstance(got, np.ndarray)):
        return [f"{path}: type {type(got).__name__} against {type(want).__name__}"]
    g, w = np.asarray(got), np.asarray(want)
    if g.shape != w.shape or g.dtype != w.dtype:
        return [f"{path}: {g.dtype}{g.shape} against {w.dtype}{w.shape}"]
    if g.dtype.kind not in "fc":
        return [] if np.array_equal(g, w) else [f"{path}: {g.ravel()[:6]} != {w.ravel()[:6]}"]
    if not np.array_equal(np.isnan(g), np.isnan(w)) or not np.array_equal(
            np.isinf(g) * np.sign(np.where(np.isinf(g), g, 0)),
            np.isinf(w) * np.sign(np.where(np.isinf(w), w, 0))):
        return [f"{path}: NaN / inf at other entries"]
    finite = np.isfinite(w)
    if not finite.any():
        return []
    scale = max(np.max(np.abs(w[finite])), np.max(np.abs(g[finite])))
    err = np.max(np.abs(g[finite] - w[finite]))
    return [] if err <= RTOL * max(scale, 1.0) else [f"{path}: off by {err:.3g} (scale {scale:.3g})"]


def checker(name: str, dispatcher: Dispatcher, log: dict):
    """numba's hook for ``dispatcher``: check the call (module docstring), then return its
    compiled result to the caller."""
    options = {k: v for k, v in dispatcher.targetoptions.items() if k != "nopython"}
    twin = numba.njit(cache=True, **options)(dispatcher.py_func)

    def hook(*args):
        key = (name, str(tuple(map(dispatcher.typeof_pyval, args))))
        entry = log.setdefault(key, {"kernel": key[0], "types": key[1], "calls": 0,
                                     "differences": [], "raised": []})
        entry["calls"] += 1
        before = _copy(args)
        try:
            interpreted, raised = tiers.run_interpreted(dispatcher, args), ""
        except Exception as exc:  # noqa: BLE001 - any: reported, not compared
            interpreted, raised = None, f"{type(exc).__name__}: {exc}"
        left = _copy(args)
        _put_back(args, before)
        compiled = twin(*args)
        if raised:
            entry["raised"] = entry["raised"][:2] + [raised]
        elif len(entry["differences"]) < 3:
            entry["differences"] += (differences(interpreted, compiled, "result")
                                     + differences(left, _copy(args), "arguments"))
        return lambda *_: compiled

    return hook


def _drives(robot):
    """``robot`` with every drive effect on its actuated joints (armature, damping, Coulomb
    friction, springs)."""
    names = robot.model.actuated_joints
    return robot.with_effects(
        armature={n: 0.3 + 0.1 * k for k, n in enumerate(names)},
        damping={n: 2.0 + 0.5 * k for k, n in enumerate(names)},
        coulomb={n: 0.4 + 0.2 * k for k, n in enumerate(names)},
        stiffness={n: 40.0 + 5.0 * k for k, n in enumerate(names)},
        spring_reference={n: [0.003 * (k + 1)] for k, n in enumerate(names)})


def _more_branches() -> None:
    """Branches warmup's inputs compile but do not run: drive effects (single state,
    batches, the simulator with friction), a wrench on the platform, a singular pose, the
    LOCAL rows of weld closures (the delta robot's derivatives)."""
    for robot in (hp.Hexapod.default(), hp.Planar3PRR.default()):
        eff, dim = _drives(robot), robot.pose_dim
        pose = robot.home_pose + np.linspace(0.002, -0.003, dim)
        twist, acc = np.linspace(0.05, -0.04, dim), np.linspace(-0.5, 0.6, dim)
        wrench = np.linspace(1.0, -2.0, dim)
        precompile._single_state(eff, pose, twist, acc)
        for r in (robot, eff):
            tau = r.inverse_dynamics(pose, twist, acc, wrench).actuator_forces
            r.forward_dynamics(pose, twist, tau, wrench)
            r.inverse_dynamics_batch(pose[None], twist[None], acc[None], wrench[None])
            r.forward_dynamics_batch(pose[None], twist[None], tau[None], wrench[None])
        precompile._batches(eff)
        for far in (robot.home_pose + 10.0, np.zeros(dim)):       # unreachable, singular
            try:
                robot.inverse_dynamics(far, twist, acc)
            except hp.HexapodPinError:
                pass
    hexapod = _drives(hp.Hexapod.default())
    simulate_fast(hexapod, 5e-3, 1e-3, actuator_forces=hexapod.static_forces(
        hexapod.home_pose), friction_regularisation=1e-3)
    delta = robot_registry.get("delta")
    twist = np.full(delta.pose_dim, 0.01)
    tau = delta.inverse_dynamics(delta.home_pose, twist, twist).actuator_forces
    delta.forward_dynamics_derivatives(delta.home_pose, twist, tau)


def main(out: str) -> None:
    log: dict = {}
    for name, dispatcher in precompile.dispatchers().items():
        tier = tiers.tier_of(dispatcher)
        if tier is not None and not tier.always_compile:
            dispatcher._compile_for_args = checker(name, dispatcher, log)
    for _, run in precompile._steps():
        run()
    _more_branches()
    with open(out, "w", encoding="utf-8") as f:
        json.dump(list(log.values()), f)


if __name__ == "__main__":
    main(sys.argv[1])
