"""The Jacobian of any supported fixed-base robot's forward dynamics, compiled.

:mod:`rrt_pin.dynamics.forward_derivatives_source` differentiates the generated
straight-line q̈ = M⁻¹(τ − b) in forward mode; :func:`module_source` wraps the result in a
loop over a batch, and :func:`rrt_pin.compiled.rnea._compile` compiles it as it does the
generated RNEA and forward dynamics: a module named by the SHA-256 of its source under
``generated/`` of the cache directory, numba's machine code beside it (its files' SHA-256
recorded and checked before they are read), one kernel per source in a process.

:func:`derivative_kernel_for` gives a model's :class:`DerivativeKernels`:

* :meth:`DerivativeKernels.derivatives`: q̈, ∂q̈/∂q, ∂q̈/∂q̇ (and, asked, ∂q̈/∂τ = M⁻¹), as
  Pinocchio's ``computeABADerivatives`` gives them (joint coordinates: a continuous
  joint's angle, so its derivative is the tangent space's);
* :meth:`DerivativeKernels.inverse_derivatives`: τ, ∂τ/∂q, ∂τ/∂q̇ of the inverse
  dynamics (``computeRNEADerivatives``; a computed-torque law's Jacobian), and
  :meth:`DerivativeKernels.gravity_derivatives`: G(q) and ∂G/∂q (PD plus gravity's);
* :meth:`DerivativeKernels.closed_loop`: q̈ and the (2nv, 2nv) Jacobian of the first-order
  system ẏ = (q̇, q̈) under PD plus the model's gravity, the law's derivatives included;
* :meth:`DerivativeKernels.closed_loop_jac`: that Jacobian as the ``jac(t, y)`` of
  ``scipy.integrate.solve_ivp`` for one run (Radau, BDF, LSODA).

The first use of a model compiles its kernel, announced on the ``rrt_pin`` logger
("compiling ur5's Jacobian kernels once (~N s)"); a later process loads it. A batch with a
non-finite input or result is refused (:class:`~rrt_pin.core.errors.InputError`).

Units: q in rad or m, q̇ in rad/s or m/s, τ in N·m or N, q̈ in rad/s² or m/s²; ∂q̈/∂q in
1/s², ∂q̈/∂q̇ in 1/s, M⁻¹ in 1/(kg·m²) (revolute pairs).
"""

from __future__ import annotations

import re
from collections.abc import Callable
from dataclasses import replace
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.compiled import forward, rnea, rnea_vector
from rrt_pin.compiled.forward import ARRAYS, BatchKernels
from rrt_pin.core import validate
from rrt_pin.core.errors import InputError
from rrt_pin.core.identity import IdentityCache
from rrt_pin.dynamics import forward_derivatives_source as fds
from rrt_pin.dynamics.forward_source import GeneratedFunction
from rrt_pin.dynamics.rnea_source import check_supported

if TYPE_CHECKING:
    import pinocchio as pin

__all__ = [
    "KINDS",
    "VECTOR_BLOCK",
    "DerivativeKernels",
    "derivative_kernel_for",
    "module_source",
    "vector_source",
]

#: The kernels a model gets: q̈ with ∂q̈/∂(q, q̇) by each variant of
#: :data:`~rrt_pin.dynamics.forward_derivatives_source.VARIANTS`; by the default variant
#: with ∂q̈/∂τ = M⁻¹ too; and the PD-plus-gravity loop's.
KINDS = (
    *(f"forward_derivatives_{v}" for v in fds.VARIANTS),
    "forward_derivatives_minv",
    "closed_loop_derivatives",
    "inverse_derivatives",
    "gravity_derivatives",
    "forward_derivatives_vector",
)
#: What compiling takes, roughly, per generated operation [s] and per kernel (numba and
#: LLVM on one core): for the announcement's estimate only.
_COMPILE_S_PER_FLOP = 1.15e-3
_COMPILE_S_PER_KERNEL = 0.2
#: How many times longer a vectorised kernel takes to compile (UR5 2.3, Panda 3.5).
_VECTOR_COMPILE = 3.0
#: Samples a block of a vectorised kernel (its scratch rows of inputs, sines and cosines
#: and results: 64 keeps Panda's, 190 rows, within L2).
VECTOR_BLOCK = 64
_INPUTS = {
    "q": ("q", "rad or m"),
    "v": ("qd", "rad/s or m/s"),
    "a": ("qdd", "rad/s² or m/s²"),
    "tau": ("tau", "N·m or N"),
    "kp": ("kp", "N·m/rad or N/m"),
    "kd": ("kd", "N·m·s/rad or N·s/m"),
    "qf": ("qf", "rad or m"),
}
_MODELS: IdentityCache[tuple[Any, DerivativeKernels]] = IdentityCache(16)


