"""Tiered execution of the compiled kernels (``hexapod_pin.core.tiers``): a kernel without
machine code runs its Python source until compiling it pays.

The reference of each check is the compiled kernel (numba's machine code, itself checked
against independent routes by the rest of the suite): the interpreted run must give its
numbers, its exceptions must end in its result, and the switch to machine code must
happen when the rule says. No test times anything: the budget rule is driven with budgets
of 0, a nanosecond or infinity.
"""

from __future__ import annotations

import json
import math
import os
import subprocess
import sys
import threading
from pathlib import Path

import numba
import numpy as np
import pytest

import hexapod_pin as hp
from hexapod_pin import precompile
from hexapod_pin.core import tiers
from hexapod_pin.core.compiled import FLAGS, all_finite, kernel
from hexapod_pin.errors import InputError

ROOT = Path(__file__).resolve().parents[2]
#: compile options of the test kernels: no disk cache (each test starts without machine code)
PLAIN = {k: v for k, v in FLAGS.items() if k != "cache"}


@pytest.fixture
def settings(monkeypatch):
    """The process's tier settings, restored after the test."""
    monkeypatch.setattr(tiers, "SETTINGS", tiers.Settings())
    return tiers.SETTINGS


def _divide_into(out, x, d):
    out[0] += 1.0                    # written before the division that fails interpreted
    out[1] = x / d                   # Python floats: ZeroDivisionError; compiled: inf
    out[2] = math.sqrt(x - 2.0)      # ValueError interpreted for x < 2; compiled: NaN
    return out[1] + out[2]


def _rows_sum(rows):
    total = 0.0
    for k in range(rows.shape[0]):
        total += rows[k, 0]
    return total


def _inner(x):
    return 2.0 * x


def _env(**extra):
    return {**os.environ, "PYTHONPATH": os.pathsep.join(
        [str(ROOT), *filter(None, [os.environ.get("PYTHONPATH")])]), **extra}


def test_every_kernel_gives_the_same_numbers_interpreted_and_compiled(tmp_path):
    """Each kernel that ``hp.warmup()``'s steps reach, on the arguments its callers pass
    there, once per tuple of argument types (``tests/tier_verify.py``): result and
    arguments left by the Python source equal the machine code's (1e-12 relative, integers
    exactly). The kernels are in the disk cache when the demo ran the warmup before."""
    # every kernel of the package with tiered execution that warmup compiles is checked
    # (a parallel twin runs the source of its serial twin; RARE: not reached by warmup)
    expected = {name for name, d in precompile.dispatchers().items()
                if not name.endswith("[parallel]") and name not in precompile.RARE
                and tiers.tier_of(d) is not None and not tiers.tier_of(d).always_compile}
    out = tmp_path / "checks.json"
    for attempt in range(2):
        done = subprocess.run([sys.executable, str(ROOT / "tests" / "tier_verify.py"),
                               str(out)], capture_output=True, text=True, env=_env(),
                              cwd=ROOT, timeout=1800, check=False)
        assert done.returncode == 0, done.stderr[-3000:]
        checks = json.loads(out.read_text())
        missing = expected - {c["kernel"] for c in checks}
        if not missing or attempt:
            break
        # a cold disk cache: compiling a twin compiles its callees into their own
        # dispatchers, whose later calls then skip the checker; warm the cache and rerun
        warm = subprocess.run([sys.executable, "-c", "import hexapod_pin; hexapod_pin.warmup()"],
                              capture_output=True, text=True, env=_env(), cwd=ROOT,
                              timeout=1800, check=False)
        assert warm.returncode == 0, warm.stderr[-3000:]
    wrong = [c for c in checks if c.get("differences")]
    assert not wrong, wrong[:10]
    assert not missing, sorted(missing)
    # the Python source of a kernel raises only where its compiled run gives inf / NaN
    # (the fallback compiles then): none on warmup's finite, regular inputs
    raised = [c for c in checks if c.get("raised")]
    assert not raised, raised[:10]


def test_an_exception_interpreted_restores_the_arguments_and_gives_the_compiled_result(
        settings):
    settings.budget = math.inf
    divide = kernel(PLAIN)(_divide_into)
    out = np.zeros(3)
    assert divide(out, 6.0, 2.0) == 5.0 and not divide.signatures      # interpreted
    np.testing.assert_array_equal(out, [1.0, 3.0, 2.0])
    out = np.zeros(3)
    assert math.isnan(divide(out, 1.0, 0.0))            # compiled: inf + NaN
    np.testing.assert_array_equal(out, [1.0, math.inf, math.nan])  # out[0] added to once
    assert divide.signatures                                         # compiled
    out = np.zeros(3)
    assert divide(out, 4.0, 0.0) == math.inf            # machine code from now on
    np.testing.assert_array_equal(out, [1.0, math.inf, math.sqrt(2.0)])


