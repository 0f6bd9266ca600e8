"""The entry points of a robot's generated module: which one a job runs, and their signatures.

A robot's module (:mod:`rrt_pin.compiled.robot_code`) has one entry per kind of job, each
compiled on first use with one signature:

* ``run_many``: single runs and small batches, any law, the fixed-step methods (and any);
* ``run_adaptive``: the same for RK45 and DOP853, without the fixed-step integrators (a
  stub stands for them: its first use compiles ~12 % less; Adams's and BDF's entries
  leave them out too);
* ``run_lanes``: a batch of PD-plus-gravity variants side by side (RK45, DOP853);
  ``run_lanes_rkc`` the same with DOP853-RKC (its tail's code compiled there alone);
* ``run_adams``, ``run_bdf``: Adams's method and SciPy's BDF (:data:`OWN_ENTRY`);
* ``run_many_pd``, ``run_adams_pd``, ``run_bdf_pd``: the same under PD plus gravity alone,
  the most common law: copies of the template's functions whose law-dispatching calls
  are bound to that law (:data:`PD_COPIES`), so a first use compiles no other law's
  dynamics (the mass matrix, the bias, the forward dynamics under given efforts): about
  40 % less to compile. Their arithmetic is the general entry's, bit for bit.
* ``run_bdf_num``, ``run_bdf_num_pd``: BDF where its Jacobian is SciPy's ``num_jac``
  for every variant (a physical model applied, ``jacobian="finite-difference"``, or no
  PD-plus-gravity law): without the generated closed-loop Jacobian, which is most of
  BDF's compilation (Panda's: 20,898 lines against the forward dynamics' 2,531).
"""

from __future__ import annotations

import re
from collections.abc import Sequence
from typing import Any

from rrt_pin.simulate import codes

__all__ = [
    "LANES_ENTRY",
    "OWN_ENTRY",
    "PD_COPIES",
    "PD_COPIES_RKC",
    "RKC_COPIES",
    "SIGNATURES",
    "entry",
    "lanes",
    "law_bound",
    "pd_entries",
    "pd_only",
]

#: The entry of the methods that have their own (the others: ``run_adaptive``,
#: ``run_many``, ``run_lanes``).
OWN_ENTRY = {
    codes.METHOD_ADAMS: "run_adams",
    codes.METHOD_BDF: "run_bdf",
    codes.METHOD_DOP853_RKC: "run_adaptive_rkc",
}

#: The lanes' entry of each method a batch runs in lanes (the others' variants one after
#: the other).
LANES_ENTRY = {
    codes.METHOD_RK45: "run_lanes",
    codes.METHOD_DOP853: "run_lanes",
    codes.METHOD_DOP853_RKC: "run_lanes_rkc",
}
#: The template's functions copied as ``<name>_pd`` with these calls renamed: bound to PD
#: plus gravity (the lanes' one law, and single runs under it). In order: a copy may call
#: an earlier one.
PD_COPIES = (
    ("first_step", {"rhs": "rhs_pd_law"}),
    ("metrics_of", {"efforts": "efforts_pd_law"}),
    ("adaptive", {"rhs": "rhs_pd_law", "first_step": "first_step_pd"}),
    ("fixed", {"rhs": "rhs_pd_law"}),
    (
        "run_many",
        {
            "adaptive": "adaptive_pd",
            "fixed": "fixed_pd",
            "efforts_at": "efforts_at_lanes",
            "metrics_of": "metrics_of_pd",
        },
    ),  # fmt: skip
)
#: ``adaptive`` (and its PD copy) with RKC's tail: the template's calls a stub, so that
#: DOP853's and RK45's entries compile none of it.
RKC_COPIES = (
    ("adaptive", {"no_rkc_tail": "rkc_tail"}, "adaptive_rkc"),
    ("adaptive_pd", {"no_rkc_tail": "rkc_tail_pd"}, "adaptive_rkc_pd"),
)
#: The same for DOP853-RKC's tail (``_robot_rkc.py``, called by ``adaptive_rkc``).
PD_COPIES_RKC = (
    ("rkc_rho", {"rhs": "rhs_pd_law"}),
    ("rkc_step", {"rhs": "rhs_pd_law"}),
    ("rkc_tail", {"rhs": "rhs_pd_law", "rkc_rho": "rkc_rho_pd", "rkc_step": "rkc_step_pd"}),
)
#: The same for the implicit and multistep methods' own files.
PD_COPIES_ADAMS = (("adams", {"rhs": "rhs_pd_law"}),)
PD_COPIES_BDF = (
    ("bdf_jacobian", {"rhs": "rhs_pd_law"}),
    ("bdf", {"rhs": "rhs_pd_law", "first_step": "first_step_pd", "bdf_jacobian": "bdf_jacobian_pd"}),
)  # fmt: skip
#: BDF's copies without the generated Jacobian, by their names.
NUMERIC_COPIES_BDF = (
    ("bdf_jacobian", {"closed_loop_jac": "no_closed_loop_jac"}, "bdf_jacobian_num"),
    ("bdf_jacobian", {"rhs": "rhs_pd_law", "closed_loop_jac": "no_closed_loop_jac"},
     "bdf_jacobian_num_pd"),
    ("bdf", {"bdf_jacobian": "bdf_jacobian_num"}, "bdf_num"),
    ("bdf", {"rhs": "rhs_pd_law", "first_step": "first_step_pd",
             "bdf_jacobian": "bdf_jacobian_num_pd"}, "bdf_num_pd"),
)  # fmt: skip