def _generators() -> dict[str, Callable[[Any], GeneratedFunction]]:
    return {
        **{
            f"forward_derivatives_{v}": (lambda m, v=v: fds.forward_derivatives_source(m, v))
            for v in fds.VARIANTS
        },
        "forward_derivatives_minv": lambda m: _renamed(
            fds.forward_derivatives_source(m, wrt=fds.DIRECTIONS), "forward_derivatives_minv"
        ),
        "closed_loop_derivatives": fds.closed_loop_derivatives_source,
        "inverse_derivatives": fds.inverse_derivatives_source,
        "gravity_derivatives": fds.gravity_derivatives_source,
        "forward_derivatives_vector": lambda m: _renamed(
            fds.forward_derivatives_source(m), "forward_derivatives_vector"
        ),
    }


def _renamed(gen: GeneratedFunction, name: str) -> GeneratedFunction:
    return replace(gen, name=name)


def module_source(gen: GeneratedFunction) -> str:
    """The batch kernel's module around ``gen``, as :func:`rrt_pin.compiled.forward.module_source`."""
    return forward.module_source(gen, __name__)


_INPUT = re.compile(r"^(t\d+) = (\w+)\[(\d+)\]$")
_TRIG = re.compile(r"^(t\d+) = (sin|cos)\((t\d+)\)$")


def vector_source(gen: GeneratedFunction, block: int = VECTOR_BLOCK) -> tuple[str, int]:
    """The batch kernel around ``gen`` vectorised across samples, and its angles a sample.

    As :func:`rrt_pin.compiled.rnea_vector.vector_source` does for the RNEA: a block's
    inputs copied into scratch rows (structure of arrays), the sines and cosines of its
    angles by polynomial (libm's for a block with an angle beyond
    :data:`~rrt_pin.compiled.rnea_vector.SINCOS_LIMIT`), the straight-line code one
    sample a lane, the results checked for finiteness once a sample and copied out.
    ``kernel(<one array (N, nv) an input>, out)`` as :func:`module_source`'s.
    """
    row_of: dict[tuple[str, int], int] = {}
    for x in gen.inputs:
        for k in range(gen.nv):
            row_of[x, k] = len(row_of)
    inputs: dict[str, tuple[str, int]] = {}
    angles: dict[int, dict[str, str]] = {}
    for line in gen.lines:
        if m := _INPUT.match(line):
            inputs[m[1]] = (m[2], int(m[3]))
        elif m := _TRIG.match(line):
            array, k = inputs[m[3]]
            if array != "q":
                raise ValueError(f"a sine or cosine of {array}[{k}] in {gen.name}")
            angles.setdefault(k, {})[m[2]] = m[1]
    order = sorted(angles)
    for k in order:
        row_of["sin", k] = len(row_of)
        row_of["cos", k] = len(row_of)
    results = [f for f, x in enumerate(gen.outputs) if x.startswith("t")]
    for f in results:
        row_of["out", f] = len(row_of)
    stride = block + rnea_vector._PAD

    def at(key: tuple[str, int]) -> str:
        return f"w[{row_of[key] * stride} + j]"

    i1, i2, i3 = (" " * n for n in (8, 12, 16))
    args = [ARRAYS[x] for x in gen.inputs]
    src = [
        '"""Generated by rrt_pin.compiled.jacobian from a Pinocchio model: do not edit.',
        "",
        f"{gen.name} of nv={gen.nv}, vectorised over blocks of {block} samples: "
        f"{gen.flops} flops and {len(order)} sine-cosine pairs a sample.",
        '"""',
        "",
        "from math import cos, inf, sin",
        "",
        "import numpy as np",
        "",
        "",
        f"def kernel({', '.join(args)}, out):",
        "    n = Q.shape[0]",
        f"    w = np.empty({len(row_of) * stride})",
        "    bad = False",
        f"    for start in range(0, n, {block}):",
        f"{i1}m = min({block}, n - start)",
        f"{i1}small = 0",
        f"{i1}for j in range(m):",
        f"{i2}r = start + j",
        *(f"{i2}{at(key)} = {ARRAYS[key[0]]}[r, {key[1]}]" for key in row_of if key[0] in ARRAYS),
    ]
    if order:
        within = " & ".join(f"(abs(Q[r, {k}]) < {rnea_vector.SINCOS_LIMIT!r})" for k in order)
        src.append(f"{i2}small += {within}")
    src += [f"{i1}if small == m:", f"{i2}for j in range(m):"]
    src += rnea_vector._sincos_block(order, at, i3, libm=False)
    src += [f"{i1}else:", f"{i2}for j in range(m):"]
    src += rnea_vector._sincos_block(order, at, i3, libm=True)
    src.append(f"{i1}for j in range(m):")
    src += rnea_vector.block_lines(gen.lines, inputs, angles, at, i2)
    src += [f"{i2}{at(('out', f))} = {gen.outputs[f]}" for f in results]
    used = set(inputs.values())
    checked = sorted({gen.outputs[f] for f in results})
    checked += [at(key) for key in row_of if key[0] in ARRAYS and key not in used]
    if checked:
        src.append(f"{i2}bad |= not (abs({rnea._pairwise_sum(checked)}) < inf)")
    src += [f"{i1}for j in range(m):", f"{i2}r = start + j"]
    for f, x in enumerate(gen.outputs):
        r, c = divmod(f, gen.shape[1])
        src.append(f"{i2}out[r, {r}, {c}] = {at(('out', f)) if x.startswith('t') else x}")
    src += ["    return np.nan if bad else 0.0", ""]
    return "\n".join(src), len(order)


