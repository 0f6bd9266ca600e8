"""ODEPACK's LSODA (``scipy.integrate.odeint``) without importing all of ``scipy.integrate``.

``import scipy.integrate`` is slow (it imports scipy.special, optimize,
sparse.linalg …) for a run that needs one Fortran routine. This module loads
scipy's ``_odepack`` extension module by itself and calls it exactly as
``scipy.integrate.odeint(..., full_output=True)`` does: same routine, same
arguments, the same bits (``tests/test_startup.py`` compares both). If the
extension cannot be loaded that way, or its call signature differs in this
scipy, :func:`odeint` falls back to ``scipy.integrate.odeint``.

Two costs of a plain ``import`` are avoided as well. The extension is found
through scipy's import spec, without running ``scipy/__init__`` (its test
runner, version checks and config). And the extension links scipy's own
OpenBLAS, which at load starts a pool of threads that spin, waiting for work,
for a while after it (CPU taken from the run on a machine with few cores);
LSODA's linear algebra is on (2·nv)² matrices, far below OpenBLAS's threading
thresholds, so the library is loaded with ``OPENBLAS_NUM_THREADS=1`` unless the
variable is set (the environment is restored at once; numpy's own OpenBLAS,
loaded before, is left as it is). Same routine, same bits.
"""

from __future__ import annotations

import contextlib
import importlib.machinery
import importlib.util
import os
import sys
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import numpy as np

__all__ = ["MESSAGES", "load", "odeint"]

#: LSODA's status codes, worded as scipy's odeint words them.
MESSAGES = {
    2: "Integration successful.",
    1: "Nothing was done; the integration time was 0.",
    -1: "Excess work done on this call (perhaps wrong Dfun type).",
    -2: "Excess accuracy requested (tolerances too small).",
    -3: "Illegal input detected (internal error).",
    -4: "Repeated error test failures (internal error).",
    -5: "Repeated convergence failures (perhaps bad Jacobian or tolerances).",
    -6: "Error weight became zero during problem.",
    -7: "Internal workspace insufficient to finish (internal error).",
    -8: "Run terminated (internal error).",
}

_NAME = "scipy.integrate._odepack"
#: OpenBLAS's thread count, read once when the library loads.
_BLAS_THREADS = "OPENBLAS_NUM_THREADS"
_module: Any = None
_direct = True  # False once the direct route failed: scipy's odeint from then on


def load() -> None:
    """Load what :func:`odeint` will call (so that a timed run excludes it)."""
    if _extension() is None:
        import scipy.integrate  # noqa: F401


def _extension() -> Any:
    """The ``_odepack`` extension module of scipy, loaded from its file (None if that fails)."""
    global _module
    if _module is not None:
        return _module
    if _NAME in sys.modules:
        _module = sys.modules[_NAME]
        return _module
    try:
        scipy = importlib.util.find_spec("scipy")  # where it is, without running its __init__
        folder = Path(next(iter(scipy.submodule_search_locations))) / "integrate"
        path = next(
            folder / f"_odepack{suffix}"
            for suffix in importlib.machinery.EXTENSION_SUFFIXES
            if (folder / f"_odepack{suffix}").is_file()
        )
        loader = importlib.machinery.ExtensionFileLoader(_NAME, str(path))
        spec = importlib.util.spec_from_file_location(_NAME, path, loader=loader)
        with _one_blas_thread():  # the library loads with the module (create_module)
            module = importlib.util.module_from_spec(spec)
            loader.exec_module(module)
    except (ImportError, OSError, StopIteration, AttributeError, TypeError, ValueError):
        return None
    # Registered under its own name: scipy.integrate, if imported later, uses this one.
    sys.modules.setdefault(_NAME, module)
    _module = sys.modules[_NAME]
    return _module


@contextlib.contextmanager
def _one_blas_thread() -> Iterator[None]:
    """``OPENBLAS_NUM_THREADS=1`` while a library loads, unless the user set the variable."""
    if _BLAS_THREADS in os.environ:
        yield
        return
    os.environ[_BLAS_THREADS] = "1"
    try:
        yield
    finally:
        os.environ.pop(_BLAS_THREADS, None)


def odeint(
    func: Callable[[np.ndarray, float], np.ndarray],
    y0: np.ndarray,
    t: np.ndarray,
    *,
    rtol: float,
    atol: float,
    mxstep: int = 0,
    ml: int | None = None,
    mu: int | None = None,
) -> tuple[np.ndarray, dict[str, Any]]:
    """``scipy.integrate.odeint(func, y0, t, ..., full_output=True)``, without its import cost.

    Args:
        func: ``f(y, t)`` (odeint's argument order) returning dy/dt.
        y0: initial state.
        t: output times [s], monotonic.
        rtol: LSODA's relative tolerance.
        atol: LSODA's absolute tolerance.
        mxstep: most internal steps between two output times (0: LSODA's default).
        ml: lower bandwidth of the Jacobian (None: full).
        mu: upper bandwidth of the Jacobian (None: full).

    Returns:
        The states at ``t`` and odeint's info dictionary (with its ``message``).
    """
    global _direct
    module = _extension() if _direct else None
    if module is not None:
        y0 = np.array(y0, dtype=float)
        t = np.array(t, dtype=float)
        band_l = -1 if ml is None else ml
        band_u = -1 if mu is None else mu
        try:
            # (func, y0, t, args, Dfun, col_deriv, ml, mu, full_output, rtol, atol, tcrit,
            #  h0, hmax, hmin, ixpr, mxstep, mxhnil, mxordn, mxords, tfirst): odeint's order
            out = module.odeint(func, y0, t, (), None, 0, band_l, band_u, 1, rtol, atol, None,
                                0.0, 0.0, 0.0, 0, mxstep, 0, 12, 5, 0)  # fmt: skip
        except TypeError:
            _direct = False  # another signature in this scipy: use its own wrapper
        else:
            states, info, status = out
            info["message"] = MESSAGES.get(status, f"LSODA status {status}")
            return states, info
    import warnings

    from scipy.integrate import ODEintWarning
    from scipy.integrate import odeint as scipy_odeint

    with warnings.catch_warnings():
        warnings.simplefilter("ignore", ODEintWarning)
        return scipy_odeint(func, y0, t, rtol=rtol, atol=atol, full_output=True,
                            mxstep=mxstep, ml=ml, mu=mu)  # fmt: skip
