"""Shared helpers of the peer benchmarks: timing, random states, tables, machine info."""

from __future__ import annotations

import os
import platform
import time
import tracemalloc
from dataclasses import dataclass
from importlib import metadata

import numpy as np

import numpy_hexapod as nh

NOT_IMPLEMENTED = "n/a (not implemented)"
#: minimum duration of one timing sample (s); smoke runs lower it
MIN_SAMPLE = {"seconds": 0.02}
#: the clock of the timings: wall time (``time.perf_counter``), or the calling thread's CPU
#: time (``time.thread_time``, ``--cpu-time``: on a shared machine the time spent waiting
#: for a core is not counted)
CLOCK = {"now": time.perf_counter}
NO_ROUTE = "-"


# -- timing ------------------------------------------------------------------------------
@dataclass(frozen=True)
class Timing:
    """Seconds per call: median and inter-quartile range over ``samples`` repeats."""

    median: float
    q25: float
    q75: float
    samples: int
    calls_per_sample: int

    def per_state(self, n: int) -> "Timing":
        return Timing(self.median / n, self.q25 / n, self.q75 / n, self.samples,
                      self.calls_per_sample)


def measure(fn, repeats: int = 7, min_sample: float | None = None) -> Timing:
    """Time ``fn()``: one warm-up call, then ``repeats`` samples of ``k`` calls each,
    ``k`` chosen so that a sample lasts at least ``min_sample`` seconds."""
    if min_sample is None:
        min_sample = MIN_SAMPLE["seconds"]
    fn()
    t0 = CLOCK["now"]()
    fn()
    one = CLOCK["now"]() - t0
    k = max(1, int(min_sample / max(one, 1e-9)))
    samples = []
    for _ in range(repeats):
        t0 = CLOCK["now"]()
        for _ in range(k):
            fn()
        samples.append((CLOCK["now"]() - t0) / k)
    s = np.array(samples)
    return Timing(float(np.median(s)), float(np.percentile(s, 25)),
                  float(np.percentile(s, 75)), repeats, k)


