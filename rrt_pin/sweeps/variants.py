"""What a sweep varies, by robot: the names, their base values, and each variant's run.

A family answers, for one kind of robot, everything a sweep asks of it; the rest of
:mod:`rrt_pin.sweeps` runs every robot alike (:func:`rrt_pin.simulate.simulate_batch`,
:func:`rrt_pin.dynamics.inverse.inverse_dynamics`). Two families:

* :class:`ChapterFamily`: the chapter's arm, whose every :class:`~rrt_pin.robot.params.Params`
  field may vary (masses, lengths, inertias, gains, starts, targets); a variant is its
  own arm under the chapter's law, eq. (31).
* :class:`JointFamily`: any other robot (a URDF, or one known by name), whose starts,
  targets and gains vary joint by joint (``q0_1``, ``kp_3``, …) under PD plus gravity.

:func:`family_for` is the one place a sweep asks which robot it has.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields
from typing import Any

import numpy as np

from rrt_pin.core import text
from rrt_pin.core.errors import RrtPinError, SpecError
from rrt_pin.robot.params import PARAM_DOCS, Params, check_columns, checked
from rrt_pin.robot.robot import Robot
from rrt_pin.robot.robots import chapter_arm
from rrt_pin.simulate.control import ChapterController, PDGravityController
from rrt_pin.sweeps.spec import Spec

__all__ = ["ChapterFamily", "JointFamily", "Variants", "family_for"]

#: The per-joint names of :class:`JointFamily`: start, start velocity, target, gains.
PREFIXES = ("q0", "qd0", "qf", "kp", "kd")


@dataclass(frozen=True, eq=False)
class Variants:
    """``count`` variants of a chunk, as runs.

    Attributes:
        q0, qd0, qf: starts [rad or m], start velocities [rad/s or m/s] and targets
            [rad or m], (count, nv).
        Tp: the rest-to-rest motion's duration of each variant (inverse dynamics) [s].
        laws: each variant's law (None where invalid, or when no law was asked for).
        bad: the variants whose values are invalid (not run).
        why: why each is invalid (None where it is not).
        params: each variant's own parameters (:class:`ChapterFamily`), else None.
    """

    q0: np.ndarray
    qd0: np.ndarray
    qf: np.ndarray
    Tp: np.ndarray
    laws: list[Any]
    bad: np.ndarray
    why: list[str | None]
    params: list[Params | None] | None = None

    def robot(self, i: int, shared: Robot) -> Robot:
        """Variant ``i``'s robot: its own when it has parameters of its own, else ``shared``."""
        if self.params is None:
            return shared
        own = self.params[i]
        assert own is not None, "an invalid variant has no robot"
        return chapter_arm(own)


class ChapterFamily:
    """The chapter's arm: every Params field may vary; a variant is its own arm."""

    def start(self, spec: Spec) -> tuple[Robot, tuple[str, ...], dict[str, float]]:
        """The robot (built from the base values), the names that may vary, their base values.

        Raises:
            SpecError: an unknown name or an invalid value in ``[base]``.
        """
        names = [f.name for f in fields(Params)]
        for name in spec.base:
            if name not in names:
                raise SpecError(f"[base] {name}: unknown parameter; valid: {text.names(names, 20)}")
        try:
            params = Params(**spec.base)
        except RrtPinError as e:
            raise SpecError(f"[base]: {e}") from e
        return chapter_arm(params), tuple(names), {n: getattr(params, n) for n in names}

    def check_ends(self, spec: Spec, name: str, values: np.ndarray) -> None:
        """Refuse an axis whose ends make the arm invalid (a negative mass).

        Raises:
            SpecError: naming the axis, the value and why.
        """
        for value in values:
            try:
                Params(**{**spec.base, name: float(value)})
            except RrtPinError as e:
                raise SpecError(f"[vary] {name} reaches {float(value):g}: {e}") from e

    def units(self, spec: Spec) -> dict[str, str]:  # noqa: ARG002  (every field has one)
        """The unit of every name that may vary, as the output's metadata writes it."""
        return {
            name: doc.rsplit("[", 1)[-1].split("]")[0] if "[" in doc else ""
            for name, doc in PARAM_DOCS.items()
        }

    def table(
        self, base: dict[str, float], spec: Spec, values: dict[str, np.ndarray], count: int
    ) -> tuple[dict[str, np.ndarray], np.ndarray, list[str | None]]:
        """Every Params field of ``count`` variants, and which are invalid (with why).

        Rod inertias left at their defaults follow the varied masses and lengths, as in
        :class:`~rrt_pin.robot.params.Params`; the checks are Params'
        (:func:`~rrt_pin.robot.params.check_columns`).
        """
        explicit = set(spec.base) | set(values)
        table = {n: np.broadcast_to(values.get(n, base[n]), (count,)).astype(float) for n in base}
        for rod, m, L in (("1", "m1", "L1"), ("2", "m2", "L2")):
            for axis in ("x", "y"):
                name = f"I{rod}{axis}"
                if name not in explicit:
                    with np.errstate(over="ignore", invalid="ignore"):
                        table[name] = table[m] * table[L] ** 2 / 3.0
        bad, why = check_columns(table)
        return table, bad, why

    def build(
        self, base: dict[str, float], spec: Spec, robot: Robot, values: dict[str, np.ndarray],
        count: int, laws: bool,
    ) -> Variants:  # fmt: skip
        """The variants' runs: each valid one its own Params (and law, if ``laws``)."""
        table, bad, why = self.table(base, spec, values, count)
        names = tuple(table)
        rows = zip(*(col.tolist() for col in table.values()), strict=True)
        params: list[Params | None] = [
            None if b else checked(dict(zip(names, row, strict=True)))
            for b, row in zip(bad.tolist(), rows, strict=True)
        ]
        made = [
            None if p is None or not laws
            else ChapterController.of(p)
            for p in params
        ]  # fmt: skip

        def cols(*names: str) -> np.ndarray:
            return np.column_stack([table[n] for n in names])

        return Variants(
            q0=cols("q10", "q20", "q30"), qd0=cols("qd10", "qd20", "qd30"),
            qf=cols("q1f", "q2f", "q3f"), Tp=table["Tp"], laws=made, bad=bad, why=why,
            params=params,
        )  # fmt: skip


