"""Validating an action: :func:`validate_action` takes what a policy gives (a list, any float dtype, one member or a
batch), refuses what is malformed or not finite with a ``ValueError`` that names it, and clips to ``[-1, 1]``.
"""

from __future__ import annotations

from typing import Any

from ..dynamics.jit import njit
import numpy as np

from .. import validation as check


@njit
def _clip_unit(a, out):  # pragma: no cover - compiled
    """``out = clip(a, -1, 1)``; False (``out`` unspecified) if any entry is not finite (one pass
    without an early exit, so that it is SIMD code)."""
    ok = True
    for i in range(a.shape[0]):
        x = a[i]
        ok &= abs(x) < np.inf  # False for NaN and for +-inf
        out[i] = min(max(x, -1.0), 1.0)
    return ok


#: dtypes the compiled clip takes as they are (native byte order)
_FAST_DTYPES = (np.dtype(np.float64), np.dtype(np.float32))


def validate_action(action: Any, nu: int, num_envs: int | None = None) -> np.ndarray:
    """Check a normalized action (or a vector env's batch of them) and saturate it to ``[-1, 1]``.

    Parameters
    ----------
    action : array_like, shape (nu,), or (num_envs, nu) for a batch
        A scalar is accepted when ``nu == 1`` (one per member for a batch).
    nu : int
    num_envs : int, optional
        Members of a batch (None: a single action).

    Returns
    -------
    ndarray, shape (nu,) or (num_envs, nu)
        The action clipped to ``[-1, 1]`` (finite out-of-range values saturate).

    Raises
    ------
    ValueError
        For an action that is not real numbers (strings, complex numbers,
        dates), wrongly shaped, NaN or infinite (naming the members of a
        batch that are not finite). Real numbers of any dtype and byte order
        (float16, big-endian, integers) are converted.
    """
    batch = () if num_envs is None else (num_envs,)
    if type(action) is np.ndarray and action.shape == batch + (nu,) and action.dtype in _FAST_DTYPES:
        out = np.empty(action.shape)  # the common case, fast: a native float array of the right shape
        if _clip_unit(action.reshape(-1), out.reshape(-1)):
            return out
    name = "action" if num_envs is None else "actions"
    a = check.reals(action, name, bools=True)  # any real dtype and byte order, as native float64
    if nu == 1 and a.shape == batch:
        a = a[..., None]
    if a.shape != batch + (nu,):
        raise ValueError(f"{name} must have shape {batch + (nu,)}, got shape {a.shape}")
    finite = np.all(np.isfinite(a), axis=-1)
    if not np.all(finite):
        which = f"got {a.tolist()}" if num_envs is None else f"members {np.flatnonzero(~finite).tolist()} are not"
        raise ValueError(f"{name} must be finite; {which}")
    return np.clip(a, -1.0, 1.0)
