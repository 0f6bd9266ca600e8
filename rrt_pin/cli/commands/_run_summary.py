"""The summary of ``rrt-pin simulate``: the run's facts as data, and as text for people.

Pure functions of a result (:func:`summary`) and of those facts (:func:`summary_text`):
final distances to qf, settling times, peak efforts, the error estimate and the limit
events. Importing this module stays cheap (no numpy).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

if TYPE_CHECKING:
    from rrt_pin.robot.robot import Robot
    from rrt_pin.simulate import SimulationResult

__all__ = ["limit_lines", "summary", "summary_text"]


def _estimate_facts(robot: Robot, result: SimulationResult) -> dict | None:
    """The error estimate for the summary and --json (None when not computed)."""
    est = result.estimate
    if est is None:
        return None
    return {
        "max": float(est.max),
        "per_coordinate": [
            {"name": name, "value": float(e), "unit": unit}
            for name, e, unit in zip(result.q_names, est.q, robot.coordinate_units, strict=True)
        ],
        "accuracy": float(est.accuracy),
        "exceeded": bool(est.exceeded),
        "how": est.how,
        "wall_time": float(est.wall_time),
    }


def _estimate_line(facts: dict) -> str:
    est = facts.get("error_estimate")
    if est is None:
        why = facts.get("error_estimate_failure")
        return "estimated global error of q(t): not computed" + (f": {why}" if why else "")
    from rrt_pin.core.text import duration

    per = ", ".join(f"{e['name']} {e['value']:.2g} {e['unit']}" for e in est["per_coordinate"])
    verdict = "exceeds" if est["exceeded"] else "within"
    return (
        f"estimated global error of q(t), max over t: {per} ({verdict} the accuracy asked "
        f"for, {est['accuracy']:.2g} rad or m; companion run: {est['how']}, "
        f"{duration(est['wall_time'])})"
    )


def summary(robot: Robot, result: SimulationResult, regulator: str | None = None) -> dict:
    """The run's summary as data: final distances to qf, settling times, peak efforts.

    ``regulator``: the law's name (default the robot's regulator). Without a target
    (a passive run of a robot that has none) the distances and settling times are None.

    A pure function of the result; :func:`summary_text` prints it and ``--json``
    writes it.
    """
    import numpy as np

    from rrt_pin.simulate.metrics import SETTLING_BAND, settling_times

    t, q, tau = result.t, result.q, result.tau
    qf = robot.defaults.qf
    q0 = robot.defaults.q0 if robot.defaults.q0 is not None else q[0]
    settled = settling_times(t, q, q0, qf) if qf is not None else [None] * q.shape[1]
    joints = [
        {
            "name": name,
            "unit": robot.coordinate_units[k],
            "q_tf": float(q[-1, k]),
            "qf": None if qf is None else float(qf[k]),
            "distance": None if qf is None else float(abs(q[-1, k] - qf[k])),
            "settled_at": None if settled[k] is None else float(settled[k]),
        }
        for k, name in enumerate(result.q_names)
    ]
    peaks = []
    for k, name in enumerate(result.tau_names):
        i = int(np.argmax(np.abs(tau[:, k])))
        peaks.append(
            {"name": name, "unit": robot.effort_units[k], "peak": float(abs(tau[i, k])),
             "t": float(t[i])}
        )  # fmt: skip
    return {
        "command": "simulate",
        "robot": robot.name,
        "regulator": regulator or robot.regulator,
        "samples": int(t.size),
        "t0": float(t[0]),
        "tf": float(t[-1]),
        "method": result.method,
        "backend": result.backend,
        "rtol": result.rtol,
        "atol": result.atol,
        "step": result.step,
        "evaluations": int(result.n_evals),
        "wall_time": float(result.wall_time),
        "error_estimate": _estimate_facts(robot, result),
        "error_estimate_failure": result.estimate_failure,
        "settling_band": SETTLING_BAND,
        "joints": joints,
        "peaks": peaks,
        "limits": [e.as_dict() for e in getattr(result, "limits", ()) or ()],
    }


def summary_text(facts: dict) -> str:
    """The summary for people: final distance to qf, 2 % settling time, peak efforts."""
    from rrt_pin.core.text import duration

    tol = (
        f"rtol {facts['rtol']:g}, atol {facts['atol']:g}"
        if facts["rtol"]
        else f"step {facts['step']:g} s"
    )
    if facts.get("tolerances") == "chosen for the accuracy":
        tol += f", chosen for accuracy {facts['accuracy']:g} rad or m"
    lines = [
        f"simulated the {facts['robot']} under {facts['regulator']}: {facts['samples']} samples, "
        f"t = {facts['t0']:g} .. {facts['tf']:g} s, method {facts['method']} ({tol}), "
        f"backend {facts['backend']}, {facts['evaluations']} evaluations, "
        f"{duration(facts['wall_time'])}",
        _estimate_line(facts),
        f"{'joint':<24} {'q(tf)':>14} {'qf':>14} {'|q(tf) - qf|':>16}  {'settled (2 %) at t':>18}",
    ]
    for j in facts["joints"]:
        when = f"{j['settled_at']:.6g} s" if j["settled_at"] is not None else "not settled"
        if j["qf"] is None:
            lines.append(f"{j['name']:<24} {j['q_tf']:>14.10g} {'-':>14} {'-':>12} {j['unit']:<3}")
            continue
        lines.append(
            f"{j['name']:<24} {j['q_tf']:>14.10g} {j['qf']:>14.10g} "
            f"{j['distance']:>12.3e} {j['unit']:<3}  {when:>18}"
        )
    lines.append(f"{'effort':<24} {'peak |effort|':>16}  {'at t [s]':>10}")
    for p in facts["peaks"]:
        lines.append(f"{p['name']:<24} {p['peak']:>12.6g} {p['unit']:<3}  {p['t']:>10.6g}")
    lines.extend(limit_lines(facts))
    return "\n".join(lines) + "\n"


def limit_lines(facts: dict) -> list[str]:
    """The summary's limit events, one line each (none for a robot that states no limit)."""
    physical = facts.get("physical") or {}
    if not physical.get("lower") and not facts.get("limits"):
        return []
    events = facts.get("limits") or []
    if not events:
        return ["limits: none crossed at the output samples"]
    lines = [
        f"limits crossed at the output samples ({len(events)}; the URDF's, enforced or not):",
        f"{'joint':<24} {'kind':<9} {'first at t':>12}  {'extent':>22}  {'count':>5}  "
        f"{'saturated for':>13}",
    ]
    what = {"position": "past by", "effort": "peak demand", "velocity": "peak"}
    for e in events:
        extent = f"{what[e['kind']]} {e['extent']:.4g} {e['unit']}"
        saturated = "" if e["saturated_time"] is None else f"{e['saturated_time']:.6g} s"
        lines.append(
            f"{e['joint']:<24} {e['kind']:<9} {e['first_time']:>10.6g} s  {extent:>22}  "
            f"{e['count']:>5}  {saturated:>12}".rstrip()
        )
    return lines
