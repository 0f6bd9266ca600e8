"""The calibration of the default tolerances and of the error estimate (generated).

Written by ``scripts/bench/calibrate.py`` (do not edit by hand; run it again after a
change to a method or to the accuracy catalogue). :func:`rrt_pin.simulate.options.resolve`
reads :data:`WORST` and :data:`SAFETY` to choose the tolerances for the accuracy asked
for; :mod:`rrt_pin.simulate.estimate` reads :data:`COMPANIONS`.
"""

from __future__ import annotations

__all__ = ["ATOL_RATIO", "COMPANIONS", "SAFETY", "WORST"]

#: The measured safety factor: leaving one problem of the calibration out, the
#: largest ratio of its error to the accuracy asked for at the rung the other
#: problems choose (pinocchio DOP853, light-joint2 at 0.001).
SAFETY = 1.69
#: atol = rtol / ATOL_RATIO [rad, m, rad/s, m/s] at every rung.
ATOL_RATIO = 100
#: (backend, method) -> ((rtol, worst max |q − q_ref| over the calibration's
#: problems [rad or m], the problem), ...), loosest first.
WORST: dict[tuple[str, str], tuple[tuple[float, float, str], ...]] = {
    ("pinocchio", "odepack"): (
        (0.001, 0.0112, "fast-oscillation"),
        (0.00031622776601683794, 0.00648, "fast-oscillation"),
        (0.0001, 0.0027, "slider-150s"),
        (3.1622776601683795e-05, 0.00123, "slider-150s"),
        (1e-05, 0.000467, "fast-oscillation"),
        (3.162277660168379e-06, 0.00022, "fast-oscillation"),
        (1e-06, 8.46e-05, "fast-oscillation"),
        (3.162277660168379e-07, 3.37e-05, "fast-oscillation"),
        (1e-07, 1.31e-05, "fast-oscillation"),
        (3.162277660168379e-08, 4.66e-06, "fast-oscillation"),
        (1e-08, 1.69e-06, "fast-oscillation"),
        (3.1622776601683795e-09, 7.04e-07, "slider-150s"),
        (1e-09, 2.2e-07, "slider-150s"),
        (3.1622776601683795e-10, 1.06e-07, "slider-150s"),
        (1e-10, 4.55e-08, "slider-150s"),
        (3.1622776601683794e-11, 1.39e-08, "slider-150s"),
        (1e-11, 5.13e-09, "slider-150s"),
        (3.1622776601683794e-12, 2.43e-09, "slider-150s"),
        (1e-12, 1.12e-09, "fast-oscillation"),
        (3.162277660168379e-13, 4.36e-10, "fast-oscillation"),
        (1e-13, 1.6e-10, "fast-oscillation"),
    ),
    ("pinocchio", "RK45"): (
        (0.001, 0.0173, "fast-oscillation"),
        (0.00031622776601683794, 0.00434, "fast-oscillation"),
        (0.0001, 0.0014, "fast-oscillation"),
        (3.1622776601683795e-05, 0.000419, "fast-oscillation"),
        (1e-05, 0.000141, "light-joint2"),
        (3.162277660168379e-06, 5.23e-05, "light-joint2"),
        (1e-06, 1.82e-05, "light-joint2"),
        (3.162277660168379e-07, 6.32e-06, "light-joint2"),
        (1e-07, 2.15e-06, "light-joint2"),
        (3.162277660168379e-08, 7.06e-07, "light-joint2"),
        (1e-08, 2.16e-07, "light-joint2"),
        (3.1622776601683795e-09, 6.52e-08, "light-joint2"),
        (1e-09, 1.98e-08, "light-joint2"),
        (3.1622776601683795e-10, 6.04e-09, "light-joint2"),
        (1e-10, 1.86e-09, "light-joint2"),
        (3.1622776601683794e-11, 5.75e-10, "light-joint2"),
        (1e-11, 1.79e-10, "fast-oscillation"),
        (3.1622776601683794e-12, 5.66e-11, "fast-oscillation"),
        (1e-12, 1.79e-11, "fast-oscillation"),
        (3.162277660168379e-13, 6.02e-12, "long-1000s"),
        (1e-13, 6.02e-12, "long-1000s"),
    ),
    ("compiled", "RK45"): (
        (0.001, 0.0173, "fast-oscillation"),
        (0.00031622776601683794, 0.00434, "fast-oscillation"),
        (0.0001, 0.0014, "fast-oscillation"),
        (3.1622776601683795e-05, 0.000419, "fast-oscillation"),
        (1e-05, 0.000141, "light-joint2"),
        (3.162277660168379e-06, 5.23e-05, "light-joint2"),
        (1e-06, 1.82e-05, "light-joint2"),
        (3.162277660168379e-07, 6.32e-06, "light-joint2"),
        (1e-07, 2.15e-06, "light-joint2"),
        (3.162277660168379e-08, 7.06e-07, "light-joint2"),
        (1e-08, 2.16e-07, "light-joint2"),
        (3.1622776601683795e-09, 6.52e-08, "light-joint2"),
        (1e-09, 1.98e-08, "light-joint2"),
        (3.1622776601683795e-10, 6.04e-09, "light-joint2"),
        (1e-10, 1.86e-09, "light-joint2"),
        (3.1622776601683794e-11, 5.75e-10, "light-joint2"),
        (1e-11, 1.79e-10, "fast-oscillation"),
        (3.1622776601683794e-12, 5.66e-11, "fast-oscillation"),
        (1e-12, 1.79e-11, "fast-oscillation"),
        (3.162277660168379e-13, 6.15e-12, "long-1000s"),
        (1e-13, 6.15e-12, "long-1000s"),
    ),
    ("pinocchio", "DOP853"): (
        (0.001, 0.00317, "fast-oscillation"),
        (0.00031622776601683794, 0.00169, "light-joint2"),
        (0.0001, 0.000157, "slider-150s"),
        (3.1622776601683795e-05, 5.64e-05, "fast-oscillation"),
        (1e-05, 2.12e-05, "fast-oscillation"),
        (3.162277660168379e-06, 1.08e-05, "ur5"),
        (1e-06, 2.33e-06, "fast-oscillation"),
        (3.162277660168379e-07, 1.02e-06, "fast-oscillation"),
        (1e-07, 2.95e-07, "fast-oscillation"),
        (3.162277660168379e-08, 1.29e-07, "fast-oscillation"),
        (1e-08, 4.1e-08, "fast-oscillation"),
        (3.1622776601683795e-09, 1.52e-08, "fast-oscillation"),
        (1e-09, 5.16e-09, "fast-oscillation"),
        (3.1622776601683795e-10, 6.92e-09, "long-1000s"),
        (1e-10, 4.96e-10, "fast-oscillation"),
        (3.1622776601683794e-11, 1.56e-10, "fast-oscillation"),
        (1e-11, 4.78e-11, "fast-oscillation"),
        (3.1622776601683794e-12, 1.46e-11, "fast-oscillation"),
        (1e-12, 9.54e-12, "light-joint2"),
        (3.162277660168379e-13, 9.54e-12, "light-joint2"),
        (1e-13, 9.54e-12, "light-joint2"),
    ),
    ("compiled", "DOP853"): (
        (0.001, 0.00308, "fast-oscillation"),
        (0.00031622776601683794, 0.00169, "light-joint2"),
        (0.0001, 0.000157, "slider-150s"),
        (3.1622776601683795e-05, 5.64e-05, "fast-oscillation"),
        (1e-05, 2.12e-05, "fast-oscillation"),
        (3.162277660168379e-06, 1.08e-05, "ur5"),
        (1e-06, 2.33e-06, "fast-oscillation"),
        (3.162277660168379e-07, 1.02e-06, "fast-oscillation"),
        (1e-07, 2.95e-07, "fast-oscillation"),
        (3.162277660168379e-08, 1.29e-07, "fast-oscillation"),
        (1e-08, 6.54e-08, "long-1000s"),
        (3.1622776601683795e-09, 1.52e-08, "fast-oscillation"),
        (1e-09, 5.16e-09, "fast-oscillation"),
        (3.1622776601683795e-10, 1.68e-09, "fast-oscillation"),
        (1e-10, 4.96e-10, "fast-oscillation"),
        (3.1622776601683794e-11, 1.56e-10, "fast-oscillation"),
        (1e-11, 4.78e-11, "fast-oscillation"),
        (3.1622776601683794e-12, 1.46e-11, "fast-oscillation"),
        (1e-12, 9.55e-12, "light-joint2"),
        (3.162277660168379e-13, 9.55e-12, "light-joint2"),
        (1e-13, 9.55e-12, "light-joint2"),
    ),
}
#: (backend, method) -> (k, p): the estimate's companion runs at k times the run's
#: rtol and atol, and the run's error is |q − q_companion| / (k^p − 1), p the
#: measured rate of error ∝ tolᵖ.
COMPANIONS: dict[tuple[str, str], tuple[float, float]] = {
    ("pinocchio", "odepack"): (0.1, 1.19),
    ("pinocchio", "RK45"): (100, 1),
    ("compiled", "RK45"): (100, 1),
    ("pinocchio", "DOP853"): (100, 0.962),
    ("compiled", "DOP853"): (0.1, 2.03),
}
