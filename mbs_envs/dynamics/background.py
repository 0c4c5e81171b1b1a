"""Compile in another process; until a kernel is compiled, run its Python, which gives the same bits.

A fresh install's first step used to wait for numba to compile a scene's kernels: 7-29 s per scene with an empty
cache (docs/performance.md). Now, within an env's construction, reset and single step (:func:`allowed`), a package
kernel called with argument types it has no compiled code for

1. is loaded from numba's disk cache if it is there (a warm cache: as before);
2. else runs as its Python (:func:`mbs_envs.dynamics.interpreted.interpreted`: the same bits as compiled code), under
   ``np.errstate(all="ignore")`` (compiled code raises no warnings), while a child process compiles it into the disk
   cache on another core; the first call after the child is done loads it from there, and every later call runs
   compiled.

Every scene's episodes are bit for bit the same either way (``tests/test_background.py``), so nothing an env returns
depends on when the switch happens. Should a kernel's Python raise where compiled code does not (a float division by
zero, ``math.exp`` overflowing: compiled code gives inf or NaN), the call's arrays are put back as they were, the
kernel is compiled there and then, and the call runs compiled. Elsewhere (a vector env of more than one member, whose
Python would loop over every member; ``simulate``; a controller; a user's own call) a kernel compiles before it runs,
as numba does by itself; so do kernels numba cannot cache (``cache=False``, or defined inside a function), and all of
them where ``os.posix_spawn`` is missing.

``MBS_ENVS_JIT`` (environment variable, read at each decision) chooses: ``background`` (the default), ``sync``
(compile before the first call, numba's own behaviour) or ``python`` (never compile what is not compiled yet in those
calls: they run as Python, e.g. to step through a kernel in a debugger).
"""

from __future__ import annotations

import base64
import contextlib
import importlib
import importlib.util
import json
import os
import pickle
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from numba.core.caching import NullCache
from numba.core.dispatcher import Dispatcher

from .interpreted import interpreted

#: the directory holding the package (the child imports it from there)
ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))

#: the environment variable that chooses the mode
ENV_VAR = "MBS_ENVS_JIT"
#: its values: compile in the background (default), compile before the call, never compile a new call
MODES = ("background", "sync", "python")


def mode() -> str:
    """The mode :data:`ENV_VAR` asks for (``background`` when unset).

    Raises
    ------
    ValueError
        Naming :data:`ENV_VAR` when it holds anything else.
    """
    m = os.environ.get(ENV_VAR, "background").strip().lower() or "background"
    if m not in MODES:
        raise ValueError(f"{ENV_VAR}={os.environ[ENV_VAR]!r}: expected one of {', '.join(MODES)}")
    return m


# -- the process that compiles ---------------------------------------------------
#
# A thread would share the GIL with the steps it runs beside: numba's compiler calls LLVM through ctypes thousands of
# times, each call releases the GIL, and getting it back waits for the stepping thread's switch interval (5 ms), so the
# compilation stalled for as long as the steps went on (measured: Planar2R-v0's kernels not compiled after 60 s of
# steps; 9 s alone). A child process compiles on the other core into numba's disk cache instead, and a call after it
# is done loads the compiled code from there.

#: the child's protocol lines start with this (anything else it prints is ignored)
_TAG = "mbs_envs-compiled "
_lock = threading.Lock()
_state: dict[str, Any] = {
    "pid": None,
    "to_child": None,
    "generation": 0,
    "pending": {},
    "done": set(),
    "failed": set(),
    "tokens": {},
}
_local = threading.local()


def generation() -> int:
    """How many compilations the child has finished for this process (a cached choice of code is stale once it moved)."""
    return _state["generation"]


def pending() -> int:
    """How many compilations are queued or running."""
    return len(_state["pending"])


