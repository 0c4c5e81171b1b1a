"""The Python of a compiled kernel, computing the bits its compiled code computes.

The package's kernels are plain Python that numba compiles without fast-math, so every floating-point operation is
one IEEE 754 operation in both forms (LLVM neither reassociates nor contracts them; a vectorized loop computes each
element as the scalar one). What differs is made the same here:

- numpy's own float64 ``exp``, ``tanh`` and ``arctan2`` are SIMD routines of its own, 1 ulp off libm's now and then:
  the kernels' Python calls libm's (``math``), as compiled code does;
- ``x ** n`` for an integer ``n`` is numba's repeated squaring (``x ** 2`` is ``x * x``), not libm's ``pow``, which
  Python's ``**`` calls (1 ulp off now and then): :func:`numba_power`, put in place of ``**`` in each kernel's source;
- numba intrinsics have registered Python versions (:func:`python_version`; the package has one, the fused
  multiply-add :func:`mbs_envs.dynamics.trig.fma`, whose exact version is :func:`fma_exact`).

:func:`interpreted` gives a kernel's Python with every kernel it calls replaced by that kernel's Python. Every
scene's episodes are bit for bit the same run either way (``tests/test_background.py``; figures in
docs/performance.md). Used by :mod:`mbs_envs.dynamics.background` while a kernel is being compiled, and by
``MBS_ENVS_JIT=python`` to step through a kernel in a debugger. Floats are float64 throughout the package's kernels;
libm's single-precision functions (numba's for float32 arguments) are not reproduced.
"""

from __future__ import annotations

import ast
import inspect
import math
import textwrap
import threading
import types
from collections.abc import Callable
from fractions import Fraction
from typing import Any

import numpy as np
from numba.core.dispatcher import Dispatcher

#: Python stand-ins of objects compiled code uses that Python cannot call (numba intrinsics), by id
_python_versions: dict[int, Callable] = {}


def python_version(obj: Any, func: Callable) -> None:
    """Register ``func`` as what :func:`interpreted` code calls in place of ``obj`` (a numba intrinsic)."""
    _python_versions[id(obj)] = func


def fma_exact(a: float, b: float, c: float) -> float:
    """``a b + c`` rounded once, in Python (as IEEE 754's fused multiply-add; ``math.fma`` is Python 3.13's).

    Exact rational arithmetic, then one correctly rounded conversion (CPython's ``int / int``);
    non-finite arguments take ``a * b + c``, whose inf and NaN are the FMA's.
    """
    a, b, c = float(a), float(b), float(c)
    if math.isfinite(a) and math.isfinite(b) and math.isfinite(c):
        r = float(Fraction(a) * Fraction(b) + Fraction(c))
        if r == 0.0:  # an exact zero: -0 only for -0 + -0 (a zero product), as IEEE 754's sum
            return a * b + c if a == 0.0 or b == 0.0 else 0.0
        return r
    return a * b + c


#: modules whose objects interpreted code keeps as they are
_KEEP = ("numpy", "math", "cmath", "numba", "builtins", "operator")

#: one builder at a time: a module's globals are registered before they are filled (its kernels call each other), so
#: another thread must not see them, nor a clone over them, until the builder is done (reentrant: the builder recurses)
_LOCK = threading.RLock()
_clones: dict[int, tuple[Dispatcher, types.FunctionType]] = {}
_globals: dict[int, dict] = {}
_proxies: dict[int, types.ModuleType] = {}


class _ModuleProxy(types.ModuleType):
    """A module seen from interpreted code: its kernels are their Python (``_compiled.no_projection``)."""

    def __init__(self, module: types.ModuleType):
        super().__init__(module.__name__)
        object.__setattr__(self, "_module", module)

    def __getattr__(self, name: str) -> Any:
        return _python_value(getattr(object.__getattribute__(self, "_module"), name))


