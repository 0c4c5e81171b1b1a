"""The one numba configuration of every compiled kernel.

``error_model="numpy"``: a division by zero gives inf/NaN as in numpy (which
divergence detection then reports) instead of raising, and the compiled code
skips Python's zero-division checks.

Caching (``cache=True``) keeps compiled kernels in ``__pycache__`` between
processes. numba invalidates a cached function only when *its own* file changes,
not when a kernel it calls from another module does (numba issue #1833): a scene's
``step_kernel`` embeds its model's kernels, so an edit of the model file alone would
leave the stale step running. Here every kernel of the package (the controllers' included) is stamped with a
hash of *all* the package's sources instead (:func:`package_stamp`, installed as numba
cache locators for this package's files only): any edit anywhere recompiles
everything once. Other packages' caches are untouched. Should numba's (private)
locator interface change, caching falls back to numba's own rule, and deleting
the ``*.nbi``/``*.nbc`` files (``find mbs_envs -name '*.nb[ic]' -delete``) after an edit is
the remedy.
"""

from __future__ import annotations

import functools
import hashlib
import os
import pathlib

import numba

from . import background
from .background import direct  # noqa: F401  (served here too: the kernels' options live in this module)

#: the package's root directory
PACKAGE = pathlib.Path(__file__).resolve().parent.parent


@functools.cache
def source_roots() -> tuple[pathlib.Path, ...]:
    """The folders of the package's sources: :data:`PACKAGE`, and the controllers' folder where it lies outside it
    (a source checkout maps its top-level ``controllers/`` to ``mbs_envs.controllers``; a wheel has it inside)."""
    import importlib.util

    roots = [PACKAGE]
    try:
        spec = importlib.util.find_spec("mbs_envs.controllers")
    except (ImportError, ValueError):  # pragma: no cover - a broken install: the package alone
        spec = None
    for location in (spec.submodule_search_locations or []) if spec is not None else []:
        root = pathlib.Path(location).resolve()
        if not any(root == r or root.is_relative_to(r) for r in roots):
            roots.append(root)
    return tuple(roots)


@functools.cache
def package_stamp() -> str:
    """SHA-1 of the package's Python sources (paths and contents, the controllers' included), computed once per
    process."""
    h = hashlib.sha1()
    for k, root in enumerate(source_roots()):
        for f in sorted(root.rglob("*.py")):
            h.update(f"{k}/{f.relative_to(root).as_posix()}".encode())
            h.update(f.read_bytes())
    return h.hexdigest()


def _install_package_locators() -> bool:
    """Put locators stamping this package's kernels with :func:`package_stamp` first in numba's
    list (where numba would put them: ``NUMBA_CACHE_DIR`` if set, else the in-tree ``__pycache__``,
    else its user-wide cache directory); False if numba's private interface is not as expected
    (its default rule then applies)."""
    try:
        from numba.core import caching

        # NUMBA_CACHE_DIR when set, else the in-tree __pycache__, else numba's user-wide directory
        bases = (caching.UserProvidedCacheLocator, caching.InTreeCacheLocator, caching.UserWideCacheLocator)
        locators = caching.CacheImpl._locator_classes
    except AttributeError:  # pragma: no cover - another numba
        return False

    def stamped(base):
        class Locator(base):
            @classmethod
            def from_function(cls, py_func, py_file):
                path = os.path.abspath(py_file)
                inside = any(path.startswith(str(root) + os.sep) for root in source_roots())
                return super().from_function(py_func, py_file) if inside else None

            def get_source_stamp(self):
                return package_stamp()

        Locator.__name__ = f"MbsEnvs{base.__name__}"
        return Locator

    if not any(k.__name__.startswith("MbsEnvs") for k in locators):
        locators[:0] = [stamped(b) for b in bases]
    return True


_install_package_locators()

#: LLVM's limit on the runtime overlap checks a vectorized loop may need (its default: 128)
MEMORY_CHECKS = 1000


def _allow_memory_checks(limit: int = MEMORY_CHECKS) -> None:
    """Let LLVM vectorize loops that need up to ``limit`` runtime checks that their arrays do not overlap.

    numba cannot say that two array arguments never alias (C's ``restrict``), so LLVM vectorizes a loop
    over many arrays only behind checks, at loop entry, that the ranges it reads and writes are disjoint,
    and gives up beyond 128 of them (``-vectorize-memory-check-threshold``). The closed-form kernels of the
    constrained models (one loop over the members reading a dozen rows and writing the accelerations and
    a flag per member) need more, and ran scalar. A vectorized loop computes every element as the scalar
    one does (no reassociation without fast-math), so results keep their bits; a batch shorter than a
    vector skips the checks. The option is LLVM's, so it holds for all numba code in the process: it can
    only let more loops vectorize.
    """
    import llvmlite.binding as llvm

    llvm.set_option("", f"-vectorize-memory-check-threshold={int(limit)}")


_allow_memory_checks()


def njit(f=None, *, cache: bool = True, **options):
    """``numba.njit`` with the project's options; usable as ``@njit`` or ``@njit(cache=False)``.

    Generic kernels that take a model's kernels as arguments (``rk_run``,
    ``engine_step``, the constrained column loops) are ``cache=False``: their cache index would hold the
    argument kernels' types, which do not survive the process. They are cached
    inside the module-level bindings that call them (``advance_kernel``, a scene's
    ``step_kernel``); closures over kernels would compile again in every process.
    ``options`` go to ``numba.njit`` (e.g. ``inline="always"``).

    Within an env's construction, reset and single step, a call from Python with argument types not compiled yet runs
    the kernel's Python (the same bits) while a child process compiles it (:mod:`mbs_envs.dynamics.background`).
    """
    decorate = numba.njit(cache=cache, error_model="numpy", **options)
    if f is None:
        return lambda g: background.install(decorate(g))
    return background.install(decorate(f))