def wait(timeout: float | None = None) -> bool:
    """Block until every requested compilation has finished (True), or ``timeout`` [s] passed (False).

    For benchmarks and tests that time compiled code; an env needs no call: it switches by itself.
    """
    end = None if timeout is None else time.monotonic() + timeout
    while _state["pending"]:
        if end is not None and time.monotonic() > end:
            return False
        time.sleep(0.01)
    return True


def _address(kernel: Dispatcher) -> tuple[str, str, str | None] | None:
    """``(module, qualname, file)`` by which a child process finds ``kernel``; None for a kernel it cannot find or
    whose compiled code would not reach this process (no disk cache: ``cache=False``, or defined inside a function)."""
    f = kernel.py_func
    if isinstance(kernel._cache, NullCache) or "<locals>" in f.__qualname__:
        return None
    module = sys.modules.get(f.__module__)
    return f.__module__, f.__qualname__, getattr(module, "__file__", None)


def _finished(key: tuple, ok: bool) -> None:
    with _lock:
        if _state["pending"].pop(key, None) is not None:
            (_state["done"] if ok else _state["failed"]).add(key)
            _state["generation"] += 1


def _read(pid: int, fd: int) -> None:
    """The parent's reader of the child's answers (a thread that waits on the pipe, holding no GIL meanwhile)."""
    buf = b""
    while True:
        try:
            chunk = os.read(fd, 65536)
        except OSError:
            chunk = b""
        if not chunk:
            break
        buf += chunk
        *lines, buf = buf.split(b"\n")
        for line in lines:
            text = line.decode(errors="replace")
            if text.startswith(_TAG):
                token, ok = text[len(_TAG) :].split()
                key = _state["tokens"].get(token)
                if key is not None:
                    _finished(key, ok == "1")
    os.close(fd)
    with contextlib.suppress(ChildProcessError, OSError):
        os.waitpid(pid, 0)  # no zombie left
    with _lock:
        if _state["pid"] == pid:
            _state.update(pid=None, to_child=None)
    for key in list(_state["pending"]):  # the child is gone: what it did not finish is compiled where it is called
        _finished(key, False)


def _child() -> int | None:
    """The write end of the pipe to this process's compiling child (started on first use; None where it cannot start:
    no ``os.posix_spawn``, e.g. on Windows, where kernels compile before they run).

    The child runs in a session of its own (a Ctrl-C in the terminal does not stop it halfway through a kernel) and
    ends when its input does: once this process has exited, it finishes the compilations asked for, so that the next
    process finds them in the cache. Raw pipes and no ``Popen`` object: nothing to warn about at exit."""
    if _state["to_child"] is not None:
        return _state["to_child"]
    if not hasattr(os, "posix_spawn"):
        return None
    env = {**os.environ, ENV_VAR: "sync", "PYTHONPATH": os.pathsep.join([ROOT, os.environ.get("PYTHONPATH", "")])}
    r_in, w_in = os.pipe()
    r_out, w_out = os.pipe()
    actions = [(os.POSIX_SPAWN_DUP2, r_in, 0), (os.POSIX_SPAWN_DUP2, w_out, 1),
               (os.POSIX_SPAWN_OPEN, 2, os.devnull, os.O_WRONLY, 0)]  # fmt: skip
    try:
        pid = os.posix_spawn(sys.executable, [sys.executable, "-m", "mbs_envs.dynamics.background"], env,
                             file_actions=actions, setsid=True)  # fmt: skip
    except OSError:
        for fd in (r_in, w_in, r_out, w_out):
            os.close(fd)
        return None
    os.close(r_in)
    os.close(w_out)
    _state.update(pid=pid, to_child=w_in)
    threading.Thread(target=_read, args=(pid, r_out), name="mbs_envs-compiled", daemon=True).start()
    return w_in


