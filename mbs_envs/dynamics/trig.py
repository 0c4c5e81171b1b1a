"""``sin`` and ``cos`` of one argument in straight-line arithmetic, so that compiled
loops over a batch vectorize (SIMD) instead of calling libm once per element.

numba's loops calling ``np.sin`` stay scalar (no SVML in pip's llvmlite); numpy's
float64 ``sin`` is scalar too, and those calls were most of a batched env step
(figures in docs/performance.md). :func:`sincos` is the classic fdlibm (Sun, 1993)
algorithm without its branches:

1. Cody-Waite reduction ``x = n pi/2 + (y0 + y1)``, ``|y0 + y1| <= pi/4``, with
   ``pi/2`` split in 33-bit pieces so that ``n * piece`` is exact for
   ``|n| < 2^20`` (fdlibm's ``__ieee754_rem_pio2``, medium range, two rounds);
2. fdlibm's ``__kernel_sin`` and ``__kernel_cos`` minimax polynomials (error
   below 2^-58 on ``[-pi/4, pi/4]``), both evaluated, with the tail ``y1``;
3. the quadrant ``n mod 4`` picks and signs them (selects, not branches).

Tested against numpy to 1 ulp (``tests/test_trig.py``). Valid for ``|x| <=``
:data:`SINCOS_RANGE`; callers recompute the rare arguments outside it (and
non-finite ones) with libm in a second, scalar pass (:func:`in_range`).
"""

from __future__ import annotations

import numpy as np
from numba import types
from numba.core.extending import intrinsic

from .interpreted import fma_exact, python_version
from .jit import njit

SINCOS_RANGE = 2.0**19 * np.pi / 2
"""[rad] ``|x|`` up to which :func:`sincos` is accurate (fdlibm's medium range)."""

_INVPIO2 = 6.36619772367581382433e-01  # 2 / pi
_PIO2_1 = 1.57079632673412561417e00  # first 33 bits of pi/2
_PIO2_2 = 6.07710050630396597660e-11  # second 33 bits of pi/2
_PIO2_2T = 2.02226624879595063154e-21  # pi/2 - (_PIO2_1 + _PIO2_2)
# fdlibm's __kernel_sin and __kernel_cos coefficients
S1, S2, S3 = -1.66666666666666324348e-01, 8.33333333332248946124e-03, -1.98412698298579493134e-04
S4, S5, S6 = 2.75573137070700676789e-06, -2.50507602534068634195e-08, 1.58969099521155010221e-10
C1, C2, C3 = 4.16666666666666019037e-02, -1.38888888888741095749e-03, 2.48015872894767294178e-05
C4, C5, C6 = -2.75573143513906633035e-07, 2.08757232129817482790e-09, -1.13596475577881948265e-11


@njit
def sincos(x):  # pragma: no cover - compiled
    """``(sin x, cos x)`` to 1 ulp for ``|x| <=`` :data:`SINCOS_RANGE` (module docstring).

    Parameters
    ----------
    x : float
        [rad]

    Returns
    -------
    s, c : float
        Outside the range the values are meaningless: test :func:`in_range`.
    """
    fn = np.rint(x * _INVPIO2)
    # x - fn pi/2 in two Cody-Waite rounds, with the tail y1 of the result y0
    t = x - fn * _PIO2_1
    w = fn * _PIO2_2
    r = t - w
    w = fn * _PIO2_2T - ((t - r) - w)
    y0 = r - w
    y1 = (r - y0) - w
    z = y0 * y0
    zy = z * y0
    rs = S2 + z * (S3 + z * (S4 + z * (S5 + z * S6)))
    s = y0 - ((z * (0.5 * y1 - zy * rs) - y1) - zy * S1)
    rc = z * (C1 + z * (C2 + z * (C3 + z * (C4 + z * (C5 + z * C6)))))
    hz = 0.5 * z
    w = 1.0 - hz
    c = w + (((1.0 - w) - hz) + (z * rc - y0 * y1))
    n = np.int64(fn)
    swap = (n & 1) != 0
    sx = c if swap else s
    cx = s if swap else c
    sx = -sx if (n & 2) != 0 else sx
    cx = -cx if ((n + 1) & 2) != 0 else cx
    return sx, cx


@njit
def in_range(x):  # pragma: no cover - compiled
    """Whether :func:`sincos` is accurate at ``x`` (False for NaN and inf)."""
    return abs(x) <= SINCOS_RANGE


@njit
def sincos_checked(x):  # pragma: no cover - compiled
    """``(sin x, cos x)`` of one argument as :func:`sincos_columns` gives it: :func:`sincos`
    where accurate, libm elsewhere (the scalar code path of one-member kernels)."""
    return sincos(x) if in_range(x) else sincos_libm(x)


