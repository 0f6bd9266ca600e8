"""SciPy's BDF in any robot's compiled integrators (``method="BDF", backend="compiled"``).

Its runs are checked against SciPy's own ``solve_ivp(method="BDF")`` on the Pinocchio
backend (the same steps: the same evaluations, the same states to rounding), given the
same Jacobian: the generated one of the PD-plus-gravity loop against Pinocchio's
``computeABADerivatives``, or SciPy's finite differences on both; and against an
independent computation, the compiled DOP853 at rtol 1e-13. One robot (UR5) keeps the
module's compilation to once.
"""

from __future__ import annotations

import numpy as np
import pytest

pytest.importorskip("numba")

import rrt_pin  # noqa: E402
from rrt_pin.core.errors import DivergenceError, InputError  # noqa: E402
from rrt_pin.dynamics.trajectory import Trajectory  # noqa: E402
from rrt_pin.robot.robot import Robot  # noqa: E402
from rrt_pin.simulate import methods  # noqa: E402
from rrt_pin.simulate.control import pd_gravity_controller, tracking_controller  # noqa: E402
from tests.support import robot_urdf  # noqa: E402

T = np.linspace(0.0, 2.0, 201)
Q0 = np.array([0.3, -1.0, 1.0, 0.3, 0.5, 0.0])
QF = np.array([0.0, -1.2, 1.2, -1.0, -1.2, 0.0])
#: The law alone (no effort limits, position limits or losses).
LAW_ONLY = {"effort_limits": False, "position_limits": False, "losses": False}
#: How far the two backends' states may differ: the same steps, rounded otherwise
#: (SciPy's BLAS and LAPACK sum in another order) [rad, m, rad/s, m/s].
SAME_STEPS = 1e-9


@pytest.fixture(scope="module")
def ur5() -> Robot:
    return Robot.from_urdf(robot_urdf("ur5"))


def _pd(robot: Robot, gain: float = 400.0):
    """Stiff gains (fastest mode ~ −40 s⁻¹ on the light wrists): BDF's raises its order."""
    return pd_gravity_controller(robot, kp=gain, kd=2.0 * np.sqrt(gain), qf=QF)


def _run(robot, law, backend, rtol, t=T, q0=Q0, method="BDF", **options):
    options = {**LAW_ONLY, **options}
    return rrt_pin.simulate(robot, law, q0, None, t, backend=backend, method=method, rtol=rtol,
                            atol=rtol / 100, estimate_error=False, **options)  # fmt: skip


def _same_steps(fast, scipy):
    assert fast.n_evals == scipy.n_evals
    assert np.abs(fast.q - scipy.q).max() <= SAME_STEPS
    assert np.abs(fast.qd - scipy.qd).max() <= 100 * SAME_STEPS


@pytest.fixture(scope="module")
def reference(ur5):
    return _run(ur5, _pd(ur5), "compiled", 1e-13, method="DOP853")


def test_bdf_runs_on_both_backends():
    m = methods.get("BDF")
    assert m.implicit and m.code is not None
    assert m.runs_on("pinocchio") and m.runs_on("compiled") and m.runs_on("compiled", batch=True)
    assert m.rtol == methods.tolerances("pinocchio", "BDF")[0]  # its default unchanged


@pytest.mark.parametrize("rtol", [1e-5, 1e-8, 1e-10])
def test_step_for_step_with_scipys_bdf(ur5, rtol):
    """The generated Jacobian against Pinocchio's: the same evaluations, the same states."""
    law = _pd(ur5)
    fast, scipy = _run(ur5, law, "compiled", rtol), _run(ur5, law, "pinocchio", rtol)
    assert fast.backend == "compiled" and scipy.backend == "pinocchio"
    _same_steps(fast, scipy)
    assert fast.n_evals > 50  # it stepped (no trivial agreement)


