"""The disk cache of derived models: derivations pickled under the SHA-256 of their inputs, generated sources
kept with a checksum, generated modules written once and imported under a lock (:data:`CACHE`)."""

from __future__ import annotations

import contextlib
import hashlib
import importlib.util
import os
import pathlib
import sys
import threading
import warnings
from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from ...dynamics.jit import package_stamp
from .codegen import generate_source
from .derivation import FORMAT, Derivation, derive_equations


#: where generated modules are kept (``$MBS_ENVS_DERIVED_CACHE`` overrides)
CACHE = pathlib.Path(os.environ.get("MBS_ENVS_DERIVED_CACHE", pathlib.Path.home() / ".cache" / "mbs_envs" / "derived"))

#: one generated module loads at a time in a process (reentrant: loading may derive)
_LOAD_LOCK = threading.RLock()


def load_generated(source: str, cache: pathlib.Path | None = None):
    """The generated module of ``source``, written once to ``cache`` as ``derived_<sha256>.py`` and imported
    (numba then caches its machine code beside it)."""
    folder = pathlib.Path(cache or CACHE)
    digest = hashlib.sha256(source.encode()).hexdigest()[:32]
    modname = f"mbs_envs_derived_{digest}"
    with _LOAD_LOCK:  # the module is in sys.modules while it runs (it reads itself there): no other thread meanwhile
        if modname in sys.modules:
            return sys.modules[modname]
        folder.mkdir(parents=True, exist_ok=True)
        path = folder / f"{modname}.py"
        if not path.exists() or path.read_text() != source:
            _write(path, source.encode())
        spec = importlib.util.spec_from_file_location(modname, path)
        module = importlib.util.module_from_spec(spec)
        sys.modules[modname] = module
        try:
            spec.loader.exec_module(module)
        except BaseException:
            del sys.modules[modname]
            raise
        return module


def cached_derivation(name: str, q: Sequence[Any], T: Any, V: Any, params: Mapping[str, float], actuation: Any = None,
                      damping: Mapping[Any, str] | None = None, cache: pathlib.Path | None = None, *,
                      constraints: Sequence[Any] = (), velocity_constraints: Sequence[Any] = (),
                      independent: Sequence[Any] | None = None, friction: Mapping[Any, Any] | None = None) -> Derivation:  # fmt: skip
    """:func:`derive_equations`, kept on disk (a pickle in ``cache``, default :data:`CACHE`) under the SHA-256 of the
    inputs' exact SymPy form (``srepr``): a second process with the same Lagrangian does not derive again."""
    import pickle

    import sympy as sp

    B = None if actuation is None else np.asarray(actuation, float).tolist()
    damp = None if damping is None else sorted((sp.srepr(k), v) for k, v in damping.items())
    ind = None if independent is None else [x if isinstance(x, (int, np.integer)) else sp.srepr(x) for x in independent]
    fric = None if not friction else sorted((sp.srepr(k), sp.srepr(sp.sympify(e))) for k, e in dict(friction).items())
    key = repr((FORMAT, name, [sp.srepr(x) for x in q], sp.srepr(sp.sympify(T)), sp.srepr(sp.sympify(V)), sorted((k, repr(v)) for k, v in dict(params).items()),
                B, damp, [sp.srepr(sp.sympify(c)) for c in constraints], [sp.srepr(sp.sympify(c)) for c in velocity_constraints], ind, fric))  # fmt: skip
    folder = pathlib.Path(cache or CACHE)
    path = folder / f"derivation_{hashlib.sha256(key.encode()).hexdigest()[:32]}.pkl"
    source = path.with_suffix(f".{package_stamp()[:16]}.source")  # its generated code, by this version of the package
    if path.exists():
        try:
            stored = pickle.loads(path.read_bytes())
            if stored[0] == key:
                _SOURCES[id(stored[1])] = (stored[1], source)
                return stored[1]
        except Exception:  # a damaged or foreign file: derive again and overwrite it
            pass
    d = derive_equations(
        name, q, T, V, params, actuation, damping, constraints, velocity_constraints, independent, friction=friction
    )
    folder.mkdir(parents=True, exist_ok=True)
    _write(path, pickle.dumps((key, d)))
    _SOURCES[id(d)] = (d, source)
    return d


def _write(path: pathlib.Path, data: bytes) -> None:
    """``data`` to ``path`` atomically (a concurrent process reads the whole file or none)."""
    tmp = path.with_suffix(f".{os.getpid()}.{threading.get_ident()}.tmp")  # one per writer, threads included
    tmp.write_bytes(data)
    os.replace(tmp, path)


#: derivations of :func:`cached_derivation` -> (the derivation, where its generated source is kept): a warm process
#: reads it instead of printing the equations again (SymPy's printing: 0.35 s of a derived scene's warm first step)
_SOURCES: dict[int, tuple[Derivation, pathlib.Path]] = {}


def source_of(d: Derivation) -> str:
    """:func:`generate_source` of ``d``, read from the derivation cache where :func:`cached_derivation` kept it (keyed
    by the package's sources as well: any edit of the generator generates again)."""
    kept = _SOURCES.get(id(d))
    path = kept[1] if kept is not None and kept[0] is d else None
    if path is not None:
        with contextlib.suppress(OSError):
            head, _, text = path.read_text().partition("\n")
            if head == _source_stamp(text):
                return text
            warnings.warn(f"damaged derivation cache file {path} (its checksum does not match): generated again",
                          stacklevel=2)  # fmt: skip
    source = generate_source(d)
    if path is not None:
        with contextlib.suppress(OSError):
            _write(path, f"{_source_stamp(source)}\n{source}".encode())
    return source


def _source_stamp(text: str) -> str:
    """The first line of a kept source file: the checksum of the rest (a truncated or altered file fails it)."""
    return "# sha256 " + hashlib.sha256(text.encode()).hexdigest()