@njit
def sincos_libm(x):  # pragma: no cover - compiled
    """``(sin x, cos x)`` by libm: the scalar pass for arguments outside :data:`SINCOS_RANGE`."""
    return np.sin(x), np.cos(x)


@njit
def sincos_rows(q, first, count):  # pragma: no cover - compiled
    """``(sin, cos)`` of rows ``first .. first + count - 1`` of ``q`` (n, B), interleaved in a
    (2 count, B) array: row ``2 k`` the sine, ``2 k + 1`` the cosine of ``q[first + k]``."""
    T = np.empty((2 * count, q.shape[1]))
    for k in range(count):
        sincos_columns(q[first + k], T[2 * k], T[2 * k + 1])
    return T


@njit
def sincos_columns(x, s, c):  # pragma: no cover - compiled
    """``s, c = sin x, cos x`` elementwise for 1-d arrays: a SIMD pass, then libm where out of range."""
    ok = True
    for i in range(x.shape[0]):
        s[i], c[i] = sincos(x[i])
        ok &= in_range(x[i])
    if not ok:
        for i in range(x.shape[0]):
            if not in_range(x[i]):
                s[i], c[i] = sincos_libm(x[i])


# -- wrapping angles ------------------------------------------------------------------------------
#
# ``wrap(x) = (x + pi) % (2 pi) - pi`` as Python computes it: ``%`` is ``fmod`` and then the
# denominator's sign (CPython's float_divmod, which numba and numpy follow). ``fmod`` is a libm call
# that keeps a compiled loop scalar; here its result is computed exactly in straight-line arithmetic.

TWO_PI = 2.0 * np.pi
"""The ``2 pi`` of :func:`wrap` (the double ``2 * np.pi``)."""

WRAP_RANGE = 2.0**40
"""``|x + pi|`` below which :func:`wrap_fast` is exact: the float quotient ``|x + pi| / 2 pi`` is then
within ``2^-13`` of the true one, so its integer part is off by at most one."""


@intrinsic
def fma(typingctx, a, b, c):  # pragma: no cover - compiled
    """``a b + c`` rounded once (IEEE 754 fused multiply-add; the hardware instruction where
    there is one, else libm's correctly rounded ``fma``), float64."""
    sig = types.float64(types.float64, types.float64, types.float64)

    def codegen(context, builder, signature, args):
        return builder.fma(*args)

    return sig, codegen


python_version(fma, fma_exact)  # what the kernels' Python calls (mbs_envs.dynamics.interpreted)


@njit(inline="always")
def wrap_fast(x):  # pragma: no cover - compiled
    """``((x + pi) % (2 pi) - pi, ok)``: the same bits as Python's ``%`` where ``ok``
    (``|x + pi| <`` :data:`WRAP_RANGE`; False for NaN and inf, where the value is meaningless).

    ``fmod(a, 2 pi) = a - n 2 pi`` with ``n`` the integer part of the true quotient is exactly
    representable, so one FMA computes it exactly once ``n`` is right; ``n`` is the float
    quotient's integer part, corrected by one where the FMA with it lands outside ``[0, 2 pi)``
    (that FMA's sign is exact). Then Python's rule: a nonzero remainder takes the sign of
    ``2 pi`` (``+ 2 pi`` if negative), a zero one is ``+0``.
    """
    a = x + np.pi
    ax = abs(a)
    n0 = np.trunc(ax / TWO_PI)
    r0 = fma(-n0, TWO_PI, ax)
    n = n0 - 1.0 if r0 < 0.0 else (n0 + 1.0 if r0 >= TWO_PI else n0)
    r = fma(-n, TWO_PI, ax)
    r = -r if a < 0.0 else r  # fmod takes the sign of its numerator
    r = r + TWO_PI if r < 0.0 else r
    r = 0.0 if r == 0.0 else r
    return r - np.pi, ax < WRAP_RANGE


@njit
def wrap_python(x):  # pragma: no cover - compiled
    """``(x + pi) % (2 pi) - pi`` by numba's ``%`` (libm's ``fmod``): the scalar pass of :func:`wrap_fast`."""
    return (x + np.pi) % TWO_PI - np.pi


@njit(inline="always")
def wrap(x):  # pragma: no cover - compiled
    """``(x + pi) % (2 pi) - pi`` [rad], Python's bits, for one argument: :func:`wrap_fast`, else
    :func:`wrap_python` (loops over a batch take :func:`wrap_fast` in one pass and the rare
    rest in a second, to stay SIMD)."""
    w, ok = wrap_fast(x)
    return w if ok else wrap_python(x)
