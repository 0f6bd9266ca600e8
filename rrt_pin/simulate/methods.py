"""The registry of integration methods: one line per method, everything else derives from it.

The CLI's ``--method`` choices and help, the benchmark's plan, which backend
runs what and batch support all read :data:`METHODS`. The default tolerances
follow the accuracy asked for (:func:`tolerances`, from the measured calibration
:mod:`rrt_pin.simulate.calibration`).

Adding an integrator is one function plus one line here:

* a fixed-step method: write ``step(stepper, q, v, h, t) -> (q, v)`` in
  :mod:`rrt_pin.simulate.integrators` (see :func:`rrt_pin.simulate.integrators.rk4`) and add
  ``Method("name", FIXED_STEP, runner="rrt_pin.simulate.integrators:name", ...)``;
* a method of ``scipy.integrate.solve_ivp``: add
  ``Method("RK23", SCIPY, adaptive=True, ...)`` (the name is scipy's);
* a compiled method also needs its ``code`` (:mod:`rrt_pin.simulate.codes`)
  and its branch in :mod:`rrt_pin.compiled._jit_integrators`; one that runs any
  robot's generated integrators only (``adams``) needs instead its template part
  (:mod:`rrt_pin.compiled._robot_adams`) and its entry in
  :mod:`rrt_pin.compiled.robot_code`, as SciPy's ``BDF`` has on compiled
  (:mod:`rrt_pin.compiled._robot_bdf`).
"""

from __future__ import annotations

from dataclasses import dataclass

from rrt_pin.core.errors import InputError
from rrt_pin.simulate import calibration, codes

__all__ = [
    "ACCURACY",
    "DEFAULT_ATOL",
    "DEFAULT_RTOL",
    "METHODS",
    "RTOL_FLOOR",
    "Method",
    "calibration_key",
    "get",
    "names",
    "tolerances",
]

#: Families of methods.
ODEPACK = "odepack"
SCIPY = "scipy"
ADAMS = "adams"  # Shampine and Gordon's DE/STEP/INTRP, compiled
CHEBYSHEV = "chebyshev"  # DOP853 handing over to Runge–Kutta–Chebyshev, compiled
FIXED_STEP = "fixed-step"
SYMPLECTIC = "symplectic"

#: The default accuracy asked for: max |q − q_exact| over the output times [rad or m].
#: The default tolerances of each method and backend are chosen to keep it on every
#: problem of the calibration (:data:`rrt_pin.simulate.accuracy.PROBLEMS` and
#: ``ROBOT_PROBLEMS``), one run or a batch (``accuracy=`` asks for another). A run
#: whose estimated error (``result.error_estimate``) exceeds the accuracy asked for
#: says so.
ACCURACY = 1e-8
#: Relative tolerance of an adaptive method the calibration does not cover.
DEFAULT_RTOL = 1e-10
#: Absolute tolerance of an adaptive method the calibration does not cover [rad, m,
#: rad/s, m/s].
DEFAULT_ATOL = 1e-12
#: The smallest relative tolerance float64 lets an adaptive method honour: 100 machine
#: epsilons (scipy's solve_ivp clips below it; ODEPACK refuses to start below ~1e-14;
#: the compiled integrators share scipy's error control).
RTOL_FLOOR = 100 * 2.220446049250313e-16