def law_bound(text: str, name: str, calls: dict[str, str], renamed: str = "") -> str:
    """The function ``name`` of ``text`` as ``name_pd`` (or ``renamed``), its ``calls`` renamed."""
    found = re.search(rf"@jit\ndef {name}\(.*?(?=\n@jit|\Z)", text, flags=re.DOTALL)
    if found is None:  # pragma: no cover - the template's own functions
        raise RuntimeError(f"the robot template lost its function {name}")
    out = found.group(0).replace(f"def {name}(", f"def {renamed or name + '_pd'}(", 1)
    for old, new in calls.items():
        out, count = re.subn(rf"\b{old}\(", f"{new}(", out)
        if not count:  # pragma: no cover
            raise RuntimeError(f"the robot template's {name} no longer calls {old}")
    return "\n\n" + out.rstrip() + "\n"


def lanes(text: str) -> str:
    """The lanes' part with both its entries: ``run_lanes_rkc`` and ``run_lanes``.

    ``run_lanes`` is its copy with RKC's tail bound to stubs, so that a DOP853 or RK45
    batch compiles none of it.
    """
    calls = {"rkc_prepare": "no_rkc_prepare", "rkc_consume": "no_rkc_consume"}
    return text + law_bound(text, "run_lanes_rkc", calls, "run_lanes")


def copies(text: str, table: tuple[tuple[Any, ...], ...]) -> str:
    """The copies of ``table``'s functions of ``text``: (name, calls[, renamed]) each."""
    return "".join(law_bound(text, *row) for row in table)


def pd_only(controllers: Sequence[Any]) -> bool:
    """Whether every law is PD plus gravity (their runs' entries: ``*_pd``)."""
    from rrt_pin.simulate.control import PDGravityController  # loaded with any law's module

    return bool(controllers) and all(type(c) is PDGravityController for c in controllers)


def entry(method: int, count: int, pd: bool, numeric: bool = False) -> str:
    """The entry a job runs: method code ``method``, ``count`` variants, all under PD + G (``pd``).

    Adaptive PD-plus-gravity variants (two or more) of RK45, DOP853 and DOP853-RKC run
    side by side in lanes (:data:`LANES_ENTRY`); Adams's method, BDF and DOP853-RKC
    otherwise on their own entries (BDF without its generated Jacobian where ``numeric``:
    every variant's Jacobian is ``num_jac``); anything else one variant after the other.
    """
    if pd and count >= 2 and method in LANES_ENTRY:
        return LANES_ENTRY[method]
    if method in OWN_ENTRY:
        name = OWN_ENTRY[method] + ("_num" if numeric and method == codes.METHOD_BDF else "")
        return name + ("_pd" if pd else "")
    if method < codes.FIXED_STEP_FROM:
        return "run_adaptive_pd" if pd else "run_adaptive"
    return "run_many_pd" if pd else "run_many"


def pd_entries(
    method: int | None, batch: bool, pd: bool, numeric: bool | None = False
) -> tuple[tuple[str, ...], ...]:
    """The entries a job may run: groups, one entry of each built makes it ready.

    A batch may run in lanes or not (one group of two); a BDF job whose Jacobian is not
    known to be numerical for every variant (``numeric`` None) may need either entry (two
    groups: both built).
    """
    code = codes.METHOD_DOP853 if method is None else method
    ways = (False, True) if numeric is None else (bool(numeric),)
    counts = (2, 1) if batch else (1,)
    return tuple(tuple(dict.fromkeys(entry(code, n, pd, way) for n in counts)) for way in ways)


def _types(numba: Any) -> tuple[Any, ...]:
    """(int64, float64, read-only 1-d and 2-d float arrays, read-only 1-d int array)."""
    i8, f8, array = numba.int64, numba.float64, numba.types.Array
    r1, r2 = array(f8, 1, "C", readonly=True), array(f8, 2, "C", readonly=True)
    return i8, f8, r1, r2, array(i8, 1, "C", readonly=True)


def _outputs(numba: Any) -> tuple[Any, ...]:
    """Every entry's last arguments: the outputs, the variants' range, the physical model."""
    i8, f8, _, r2, ri1 = _types(numba)
    return (f8[:, :, ::1], f8[:, :, ::1], f8[:, ::1], i8[:, ::1], f8[::1], i8, i8, r2, ri1)


def _many_signature(numba: Any) -> Any:
    i8, f8, r1, r2, ri1 = _types(numba)
    return numba.types.void(
        i8, r2, r1, f8, r1, f8, f8, i8, ri1, r2, r1, r2, i8, f8, *_outputs(numba)
    )


def _lanes_signature(numba: Any) -> Any:
    i8, f8, r1, r2, _ = _types(numba)
    return numba.types.void(i8, r2, r1, r1, f8, f8, i8, r2, i8, f8, *_outputs(numba))


#: Each entry's one signature (numba's types, given the numba module).
SIGNATURES = {
    "run_lanes": _lanes_signature,
    "run_lanes_rkc": _lanes_signature,
    **{
        name + suffix: _many_signature
        for name in (
            "run_many",
            "run_adaptive",
            "run_adaptive_rkc",
            "run_adams",
            "run_bdf",
            "run_bdf_num",
        )
        for suffix in ("", "_pd")
    },
}
