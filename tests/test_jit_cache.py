"""The numba cache guard (debris_gym.jit): a changed source drops the compiled modules' caches.

Regression: numba keys a cached kernel on its own file only, so after an edit of
batch_geometry.py the cached mission_batch kernels (with the old geometry inlined) kept running
and gave wrong gaps until their cache files were deleted by hand.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from debris_gym import jit

MODULES = ("geo", "step")


def _package(tmp_path: Path) -> Path:
    pkg = tmp_path / "pkg"
    (pkg / "__pycache__").mkdir(parents=True)
    for name in MODULES:
        (pkg / f"{name}.py").write_text(f"# {name} v1\n")
    return pkg


def _cache_files(pkg: Path, names=("geo.f-10.py311.nbi", "step.g-5.py311.1.nbc")) -> list[Path]:
    paths = [pkg / "__pycache__" / n for n in names]
    for p in paths:
        p.write_bytes(b"compiled")
    return paths


def test_a_changed_helper_module_drops_every_compiled_modules_cache(tmp_path):
    pkg = _package(tmp_path)
    assert jit.drop_stale_cache(pkg, MODULES)  # no digest yet: start clean
    cached = _cache_files(pkg)
    other = pkg / "__pycache__" / "unrelated.h-1.py311.nbi"
    other.write_bytes(b"compiled")
    pyc = pkg / "__pycache__" / "geo.cpython-311.pyc"
    pyc.write_bytes(b"bytecode")

    assert not jit.drop_stale_cache(pkg, MODULES)  # unchanged sources: the cache stays
    assert all(p.exists() for p in cached)

    (pkg / "geo.py").write_text("# geo v2\n")  # only the helper's module changes
    assert jit.drop_stale_cache(pkg, MODULES)
    assert not any(p.exists() for p in cached)  # the kernel of step.py is dropped too
    assert other.exists() and pyc.exists()  # other modules' caches and bytecode stay
    assert (pkg / "__pycache__" / "numba_sources.sha256").read_text() == jit.sources_digest(
        pkg, MODULES
    )
    assert not jit.drop_stale_cache(pkg, MODULES)


def test_the_digest_covers_every_compiled_module_of_the_package():
    pkg = Path(jit.__file__).resolve().parent
    users = sorted(
        p.stem
        for p in pkg.rglob("*.py")
        if p.stem != "jit"
        and any(f"@{d}" in p.read_text() for d in ("kernel", "inlined", "threaded", "borrowing"))
    )
    assert users == sorted(jit.COMPILED_MODULES)
    assert "numba.njit" not in "".join(
        p.read_text() for p in pkg.rglob("*.py") if p.stem != "jit"
    )  # every compiled function goes through the guarded decorators


def test_changed_compile_options_drop_the_cache(tmp_path):
    """Regression: numba's cache keys on neither the helpers' files nor the decorator options,
    so editing the options in jit.py (e.g. ``error_model``) kept running the old machine code."""
    pkg = _package(tmp_path)
    assert jit.drop_stale_cache(pkg, MODULES)
    before = jit.sources_digest(pkg, MODULES)
    assert before == jit.sources_digest(pkg, MODULES, jit.COMPILE_OPTIONS)
    changed = {**jit.COMPILE_OPTIONS, "error_model": "python"}
    assert jit.sources_digest(pkg, MODULES, changed) != before
    # the stamp written for one set of options is stale for another
    stamp = (pkg / "__pycache__" / "numba_sources.sha256").read_text()
    assert stamp == before != jit.sources_digest(pkg, MODULES, changed)


def test_division_by_zero_in_compiled_code_follows_numpy():
    """error_model="numpy": 1/0 is inf in a kernel (no zero test, no ZeroDivisionError)."""

    @jit.kernel
    def divide(a, b):
        return a / b

    assert divide(1.0, 0.0) == np.inf


def _refcount_calls(dispatcher) -> int:
    ir = "".join(dispatcher.inspect_llvm().values())
    return ir.count("@NRT_incref") + ir.count("@NRT_decref")


def test_a_borrowing_loop_carries_no_reference_counting():
    """The step's row loop hands arrays to inlined phases on every row; under numba's
    reference counting each hand-over is an atomic update (docs/benchmarks.md). The same loop
    compiled as a ``borrowing`` kernel has none, and the step's row loop is one."""
    from debris_gym import mission_step

    def rows(values, out):
        for i in range(values.shape[0]):
            out[i] = _row_sum(values, i)

    values, out = np.arange(12.0).reshape(4, 3), np.zeros(4)
    counted = jit.numba.njit(_nrt=True)(rows)  # no cache: the IR is read back
    borrowed = jit.numba.njit(_nrt=False)(rows)
    counted(values, out)
    borrowed(values, out)
    np.testing.assert_array_equal(out, values.sum(axis=1))
    assert _refcount_calls(counted) > 0
    assert _refcount_calls(borrowed) == 0
    assert mission_step.step_rows.targetoptions["_nrt"] is False


@jit.numba.njit(inline="always")
def _row_sum(values, i):
    row = values[i]  # a view: a reference-counted array
    s = 0.0
    for k in range(row.shape[0]):
        s += row[k]
    return s