@dataclass(frozen=True)
class Method:
    """One integration method.

    Attributes:
        name: the name users type (``--method NAME``, ``method=NAME``).
        family: ``odepack``, ``scipy`` (``solve_ivp``), ``adams`` (compiled Shampine–Gordon),
            ``chebyshev`` (compiled DOP853 with a Runge–Kutta–Chebyshev tail),
            ``fixed-step`` or ``symplectic``.
        summary: one line for help texts.
        adaptive: error-controlled (``rtol``/``atol`` apply); else fixed steps (``step``).
        implicit: takes a Jacobian (``jacobian="analytic"`` gives it one).
        backends: backends that run it (see :mod:`rrt_pin.core.backends`).
        batch: backends whose ``simulate_batch`` runs it.
        code: its code in the compiled loop (:mod:`rrt_pin.simulate.codes`), or None.
        runner: ``module:function`` of a fixed-step method's step, or None.
        rtol: default relative tolerance at the default accuracy (adaptive methods,
            on its first backend: :func:`tolerances` gives any accuracy's and
            backend's), else None.
        atol: the same, absolute [rad, m, rad/s, m/s], else None.
        order: order of a fixed-step method (its error shrinks as stepᵒʳᵈᵉʳ; the
            error estimate compares with twice or half the step and applies
            Richardson's formula), else None.
        min_rtol: the smallest relative tolerance it can honour (adaptive methods,
            :data:`RTOL_FLOOR` unless given), else None. A tighter one is refused.
        calibrated_as: the method whose calibration (the tolerances for the accuracy
            asked, the estimate's companion) this one takes, or None for its own: a
            method that takes another's steps wherever it does not hand over, so that
            the other's problems, the hardest of the catalogue, bind it too.
    """

    name: str
    family: str
    summary: str
    adaptive: bool = False
    implicit: bool = False
    backends: tuple[str, ...] = ("pinocchio",)
    batch: tuple[str, ...] = ()
    code: int | None = None
    runner: str | None = None
    rtol: float | None = None
    atol: float | None = None
    order: int | None = None
    min_rtol: float | None = None
    calibrated_as: str | None = None

    def __post_init__(self) -> None:
        if self.adaptive and self.rtol is None:  # (one calibrated as another: set below)
            rtol, atol = tolerances(self.backends[0], self.name, ACCURACY)
            object.__setattr__(self, "rtol", rtol)
            object.__setattr__(self, "atol", atol)
        if self.adaptive and self.min_rtol is None:
            object.__setattr__(self, "min_rtol", RTOL_FLOOR)

    def runs_on(self, backend: str, batch: bool = False) -> bool:
        """Whether ``backend`` runs this method (in a batch when ``batch``)."""
        return backend in (self.batch if batch else self.backends)


def tolerances(backend: str, method: str, accuracy: float = ACCURACY) -> tuple[float, float]:
    """The default (rtol, atol [rad, m, rad/s, m/s]) of ``method`` on ``backend`` for ``accuracy``.

    The loosest rung of the calibration (:data:`rrt_pin.simulate.calibration.WORST`)
    whose worst error on the calibration's problems, times the measured safety
    factor (:data:`rrt_pin.simulate.calibration.SAFETY`), is within ``accuracy``
    [rad or m], as is every tighter rung's; its tightest rung when none is (the
    run's error estimate then says whether the accuracy was met). atol = rtol / :data:`~rrt_pin.simulate.calibration.ATOL_RATIO`.
    A method calibrated as another (:attr:`Method.calibrated_as`) gets that one's.
    A method the calibration does not cover gets :data:`DEFAULT_RTOL`, :data:`DEFAULT_ATOL`.
    A method that runs step for step on several backends gets the same (the tightest
    of their choices), so that its backends give the same numbers.
    """
    entry = METHODS.get(method) if "METHODS" in globals() else None
    if entry is not None and entry.calibrated_as:
        return tolerances(backend, entry.calibrated_as, accuracy)
    if entry is not None and entry.code is not None and len(entry.backends) > 1:
        chosen = [_tolerances(b, method, accuracy) for b in entry.backends]
        known = [c for c in chosen if c is not None]
        if known:
            return min(known)
    found = _tolerances(backend, method, accuracy)
    return found if found is not None else (DEFAULT_RTOL, DEFAULT_ATOL)


def _tolerances(backend: str, method: str, accuracy: float) -> tuple[float, float] | None:
    """One backend's calibrated choice, or None."""
    rungs = calibration.WORST.get((backend, method))
    if not rungs:
        return None
    bound = accuracy / calibration.SAFETY
    rtol = rungs[-1][0]
    for r, worst, _ in reversed(rungs):  # tightest first
        if worst > bound:
            break
        rtol = r
    return rtol, rtol / calibration.ATOL_RATIO


def calibration_key(backend: str, method: str) -> tuple[str, str]:
    """The (backend, method) under which the calibration holds ``method``'s measurements."""
    entry = METHODS.get(method)
    measured = entry.calibrated_as if entry is not None and entry.calibrated_as else method
    return backend, measured


_BOTH = ("pinocchio", "compiled")

