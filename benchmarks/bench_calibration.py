"""Kinematic calibration (hexapod_pin.calibration): time of one identification and the
validation error against the number of measurement poses, random against selected poses.

The truth is the default hexapod with millimetre-level deviations in every chain parameter
(1 mm line points, sensor zeros, leg lengths, platform joints; 1 mrad line directions) and
an instrument frame off by 2 mm / 2 mrad; measurements come from the Pinocchio tree of the
true robot with Gaussian noise of 10 um and 20 urad (per axis) on the measured poses.
Identification from the nominal start, all 54 chain parameters plus both frames
(54 base parameters).

    python benchmarks/bench_calibration.py                 # the tables of benchmarks/README.md
    python benchmarks/bench_calibration.py --smoke         # small sizes, a quick check
    python benchmarks/bench_calibration.py --plot out.png  # also the figures (matplotlib)
"""

from __future__ import annotations

import argparse
import os
import platform
import time

os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")     # before numpy: see benchmarks/README.md
os.environ.setdefault("OMP_NUM_THREADS", "1")

import numpy as np

import hexapod_pin as hp
from hexapod_pin.calibration import (
    calibrate,
    plots,
    random_as_built,
    select_poses,
    synthetic_measurements,
)
from hexapod_pin.calibration.problem import reference_poses
from hexapod_pin.calibration.results import measurement_chains
from hexapod_pin.calibration.selection import candidate_blocks, observability
from hexapod_pin.calibration.synthetic import frames_of
from hexapod_pin.errors import IdentifiabilityError

NOISE = {"position_noise": 1e-5, "rotation_noise": 2e-5}
INSTRUMENT = np.array([2e-3, -1e-3, 1.5e-3, 1e-3, -2e-3, 1.5e-3])


def truth(nominal: hp.Hexapod) -> hp.HexapodGeometry:
    return random_as_built(nominal.geometry, 1e-3, seed=7)


def timing_table(nominal, true, pool, sizes, repeats):
    print("\n### Time of one identification (54 base parameters, noisy poses)\n")
    print("| poses | residuals | time (s), median [min, max] | function evaluations "
          "| normalised residual RMS |")
    print("|---:|---:|---|---:|---:|")
    for n in sizes:
        data = synthetic_measurements(nominal, true, pool[:n], instrument=INSTRUMENT,
                                      seed=n, **NOISE)
        times, result = [], None
        for _ in range(repeats):
            t0 = time.perf_counter()
            result = calibrate(nominal, data.poses, data.actuators)
            times.append(time.perf_counter() - t0)
        print(f"| {n} | {6 * n} | {np.median(times):.3f} [{min(times):.3f}, {max(times):.3f}] "
              f"| {result.iterations} | {result.residuals_after.normalized_rms:.3f} |")


def error_table(nominal, true, candidates, held, counts, seeds, plot):
    print("\n### Validation error against the number of poses (held-out noisy poses)\n")
    print(f"{len(held.poses)} held-out poses; random: median over {seeds} draws from the "
          f"{len(candidates)} candidates; selected: O1, greedy and exchange, from the same "
          "candidates. Errors: RMS of the target position (um) and rotation (urad) from the "
          "forward kinematics of the readings, and of the readings (um) from the inverse "
          "kinematics of the measured poses. The true model itself shows "
          f"{floor(true, held):.1f} um of reading error on these data (the noise floor); "
          f"{nominal_errors(nominal, true, candidates[:40], held)}.\n")
    print("| poses | choice | O1 | position (um) | rotation (urad) | readings (um) |")
    print("|---:|---|---:|---:|---:|---:|")
    curves: dict[str, list[float]] = {"random": [], "selected (O1, exchange)": []}
    rng = np.random.default_rng(0)
    for n in counts:
        rows = []
        for _ in range(seeds):
            pick = rng.choice(len(candidates), n, replace=False)
            rows.append(evaluate(nominal, true, candidates[pick], held, n))
        med = np.median(np.array([r[1:] for r in rows]), axis=0)
        o1 = np.median([r[0] for r in rows])
        print(f"| {n} | random | {o1:.3g} | {med[0]:.1f} | {med[1]:.1f} | {med[2]:.1f} |")
        curves["random"].append(med[0])
        for method in ("greedy", "exchange"):
            chosen = select_poses(nominal, candidates, n, method=method)
            o1, *err = evaluate(nominal, true, chosen.poses, held, n)
            print(f"| {n} | selected ({method}) | {chosen.o1:.3g} | {err[0]:.1f} | "
                  f"{err[1]:.1f} | {err[2]:.1f} |")
        curves["selected (O1, exchange)"].append(err[0])
    if plot:
        plots.plot_error_against_poses(counts, curves, path=plot)
        print(f"\nwrote {plot}")


def evaluate(nominal, true, poses, held, seed):
    data = synthetic_measurements(nominal, true, poses, instrument=INSTRUMENT, seed=seed,
                                  **NOISE)
    try:
        result = calibrate(nominal, data.poses, data.actuators)
    except IdentifiabilityError:
        return 0.0, np.inf, np.inf, np.inf
    s = result.validate(held.poses, held.actuators).identified.summary()
    blocks, _ = candidate_blocks(nominal, poses)
    return (observability(blocks)[0], s["position_rms"] * 1e6, s["rotation_rms"] * 1e6,
            s["actuator_rms"] * 1e6)


def nominal_errors(nominal, true, poses, held) -> str:
    """The uncalibrated model's validation errors (instrument registered), as text."""
    data = synthetic_measurements(nominal, true, poses, instrument=INSTRUMENT, seed=1, **NOISE)
    s = calibrate(nominal, data.poses, data.actuators).validate(
        held.poses, held.actuators).nominal.summary()
    return (f"the nominal model (instrument registered, no calibration) is off by "
            f"{s['position_rms'] * 1e6:.0f} um, {s['rotation_rms'] * 1e6:.0f} urad and "
            f"{s['actuator_rms'] * 1e6:.0f} um of readings")


def floor(true, held) -> float:
    """RMS reading error (um) of the true model itself on the held-out noisy poses."""
    frame = hp.Hexapod(true.with_chains(measurement_chains(true.chain_geometry,
                                                           frames_of(INSTRUMENT, None))))
    q = frame.inverse_kinematics_batch(held.poses).actuator_positions
    return float(np.sqrt(np.mean((q - held.actuators) ** 2)) * 1e6)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--smoke", action="store_true", help="small sizes")
    parser.add_argument("--plot", help="figure of the error against the number of poses")
    args = parser.parse_args()
    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
          f"Python {platform.python_version()}, numpy {np.__version__}")
    nominal = hp.Hexapod.default()
    true = truth(nominal)
    pool = reference_poses(nominal, 2600, seed=1)
    sizes = (20, 50) if args.smoke else (50, 200, 1000)
    timing_table(nominal, true, pool, sizes, repeats=1 if args.smoke else 3)
    candidates = reference_poses(nominal, 1000, seed=2)
    held = synthetic_measurements(nominal, true, reference_poses(nominal, 400, seed=3)[:100],
                                  instrument=INSTRUMENT, seed=99, **NOISE)
    counts = (12, 20) if args.smoke else (12, 16, 24, 40, 80)
    error_table(nominal, true, candidates, held, counts, 2 if args.smoke else 5, args.plot)


if __name__ == "__main__":
    main()