def test_step_for_step_with_finite_differences(ur5):
    """jacobian='finite-difference' on both: SciPy's num_jac, its evaluations counted."""
    law = _pd(ur5)
    fast = _run(ur5, law, "compiled", 1e-8, jacobian="finite-difference")
    scipy = _run(ur5, law, "pinocchio", 1e-8, jacobian="finite-difference")
    _same_steps(fast, scipy)
    analytic = _run(ur5, law, "compiled", 1e-8)
    assert fast.n_evals >= analytic.n_evals + 2 * ur5.nv + 1  # the Jacobian's evaluations
    assert np.abs(fast.q - analytic.q).max() < 1e-6


def test_a_law_without_a_generated_jacobian_takes_finite_differences(ur5):
    """No effort (passive motion): finite differences on compiled, as SciPy's with jacobian=None."""
    fast = _run(ur5, None, "compiled", 1e-8)
    scipy = _run(ur5, None, "pinocchio", 1e-8, jacobian="finite-difference")
    _same_steps(fast, scipy)


def test_the_physical_model_takes_finite_differences(ur5):
    """Effort limits, position limits and losses: no generated Jacobian of them, SciPy's num_jac."""
    physical = {"effort_limits": True, "position_limits": True, "losses": True}
    law = _pd(ur5)
    fast = _run(ur5, law, "compiled", 1e-8, **physical)
    scipy = _run(ur5, law, "pinocchio", 1e-8, jacobian="finite-difference", **physical)
    _same_steps(fast, scipy)
    assert np.abs(fast.q - _run(ur5, law, "compiled", 1e-8).q).max() > 1e-6  # it applied them


def test_a_tracking_law_takes_finite_differences(ur5):
    """Computed torque along a sampled motion: SciPy's finite differences on both backends.

    Not step for step: the efforts M(q)·x + b(q, q̇) round differently from Pinocchio's,
    the finite differences (steps ~1e-8 of the state) magnify that to ~1e-8 of J, and the
    reference interpolated linearly puts a kink at every sample, where Newton's decisions
    sit at their thresholds: a few steps part (6,045 against 6,059 evaluations here).
    """
    t = np.linspace(0.0, 1.0, 101)
    q = Q0 + 0.2 * np.sin(np.pi * t)[:, None]
    qd = 0.2 * np.pi * np.cos(np.pi * t)[:, None] * np.ones(6)
    qdd = -0.2 * np.pi**2 * np.sin(np.pi * t)[:, None] * np.ones(6)
    law = tracking_controller(ur5, Trajectory(t=t, q=q, qd=qd, qdd=qdd), kp=400.0, kd=40.0)
    fast = _run(ur5, law, "compiled", 1e-8, t=t)
    scipy = _run(ur5, law, "pinocchio", 1e-8, t=t, jacobian="finite-difference")
    assert abs(fast.n_evals - scipy.n_evals) <= 0.05 * scipy.n_evals
    assert np.abs(fast.q - scipy.q).max() <= 1e-7
    assert np.abs(fast.q - q).max() < 0.05  # it tracked


def test_it_converges_as_rtol_shrinks(ur5, reference):
    law = _pd(ur5)
    errors = [np.abs(_run(ur5, law, "compiled", r).q - reference.q).max()
              for r in (1e-5, 1e-7, 1e-9, 1e-11)]  # fmt: skip
    assert all(tight < loose / 5.0 for loose, tight in zip(errors, errors[1:], strict=False))
    assert errors[-1] < 1e-9


def test_the_accuracy_asked_is_kept(ur5, reference):
    fast = rrt_pin.simulate(ur5, _pd(ur5), Q0, None, T, backend="compiled", method="BDF",
                            estimate_error=False, **LAW_ONLY)  # fmt: skip
    assert fast.rtol == methods.get("BDF").rtol
    assert np.abs(fast.q - reference.q).max() <= methods.ACCURACY