#: Every integration method, by name, in the order help texts list them.
METHODS: dict[str, Method] = {
    m.name: m
    for m in (
        Method(
            "odepack",
            ODEPACK,
            "ODEPACK's LSODA (Adams up to order 12, BDF when stiff) through scipy's odeint",
            adaptive=True,
            batch=("pinocchio",),
        ),
        Method(
            "RK45",
            SCIPY,
            "Dormand–Prince 5(4), explicit (scipy's solve_ivp; step for step on compiled)",
            adaptive=True,
            backends=_BOTH,
            batch=_BOTH,
            code=codes.METHOD_RK45,
        ),
        Method(
            "DOP853",
            SCIPY,
            "Dormand–Prince 8(5,3), explicit (scipy's solve_ivp; step for step on compiled)",
            adaptive=True,
            backends=_BOTH,
            batch=_BOTH,
            code=codes.METHOD_DOP853,
        ),
        Method(
            "adams",
            ADAMS,
            "Shampine–Gordon Adams PECE, orders 1–12, interpolated outputs (any robot but "
            "the chapter's arm)",
            adaptive=True,
            backends=("compiled",),
            batch=("compiled",),
            code=codes.METHOD_ADAMS,
        ),
        Method(
            "DOP853-RKC",
            CHEBYSHEV,
            "DOP853, handing over to Runge–Kutta–Chebyshev (order 2) where its stability "
            "sets its steps, and back (any robot but the chapter's arm)",
            adaptive=True,
            backends=("compiled",),
            batch=("compiled",),
            code=codes.METHOD_DOP853_RKC,
            calibrated_as="DOP853",  # DOP853's steps until it hands over, bit for bit
        ),
        Method("LSODA", SCIPY, "scipy's LSODA, analytic Jacobian", adaptive=True, implicit=True),
        Method("Radau", SCIPY, "implicit Runge–Kutta of order 5", adaptive=True, implicit=True),
        Method(
            "BDF",
            SCIPY,
            "backward differentiation, orders 1–5 (scipy's solve_ivp; step for step on compiled)",
            adaptive=True,
            implicit=True,
            backends=_BOTH,
            batch=("compiled",),
            code=codes.METHOD_BDF,
        ),
        Method(
            "symplectic_euler",
            FIXED_STEP,
            "semi-implicit Euler, 1st order, one evaluation a step",
            backends=_BOTH,
            batch=_BOTH,
            code=codes.METHOD_SYMPLECTIC_EULER,
            runner="rrt_pin.simulate.integrators:symplectic_euler",
            order=1,
        ),
        Method(
            "rk4",
            FIXED_STEP,
            "classical Runge–Kutta, 4th order, four evaluations a step",
            backends=_BOTH,
            batch=_BOTH,
            code=codes.METHOD_RK4,
            runner="rrt_pin.simulate.integrators:rk4",
            order=4,
        ),
        Method(
            "verlet",
            FIXED_STEP,
            "velocity Verlet in (q, q̇), 2nd order, time-symmetric",
            backends=_BOTH,
            batch=_BOTH,
            code=codes.METHOD_VERLET,
            runner="rrt_pin.simulate.integrators:verlet",
            order=2,
        ),
        Method(
            "leapfrog",
            SYMPLECTIC,
            "Störmer–Verlet in canonical variables, symplectic for M(q)",
            order=2,
        ),
    )
}


def _take_calibrations() -> None:
    """The default tolerances of each method calibrated as another: that one's."""
    for m in METHODS.values():
        if m.calibrated_as:
            rtol, atol = tolerances(m.backends[0], m.name, ACCURACY)
            object.__setattr__(m, "rtol", rtol)
            object.__setattr__(m, "atol", atol)


_take_calibrations()


def get(name: object, backend: str | None = None, batch: bool = False) -> Method:
    """The method called ``name``, checked to run on ``backend`` (in a batch when ``batch``).

    Raises:
        InputError: unknown name, or a method the backend does not run (naming
            the valid ones).
    """
    method = METHODS.get(name) if isinstance(name, str) else None
    if method is None:
        raise InputError(f"method={name!r} is not one of {', '.join(METHODS)}")
    if backend is not None and not method.runs_on(backend, batch):
        valid = names(backend, batch)
        where = f"backend {backend!r}" + (" in a batch" if batch else "")
        raise InputError(f"method={name!r} does not run on {where}; valid: {', '.join(valid)}")
    return method


def names(
    backend: str | None = None, batch: bool = False, adaptive: bool | None = None
) -> tuple[str, ...]:
    """Names of the methods (of one backend, batch-capable, adaptive or fixed-step)."""
    return tuple(
        m.name
        for m in METHODS.values()
        if (backend is None or m.runs_on(backend, batch))
        and (backend is not None or not batch or m.batch)
        and (adaptive is None or m.adaptive == adaptive)
    )
