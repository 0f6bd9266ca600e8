"""Integer codes shared by the compiled loop and its Python wrappers (no numba here).

Numba freezes module-level integers into the machine code, so both sides read
these names from this one module: :mod:`rrt_pin.compiled._jit_dynamics` and
:mod:`rrt_pin.compiled._jit_integrators` compare against them, and
:mod:`rrt_pin.compiled.integrate` and :mod:`rrt_pin.simulate.methods` hand them over.
Changing a value here changes the fingerprint of the machine-code cache
(:data:`rrt_pin.compiled._cache.JIT_MODULES`).
"""

from __future__ import annotations

__all__ = [
    "KIND_CHAPTER",
    "LAW_NONE",
    "LAW_OPEN_LOOP",
    "LAW_PD_GRAVITY",
    "LAW_TRACKING",
    "KIND_CHAPTER_FOLDED",
    "KIND_NONE",
    "KEEP_FINAL",
    "KEEP_METRICS",
    "KEEP_TRAJECTORIES",
    "KIND_PD_PLANT_GRAVITY",
    "METHOD_ADAMS",
    "METHOD_BDF",
    "METHOD_BDF_NUMERIC",
    "METHOD_DOP853",
    "METHOD_DOP853_RKC",
    "METRIC_DEMAND",
    "METRIC_ENERGY",
    "METRIC_EXCURSION",
    "METRIC_FINAL",
    "METRIC_LIMIT",
    "METRIC_PEAK",
    "METRIC_PEAK_TIME",
    "METRIC_SATURATION",
    "METRIC_SETTLE",
    "METRIC_WIDTH",
    "METHOD_RK4",
    "METHOD_RK45",
    "METHOD_SYMPLECTIC_EULER",
    "METHOD_VERLET",
    "NC",
    "NP",
    "SINCOS_FLOPS",
    "STATUS_EFFORT_NONFINITE",
    "STATUS_MAX_STEPS",
    "STATUS_NO_CONVERGENCE",
    "STATUS_NONFINITE",
    "STATUS_OK",
    "STATUS_SINGULAR_MASS",
    "STATUS_STEP_UNDERFLOW",
    "metric_start",
]

# Integration methods: adaptive ones below 10, fixed-step ones from 10 on.
METHOD_RK45 = 0
METHOD_DOP853 = 1
METHOD_ADAMS = 2  # Shampine–Gordon variable-order Adams (any robot's generated integrators only)
METHOD_BDF = 3  # SciPy's BDF with the loop's generated Jacobian (any robot's generated code only)
METHOD_BDF_NUMERIC = 4  # the same with SciPy's finite-difference Jacobian, whatever the law
METHOD_DOP853_RKC = 5  # DOP853 handing over to RKC in a stiff tail (generated code only)
METHOD_SYMPLECTIC_EULER = 10
METHOD_RK4 = 11
METHOD_VERLET = 12
#: Codes from this one on are fixed-step methods.
FIXED_STEP_FROM = 10

# Controller kinds of the compiled closed loop.
KIND_NONE = 0  # no effort: passive motion
KIND_CHAPTER = 1  # eq. (31) with its own parameters (another arm than the plant's)
KIND_PD_PLANT_GRAVITY = 2  # PD plus the plant's own G(q)
KIND_CHAPTER_FOLDED = 3  # eq. (31) with the plant's g, m2, m3, L2: its gravity is the plant's G(q)

# Laws of any robot's compiled integrators (rrt_pin.compiled._robot_template).
LAW_NONE = 0  # no effort: passive motion
LAW_PD_GRAVITY = 1  # PD plus the robot's own G(q)
LAW_TRACKING = 2  # computed torque along a sampled motion
LAW_OPEN_LOOP = 3  # efforts played from samples

# Status codes of a run.
STATUS_OK = 0
STATUS_NONFINITE = 1  # a non-finite state or derivative; coordinate = its index 0..5
STATUS_STEP_UNDERFLOW = 2  # the step size fell below 10 ulp of t
STATUS_SINGULAR_MASS = 3  # M(q) not positive definite; coordinate = pivot 0..2
STATUS_MAX_STEPS = 4  # step budget exhausted; coordinate = component limiting the step
STATUS_NO_CONVERGENCE = 5  # Verlet's implicit half kick diverged; coordinate = its index 0..5
STATUS_EFFORT_NONFINITE = 6  # an effort at an output time is not finite; coordinate = 3·row + k

# What a batch keeps of each variant.
KEEP_TRAJECTORIES = 0  # the states and efforts at every output time
KEEP_FINAL = 1  # the state and efforts at the last output time only (no dense output)
KEEP_METRICS = 2  # the final ones and the metrics row below, from samples not kept

# A row of metrics (rrt_pin.compiled._jit_metrics), per coordinate k = 0, 1, 2 at start + k.
METRIC_FINAL = 0  # |q(tf) - qf| [rad, rad, m]
METRIC_SETTLE = 3  # settling time [s], NaN when not settled
METRIC_PEAK = 6  # peak |tau| [N·m, N·m, N]
METRIC_PEAK_TIME = 9  # its time [s]
METRIC_EXCURSION = 12  # max |q(t) - q(t0)| [rad, rad, m]
METRIC_ENERGY = 15  # control energy, integral of sum |tau·qd| dt [J] (one value)
METRIC_LIMIT = 16  # largest distance past the stated position limits [rad, rad, m], 0 inside
METRIC_SATURATION = 19  # time the law's demand exceeded the stated effort limit [s]
METRIC_DEMAND = 22  # peak |demanded effort| (the law's, before saturation) [N·m, N·m, N]
METRIC_WIDTH = 25

#: Number of physical parameters (``rrt_pin.dynamics.kernel.PARAM_ORDER``) and of controller parameters.
NP = 15
NC = 9 + NP

#: Floating-point operations of ``_jit_dynamics.vsincos`` (reduction 6, two polynomials 20,
#: assembly 7): the compiled kernels' flop counts (:mod:`rrt_pin.cli.flops`) include it.
SINCOS_FLOPS = 33


def metric_start(offset: int, nv: int) -> int:
    """Where a ``METRIC_*`` offset (laid out for 3 coordinates) lies in a row for ``nv``.

    Each block of 3 becomes a block of ``nv``; a remainder counts single values (the
    energy) before it: ``offset // 3 * nv + offset % 3`` (the row's width from
    :data:`METRIC_WIDTH` the same way).
    """
    return offset // 3 * nv + offset % 3