def measure_interleaved(fns, repeats: int = 7, min_sample: float | None = None) -> list[Timing]:
    """:func:`measure` of several functions with their samples interleaved (sample 1 of
    each, then sample 2 of each, ...): on a shared machine a change of load hits every
    function alike, so that their ratios hold even when the absolute times drift. Each
    sample follows a tenth of its calls untimed (the caches the previous function's sample
    evicted refilled)."""
    if min_sample is None:
        min_sample = MIN_SAMPLE["seconds"]
    counts = []
    for fn in fns:
        fn()
        t0 = CLOCK["now"]()
        fn()
        counts.append(max(1, int(min_sample / max(CLOCK["now"]() - t0, 1e-9))))
    samples: list[list[float]] = [[] for _ in fns]
    for _ in range(repeats):
        for fn, k, out in zip(fns, counts, samples):
            for _ in range(max(1, k // 10)):    # untimed: the caches the last one evicted
                fn()
            t0 = CLOCK["now"]()
            for _ in range(k):
                fn()
            out.append((CLOCK["now"]() - t0) / k)
    return [Timing(float(np.median(s)), float(np.percentile(s, 25)),
                   float(np.percentile(s, 75)), repeats, k) for s, k in zip(samples, counts)]


def first_call_seconds(fn) -> float:
    t0 = CLOCK["now"]()
    fn()
    return CLOCK["now"]() - t0


def peak_memory(fn) -> int:
    """Peak bytes allocated (tracemalloc: numpy buffers included) during ``fn()``."""
    tracemalloc.start()
    try:
        fn()
        return tracemalloc.get_traced_memory()[1]
    finally:
        tracemalloc.stop()


def fmt_us(t: Timing | str | None) -> str:
    """``median [q25-q75]`` in microseconds, 3 significant digits."""
    if t is None:
        return NO_ROUTE
    if isinstance(t, str):
        return t
    return f"{_sig(t.median * 1e6)} [{_sig(t.q25 * 1e6)}-{_sig(t.q75 * 1e6)}]"


def _sig(x: float) -> str:
    if x >= 100:
        return f"{x:.0f}"
    if x >= 10:
        return f"{x:.1f}"
    if x >= 1:
        return f"{x:.2f}"
    return f"{x:.3f}"


# -- tables ------------------------------------------------------------------------------
def table(headers: list[str], rows: list[list[str]], title: str | None = None) -> str:
    """A Markdown (pipe) table, columns padded for reading in a terminal."""
    cells = [headers] + [[str(c) for c in r] for r in rows]
    widths = [max(len(r[i]) for r in cells) for i in range(len(headers))]
    line = lambda r: "| " + " | ".join(c.ljust(w) for c, w in zip(r, widths)) + " |"  # noqa
    out = [] if title is None else [f"\n{title}\n"]
    out += [line(headers), "|" + "|".join("-" * (w + 2) for w in widths) + "|"]
    out += [line(r) for r in cells[1:]]
    return "\n".join(out)


# -- random states -----------------------------------------------------------------------
@dataclass(frozen=True)
class States:
    """N random platform states (each array (N, 6)), SI units, world axes."""

    poses: np.ndarray
    twists: np.ndarray
    twist_dots: np.ndarray
    wrenches: np.ndarray

    def __len__(self) -> int:
        return len(self.poses)

    def take(self, n: int) -> "States":
        return States(self.poses[:n], self.twists[:n], self.twist_dots[:n], self.wrenches[:n])


def random_states(geometry, n: int, seed: int = 0, max_force_ratio: float = 0.5) -> States:
    """N random platform states, well inside the workspace (vectorised rejection sampling).

    Poses near home (+-3 cm, +-0.12 rad) inside the strokes and gap limits; twists
    ``v`` +-0.1 m/s, ``w`` +-0.5 rad/s; twist_dots +-1 m/s^2, +-3 rad/s^2; wrenches
    +-5 N, +-0.3 N m (uniform). States near a singularity are rejected: the inverse-
    dynamics forces must stay below ``max_force_ratio * max_actuator_force`` (else the
    library's bounded routes rightly raise ActuatorSaturationError).
    """
    rng = np.random.default_rng(seed)
    p = nh.params_from_geometry(geometry)
    home = np.array(geometry.home_pose)
    scale = np.array([0.03, 0.03, 0.03, 0.12, 0.12, 0.12])
    limit = max_force_ratio * geometry.max_actuator_force
    chunks, have = [], 0
    while have < n:
        m = max(2 * (n - have), 64)
        poses = home + rng.uniform(-1, 1, (m, 6)) * scale
        twists = rng.uniform(-1, 1, (m, 6)) * np.array([0.1] * 3 + [0.5] * 3)
        twist_dots = rng.uniform(-1, 1, (m, 6)) * np.array([1.0] * 3 + [3.0] * 3)
        wrenches = rng.uniform(-1, 1, (m, 6)) * np.array([5.0] * 3 + [0.3] * 3)
        q = nh.inverse_kinematics(p, poses)
        ok = np.all(np.isfinite(q), axis=1) & np.all(np.abs(q) <= geometry.rail_half_length, 1)
        gaps = q[:, 1::2] - q[:, 0::2]
        ok &= np.all(gaps >= geometry.carriage_min_gap, axis=1)
        tau = nh.inverse_dynamics(p, poses[ok], twists[ok], twist_dots[ok], wrenches[ok])
        ok[ok] = np.all(np.abs(tau) <= limit, axis=1)
        chunks.append((poses[ok], twists[ok], twist_dots[ok], wrenches[ok]))
        have += int(ok.sum())
    return States(*(np.concatenate([c[k] for c in chunks])[:n] for k in range(4)))


# -- machine and versions ---------------------------------------------------------------
def machine_info() -> dict[str, str]:
    """CPU model, core count, load average, Python and tool versions."""
    cpu = platform.processor() or "unknown"
    try:
        with open("/proc/cpuinfo") as fh:
            for line in fh:
                if line.startswith("model name"):
                    cpu = line.split(":", 1)[1].strip()
                    break
    except OSError:
        pass
    info = {"cpu": cpu, "cores": str(os.cpu_count()), "python": platform.python_version()}
    try:
        info["load average (1, 5, 15 min)"] = " ".join(f"{x:.2f}" for x in os.getloadavg())
    except OSError:
        pass
    for dist in ("pin", "proxsuite", "mujoco", "numpy", "scipy"):
        try:
            info[dist] = metadata.version(dist)
        except metadata.PackageNotFoundError:
            info[dist] = "not installed"
    return info


def print_machine_info() -> None:
    info = machine_info()
    print("machine: " + "; ".join(f"{k}: {v}" for k, v in info.items()))
