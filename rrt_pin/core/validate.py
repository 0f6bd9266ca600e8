"""One place for checking values at the library's boundary, with one wording.

Every check raises :class:`~rrt_pin.core.errors.InputError` (or returns the value
converted to what the library computes with). Messages name the argument, the
value and the unit: ``"q0[2]=nan must be finite [rad or m]"``.

Accepted as real numbers: ``int``, ``float``, numpy integer and floating
scalars and 0-d arrays. Refused: ``bool`` (``True`` is not a tolerance),
complex numbers, strings, None.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from numbers import Integral, Real
from typing import Any

import numpy as np

from rrt_pin.core.errors import InputError

__all__ = [
    "choice",
    "shown",
    "positive_int",
    "real",
    "samples",
    "states",
    "times",
    "tolerance",
    "vector",
]


def _unit(unit: str) -> str:
    return f" [{unit}]" if unit else ""


def shown(value: Any, width: int = 60) -> str:
    """``value`` as a message shows it: Python's repr, never numpy's.

    A numpy scalar or 0-d array prints as the Python number it holds (``0.5``,
    not ``np.float64(0.5)``); a repr longer than ``width`` characters is cut
    with "…".
    """
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, np.generic):
        value = value.item()
    text = repr(value)
    return text if len(text) <= width else text[: width - 1] + "…"


def real(
    name: str,
    value: Any,
    unit: str = "",
    *,
    positive: bool = False,
    nonnegative: bool = False,
    below: float | None = None,
) -> float:
    """A finite real number (optionally > 0, >= 0, or < ``below``) as a float.

    Raises:
        InputError: the value is not a finite real number or out of range.
    """
    if isinstance(value, np.ndarray) and value.ndim == 0:
        value = value[()]
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, Real):
        raise InputError(f"{name}={shown(value)} must be a real number{_unit(unit)}")
    try:
        x = float(value)
    except OverflowError:
        raise InputError(f"{name}={shown(value)} is too large{_unit(unit)}") from None
    if not math.isfinite(x):
        raise InputError(f"{name}={shown(value)} must be finite{_unit(unit)}")
    if positive and x <= 0.0:
        raise InputError(f"{name}={shown(value)} must be > 0{_unit(unit)}")
    if nonnegative and x < 0.0:
        raise InputError(f"{name}={shown(value)} must be >= 0{_unit(unit)}")
    if below is not None and x >= below:
        raise InputError(f"{name}={shown(value)} must be < {below:g}{_unit(unit)}")
    return x


def tolerance(name: str, value: Any, unit: str = "") -> float:
    """An integration tolerance: a finite real number with 0 < value < 1.

    Raises:
        InputError: otherwise (``True``, ``0``, ``1e300``, ``nan`` …).
    """
    return real(name, value, unit, positive=True, below=1.0)


def positive_int(name: str, value: Any) -> int:
    """An integer >= 1 (``bool`` refused).

    Raises:
        InputError: otherwise.
    """
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, Integral) or value < 1:
        raise InputError(f"{name}={shown(value)} must be an integer >= 1")
    return int(value)


def choice(name: str, value: Any, choices: Sequence[str]) -> str:
    """One of ``choices``.

    Raises:
        InputError: naming the valid choices.
    """
    if not isinstance(value, str) or value not in choices:
        raise InputError(f"{name}={shown(value)} is not one of {', '.join(choices)}")
    return value


def _array(name: str, value: Any, unit: str) -> np.ndarray:
    if type(value) is np.ndarray and value.dtype == np.float64:
        return value  # the common case, without the checks below
    if isinstance(value, (str, bytes)) or value is None:
        raise InputError(f"{name}={shown(value)} is not an array of numbers{_unit(unit)}")
    try:
        arr = np.asarray(value)  # no copy of a float array: callers copy where they keep it
    except (TypeError, ValueError) as e:
        raise InputError(f"{name} is not an array of numbers{_unit(unit)}") from e
    if arr.dtype == bool or arr.dtype.kind not in "iuf":
        if arr.dtype.kind == "c":
            raise InputError(f"{name} holds complex numbers; it needs real ones{_unit(unit)}")
        if arr.dtype.kind != "O":
            raise InputError(f"{name} is not an array of numbers{_unit(unit)}")
        try:
            arr = arr.astype(float)
        except (TypeError, ValueError, OverflowError) as e:
            raise InputError(f"{name} is not an array of numbers{_unit(unit)}") from e
    return arr.astype(float, copy=False)


#: Up to this many values, finiteness is checked on Python floats (faster than a ufunc).
_SMALL = 32


def _finite(name: str, arr: np.ndarray, unit: str) -> np.ndarray:
    if arr.size <= _SMALL:
        if all(map(math.isfinite, arr.ravel().tolist())):
            return arr
    elif np.isfinite(arr).all():
        return arr
    bad = ~np.isfinite(arr)
    if bad.any():
        where = tuple(int(i) for i in np.argwhere(bad)[0])
        index = ", ".join(str(i) for i in where)
        raise InputError(f"{name}[{index}]={float(arr[where])!r} must be finite{_unit(unit)}")
    return arr


def vector(name: str, value: Any, n: int, unit: str = "") -> np.ndarray:
    """A finite vector of shape (n,) (a fresh float array).

    Raises:
        InputError: wrong shape or a non-finite entry.
    """
    arr = _array(name, value, unit)
    if arr.shape != (n,):
        raise InputError(f"{name} has shape {arr.shape} but needs ({n},){_unit(unit)}")
    if isinstance(value, (list, tuple)):  # _array made a fresh array of it already
        return _finite(name, arr, unit)
    return _finite(name, np.array(arr, dtype=float), unit)


def states(name: str, value: Any, n: int, unit: str = "") -> np.ndarray:
    """Finite rows of shape (B, n), B >= 1 (a fresh C-contiguous float array).

    Raises:
        InputError: wrong shape or a non-finite entry.
    """
    arr = _array(name, value, unit)
    if arr.ndim != 2 or arr.shape[1] != n or arr.shape[0] < 1:
        raise InputError(f"{name} has shape {arr.shape} but needs (B, {n}){_unit(unit)}")
    return _finite(name, np.array(arr, dtype=float, order="C"), unit)


def samples(
    name: str, value: Any, width: int, unit: str = "", *, finite: bool = True
) -> tuple[np.ndarray, bool]:
    """Finite samples (N, width); a single sample (width,) becomes (1, width).

    ``finite=False`` checks only the shape: for a caller whose compiled loop
    flags non-finite values itself and then calls this again to name the value.

    Returns:
        The array and whether the input was a single sample.

    Raises:
        InputError: wrong shape or a non-finite entry.
    """
    arr = _array(name, value, unit)
    single = arr.ndim == 1
    if single:
        arr = arr[None, :]
    if arr.ndim != 2 or arr.shape[1] != width:
        raise InputError(
            f"{name} has shape {np.shape(value)} but needs (N, {width}) or ({width},){_unit(unit)}"
        )
    arr = np.ascontiguousarray(arr, dtype=float)
    return (_finite(name, arr, unit) if finite else arr), single


def times(value: Any, name: str = "t_eval") -> np.ndarray:
    """Strictly increasing finite times, at least two [s].

    Raises:
        InputError: otherwise (naming the first offending entry).
    """
    t = _array(name, value, "s")
    if t.ndim != 1 or t.size < 2:
        raise InputError(f"{name} has shape {t.shape}; it needs at least 2 times [s]")
    t = np.array(t, dtype=float)
    steps = t[1:] - t[:-1]
    if math.isfinite(t[0]) and math.isfinite(t[-1]) and steps.min() > 0.0:
        return t  # strictly increasing between finite ends: every time is finite
    t = _finite(name, t, "s")
    if (steps <= 0).any():
        i = int(np.flatnonzero(steps <= 0)[0])
        raise InputError(
            f"{name} must increase: {name}[{i + 1}]={float(t[i + 1])!r} <= {float(t[i])!r} [s]"
        )
    return t