def test_a_numpy_scalar_interpreted_warns_nothing_and_returns_a_python_scalar(settings):
    settings.budget = math.inf
    divide = kernel(PLAIN)(_divide_into)
    out = np.zeros(3)
    got = divide(out, np.float64(6.0), np.float64(0.0))   # numpy: inf and no exception
    assert got == math.inf and type(got) is float and not divide.signatures
    np.testing.assert_array_equal(out, [1.0, math.inf, 2.0])


def test_after_the_budget_the_kernel_runs_machine_code(settings):
    settings.budget = 1e-9
    rows_sum = kernel(PLAIN)(_rows_sum)
    rows = np.arange(12.0).reshape(6, 2)
    assert rows_sum(rows) == 30.0 and not rows_sum.signatures          # first: interpreted
    assert tiers.tier_of(rows_sum).interpreted_seconds() > 0.0
    assert rows_sum(rows) == 30.0 and len(rows_sum.signatures) == 1    # budget spent
    assert rows_sum(rows.astype(np.float32)) == 30.0                   # new types: interpreted
    assert len(rows_sum.signatures) == 1


def test_eager_mode_and_the_eager_block_compile_on_the_first_call(settings):
    rows = np.ones((3, 2))
    settings.mode = "eager"
    first = kernel(PLAIN)(_rows_sum)
    assert first(rows) == 3.0 and first.signatures
    settings.mode = "tiered"
    second = kernel(PLAIN)(_rows_sum)
    with tiers.eager():
        assert second(rows) == 3.0 and second.signatures
    third = kernel(PLAIN)(_rows_sum)
    assert third(rows) == 3.0 and not third.signatures


def test_a_large_call_of_a_loop_kernel_compiles_at_once(settings):
    settings.budget = 1.0
    small, large = np.ones((10, 2)), np.ones((int(2 / tiers.PRIOR_SECONDS_PER_UNIT), 2))
    rows_sum = kernel(PLAIN, work=0)(_rows_sum)
    assert rows_sum(small) == 10.0 and not rows_sum.signatures   # 10 x 2 ms: interpreted
    rows_sum = kernel(PLAIN, work=0)(_rows_sum)
    assert rows_sum(large) == large.shape[0] and rows_sum.signatures   # 1000 x 2 ms: compiled


def test_an_always_compiled_kernel_never_runs_interpreted(settings):
    settings.budget = math.inf
    rows_sum = kernel(PLAIN, always_compile=True)(_rows_sum)
    assert rows_sum(np.ones((2, 2))) == 2.0 and rows_sum.signatures


def test_an_inner_kernel_called_by_an_interpreted_one_follows_its_own_tier(settings):
    settings.budget = math.inf
    inner = kernel(PLAIN)(_inner)

    def twice(x):
        return inner(x) + inner(x + 1.0)

    outer = kernel(PLAIN)(twice)
    assert outer(1.0) == 6.0
    assert not outer.signatures and not inner.signatures
    assert tiers.tier_of(inner).interpreted_seconds() > 0.0


def test_a_kernel_in_the_disk_cache_is_loaded_not_interpreted(settings):
    settings.budget = math.inf
    vec = np.ones(3)
    with tiers.eager():
        assert all_finite(vec)                 # in the package's disk cache now
    fresh = tiers.install(numba.njit(**FLAGS)(all_finite.py_func))
    assert tiers.tier_of(fresh) is not None
    assert fresh(vec) and fresh.signatures and sum(fresh.stats.cache_hits.values()) == 1


