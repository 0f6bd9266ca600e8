"""The generated RNEA vectorised across samples: the source of its batch kernel (numba-free).

:func:`vector_source` turns the straight-line RNEA of one sample
(:class:`rrt_pin.dynamics.rnea_source.GeneratedRnea`) into a module whose
``kernel(Q, V, A, out)`` runs a batch block by block, as the chapter's arm's
``inverse_batch`` does (:mod:`rrt_pin.compiled._jit_dynamics`):

1. the block's rows are copied into a scratch array, one contiguous row of
   :data:`BLOCK` values a coordinate (structure of arrays), and its angles
   scanned for |x| < :data:`SINCOS_LIMIT`;
2. the sines and cosines of the block's angles: Cephes' polynomials (the same
   operations as ``_jit_dynamics.vsincos``, no call and no branch) when every
   angle is below the limit, else the same per sample with libm beyond it (so a
   sample's efforts never depend on the other samples of its block);
3. the straight-line RNEA over the block, one sample a lane: no call, no branch
   and only constant offsets into one array, so LLVM runs several samples an
   instruction; the efforts go to the scratch array and their sum, with the
   inputs no effort depends on, is tested once a sample (``bad |= not |s| < ∞``,
   an OR that vectorizes): non-finite inputs reach an effort through +, −, ·,
   sin and cos as non-finite values, so only the unused ones are added;
4. the efforts copied back into the rows of ``out``.

Steps 2 and 3 are functions of their own (``sincos_poly``, ``sincos_libm``, ``body``),
lowered to LLVM IR past numba's front end (:mod:`rrt_pin.compiled._straight`: the same
instructions, an order of magnitude less to compile); each sample's checked sum goes to
a row of the scratch array, which the kernel tests.

No fast-math: every operation is the scalar code's, in its order, so the lanes
give the bits a one-sample loop gives.
"""

from __future__ import annotations

import re
from collections.abc import Callable
from typing import Any

from rrt_pin.dynamics.rnea_source import GeneratedRnea

__all__ = [
    "BLOCK", "SINCOS_LIMIT", "kernel_signature", "pairwise_sum", "sincos_lines", "vector_source",
]  # fmt: skip

#: Samples a block: its scratch rows (inputs, sines and cosines, efforts) stay in L1.
BLOCK = 128
#: Padding of each scratch row [values]: rows 2^k·8 bytes apart make a row's stores look
#: like the next rows' loads to the CPU (4 KiB aliasing; 256 unpadded doubled the time).
_PAD = 8
#: Below this |angle| [rad] the polynomial sine and cosine are used (as
#: ``_jit_dynamics.SINCOS_LIMIT``); at or beyond it, and for inf and nan, libm's.
SINCOS_LIMIT = 1e8

# Cephes' sin.c (S. L. Moshier), as in _jit_dynamics: reduction by π/4 in three parts,
# degree-13/14 polynomials; absolute error <= 2.3e-16 for |x| < SINCOS_LIMIT.
_FOPI = 1.27323954473516268615  # 4/π
_DP = (7.85398125648498535156e-1, 3.77489470793079817668e-8, 2.69515142907905952645e-15)
_S = (
    1.58962301576546568060e-10, -2.50507477628578072866e-8, 2.75573136213857245213e-6,
    -1.98412698295895385996e-4, 8.33333333332211858878e-3, -1.66666666666666307295e-1,
)  # fmt: skip
_C = (
    -1.13585365213876817300e-11, 2.08757008419747316778e-9, -2.75573141792967388112e-7,
    2.48015872888517045348e-5, -1.38888888888730564116e-3, 4.16666666666665929218e-2,
)  # fmt: skip

_INPUT = re.compile(r"^(t\d+) = ([qva])\[(\d+)\]$")
_TRIG = re.compile(r"^(t\d+) = (sin|cos)\((t\d+)\)$")


def _horner(coefficients: tuple[float, ...], x: str) -> str:
    out = repr(coefficients[0])
    for c in coefficients[1:]:
        out = f"({out} * {x} + {c!r})"
    return out