def test_a_nonfinite_law_is_reported(ur5):
    """Efforts of 1e308 N·m: q̈ overflows at the first evaluation."""
    law = pd_gravity_controller(ur5, kp=1e308, kd=0.0, qf=Q0 - 1.0)
    with pytest.raises(DivergenceError) as e:
        _run(ur5, law, "compiled", 1e-8)
    assert e.value.t == 0.0
    assert any(name in str(e.value) for name in (*ur5.q_names, *ur5.qd_names))


@pytest.mark.parametrize("keep", ["trajectories", "final", "metrics"])
def test_batch_rows_equal_single_runs(ur5, keep):
    laws = [_pd(ur5, g) for g in (50.0, 400.0)]
    q0s = Q0 + np.array([[-0.1], [0.1]])
    batch = rrt_pin.simulate_batch(ur5, laws, q0s, None, T, backend="compiled", method="BDF",
                                   keep=keep, rtol=1e-8, atol=1e-10, estimate_error=False,
                                   threads=2, **LAW_ONLY)  # fmt: skip
    assert batch.method == "BDF"
    for b in range(2):
        one = _run(ur5, laws[b], "compiled", 1e-8, q0=q0s[b])
        assert np.array_equal(batch.q[b], one.q if keep == "trajectories" else one.q[-1:])
        assert batch.evaluations[b] == one.n_evals


def test_the_chapters_arm_kernel_refuses_it():
    from rrt_pin.robot.robots import chapter_arm

    arm = chapter_arm()
    with pytest.raises(InputError, match="BDF"):
        rrt_pin.simulate(arm, None, np.zeros(3), None, T, backend="compiled", method="BDF")


def test_a_bdf_run_compiles_its_entry_alone(ur5, monkeypatch):
    """A single run or a batch with method='BDF' asks for its own entry only (not
    run_many): under PD plus gravity its law-bound copy, else the general one."""
    from rrt_pin.compiled import robot_code, robot_runs
    from rrt_pin.simulate.options import resolve

    asked = []

    class Code:  # stands for a robot's code not compiled yet: records what is compiled
        def entry(self, name):
            asked.append(name)

    monkeypatch.setattr(robot_code, "integrators_for", lambda model, name=None: Code())
    options = resolve(T, backend="compiled", method="BDF", rtol=1e-9, atol=1e-11)
    robot_runs.prepare(ur5, [_pd(ur5)], options)
    robot_runs.prepare(ur5, [_pd(ur5), _pd(ur5)], options)
    robot_runs.prepare(ur5, [_pd(ur5), None], options)
    assert asked == ["run_bdf_pd", "run_bdf_pd", "run_bdf"]
    # where every Jacobian is numerical, the entry without the generated one
    from rrt_pin.robot.limits import physical_model

    applied = physical_model(ur5)
    assert applied.active
    numeric = resolve(T, backend="compiled", method="BDF", rtol=1e-9, atol=1e-11,
                      jacobian="finite-difference")  # fmt: skip
    robot_runs.prepare(ur5, [_pd(ur5)], options, applied)
    robot_runs.prepare(ur5, [_pd(ur5)], numeric)
    robot_runs.prepare(ur5, [None, None], options)
    robot_runs.prepare(ur5, [_pd(ur5), None], options, applied)
    assert asked[3:] == ["run_bdf_num_pd", "run_bdf_num_pd", "run_bdf_num", "run_bdf_num"]


@pytest.mark.parametrize("method", ["BDF", "adams"])
def test_auto_never_sends_the_arm_a_method_its_kernel_refuses(method, monkeypatch):
    """Even with the arm's machine code loaded, auto keeps a generated-only method off it."""
    from rrt_pin import compiled
    from rrt_pin.core import backends
    from rrt_pin.robot.robots import chapter_arm

    monkeypatch.setattr(compiled, "state_for", lambda *args: (True, False, True))  # loaded
    arm = chapter_arm()
    choice = backends.choose(arm, "simulate", method, 15.0, controllers=[None])
    assert choice.name == "pinocchio" and "chapter's arm's own kernel" in choice.reason
    assert backends.choose(arm, "simulate", "DOP853", 15.0, controllers=[None]).name == "compiled"


