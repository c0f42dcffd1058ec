"""The planar 3-PRR's MuJoCo twin (benchmarks/mjcf_planar.py) and its benchmark rows.

Kinematic and inertial agreement of the MJCF with our Pinocchio model (before any
dynamics), MuJoCo's dynamics against the independent reference states, the handling of the
redundant out-of-plane closure rows, and the smoke agreement check of bench_scaling.py's
planar section (rigid routes to 1e-8). Each check is shown able to fail on a perturbed MJCF.
"""

import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from conftest import import_benchmarks, load_reference

mujoco = pytest.importorskip("mujoco")

from hexapod_pin.planar.robot import Planar3PRR, PlanarGeometry

ROOT = Path(__file__).resolve().parents[2]
BENCH = ROOT / "benchmarks"


@pytest.fixture(scope="module")
def bench():
    """The benchmark modules (benchmarks/ is not a package)."""
    return import_benchmarks("mjcf_planar", "bench_scaling")


@pytest.fixture(scope="module")
def robot():
    return Planar3PRR.default()


@pytest.fixture(scope="module")
def samples(bench, robot):
    return bench[1].planar_states(robot, 8, seed=3)


def _check(mp, robot, mj, samples):
    return mp.model_check(robot, mj, *zip(*(s[:3] for s in samples)))


def test_mjcf_matches_pinocchio_model(bench, robot, samples):
    """Joint values, sites, closure residual, mass matrix, bias forces, state completion,
    inert z rows and tiny inertias: MJCF vs our Pinocchio model, all at round-off."""
    mp = bench[0]
    worst = _check(mp, robot, mp.MujocoPlanar(robot.geometry), samples)
    assert set(worst) == set(mp.CHECKS)
    for key, value in worst.items():
        assert value <= 1e-12, (key, value)


@pytest.mark.parametrize("change, caught", [
    ({"link_length": 0.30 * (1 + 1e-6)}, ("joints", "sites", "mass")),
    ({"platform_inertia": 0.002 * (1 + 1e-6)}, ("mass",)),
    ({"link_mass": 0.2 * (1 + 1e-6)}, ("mass", "bias")),
])
def test_model_check_detects_a_wrong_mjcf(bench, robot, samples, change, caught):
    mp = bench[0]
    wrong = mp.MujocoPlanar(robot.geometry.replace(**change))
    worst = _check(mp, robot, wrong, samples)
    for key in caught:
        assert worst[key] > 1e-9, (key, worst[key])


@pytest.mark.parametrize("entry", load_reference()["planar"], ids=lambda e: e["name"])
def test_mujoco_matches_reference_states(bench, entry):
    """MuJoCo alone (its own closed form, completion, mj_inverse + reduction, refined
    mj_forward) against the independent reference: no hexapod_pin code involved."""
    mp = bench[0]
    mj = mp.MujocoPlanar(PlanarGeometry(**entry["geometry"]))
    pose, twist, twist_dot, wrench = (np.array(entry[k]) for k in
                                      ("pose", "twist", "twist_dot", "wrench"))
    ref = np.array(entry["actuator_forces"])
    tol = 1e-9 * max(1.0, np.max(np.abs(ref)))
    qpos, qvel, qacc = mj.set_task_state(pose, twist, twist_dot)
    assert np.max(np.abs(qpos[mj.slider_q] - entry["s"])) <= 1e-12
    for rows in ("in_plane", "all"):
        tau = mj.inverse_tree_state(qpos, qvel, qacc, wrench, rows=rows)
        assert np.max(np.abs(tau - ref)) <= tol, rows
    static = mj.inverse_task(pose, np.zeros(3), np.zeros(3), wrench)
    assert np.max(np.abs(static - entry["static_forces"])) <= tol
    acc = mj.forward(qpos, qvel, ref, wrench, refine=True)
    assert np.max(np.abs(acc[mj.platform_v] - twist_dot)) <= 1e-8
    soft = mj.forward(qpos, qvel, ref, wrench)
    assert 0.0 < np.max(np.abs(soft[mj.platform_v] - twist_dot)) < 0.1   # soft, not rigid


def test_redundant_rows_carry_nothing(bench, robot, samples):
    """The connect z rows are zero in efc_J, get zero force, and the minimum-norm
    least-squares reduction puts zero multipliers on them."""
    mp = bench[0]
    mj = mp.MujocoPlanar(robot.geometry)
    m, d = mj.model, mj.data
    pose, twist, twist_dot, wrench = samples[0]
    qpos, qvel, qacc = mj.set_task_state(pose, twist, twist_dot)
    mujoco.mj_inverse(m, d)
    jac = d.efc_J.reshape(d.nefc, m.nv)
    assert d.nefc == 9
    z_rows = [2, 5, 8]
    assert np.all(jac[z_rows] == 0.0) and np.all(d.efc_force[z_rows] == 0.0)
    mat = np.hstack([mj.selection, jac.T])
    rhs = d.qfrc_inverse - mj.wrench_qfrc(wrench)
    sol = np.linalg.lstsq(mat, rhs, rcond=None)[0]
    assert np.max(np.abs(sol[3:][z_rows])) <= 1e-12
    assert np.max(np.abs(mat @ sol - rhs)) <= 1e-10        # consistent system
    assert np.max(np.abs(sol[:3] - mj.inverse_tree_state(qpos, qvel, qacc, wrench))) <= 1e-10


def test_planar_section_agrees(bench):
    """bench_scaling's planar section: every rigid route within 1e-8 of its reference."""
    text, failures = bench[1].planar_vs_mujoco(6, repeats=1, timing=False)
    assert failures == []
    for name in ("MuJoCo mj_inverse + reduction, all 9 rows, lstsq",
                 "MuJoCo + proximal refinement (rigid", "MuJoCo refined + mj_Euler",
                 "ours Planar3PRR.inverse_dynamics kkt", "ours Planar3PRR.forward_dynamics"):
        assert name in text


def test_planar_section_detects_a_wrong_mjcf(bench, monkeypatch):
    """A MuJoCo twin with 1e-6 heavier sliders fails the MJCF check and the ID agreement."""
    mp, bs = bench
    original = mp.MujocoPlanar

    def heavier(geometry, **options):
        return original(geometry.replace(slider_mass=geometry.slider_mass * (1 + 1e-6)),
                        **options)

    monkeypatch.setattr(bs.mjcf_planar, "MujocoPlanar", heavier)
    _, failures = bs.planar_vs_mujoco(4, repeats=1, timing=False)
    assert any("planar MJCF check mass" in f for f in failures)
    assert any("MuJoCo mj_inverse" in f for f in failures)


def test_only_planar_smoke_run():
    """The script's planar-only smoke run exits 0 with the MuJoCo columns filled."""
    proc = subprocess.run([sys.executable, str(BENCH / "bench_scaling.py"), "--smoke",
                           "--only-planar"], cwd=ROOT, capture_output=True, text=True,
                          timeout=300, check=False)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert "all routes agree" in proc.stdout
    row = next(line for line in proc.stdout.splitlines()
               if line.startswith("| planar 3-PRR (3 closures"))
    assert " - " not in row                 # MuJoCo columns present for the planar row
