"""One validation path for every user-facing parameter.

Every entry point (``gym.make`` keywords, ``reset`` options, ``set_attr`` on
the vector and SB3 adapters, model constructors, controllers, ``simulate``)
checks its arguments with these functions: each takes the value and the
name the user gave it under, returns it converted (a Python ``float`` or
``int``, a float array, a ``dict``), or raises ``ValueError`` naming the
argument and the value, before anything has changed. Strings, booleans,
complex numbers, dates and containers are refused where a number is meant
(no silent conversion of ``"0.01"``).

:class:`Checked` turns a validator into an attribute: every later assignment
(``env.dt = ...``, ``venv.set_attr("dt", ...)``) goes through it too.
"""

from __future__ import annotations

import numbers
from collections.abc import Callable, Mapping
from typing import Any

import numpy as np

#: Largest magnitude any physical parameter may have (SI units): beyond it the
#: equations' products overflow float64 (e.g. ``m l^2`` at 1e200) or the
#: observation bounds stop being representable in float32.
PARAM_MAX = 1e12


def _is_number(x: Any) -> bool:
    """A real scalar: Python or numpy int/float (or a 0-d real array), not bool, str, complex or date."""
    if isinstance(x, np.ndarray):
        return x.ndim == 0 and x.dtype.kind in "iuf"
    return isinstance(x, numbers.Real) and not isinstance(x, (bool, np.bool_, np.datetime64, np.timedelta64))


def _interval(low: float, high: float, low_open: bool, high_open: bool) -> str:
    return f"{'(' if low_open else '['}{low:g}, {high:g}{')' if high_open else ']'}"


def real(
    value: Any,
    name: str,
    low: float = -np.inf,
    high: float = np.inf,
    *,
    low_open: bool = False,
    high_open: bool = False,
) -> float:
    """A finite real number in ``[low, high]`` (ends open where asked).

    Parameters
    ----------
    value : Any
    name : str
        How the user called it (used in the message).
    low, high : float
    low_open, high_open : bool

    Returns
    -------
    float

    Raises
    ------
    ValueError
        Naming ``name`` and ``value``: not a real number, not finite, or out of range.
    """
    if not _is_number(value):
        raise ValueError(f"{name} must be a real number, got {value!r} ({type(value).__name__})")
    x = float(value)
    ok = np.isfinite(x) and (x > low if low_open else x >= low) and (x < high if high_open else x <= high)
    if not ok:
        raise ValueError(f"{name} must be finite and in {_interval(low, high, low_open, high_open)}, got {value!r}")
    return x + 0.0  # -0.0 -> 0.0: a signed zero would flip intervals such as U(-s, s) (numpy refuses high < low)


def positive(value: Any, name: str, high: float = np.inf) -> float:
    """A finite number ``> 0`` (and ``<= high``)."""
    return real(value, name, 0.0, high, low_open=True)


def nonnegative(value: Any, name: str, high: float = np.inf) -> float:
    """A finite number ``>= 0`` (and ``<= high``)."""
    return real(value, name, 0.0, high)