def test_auto_counts_a_method_ready_only_when_its_own_entry_is(monkeypatch):
    """A robot whose run_many is built but not run_bdf: auto does not wait for BDF's compile."""
    from rrt_pin.compiled import robot_code, robot_entries
    from rrt_pin.core import backends
    from rrt_pin.robot import robots

    ur5 = robots.get("ur5")
    seen = []

    def state(model, batch=False, code=None, pd=False, numeric=False):  # noqa: ANN001, ANN202
        seen.append(code)
        laws.append(pd)
        return False, False, code not in robot_entries.OWN_ENTRY  # run_many built, not run_bdf

    laws = []
    monkeypatch.setattr(robot_code, "state", state)
    assert backends.choose(ur5, "simulate", "BDF", 1e6, controllers=[None]).name == "pinocchio"
    assert backends.choose(ur5, "simulate", "DOP853", 1e6, controllers=[None]).name == "compiled"
    assert (
        robot_entries.OWN_ENTRY.get(seen[0]) == "run_bdf" and seen[1] not in robot_entries.OWN_ENTRY
    )
    # the laws tell which entry: PD plus gravity's own, else the general one
    backends.choose(ur5, "simulate", "DOP853", 1e6, controllers=[_pd(ur5)])
    assert laws == [False, False, True]


def test_auto_looks_at_the_bdf_entry_the_run_will_take(ur5, monkeypatch):
    """BDF's entry differs by its Jacobian (generated, or numerical under a physical model
    or finite differences): auto asks for the one the run takes; not knowing, for both."""
    from rrt_pin.compiled import robot_code, robot_entries
    from rrt_pin.simulate import codes

    seen = []

    def state(model, batch=False, code=None, pd=False, numeric=False):  # noqa: ANN001, ANN202
        seen.append((pd, numeric))
        return False, False, False  # nothing built: the runs below take Pinocchio

    monkeypatch.setattr(robot_code, "state", state)
    off = {"effort_limits": False, "position_limits": False, "losses": False}
    t = np.linspace(0.0, 0.02, 3)
    for kw in ({}, off, {"jacobian": "finite-difference", **off}):
        run = rrt_pin.simulate(ur5, _pd(ur5), np.full(6, 0.1), None, t, method="BDF",
                               backend="auto", estimate_error=False, **kw)  # fmt: skip
        assert run.backend == "pinocchio"
    assert seen == [(True, True), (True, False), (True, True)]
    bdf = codes.METHOD_BDF
    assert robot_entries.pd_entries(bdf, False, True, None) == (
        ("run_bdf_pd",),
        ("run_bdf_num_pd",),
    )
    assert robot_entries.pd_entries(bdf, True, False, True) == (("run_bdf_num",),)
    assert robot_entries.pd_entries(None, True, True) == (("run_lanes", "run_adaptive_pd"),)


def test_a_bdf_run_under_a_physical_model_asks_for_the_numerical_entry_alone(ur5, monkeypatch):
    """Under the URDF's limits (the default) BDF's Jacobian is numerical: the run asks for
    run_bdf_num_pd only, at every step of the way (nothing generated to compile)."""
    from rrt_pin.compiled import robot_code

    asked = []
    entry = robot_code.RobotCode.entry

    def recording(self, name):  # noqa: ANN001, ANN202
        asked.append(name)
        return entry(self, name)

    monkeypatch.setattr(robot_code.RobotCode, "entry", recording)
    t = np.linspace(0.0, 0.05, 6)
    rrt_pin.simulate(ur5, _pd(ur5), np.full(6, 0.1), None, t, method="BDF", backend="compiled",
                     estimate_error=False)  # fmt: skip
    rrt_pin.simulate_batch(ur5, _pd(ur5), np.full((2, 6), 0.1), None, t, method="BDF",
                           backend="compiled", estimate_error=False)  # fmt: skip
    assert set(asked) == {"run_bdf_num_pd"}