def sincos_lines(x: str, s: str, c: str, tag: str) -> list[str]:
    """Statements setting ``s``, ``c`` to sin ``x``, cos ``x`` for |x| < SINCOS_LIMIT.

    The operations of ``_jit_dynamics.vsincos`` (the same bits), as plain Python
    (``tag`` makes the temporaries' names unique). Any x gives no exception, but
    beyond the limit (or inf, nan) the values are meaningless.
    """
    p = f"_{tag}"
    return [
        f"{p}a = abs({x})",
        f"{p}j = int({p}a * {_FOPI!r})",
        f"{p}j += {p}j & 1",
        f"{p}y = float({p}j)",
        f"{p}z = (({p}a - {p}y * {_DP[0]!r}) - {p}y * {_DP[1]!r}) - {p}y * {_DP[2]!r}",
        f"{p}zz = {p}z * {p}z",
        f"{p}ps = {p}z + {p}z * {p}zz * {_horner(_S, f'{p}zz')}",
        f"{p}pc = 1.0 - 0.5 * {p}zz + {p}zz * {p}zz * {_horner(_C, f'{p}zz')}",
        f"{p}o = {p}j & 7",
        f"{p}s = {p}pc if {p}o & 2 else {p}ps",
        f"{p}s = -{p}s if {p}o & 4 else {p}s",
        f"{c} = {p}ps if {p}o & 2 else {p}pc",
        f"{c} = -{c} if ({p}o + 2) & 4 else {c}",
        f"{s} = -{p}s if {x} < 0.0 else {p}s",
    ]


def pairwise_sum(terms: list[str]) -> str:
    """A balanced sum of ``terms`` (a short dependency chain)."""
    while len(terms) > 1:
        terms = [
            f"({terms[k]} + {terms[k + 1]})" if k + 1 < len(terms) else terms[k]
            for k in range(0, len(terms), 2)
        ]
    return terms[0]


def _is_constant(expr: str) -> bool:
    return not expr.startswith("t")


def vector_source(gen: GeneratedRnea, block: int = BLOCK) -> tuple[str, int]:
    """The module of the vectorised batch kernel of ``gen``, and its angles a sample.

    ``kernel(Q (N, nq), V (N, nv), A (N, nv), out (N, nv))`` writes each row's
    efforts into ``out`` and returns 0.0 when every entry of Q, V, A and out is
    finite, else NaN. Each angle costs a sine-cosine pair on top of ``gen.flops``:
    ``rrt_pin.simulate.codes.SINCOS_FLOPS`` operations (one reduction for both).
    """
    arrays = {"q": gen.nq, "v": gen.nv, "a": gen.nv}
    row_of = {}  # (array, k) -> scratch row
    for name, size in arrays.items():
        for k in range(size):
            row_of[name, k] = len(row_of)
    inputs: dict[str, tuple[str, int]] = {}  # temporary -> (array, k)
    angles: dict[int, dict[str, str]] = {}  # q index -> {"sin"/"cos": temporary}
    for line in gen.lines:
        if m := _INPUT.match(line):
            inputs[m[1]] = (m[2], int(m[3]))
        elif m := _TRIG.match(line):
            array, k = inputs[m[3]]
            if array != "q":
                raise ValueError(f"a sine or cosine of {array}[{k}] in the generated RNEA")
            angles.setdefault(k, {})[m[2]] = m[1]
    order = sorted(angles)
    for k in order:  # rows of the sine and the cosine of each angle
        row_of["sin", k] = len(row_of)
        row_of["cos", k] = len(row_of)
    tau_rows = {}
    for k, t in enumerate(gen.tau):
        if not _is_constant(t):
            tau_rows[k] = len(row_of)
            row_of["tau", k] = len(row_of)
    used = set(inputs.values())
    unused = [key for key in row_of if key[0] in arrays and key not in used]

    stride = block + _PAD

    def at(key: tuple[str, int]) -> str:
        return f"w[{row_of[key] * stride} + j]"

    i1, i2, i3 = (" " * n for n in (8, 12, 16))
    from rrt_pin.compiled._straight import stub  # where a module is written, not at import

    # the RNEA over a block, one sample a lane, lowered past numba's front end
    flag = len(row_of)  # each sample's sum of checked values, tested by the kernel
    body = ["def body(w, m):", "    for j in range(m):"]
    body += block_lines(gen.lines, inputs, angles, at, i2[4:])
    checked = []
    for k, row in tau_rows.items():
        body.append(f"{i2[4:]}w[{row * stride} + j] = {gen.tau[k]}")
        checked.append(gen.tau[k])
    checked += [at(key) for key in unused]
    if checked:
        body.append(f"{i2[4:]}w[{flag * stride} + j] = abs({pairwise_sum(checked)})")
    src = [
        '"""Generated by rrt_pin.compiled.rnea from a Pinocchio model: do not edit.',
        "",
        f"RNEA of nq={gen.nq}, nv={gen.nv}, vectorised over blocks of {block} samples: "
        f"{gen.flops} flops and {len(order)} sine-cosine pairs a sample.",
        '"""',
        "",
        "from math import cos, inf, sin",
        "",
        "import numba",
        "import numpy as np",
        "",
        "from rrt_pin.compiled._straight import lowered",
        "",
        "",
        "def jit(f):",
        '    return numba.njit(nogil=True, error_model="numpy")(f)',
        "",
        "",
        stub("body", ("w", "m"), "\n".join(body) + "\n", counts=("m",)),
        "",
        *(
            stub(
                f"sincos_{kind}",
                ("w", "m"),
                "\n".join(
                    [
                        f"def sincos_{kind}(w, m):",
                        "    for j in range(m):",
                        *_sincos_block(order, at, i2[4:], libm=kind == "libm"),
                    ]
                )
                + "\n",
                counts=("m",),
            )
            + "\n"
            for kind in (("poly", "libm") if order else ())
        ),  # fmt: skip
        "def kernel(Q, V, A, out):",
        "    n = Q.shape[0]",
        f"    w = np.empty({(len(row_of) + 1) * stride})",
        "    bad = False",
        f"    for start in range(0, n, {block}):",
        f"{i1}m = min({block}, n - start)",
        f"{i1}small = 0",
        f"{i1}for j in range(m):",
        f"{i2}r = start + j",
    ]
    for (name, k), _row in row_of.items():
        if name in arrays:
            src.append(f"{i2}{at((name, k))} = {name.upper()}[r, {k}]")
    if order:
        within = " & ".join(f"(abs(Q[r, {k}]) < {SINCOS_LIMIT!r})" for k in order)
        src.append(f"{i2}small += {within}")
    if order:
        src += [f"{i1}if small == m:", f"{i2}sincos_poly(w, m)", f"{i1}else:",
                f"{i2}sincos_libm(w, m)"]  # fmt: skip
    src.append(f"{i1}body(w, m)")
    if checked:
        src += [f"{i1}for j in range(m):", f"{i2}bad |= not (w[{flag * stride} + j] < inf)"]
    src += [f"{i1}for j in range(m):", f"{i2}r = start + j"]
    for k, t in enumerate(gen.tau):
        src.append(f"{i2}out[r, {k}] = {at(('tau', k)) if k in tau_rows else t}")
    src += ["    return np.nan if bad else 0.0", ""]
    return "\n".join(src), len(order)