#: numpy's functions that compiled code computes by libm, and Python's libm calls that give the same bits
#: (numpy's own float64 ``exp``, for one, is a SIMD routine of its own: 1 ulp off libm's now and then)
_LIBM = {
    "exp": math.exp, "expm1": math.expm1, "log": math.log, "log1p": math.log1p, "log2": math.log2,
    "log10": math.log10, "sin": math.sin, "cos": math.cos, "tan": math.tan, "arcsin": math.asin,
    "arccos": math.acos, "arctan": math.atan, "arctan2": math.atan2, "sinh": math.sinh, "cosh": math.cosh,
    "tanh": math.tanh, "arcsinh": math.asinh, "arccosh": math.acosh, "arctanh": math.atanh,
}  # fmt: skip


def _libm(name: str, f: Callable) -> Callable:
    """``np.<name>`` as compiled code computes it: libm's ``f`` on a float, element by element on an array."""
    elementwise = np.frompyfunc(f, 2 if name == "arctan2" else 1, 1)

    def g(*x):
        if all(isinstance(a, (float, int, np.floating, np.integer)) for a in x):
            return np.float64(f(*(float(a) for a in x)))
        return elementwise(*x).astype(np.float64)

    g.__name__ = name
    return g


class _NumpyProxy(types.ModuleType):
    """numpy seen from interpreted code: :data:`_LIBM`'s functions by libm, everything else numpy's."""

    def __init__(self):
        super().__init__("numpy")
        for name, f in _LIBM.items():
            object.__setattr__(self, name, _libm(name, f))

    def __getattr__(self, name: str) -> Any:
        return getattr(np, name)


_numpy = _NumpyProxy()


def _python_value(v: Any) -> Any:
    """What interpreted code sees in place of ``v``: a kernel's Python, an intrinsic's stand-in, else ``v``."""
    if isinstance(v, Dispatcher):
        return interpreted(v)
    if id(v) in _python_versions:
        return _python_versions[id(v)]
    if v is np:
        return _numpy
    if isinstance(v, types.ModuleType) and not v.__name__.split(".")[0] in _KEEP:
        p = _proxies.get(id(v))
        if p is None:
            p = _proxies[id(v)] = _ModuleProxy(v)
        return p
    if type(v) is tuple and any(isinstance(x, Dispatcher) for x in v):
        return tuple(_python_value(x) for x in v)
    return v


def numba_power(a: Any, b: Any) -> Any:
    """``a ** b`` as numba's compiled code computes it (:mod:`numba.cpython.numbers`).

    An integer exponent is applied by repeated squaring (``x ** 2`` is ``x * x``; libm's ``pow``, which Python's
    ``**`` calls, is 1 ulp off that now and then); a float exponent by libm's ``pow``, except ``2.0``, ``0.5``,
    ``1.0`` and ``-1.0``, which LLVM rewrites (``x * x``, ``|sqrt x|``, ``x``, ``1 / x``; the package's kernels use
    none of them); integers to integer powers as Python does. Arrays element by element.
    """
    if isinstance(a, np.ndarray) or isinstance(b, np.ndarray):
        return np.frompyfunc(numba_power, 2, 1)(a, b).astype(
            np.result_type(a, b, np.float64 if isinstance(b, float) else b)
        )
    integral_b = isinstance(b, (int, np.integer)) and not isinstance(b, (bool, np.bool_))
    if integral_b and isinstance(a, (int, np.integer)):
        return a**b
    if integral_b:
        n, r, x = abs(int(b)), None, a
        while n:
            if n & 1:
                r = x if r is None else r * x
            n >>= 1
            x = x * x
        r = type(a)(1.0) if r is None else r
        return 1.0 / r if b < 0 else r
    b = float(b)  # LLVM's rewrites of a constant exponent (its instcombine, without fast-math), else libm
    if b == 2.0:
        return a * a
    if b == 0.5:
        return np.float64(math.inf if a == -math.inf else abs(math.sqrt(a)) if a >= 0.0 else math.nan)
    if b == 1.0:
        return a
    if b == -1.0:
        return 1.0 / a
    return np.float64(math.pow(float(a), b))


