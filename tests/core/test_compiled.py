"""The numba cache of the package's kernels is keyed on every compiled module, so that an
edit to a kernel inlined into another module's kernel cannot leave stale machine code."""

from __future__ import annotations

import importlib.util

import numba
import pytest

from hexapod_pin.core import compiled
from hexapod_pin.hexapod import batch, kernels


@pytest.mark.parametrize("kernel", [kernels.leg_state, batch._inverse.serial, batch._inverse.parallel])
def test_package_kernels_use_the_package_stamp(kernel):
    locator = kernel._cache._impl.locator
    assert isinstance(locator, (compiled.PackageInTreeLocator, compiled.PackageUserWideLocator,
                                compiled.PackageUserProvidedLocator))   # NUMBA_CACHE_DIR set
    assert locator.get_source_stamp() == compiled.source_stamp()


def test_the_stamp_covers_every_compiled_module():
    names = {p.relative_to(compiled.PACKAGE_DIR).as_posix() for p in compiled.compiled_modules()}
    assert {"hexapod/kernels.py", "hexapod/batch.py", "hexapod/fast.py",
            "planar/kernels.py", "core/linear_kernels.py", "core/integrator_kernels.py",
            "core/constraint_views.py"} <= names


def test_the_stamp_changes_with_any_compiled_module(tmp_path, monkeypatch):
    (tmp_path / "sub").mkdir()
    inner, outer = tmp_path / "sub" / "inner.py", tmp_path / "outer.py"
    inner.write_text("@jit\ndef f(x):\n    return x\n")
    outer.write_text("@jit\ndef g(x):\n    return f(x)\n")
    (tmp_path / "plain.py").write_text("x = 1\n")
    monkeypatch.setattr(compiled, "PACKAGE_DIR", tmp_path)
    compiled.source_stamp.cache_clear()
    try:
        assert [p.name for p in compiled.compiled_modules()] == ["outer.py", "inner.py"]
        first = compiled.source_stamp()
        compiled.source_stamp.cache_clear()
        (tmp_path / "plain.py").write_text("x = 2\n")              # not compiled: same stamp
        assert compiled.source_stamp() == first
        compiled.source_stamp.cache_clear()
        inner.write_text("@jit\ndef f(x):\n    return 2 * x\n")    # the inlined kernel changed
        assert compiled.source_stamp() != first
    finally:
        compiled.source_stamp.cache_clear()


def test_functions_outside_the_package_keep_numbas_locators(tmp_path):
    source = tmp_path / "elsewhere.py"
    source.write_text("def h(x):\n    return x\n")
    spec = importlib.util.spec_from_file_location("elsewhere", source)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    assert compiled.PackageInTreeLocator.from_function(module.h, str(source)) is None
    assert compiled.PackageUserWideLocator.from_function(module.h, str(source)) is None
    assert numba.core.caching.InTreeCacheLocator.from_function(module.h, str(source))