class JointFamily:
    """Any other robot: starts, targets and gains vary joint by joint, under PD plus gravity."""

    def start(self, spec: Spec) -> tuple[Robot, tuple[str, ...], dict[str, float]]:
        """The robot, the names that may vary (``q0_1`` …), their base values (NaN: none).

        Raises:
            SpecError: a name or a value count in ``[base]`` that does not fit the robot.
        """
        robot = Robot.from_urdf(spec.urdf_file(), g=float(spec.base.get("g", 9.81)))
        n = robot.nv
        names = tuple(f"{p}_{k}" for p in PREFIXES for k in range(1, n + 1))
        base = {name: math.nan for name in names}
        base.update({f"qd0_{k}": 0.0 for k in range(1, n + 1)})
        for key, value in spec.base.items():
            if key == "g":
                continue
            if key not in PREFIXES:
                raise SpecError(f"[base] {key}: a URDF sweep takes g, {', '.join(PREFIXES)}")
            given = [value] * n if not isinstance(value, list) else value
            if len(given) != n:
                raise SpecError(
                    f"[base] {key} has {len(given)} values; {robot.name} has {n} joints"
                )
            base.update({f"{key}_{k + 1}": float(v) for k, v in enumerate(given)})
        return robot, names, base

    def check_ends(self, spec: Spec, name: str, values: np.ndarray) -> None:
        """Refuse a gain axis that reaches below 0.

        Raises:
            SpecError: naming the axis and its low end.
        """
        low = float(np.min(values))
        if name.startswith(("kp", "kd")) and low < 0:
            raise SpecError(f"[vary] {name} reaches {low:g}: a gain must be >= 0")

    def units(self, spec: Spec) -> dict[str, str]:
        """The varied names' units in the output's metadata (none: they differ by joint)."""
        return {a.name: "" for a in spec.axes}

    def build(
        self, base: dict[str, float], spec: Spec, robot: Robot, values: dict[str, np.ndarray],
        count: int, laws: bool,
    ) -> Variants:  # fmt: skip
        """The variants' runs: the shared robot, each variant's PD plus gravity law."""
        n = robot.nv
        cols = {
            k: np.column_stack([
                np.broadcast_to(values.get(f"{k}_{j}", base[f"{k}_{j}"]), (count,))
                for j in range(1, n + 1)
            ]).astype(float)
            for k in PREFIXES
        }  # fmt: skip
        bad = (cols["kp"] < 0).any(axis=1) | (cols["kd"] < 0).any(axis=1)
        why: list[str | None] = ["a gain is negative" if b else None for b in bad]
        made = [
            None if bad[i] or not laws
            else PDGravityController(kp=cols["kp"][i], kd=cols["kd"][i], qf=cols["qf"][i],
                                     model=robot.model, robot=robot)
            for i in range(count)
        ]  # fmt: skip
        Tp = np.full(count, float(spec.base.get("Tp", spec.tf)))
        return Variants(cols["q0"], cols["qd0"], cols["qf"], Tp, made, bad, why)


def family_for(spec: Spec) -> ChapterFamily | JointFamily:
    """The family of the spec's robot: the chapter's arm (no URDF, no other name) or a joint one."""
    return ChapterFamily() if spec.chapter_arm else JointFamily()