class _Power(ast.NodeTransformer):
    """``a ** b`` -> ``__numba_power__(a, b)``."""

    def visit_BinOp(self, node: ast.BinOp) -> ast.AST:
        self.generic_visit(node)
        if isinstance(node.op, ast.Pow):
            return ast.copy_location(
                ast.Call(ast.Name("__numba_power__", ast.Load()), [node.left, node.right], []), node
            )
        return node

    def visit_AugAssign(self, node: ast.AugAssign) -> ast.AST:
        if isinstance(node.op, ast.Pow):
            raise SyntaxError("**= in a kernel")  # none in the package: the function keeps its own code
        return self.generic_visit(node)


def _code(f: types.FunctionType) -> types.CodeType:
    """``f``'s code with every ``**`` as :func:`numba_power` (its own code where it has none, or where its source
    cannot be read)."""
    code = f.__code__
    try:
        src = textwrap.dedent(inspect.getsource(f))
    except (OSError, TypeError):
        return code
    if "**" not in src:
        return code
    try:
        tree = ast.parse(src)
        fn = tree.body[0]
        if not isinstance(fn, ast.FunctionDef) or fn.name != code.co_name:
            return code
        fn.decorator_list = []
        fn = _Power().visit(fn)
        if code.co_freevars:  # a closure: defined inside a function that binds its free variables
            outer = ast.FunctionDef("__outer__", ast.arguments([], [ast.arg(v) for v in code.co_freevars], None, [], [], None, []),
                                    [fn, ast.Return(ast.Name(fn.name, ast.Load()))], [], None)  # fmt: skip
            tree.body = [outer]
        else:
            tree.body = [fn]
        ast.increment_lineno(tree, code.co_firstlineno - 1)  # tracebacks and debuggers show the kernel's own lines
        module = compile(ast.fix_missing_locations(tree), code.co_filename, "exec")
    except SyntaxError:
        return code
    consts = module.co_consts
    if code.co_freevars:
        consts = next(c for c in consts if isinstance(c, types.CodeType)).co_consts
    return next(c for c in consts if isinstance(c, types.CodeType) and c.co_name == code.co_name)


def _module_globals(g: dict) -> dict:
    """A copy of a module's globals with every value as :func:`_python_value` (one per module)."""
    out = _globals.get(id(g))
    if out is None:
        out = _globals[id(g)] = {
            "__numba_power__": numba_power
        }  # registered before it is filled: kernels of one module call each other
        out.update({k: _python_value(v) for k, v in list(g.items())})
    return out


def _cell(c) -> types.CellType:
    try:
        return types.CellType(_python_value(c.cell_contents))
    except ValueError:  # an empty cell
        return types.CellType()


def interpreted(kernel: Dispatcher) -> types.FunctionType:
    """The Python of a numba kernel: its source function, calling the Python of every kernel it calls.

    Parameters
    ----------
    kernel : numba Dispatcher

    Returns
    -------
    function
        Takes the kernel's arguments and computes its results bit for bit (module docstring),
        however slowly. One per kernel and process.
    """
    with _LOCK:
        return _interpreted(kernel)


def _interpreted(kernel: Dispatcher) -> types.FunctionType:
    c = _clones.get(id(kernel))
    if c is None:
        f = kernel.py_func
        code = _code(f)
        cells = dict(zip(f.__code__.co_freevars, f.__closure__ or ()))
        closure = tuple(_cell(cells[v]) for v in code.co_freevars) or None
        clone = types.FunctionType(code, _module_globals(f.__globals__), f.__name__, f.__defaults__, closure)
        clone.__kwdefaults__, clone.__qualname__, clone.__doc__ = f.__kwdefaults__, f.__qualname__, f.__doc__
        c = _clones[id(kernel)] = (kernel, clone)  # the kernel kept alive: its id stays its own
    return c[1]