def integer(value: Any, name: str, low: int, high: int) -> int:
    """An integer in ``[low, high]`` (Python or numpy int; not bool, float or str)."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (numbers.Integral, np.integer)):
        raise ValueError(f"{name} must be an integer in [{low}, {high}], got {value!r} ({type(value).__name__})")
    if not low <= int(value) <= high:
        raise ValueError(f"{name} must be an integer in [{low}, {high}], got {value!r}")
    return int(value)


def reals(value: Any, name: str, *, bools: bool = False) -> np.ndarray:
    """``value`` as a native float64 array, if it holds real numbers only.

    Any real dtype and byte order converts (float16, big-endian, integers;
    booleans only with ``bools``); strings, bytes, complex numbers, dates,
    ``None``, mappings, ragged or other objects, masked arrays with a masked entry and
    objects numpy cannot read (a torch tensor that requires grad) raise ``ValueError``
    naming ``name``. Finiteness and range are the caller's business.
    """
    try:
        if isinstance(value, (Mapping, set, frozenset)):
            raise TypeError
        if isinstance(value, np.ma.MaskedArray):
            if np.ma.getmaskarray(value).any():
                raise ValueError(f"{name} must be real numbers, got a masked array with masked entries") from None
            value = value.data
        raw = np.asarray(value, dtype=object) if isinstance(value, (str, bytes)) else np.asarray(value)
        kinds = "biuf" if bools else "iuf"
        element = lambda x: _is_number(x) or (bools and isinstance(x, (bool, np.bool_)))
        if raw.dtype.kind not in kinds and not (
            raw.dtype.kind == "O" and raw.size and all(element(x) for x in raw.reshape(-1))
        ):
            raise TypeError
        return raw.astype(float)
    except ValueError as e:
        if str(e).startswith(name):
            raise
        raise ValueError(f"{name} must be real numbers, got {_shown(value)}") from None
    except Exception:  # numpy's TypeError/OverflowError, a tensor's RuntimeError, ...: all the same refusal
        raise ValueError(f"{name} must be real numbers, got {_shown(value)}") from None


def shaped(value: Any, name: str, shape: tuple, *, bools: bool = False, broadcast: bool = False) -> np.ndarray:
    """``value`` as a float64 array of ``shape`` (:func:`reals`), or ``ValueError`` naming ``name`` and both shapes.

    With ``broadcast`` a value that broadcasts to ``shape`` (a scalar ``episode_start``) is taken; otherwise its
    size must equal ``shape``'s and it is reshaped (a state saved flat). The array is a new one: writing into it
    never changes ``value``.
    """
    arr = reals(value, name, bools=bools)
    if broadcast and arr.size != int(np.prod(shape)):
        try:
            return np.array(np.broadcast_to(arr, shape))
        except ValueError:
            raise ValueError(f"{name} must broadcast to shape {tuple(shape)}, got shape {arr.shape}") from None
    if arr.size != int(np.prod(shape)):
        raise ValueError(
            f"{name} must hold {int(np.prod(shape))} numbers (shape {tuple(shape)}), got shape {arr.shape}"
        )
    return arr.reshape(shape).copy()


def as_vector(x: Any, n: int, name: str) -> np.ndarray:
    """Convert ``x`` to a float array of shape ``(..., n)``; ``ValueError`` otherwise (naming ``name``).

    Real numbers only, through :func:`reals` (strings, booleans, complex numbers,
    masked entries, mappings are refused); a float64 array passes as it is (no copy)."""
    arr = x if type(x) is np.ndarray and x.dtype == np.float64 else reals(x, name)
    if arr.ndim == 0 or arr.shape[-1] != n:
        raise ValueError(f"{name} must have shape (..., {n}), got shape {arr.shape}")
    return arr


def _shown(value: Any) -> str:
    """``repr`` of a refused value, cut to 200 characters (and never raising)."""
    try:
        text = repr(value)
    except Exception:
        text = f"<{type(value).__name__}>"
    return text if len(text) <= 200 else text[:200] + "..."


def boolean(value: Any, name: str) -> bool:
    """A bool (Python or numpy), not a string, number or ``None``: ``compiled="False"`` is refused, not read as True."""
    if not isinstance(value, (bool, np.bool_)):
        raise ValueError(f"{name} must be True or False, got {_shown(value)} ({type(value).__name__})")
    return bool(value)


def mask(value: Any, name: str, n: int) -> np.ndarray:
    """A boolean mask of shape ``(n,)``: bools, or integers 0 and 1; strings, floats (NaN) and others refused."""
    try:
        raw = np.asarray(value)
    except Exception:
        raw = np.asarray(None, dtype=object)
    if raw.dtype.kind == "O" and raw.ndim and all(isinstance(x, (bool, np.bool_)) for x in raw.reshape(-1)):
        raw = raw.astype(bool)
    if raw.dtype.kind in "iu" and np.all((raw == 0) | (raw == 1)):
        raw = raw.astype(bool)
    if raw.dtype.kind != "b":
        raise ValueError(f"{name} must be booleans of shape ({n},), got {_shown(value)}")
    if raw.shape != (n,):
        raise ValueError(f"{name} must have shape ({n},), got shape {raw.shape}")
    return raw.copy()


#: the largest seed (numpy's ``SeedSequence`` takes any non-negative integer; Gymnasium's seeding the same)
SEED_MAX = 2**128 - 1


def seed(value: Any, name: str = "seed") -> int | None:
    """A seed: ``None`` or an integer in ``[0, 2^128)`` (Python or numpy int; not bool, float or str).

    The one seed rule of the single env, the vector env (per member) and the SB3 adapter."""
    if value is None:
        return None
    if (
        isinstance(value, (bool, np.bool_))
        or not isinstance(value, (numbers.Integral, np.integer))
        or not 0 <= int(value) <= SEED_MAX
    ):
        raise ValueError(
            f"{name} must be None or an integer >= 0 (below 2^128), got {_shown(value)} ({type(value).__name__})"
        )
    return int(value)


def seeds(value: Any, n: int, name: str = "seed") -> list[int | None] | None:
    """A vector env's seeds: ``None``; an int ``s`` (member ``i`` gets ``s + i``); or a sequence of ``n``
    seeds or ``None`` each (:func:`seed`). All checked before any is used."""
    if value is None:
        return None
    if isinstance(value, (numbers.Integral, np.integer)) and not isinstance(value, (bool, np.bool_)):
        first = seed(value, name)
        return [seed(first + i, name) for i in range(n)]
    if isinstance(value, (str, bytes, Mapping)) or not hasattr(value, "__len__"):
        raise ValueError(f"{name} must be None, an int, or a sequence of {n} ints or None, got {_shown(value)}")
    items = list(value)
    if len(items) != n:
        raise ValueError(f"{name} must be an int or a sequence of {n} seeds, got {len(items)}: {_shown(value)}")
    return [seed(s, f"{name}[{i}]") for i, s in enumerate(items)]


def vector(
    value: Any,
    name: str,
    n: int,
    low: float = -np.inf,
    high: float = np.inf,
    *,
    low_open: bool = False,
    broadcast: bool = True,
) -> np.ndarray:
    """A float array of shape ``(n,)`` (a scalar broadcast when ``broadcast``), every entry finite and in range.

    Raises
    ------
    ValueError
        Naming ``name``: not numbers (strings, objects, complex), wrong shape,
        or an entry not finite or out of range.
    """
    x = reals(value, name)
    if x.shape != (n,):
        if not (broadcast and x.ndim == 0):
            raise ValueError(
                f"{name} must have shape ({n},){' or be a scalar' if broadcast else ''}, got shape {x.shape}"
            )
        x = np.full(n, float(x))
    ok = np.isfinite(x) & ((x > low) if low_open else (x >= low)) & (x <= high)
    if not np.all(ok):
        interval = _interval(low, high, low_open, False)
        raise ValueError(f"{name} must be finite and in {interval}, got {np.asarray(value).tolist()!r}")
    return x


def mapping(value: Any, name: str) -> dict:
    """A mapping (``None`` -> ``{}``) with string keys, as a new ``dict``."""
    if value is None:
        return {}
    if not isinstance(value, Mapping):
        raise ValueError(f"{name} must be a dict (or None), got {value!r} ({type(value).__name__})")
    bad = [k for k in value if not isinstance(k, str)]
    if bad:
        raise ValueError(f"{name} keys must be names (str), got {bad!r}")
    return dict(value)


def one_of(value: Any, name: str, options: tuple) -> Any:
    """The option ``value`` equals: ``None``, a string, or an integer (not bool, not float)."""
    for o in options:
        if o is None and value is None:
            return o
        if isinstance(o, str) and isinstance(value, str) and value == o:
            return o
        if (
            isinstance(o, int)
            and isinstance(value, (numbers.Integral, np.integer))
            and not isinstance(value, (bool, np.bool_))
            and value == o
        ):
            return o
    raise ValueError(f"{name} must be one of {list(options)}, got {value!r}")


class Checked:
    """A data descriptor validating every assignment through ``check(value, name)``.

    ``dt = Checked(positive)`` in a class body makes ``obj.dt = x`` store
    ``positive(x, "dt")``; reading gives the stored value. So a value set
    after construction (``set_attr`` on a vector env) is checked exactly as
    the constructor checks it. Every assignment counts up the object's
    :func:`settings_version` (what is derived from its settings can be cached
    against it). With ``fixed=True`` the attribute is set once
    (at construction) and any later assignment is refused: for settings
    that other state was derived from (the observation space, the compiled
    step).
    """

    def __init__(self, check: Callable[[Any, str], Any], fixed: bool = False):
        self.check = check
        self.fixed = fixed

    def __set_name__(self, owner: type, name: str) -> None:
        self.name = name
        self.slot = f"_checked_{name}"

    def __get__(self, obj: Any, owner: type | None = None) -> Any:
        if obj is None:
            return self
        try:
            return obj.__dict__[self.slot]
        except KeyError:
            raise AttributeError(self.name) from None

    def __set__(self, obj: Any, value: Any) -> None:
        if self.fixed and self.slot in obj.__dict__:
            raise ValueError(
                f"{self.name} is fixed at construction (other settings derive from it); make a new env instead"
            )
        obj.__dict__[self.slot] = frozen(self.check(value, self.name))
        touch(obj)


def frozen(value: Any) -> Any:
    """An array setting as a read-only copy (``env.u_max[:] = -40`` raises instead of bypassing the
    check); other values unchanged. Readers that hand it to compiled code take a writable copy."""
    if isinstance(value, np.ndarray):
        value = value.copy()
        value.setflags(write=False)
    return value


def touch(obj: Any) -> None:
    """Count up ``obj``'s :func:`settings_version` (a setting changed)."""
    obj.__dict__["_settings_version"] = obj.__dict__.get("_settings_version", 0) + 1


def settings_version(obj: Any) -> int:
    """How many times ``obj``'s :class:`Checked` settings (and those that call :func:`touch`) were set."""
    return obj.__dict__.get("_settings_version", 0)