def test_threads_crossing_the_budget_together_get_the_compiled_numbers(settings):
    settings.budget = 1e-4
    rows_sum = kernel(PLAIN)(_rows_sum)
    rows = np.arange(40.0).reshape(20, 2)
    results, errors = [], []

    def work():
        try:
            for _ in range(50):
                results.append(rows_sum(rows))
        except Exception as exc:      # noqa: BLE001 - reported below
            errors.append(exc)

    threads = [threading.Thread(target=work) for _ in range(4)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert not errors and results == [380.0] * 200 and len(rows_sum.signatures) == 1


def test_the_environment_variables_are_checked():
    assert tiers.read_settings({}) == tiers.Settings("tiered", tiers.DEFAULT_BUDGET)
    assert tiers.read_settings({tiers.MODE_VARIABLE: "Eager",
                                tiers.BUDGET_VARIABLE: "inf"}) == tiers.Settings("eager",
                                                                                 math.inf)
    with pytest.raises(InputError, match="HEXAPOD_PIN_COMPILE"):
        tiers.read_settings({tiers.MODE_VARIABLE: "lazy"})
    for bad in ("-1", "nan", "soon"):
        with pytest.raises(InputError, match="HEXAPOD_PIN_COMPILE_BUDGET"):
            tiers.read_settings({tiers.BUDGET_VARIABLE: bad})


def test_another_numba_layout_leaves_the_kernel_to_plain_compilation(monkeypatch):
    assert not tiers.supported(object())
    monkeypatch.setattr(tiers, "_ORIGINAL", None)
    plain = tiers.install(numba.njit(**PLAIN)(_inner))
    assert tiers.tier_of(plain) is None and plain(1.0) == 2.0 and plain.signatures


def test_a_first_inverse_dynamics_with_an_empty_cache_compiles_nothing(tmp_path):
    code = ("import json, numpy as np\n"
            "from numba.core import event\n"
            "import hexapod_pin as hp\n"
            "robot = hp.Hexapod.default()\n"
            "with event.install_recorder('numba:compile') as rec:\n"
            "    res = robot.inverse_dynamics(robot.home_pose + 0.01, np.full(6, 0.1),\n"
            "                                 np.full(6, 0.2))\n"
            "print(json.dumps({'compiled': len(rec.buffer),\n"
            "                  'forces': res.actuator_forces.tolist()}))\n")
    done = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                          env=_env(NUMBA_CACHE_DIR=str(tmp_path), HEXAPOD_PIN_COMPILE="tiered"),
                          cwd=ROOT, timeout=300, check=False)
    assert done.returncode == 0, done.stderr[-3000:]
    out = json.loads(done.stdout.strip().splitlines()[-1])
    assert out["compiled"] == 0
    robot = hp.Hexapod.default()
    with tiers.eager():                   # machine code in this process
        want = robot.inverse_dynamics(robot.home_pose + 0.01, np.full(6, 0.1),
                                      np.full(6, 0.2)).actuator_forces
    np.testing.assert_allclose(out["forces"], want, rtol=1e-12, atol=1e-12 * np.abs(want).max())


def test_the_checker_of_the_first_test_sees_a_difference():
    import tier_verify

    assert tier_verify.differences(1.0, 1.0) == []
    assert tier_verify.differences(1.0 + 1e-11, 1.0)                  # beyond 1e-12
    assert tier_verify.differences((np.ones(2), 3), (np.ones(2), 4))   # an integer
    assert tier_verify.differences(np.array([np.nan]), np.array([np.inf]))
    assert tier_verify.differences(np.float64(1.0), 1.0)               # a numpy scalar
    assert tier_verify.differences(np.array([1e3, 0.0]), np.array([1e3, 2e-9]))
    assert not tier_verify.differences(np.array([1e3, 0.0]), np.array([1e3, 2e-10]))


def test_the_price_counts_the_kernels_a_compilation_compiles(settings):
    settings.budget = 0.25
    inner = kernel(PLAIN)(_inner)

    def twice(x):
        return inner(x) + inner(x + 1.0)

    outer = kernel(PLAIN)(twice)
    assert tiers.closure(outer) == (outer, inner)
    assert tiers.tier_of(outer).price() == 0.5 and tiers.tier_of(inner).price() == 0.25
    with tiers.eager():
        inner(1.0)                                   # machine code: no longer counted
    assert tiers.tier_of(outer).price() == 0.25


def test_an_exception_in_an_inner_kernel_reruns_the_outermost_one_compiled(settings):
    settings.budget = math.inf
    divide = kernel(PLAIN)(_divide_into)

    def twice(out, x, d):
        out[3] += 10.0                    # the outer kernel's own write, before the failure
        return divide(out, x, d) + divide(out, x, d)

    outer = kernel(PLAIN)(twice)
    out = np.zeros(4)
    assert outer(out, 6.0, 2.0) == 10.0 and not outer.signatures          # interpreted
    np.testing.assert_array_equal(out, [2.0, 3.0, 2.0, 10.0])
    out = np.zeros(4)
    assert outer(out, 6.0, 0.0) == math.inf and outer.signatures          # compiled
    np.testing.assert_array_equal(out, [2.0, math.inf, 2.0, 10.0])        # written once


def test_a_failing_bookkeeping_falls_back_to_compiling(settings, monkeypatch):
    settings.budget = math.inf
    rows_sum = kernel(PLAIN)(_rows_sum)
    monkeypatch.setattr(tiers.Tier, "price", lambda self: 1 / 0)
    assert rows_sum(np.ones((2, 2))) == 2.0 and rows_sum.signatures
