"""Integer codes shared by the compiled loop and its Python wrappers (no numba here).

Numba freezes module-level integers into the machine code, so both sides read
these names from this one module: :mod:`rrt_pin.compiled._jit_dynamics` and
:mod:`rrt_pin.compiled._jit_integrators` compare against them, and
:mod:`rrt_pin.compiled.integrate` and :mod:`rrt_pin.methods` hand them over.
Changing a value here changes the fingerprint of the machine-code cache
(:data:`rrt_pin.compiled._cache.JIT_MODULES`).
"""

from __future__ import annotations

__all__ = [
    "KIND_CHAPTER",
    "KIND_CHAPTER_FOLDED",
    "KIND_NONE",
    "KIND_PD_PLANT_GRAVITY",
    "METHOD_DOP853",
    "METHOD_RK4",
    "METHOD_RK45",
    "METHOD_SYMPLECTIC_EULER",
    "METHOD_VERLET",
    "NC",
    "NP",
    "STATUS_MAX_STEPS",
    "STATUS_NO_CONVERGENCE",
    "STATUS_NONFINITE",
    "STATUS_OK",
    "STATUS_SINGULAR_MASS",
    "STATUS_STEP_UNDERFLOW",
]

# Integration methods: adaptive ones below 10, fixed-step ones from 10 on.
METHOD_RK45 = 0
METHOD_DOP853 = 1
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

# Status codes of a run.
STATUS_OK = 0
STATUS_NONFINITE = 1  # a non-finite state or derivative; coordinate = its index 0..5
STATUS_STEP_UNDERFLOW = 2  # the step size fell below 10 ulp of t
STATUS_SINGULAR_MASS = 3  # M(q) not positive definite; coordinate = pivot 0..2
STATUS_MAX_STEPS = 4  # step budget exhausted; coordinate = component limiting the step
STATUS_NO_CONVERGENCE = 5  # Verlet's implicit half kick diverged; coordinate = its index 0..5

#: Number of physical parameters (``rrt_pin.kernel.PARAM_ORDER``) and of controller parameters.
NP = 15
NC = 9 + NP