def _request(kernel: Dispatcher, sig: tuple) -> bool:
    """Ask the child to compile ``kernel`` for ``sig`` (once); False where it cannot (the caller compiles)."""
    key = (id(kernel), sig)
    if key in _state["pending"]:
        return True
    address = _address(kernel)
    if address is None:
        return False
    try:
        blob = base64.b64encode(pickle.dumps(sig)).decode()
    except Exception:  # noqa: BLE001 - a type that does not pickle: compiled here
        return False
    with _lock:
        fd = _child()
        if fd is None:
            return False
        token = str(len(_state["tokens"]))
        _state["tokens"][token] = key
        _state["pending"][key] = kernel
        try:
            os.write(
                fd, (json.dumps({"token": token, "address": address, "sig": blob}) + "\n").encode()
            )  # one writer at a time (the lock)
        except OSError:
            del _state["pending"][key]
            return False
    return True


def _kernel_at(module: str, qualname: str, file: str | None) -> Dispatcher:
    """The kernel a parent named (its module imported, or loaded from its file, as the derived models are)."""
    try:
        m = importlib.import_module(module)
    except ImportError:
        spec = importlib.util.spec_from_file_location(module, file)
        m = importlib.util.module_from_spec(spec)
        sys.modules[module] = m
        spec.loader.exec_module(m)
    obj = m
    for part in qualname.split("."):
        obj = getattr(obj, part)
    return obj


def _serve() -> None:
    """The child: compile each requested kernel (into numba's disk cache) and answer ``<tag> <token> <1|0>``."""
    for line in sys.stdin:
        r = {}
        try:
            r = json.loads(line)
            kernel = _kernel_at(*r["address"])
            kernel.compile(pickle.loads(base64.b64decode(r["sig"])))
            ok = "1"
        except Exception:  # noqa: BLE001 - the parent compiles it itself and sees the error there
            ok = "0"
        try:
            print(_TAG + r.get("token", "?") + " " + ok, flush=True)
        except OSError:  # the parent is gone: the compilations go on, for the next process's cache
            pass


@contextlib.contextmanager
def allowed():
    """Within: this thread's calls of the package's kernels that are not compiled yet run as Python while the child
    compiles them (an env's construction, reset and single step: calls of bounded cost). Elsewhere they compile before
    they run, as numba does (a long simulation must not run its whole length as Python)."""
    before = getattr(_local, "allow", False)
    _local.allow = True
    try:
        yield
    finally:
        _local.allow = before


def _arrays(x, out: list) -> None:
    """The call's writeable arrays beside copies of them (a read-only array, a derived model's parameters, cannot
    have been written by the Python, and cannot be restored)."""
    if isinstance(x, np.ndarray):
        if x.flags.writeable:
            out.append((x, x.copy()))
    elif isinstance(x, tuple):
        for y in x:
            _arrays(y, out)


def _guarded(kernel: Dispatcher, sig: tuple) -> Callable:
    """The kernel's Python for one call, falling back to its compiled code should the Python raise (module docstring)."""
    f = interpreted(kernel)

    def call(*args):
        saved: list = []
        _arrays(args, saved)
        try:
            with np.errstate(all="ignore"):
                return f(*args)
        except Exception:  # noqa: BLE001 - the compiled code decides what the call gives
            for a, copy in saved:
                a[...] = copy
            kernel.compile(sig)
            return kernel(*args)

    return call


def _signature(kernel: Dispatcher, args: tuple) -> tuple:
    """numba's types of ``args`` as the kernel's dispatcher finds them (its record of a call's types left empty, as
    numba leaves it after a call)."""
    try:
        return tuple(kernel.typeof_pyval(a) for a in args)
    finally:
        kernel._types_active_call.clear()


def _choose(kernel: Dispatcher, args: tuple, sig: tuple | None = None, allow: bool = False) -> Callable | None:
    """The Python to run a call of ``kernel`` that has no compiled code (asking the child to compile it), or None to
    compile it here and now."""
    if not (allow or getattr(_local, "allow", False)):
        return None
    m = mode()
    if m == "sync":
        return None
    if sig is None:
        sig = _signature(kernel, args)
    key = (id(kernel), sig)
    if key in _state["done"] or key in _state["failed"]:
        return None  # compiled by the child (loaded from the disk cache now), or failed there (raised here)
    if m == "background" and key not in _state["pending"] and (_in_cache(kernel, sig) or not _request(kernel, sig)):
        return None  # loaded from the disk cache, or not for the child: compiled here (a pending one: no disk lookup)
    return _guarded(kernel, sig)