def block_lines(
    lines: tuple[str, ...] | list[str],
    inputs: dict[str, tuple[str, int]],
    angles: dict[int, dict[str, str]],
    at: Callable[[tuple[str, int]], str],
    indent: str,
) -> list[str]:
    """Generated straight-line ``lines`` over a block, inputs and sines from scratch rows.

    Inputs, sines and cosines are read from their rows (``at``); the rest is as it is.
    """
    trig = {t: (fn, k) for k, d in angles.items() for fn, t in d.items()}
    out = []
    for line in lines:
        name = line.split(" = ", 1)[0]
        if name in inputs:
            out.append(f"{indent}{name} = {at(inputs[name])}")
        elif name in trig:
            out.append(f"{indent}{name} = {at(trig[name])}")
        else:
            out.append(f"{indent}{line}")
    return out


def _sincos_block(
    order: list[int], at: Callable[[tuple[str, int]], str], indent: str, libm: bool
) -> list[str]:
    """The loop body setting the sine and cosine rows of every angle of a block."""
    if not order:
        return [f"{indent}pass"]
    out = []
    for k in order:
        x, s, c = at(("q", k)), at(("sin", k)), at(("cos", k))
        out.append(f"{indent}x = {x}")
        if libm:
            out.append(f"{indent}within = abs(x) < {SINCOS_LIMIT!r}")
            out.append(f"{indent}xr = x if within else 0.0")
            out += [f"{indent}{line}" for line in sincos_lines("xr", "sv", "cv", "p")]
            out.append(f"{indent}{s} = sv if within else sin(x)")
            out.append(f"{indent}{c} = cv if within else cos(x)")
        else:
            out += [f"{indent}{line}" for line in sincos_lines("x", "sv", "cv", "p")]
            out += [f"{indent}{s} = sv", f"{indent}{c} = cv"]
    return out


def kernel_signature(numba: Any) -> Any:
    """kernel(Q, V, A, out) -> float64: inputs C-ordered and read-only accepted (no copy)."""
    f8 = numba.float64
    read = numba.types.Array(f8, 2, "C", readonly=True)
    return f8(read, read, read, f8[:, ::1])
