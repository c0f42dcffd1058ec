"""Compiling the kernels up front (``hp.warmup``, ``hexapod-pin warmup``) and the one-line
compile notice of a first call (logger "hexapod_pin", INFO)."""

from __future__ import annotations

import json
import logging

import numba
import pytest
from typer.testing import CliRunner

import hexapod_pin as hp
from hexapod_pin import precompile
from hexapod_pin.cli import app
from hexapod_pin.core import compiled


def test_warmup_compiles_every_kernel_and_reports_its_progress():
    calls = []
    report = hp.warmup(progress=lambda done, total: calls.append((done, total)))
    assert calls == [(k, precompile.N_STEPS) for k in range(precompile.N_STEPS + 1)]
    assert len(report.steps) == precompile.N_STEPS
    assert all(step.seconds >= 0.0 and step.compiled >= 0 for step in report.steps)
    kernels = precompile.dispatchers()
    assert len(kernels) == len(report.kernels) > 100
    # the first calls the issue names: their kernels hold machine code now
    for name in ("hexapod_pin.hexapod.fast.simulate_kernel",
                 "hexapod_pin.hexapod.batch._inverse[serial]",
                 "hexapod_pin.hexapod.batch._inverse[parallel]",
                 "hexapod_pin.planar.kernels.inverse_dynamics_batch[parallel]",
                 "hexapod_pin.planning.solver.backward_pass"):
        assert kernels[name].signatures, name
    # every other kernel is compiled or inlined into one, but the few of rarer routes
    assert set(report.uncompiled) <= precompile.RARE
    assert set(precompile.uncompiled(kernels)) == set(report.uncompiled)


def test_a_batch_loop_and_its_parallel_twin_have_their_own_cache_entries():
    from hexapod_pin.hexapod import batch

    serial, parallel = batch._inverse.serial, batch._inverse.parallel
    assert parallel.targetoptions.get("parallel") and not serial.targetoptions.get("parallel")
    assert serial._cache._cache_file._index_name != parallel._cache._cache_file._index_name


def test_uncompiled_follows_calls_into_other_kernels():
    leaf = numba.njit(lambda x: x + 1.0)
    fresh = numba.njit(lambda x: x * 2.0)
    kernels = {"leaf": leaf, "fresh": fresh}
    assert set(precompile.uncompiled(kernels)) == {"leaf", "fresh"}
    fresh(1.0)
    assert precompile.uncompiled(kernels) == ("leaf",)


def _records(caplog):
    return [r for r in caplog.records if r.name == "hexapod_pin" and "compiling" in r.message]


def test_a_first_compilation_logs_one_line_and_later_calls_none(caplog):
    caplog.set_level(logging.INFO, logger="hexapod_pin")
    kernel = numba.njit(cache=False)(compiled.all_finite.py_func)   # never cached: compiles
    vec = [1.0, 2.0]
    import numpy as np

    assert kernel(np.array(vec))
    first = _records(caplog)
    assert len(first) == 1 and first[0].levelno == logging.INFO
    assert "hexapod_pin.core.compiled.all_finite" in first[0].message
    assert "\n" not in first[0].getMessage()
    caplog.clear()
    assert kernel(np.array(vec)) and not _records(caplog)          # in memory
    cached = numba.njit(cache=True)(compiled.all_finite.py_func)
    cached(np.array(vec))                                        # compiled or loaded
    caplog.clear()
    again = numba.njit(cache=True)(compiled.all_finite.py_func)
    assert again(np.array(vec)) and not _records(caplog)         # loaded from the disk cache
    assert again.stats.cache_hits


def test_other_packages_kernels_log_nothing(caplog):
    caplog.set_level(logging.INFO, logger="hexapod_pin")
    numba.njit(lambda x: x - 1.0)(3.0)
    assert not _records(caplog)


def test_the_warmup_command_exits_0_and_reports_its_steps():
    result = CliRunner().invoke(app, ["warmup", "--json"])
    assert result.exit_code == 0, result.output
    out = json.loads(result.stdout)
    assert len(out["steps"]) == precompile.N_STEPS
    assert out["kernels"] > 100 and set(out["uncompiled"]) <= precompile.RARE
    text = CliRunner().invoke(app, ["warmup"])
    assert text.exit_code == 0 and "compiled kernels in the library" in text.stdout


@pytest.mark.parametrize("command", [["demo", "--no-html", "--json"]])
def test_the_demo_runs_the_warmup(command):
    result = CliRunner().invoke(app, command)
    assert result.exit_code == 0, result.output
    assert json.loads(result.stdout)["warmup"]["kernels"] > 100


def test_the_warmup_command_shows_a_progress_bar_in_a_terminal(monkeypatch):
    import functools

    from rich.console import Console

    from hexapod_pin.cli import common

    monkeypatch.setattr(common, "Console", functools.partial(Console, force_terminal=True,
                                                             width=100))
    loud = CliRunner().invoke(app, ["warmup"])
    assert loud.exit_code == 0 and "compiling the kernels" in loud.stderr
    assert f"{precompile.N_STEPS}/{precompile.N_STEPS}" in loud.stderr
    quiet = CliRunner().invoke(app, ["warmup", "--quiet"])
    assert quiet.exit_code == 0 and "compiling the kernels" not in quiet.stderr


def test_the_package_kernels_honour_numba_cache_dir(tmp_path):
    import os
    import subprocess
    import sys

    code = ("from hexapod_pin.core import compiled; "
            "print(compiled.all_finite._cache._cache_path)")
    env = dict(os.environ, NUMBA_CACHE_DIR=str(tmp_path))
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True).stdout.strip()
    assert out.startswith(str(tmp_path)), out
    env.pop("NUMBA_CACHE_DIR")
    out = subprocess.run([sys.executable, "-c", code], env=env, capture_output=True,
                         text=True, check=True).stdout.strip()
    assert not out.startswith(str(tmp_path)) and "hexapod_pin" in out    # in the package