def _in_cache(kernel: Dispatcher, sig: tuple) -> bool:
    """Load ``kernel``'s code for ``sig`` from numba's disk cache if it is there (a warm cache: loading beats any
    child), as ``Dispatcher.compile`` does before it compiles; whether it was there."""
    try:
        from numba.core.compiler_lock import global_compiler_lock

        with global_compiler_lock:
            if tuple(sig) in kernel.overloads:
                return True
            cres = kernel._cache.load_overload(sig, kernel.targetctx)
            if cres is None:
                return False
            kernel._cache_hits[sig] += 1
            if not cres.objectmode:
                kernel.targetctx.insert_user_function(cres.entry_point, cres.fndesc, [cres.library])
            kernel.add_overload(cres)
            return True
    except Exception:  # noqa: BLE001 - numba's cache interface is private: as if not there (the child compiles it)
        return False


def install(kernel: Dispatcher) -> Dispatcher:
    """Route ``kernel``'s calls from Python that find no compiled code through :func:`_choose` (numba calls
    ``_compile_for_args`` for them, and runs what it returns)."""
    compile_for_args = kernel._compile_for_args

    def _compile_for_args(*args, **kws):
        if kws:
            return compile_for_args(*args, **kws)
        f = _choose(kernel, args)
        return compile_for_args(*args) if f is None else f

    kernel._compile_for_args = _compile_for_args
    return kernel


def entry(kernel: Dispatcher, args: tuple) -> tuple[Callable, bool]:
    """``(function, compiled)``: the compiled overload's entry point for the types of ``args``
    (:func:`direct`), or, while it is being compiled, the kernel's Python and False."""

    sig = _signature(kernel, args)
    if sig in kernel.overloads:
        return kernel.overloads[sig].entry_point, True
    f = _choose(kernel, args, sig, allow=True)
    return (f, False) if f is not None else (direct(kernel, args), True)


def _after_fork_child() -> None:
    """A forked child has neither the parent's compiling child nor its reader: it starts its own when it needs one
    (and does not hold the parent's pipe to it open: the compiling child ends when the parent does)."""
    global _lock
    _lock = threading.Lock()
    if _state["to_child"] is not None:
        with contextlib.suppress(OSError):
            os.close(_state["to_child"])
    _state.update(pid=None, to_child=None, pending={}, tokens={})


if hasattr(os, "register_at_fork"):
    os.register_at_fork(after_in_child=_after_fork_child)


def direct(kernel, args: tuple):
    """The compiled overload of the numba dispatcher ``kernel`` for the types of ``args`` (compiled, or loaded from the
    cache, if it is new), as a function that takes the arguments without the dispatcher's resolution of their types.

    The dispatcher types every argument at every call (for a scene's step kernel, two dozen arrays in nested tuples:
    1.3 us of SpatialChain-v0's 27 us step at 10 links on a quiet machine, docs/performance.md); the overload's entry
    point unboxes them by its signature alone. numba's
    unboxing does not check an array's dtype, dimensions or layout, so the caller must pass arguments of the types of
    ``args`` only: arrays it builds the same way every call, and the same objects otherwise (a single env's step,
    :meth:`mbs_envs.envs.base.MBSEnv.run_step_kernel`, keys it on those objects). ``args`` are only typed here, not
    passed to the kernel.
    """
    sig = tuple(kernel.typeof_pyval(a) for a in args)
    if sig not in kernel.overloads:
        kernel.compile(sig)
    return kernel.overloads[sig].entry_point


if __name__ == "__main__":
    _serve()