class DerivativeKernels(BatchKernels):
    """One model's compiled q̈ and its Jacobian over batches of samples.

    Every function takes arrays (N, nv) of float64 (others are converted) and returns
    new arrays. Compiled, checked and refused as :class:`~rrt_pin.compiled.forward.ForwardKernels`
    (whose batch machinery it shares); its kinds are :data:`KINDS`.

    Attributes:
        name: the model's name (in the announcement and messages).
        nv: joint coordinates a sample.
    """

    called = "Jacobian kernels"
    inputs = _INPUTS

    @staticmethod
    def generators() -> dict[str, Callable[[Any], GeneratedFunction]]:
        """The generator of each kind's code, by kind (:data:`KINDS`)."""
        return _generators()

    def _text(self, kind: str, gen: GeneratedFunction) -> tuple[str, int | None]:
        if kind.endswith("_vector"):
            return vector_source(gen)
        return module_source(gen), None

    def _seconds(self, gen: GeneratedFunction) -> float:
        scale = _VECTOR_COMPILE if "_vector" in gen.name else 1
        return _COMPILE_S_PER_KERNEL + _COMPILE_S_PER_FLOP * gen.flops * scale

    def _result(self, kind: str, gen: GeneratedFunction) -> tuple[str, str]:  # noqa: ARG002
        return "the forward dynamics' Jacobian", gen.name

    def derivatives(
        self,
        q: Any,
        qd: Any,
        tau: Any,
        *,
        minv: bool = False,
        variant: str | None = None,
        vectorised: bool = False,
        num_threads: int | None = None,
    ) -> tuple[np.ndarray, ...]:
        """q̈ (N, nv), ∂q̈/∂q and ∂q̈/∂q̇ (N, nv, nv), and with ``minv`` M⁻¹ = ∂q̈/∂τ (N, nv, nv).

        Args:
            q: joint coordinates (N, nv) [rad or m].
            qd: joint velocities (N, nv) [rad/s or m/s].
            tau: joint efforts (N, nv) [N·m or N].
            minv: also return ∂q̈/∂τ = M(q)⁻¹ (a larger kernel, of the default variant).
            variant: how the kernel is generated, one of
                :data:`~rrt_pin.dynamics.forward_derivatives_source.VARIANTS`; default
                :data:`~rrt_pin.dynamics.forward_derivatives_source.DEFAULT_VARIANT`.
            vectorised: run the default variant vectorised across samples (several
                samples an instruction; compiling it takes about three times longer).
            num_threads: threads; default: the CPUs free now, never a thread with fewer
                samples than the kernel's ``min_per_thread``.

        Raises:
            InputError: bad shapes, a non-finite input or result, an unknown variant.
        """
        if variant is None:
            variant = fds.DEFAULT_VARIANT
        variant = validate.choice("variant", variant, fds.VARIANTS)
        kind = "forward_derivatives_minv" if minv else f"forward_derivatives_{variant}"
        if vectorised:
            if minv or variant != fds.DEFAULT_VARIANT:
                raise InputError(
                    f"vectorised=True runs variant={fds.DEFAULT_VARIANT!r} without minv; "
                    f"got variant={variant!r}, minv={minv}"
                )
            kind = "forward_derivatives_vector"
        out = self._run(kind, (q, qd, tau), num_threads)
        return _split(out, self.nv)

    def inverse_derivatives(
        self, q: Any, qd: Any, qdd: Any, *, num_threads: int | None = None
    ) -> tuple[np.ndarray, ...]:
        """τ (N, nv) [N·m or N], ∂τ/∂q and ∂τ/∂q̇ (N, nv, nv), as ``computeRNEADerivatives``.

        ∂τ/∂q̈ is M(q) (:meth:`rrt_pin.compiled.forward.ForwardKernels.mass_matrix`).

        Args:
            q: joint coordinates (N, nv) [rad or m].
            qd: joint velocities (N, nv) [rad/s or m/s].
            qdd: joint accelerations (N, nv) [rad/s² or m/s²].
            num_threads: as :meth:`derivatives`.

        Raises:
            InputError: bad shapes, a non-finite input or result.
        """
        return _split(self._run("inverse_derivatives", (q, qd, qdd), num_threads), self.nv)

    def gravity_derivatives(
        self, q: Any, *, num_threads: int | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """G(q) (N, nv) [N·m or N] and ∂G/∂q (N, nv, nv) [N·m/rad or N/m].

        Raises:
            InputError: bad shapes, a non-finite input.
        """
        g, dg = _split(self._run("gravity_derivatives", (q,), num_threads), self.nv)
        return g, dg

    def closed_loop(
        self, q: Any, qd: Any, kp: Any, kd: Any, qf: Any, *, num_threads: int | None = None
    ) -> tuple[np.ndarray, np.ndarray]:
        """q̈ (N, nv) and ∂(q̇, q̈)/∂(q, q̇) (N, 2nv, 2nv) under τ = G(q) − kd·q̇ − kp·(q − qf).

        Args:
            q: joint coordinates (N, nv) [rad or m].
            qd: joint velocities (N, nv) [rad/s or m/s].
            kp: stiffness gains a sample (N, nv) [N·m/rad or N/m].
            kd: damping gains a sample (N, nv) [N·m·s/rad or N·s/m].
            qf: targets a sample (N, nv) [rad or m].
            num_threads: as :meth:`derivatives`.

        Raises:
            InputError: bad shapes, a non-finite input or result.
        """
        out = self._run("closed_loop_derivatives", (q, qd, kp, kd, qf), num_threads)
        n, nv = out.shape[0], self.nv
        jac = np.zeros((n, 2 * nv, 2 * nv))
        jac[:, :nv, nv:] = np.eye(nv)
        jac[:, nv:, :] = out[:, :, 1:]
        return out[:, :, 0].copy(), jac

    def closed_loop_jac(
        self, kp: Any, kd: Any, qf: Any
    ) -> Callable[[float, np.ndarray], np.ndarray]:
        """``jac(t, y)`` of ``solve_ivp`` for one run of PD plus gravity, y = (q, q̇) (2nv,).

        The gains and target are fixed here (nv,) [N·m/rad, N·m·s/rad, rad]; each call
        returns a new (2nv, 2nv) array. Non-finite states are not checked (the
        integrator's right-hand side does that).
        """
        nv = self.nv
        fn = self.kernel("closed_loop_derivatives").kernel
        kp1, kd1, qf1 = (
            validate.samples(name, x, nv, _INPUTS[name][1])[0]
            for name, x in (("kp", kp), ("kd", kd), ("qf", qf))
        )
        out = np.empty((1, nv, 1 + 2 * nv))
        eye = np.eye(nv)

        def jac(t: float, y: np.ndarray) -> np.ndarray:
            y = np.ascontiguousarray(y, dtype=float)
            fn(y[:nv].reshape(1, nv), y[nv:].reshape(1, nv), kp1, kd1, qf1, out)
            j = np.zeros((2 * nv, 2 * nv))
            j[:nv, nv:] = eye
            j[nv:] = out[0, :, 1:]
            return j

        return jac


def _split(out: np.ndarray, nv: int) -> tuple[np.ndarray, ...]:
    """q̈ and the blocks of nv columns after it, each a new C-ordered array."""
    blocks = (out.shape[2] - 1) // nv
    parts = [out[:, :, 0]] + [out[:, :, 1 + b * nv : 1 + (b + 1) * nv] for b in range(blocks)]
    return tuple(np.ascontiguousarray(p) for p in parts)


def derivative_kernel_for(model: pin.Model, name: str | None = None) -> DerivativeKernels:
    """The compiled Jacobian kernels of ``model`` (generated, loaded or compiled once a process).

    Kernels are compiled (or loaded) on first use of each (:meth:`DerivativeKernels.compile`
    ahead). A model seen before and unchanged (compared with a copy kept) costs a look-up
    and a model comparison.

    Args:
        model: a fixed-base Pinocchio model with revolute, prismatic or continuous joints.
        name: what the announcement and messages call it; default ``model.name``.

    Raises:
        UnsupportedJoint: a joint is not revolute, prismatic or continuous.
    """
    entry = _MODELS.get(model)
    if entry is not None and bool(entry[0] == model):
        return entry[1]
    import pinocchio as pin

    check_supported(model)
    copy = pin.Model(model)
    kernels = DerivativeKernels(copy, name or str(model.name) or "the model")
    _MODELS.put(model, value=(copy, kernels))
    return kernels
