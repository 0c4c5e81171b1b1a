"""The one numba configuration of every compiled kernel.

``error_model="numpy"``: a division by zero gives inf/NaN as in numpy (which
divergence detection then reports) instead of raising, and the compiled code
skips Python's zero-division checks.
"""

from __future__ import annotations

import numba


def njit(f=None, *, cache: bool = True):
    """``numba.njit`` with the project's options; usable as ``@njit`` or ``@njit(cache=False)``.

    ``cache=False`` for functions that close over other kernels (numba cannot cache those).
    """
    decorate = numba.njit(cache=cache, error_model="numpy")
    return decorate if f is None else decorate(f)
