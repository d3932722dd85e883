"""The package's numba decorators, and a compile cache that follows every compiled module.

:data:`kernel` compiles a loop that Python calls; :data:`inlined` compiles a helper that the
kernels call, inlined into them by numba (``inline="always"``): as separate functions the
helpers cost an array-view set-up per call (docs/benchmarks.md, "Measured design choices").

Both cache their machine code on disk (``cache=True``), but numba keys a cached kernel only on
its *own* source file: a kernel of ``mission_batch.py`` with a helper inlined from
``batch_geometry.py`` would keep running the old helper after ``batch_geometry.py`` changed (an
editable install after ``git pull``). :func:`drop_stale_cache` guards against that: on import
it hashes the sources of :data:`COMPILED_MODULES` and, when the hash differs from the one stored
beside numba's cache files, deletes those files so that everything compiles afresh.
"""

from __future__ import annotations

import contextlib
import hashlib
import os
import tempfile
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING, Any, Protocol, TypeVar

import numba

if TYPE_CHECKING:
    from numba.core.dispatcher import Dispatcher

COMPILED_MODULES = (
    "base_law",
    "batch_geometry",
    "swept_contacts",
    "generators",
    "convex_polygons",
    "orbit_separation",
    "orbit_fields",
    "orbit_truth",
    "geometry_kernels",
    "goal",
    "gap_order",
    "mission_step",
    "step_observe",
    "mission_starts",
    "potential",
    "observation",
    "shield_kernel",
    "thrust",
    "uncertainty",
)
"""Modules of this package with numba-compiled functions (their caches are dropped together)."""

STRUCTURE_MODULES = ("mission_data", "field_spec", "shield_model")
"""Modules whose named tuples the compiled signatures are made of (the compiled code reads their
fields by position), or whose constants compiled code bakes in (``MAX_POLYGON_VERTICES``): a
change to them drops the cache too."""

COMPILE_OPTIONS: dict[str, Any] = {
    "cache": True,
    "nogil": True,
    "error_model": "numpy",
    "_nrt": True,
}
"""Options of every decorator below. ``error_model="numpy"``: a division by zero gives inf/NaN
as in numpy instead of raising, which spares a zero test before every ``/`` in the hot loops.
``_nrt=True`` (numba's reference counting, its default) is explicit so that a kernel called
from a :data:`borrowing` loop does not inherit the loop's setting."""

_STAMP = "numba_sources.sha256"


def sources_digest(
    package_dir: Path,
    modules: tuple[str, ...] = COMPILED_MODULES,
    options: dict[str, object] = COMPILE_OPTIONS,
) -> str:
    """sha256 of the sources of ``modules`` (files ``<name>.py`` in ``package_dir``) and of the
    compile ``options`` (numba's cache does not key on them either)."""
    digest = hashlib.sha256()
    digest.update(repr(sorted(options.items())).encode())
    for name in modules:
        digest.update(name.encode())
        digest.update((package_dir / f"{name}.py").read_bytes())
    return digest.hexdigest()


def drop_stale_cache(package_dir: Path, modules: tuple[str, ...] = COMPILED_MODULES) -> bool:
    """Delete numba's in-tree cache files of ``modules`` if any of their sources changed.

    The cache lives in ``package_dir/__pycache__`` (files ``<module>.<function>-<line>.*.nbi``
    / ``.nbc``); the digest of the sources it was built from is kept there in
    ``numba_sources.sha256``. Nothing happens when the directory cannot be written (numba then
    caches elsewhere, keyed on fresh installs) or when the digest matches.

    Returns:
        True if stale files were deleted (or no digest was recorded yet).
    """
    cache_dir = package_dir / "__pycache__"
    with contextlib.suppress(OSError):
        cache_dir.mkdir(exist_ok=True)
    stamp = cache_dir / _STAMP
    digest = sources_digest(package_dir, modules)
    try:
        if stamp.read_text() == digest:
            return False
    except OSError:
        pass
    if not cache_dir.is_dir() or not os.access(cache_dir, os.W_OK):
        return False
    for name in modules:
        for pattern in (f"{name}.*.nbi", f"{name}.*.nbc"):
            for path in cache_dir.glob(pattern):
                with contextlib.suppress(OSError):  # another process may delete it first
                    path.unlink()
    # write the digest atomically: concurrent imports (SubprocVecEnv workers) never read half
    fd, tmp = tempfile.mkstemp(dir=cache_dir, prefix=".stamp-")
    try:
        with os.fdopen(fd, "w") as f:
            f.write(digest)
        os.replace(tmp, stamp)
    except OSError:
        with contextlib.suppress(OSError):
            os.unlink(tmp)
    return True


DECORATOR_MODULES = ("jit",)
"""This module: the decorators' options (a loop's reference counting among them) shape the
machine code, so a change to them drops the cache too."""

with contextlib.suppress(OSError):
    drop_stale_cache(
        Path(__file__).resolve().parent,
        COMPILED_MODULES + STRUCTURE_MODULES + DECORATOR_MODULES,
    )

_Function = TypeVar("_Function", bound=Callable[..., Any])


class Decorator(Protocol):
    """The type of the decorators below: a function in, its numba dispatcher out."""

    def __call__(self, function: _Function, /) -> Dispatcher[_Function]: ...


kernel: Decorator = numba.njit(**COMPILE_OPTIONS)
"""Decorator for a compiled loop called from Python."""

inlined: Decorator = numba.njit(**COMPILE_OPTIONS, inline="always")
"""Decorator for a compiled helper that kernels call (inlined into them)."""

threaded: Decorator = numba.njit(**COMPILE_OPTIONS, parallel=True)
"""Decorator for a compiled loop whose ``numba.prange`` iterations run on several threads."""

borrowing: Decorator = numba.njit(**{**COMPILE_OPTIONS, "_nrt": False})
"""Decorator for a compiled loop without numba's reference counting (its runtime, NRT, left
out of the loop's code): the loop only borrows the arrays its caller hands it, and may not
allocate (numba refuses to compile an allocation there). Kernels it calls keep their
reference counting (``_nrt=True`` in :data:`COMPILE_OPTIONS`: numba would otherwise compile
them with the caller's setting)."""


def specialise(dispatcher: Dispatcher[Any], *args: object) -> Callable[..., Any]:
    """The machine code of ``dispatcher`` (compiled or loaded from the cache if need be) for the
    types of ``args``, as a callable that skips numba's per-call type dispatch.

    Numba types every argument on each call of a dispatcher; for a named tuple it does so in
    Python, element by element, which costs more than the whole of a small step
    (docs/benchmarks.md, "Measured design choices"). A caller that passes the same structures
    every time resolves the machine code once and calls it directly. The caller must then pass
    arguments of exactly the types of ``args`` (same dtypes, dimensions and contiguity): the
    machine code does not check.
    """
    return dispatcher.compile(tuple(dispatcher.typeof_pyval(a) for a in args))
