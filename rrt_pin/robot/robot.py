"""One description of a robot, the chapter's RRT arm or any fixed-base URDF.

A :class:`Robot` knows its joints (name, kind, unit), the names and units of
its coordinate, velocity, acceleration and effort columns, its defaults (the
chapter's q0, qf, gains and Tp for the arm), the parameters and backends it
accepts, and how its joint coordinates map to Pinocchio's configuration
vector. Its Pinocchio model is built on first use, so a run on the arm's
closed-form kernels never imports Pinocchio.

Joint coordinates are one number per velocity degree of freedom: the angle of
a revolute or continuous joint [rad], the displacement of a prismatic one [m].
Pinocchio stores a continuous joint as (cos θ, sin θ), so its ``q`` has more
entries than ``v`` (nq > nv); :meth:`Robot.configuration` and
:meth:`Robot.coordinates` convert, and every result, CSV and controller of
rrt_pin speaks joint coordinates.
"""

from __future__ import annotations

import functools
import warnings
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Any

import numpy as np

from rrt_pin.core import backends, validate
from rrt_pin.core.errors import InputError, UrdfError

if TYPE_CHECKING:
    import pinocchio as pin

    from rrt_pin.robot.params import Params

__all__ = [
    "CHAPTER_COLUMNS", "JOINT_KINDS", "Joint", "Robot", "RobotDefaults", "bare_model",
    "params_given",
]  # fmt: skip

#: The chapter's column names: coordinates, velocities, accelerations, efforts.
CHAPTER_COLUMNS = (
    ("q1", "q2", "q3"),
    ("qd1", "qd2", "qd3"),
    ("qdd1", "qdd2", "qdd3"),
    ("T01x", "T12y", "F23z"),
)

#: Joint kinds a Robot handles: (unit of the coordinate, unit of the effort).
JOINT_KINDS: dict[str, tuple[str, str]] = {
    "revolute": ("rad", "N·m"),
    "continuous": ("rad", "N·m"),
    "prismatic": ("m", "N"),
    "helical": ("rad", "N·m"),
    "translation": ("m", "N"),
}

_RATE = {"rad": "rad/s", "m": "m/s"}
_ACCEL = {"rad": "rad/s²", "m": "m/s²"}


def _kind(shortname: str) -> str | None:
    """The kind of a Pinocchio joint model (``JointModelRX`` -> ``revolute``), or None."""
    if shortname.startswith(("JointModelRUB", "JointModelRevoluteUnbounded")):
        return "continuous"
    if shortname in ("JointModelRX", "JointModelRY", "JointModelRZ") or shortname.startswith(
        "JointModelRevolute"
    ):
        return "revolute"
    if shortname in ("JointModelPX", "JointModelPY", "JointModelPZ") or shortname.startswith(
        "JointModelPrismatic"
    ):
        return "prismatic"
    if shortname.startswith("JointModelHelical"):
        return "helical"
    if shortname == "JointModelTranslation":
        return "translation"
    return None


@dataclass(frozen=True)
class Joint:
    """One joint of a robot.

    Attributes:
        name: the joint's name (URDF) or the chapter's (``q1``).
        kind: one of :data:`JOINT_KINDS`.
        nq: entries in Pinocchio's configuration (2 for a continuous joint).
        nv: degrees of freedom (coordinates).
        idx_q: first index in Pinocchio's configuration vector.
        idx_v: first index in the velocity vector (= in the joint coordinates).
        effort_doc: what the joint's effort is, for plot titles (may be empty).
    """

    name: str
    kind: str
    nq: int = 1
    nv: int = 1
    idx_q: int = 0
    idx_v: int = 0
    effort_doc: str = ""

    @property
    def unit(self) -> str:
        """Unit of the coordinate: ``rad`` or ``m``."""
        return JOINT_KINDS[self.kind][0]

    @property
    def effort_unit(self) -> str:
        """Unit of the effort: ``N·m`` or ``N``."""
        return JOINT_KINDS[self.kind][1]


@dataclass(frozen=True)
class RobotDefaults:
    """A robot's default task: start, target, gains of its regulator, motion time.

    Any field may be None (a URDF has no defaults but ``qd0 = 0``).

    Attributes:
        q0: initial coordinates [rad or m].
        qd0: initial velocities [rad/s or m/s].
        qf: target coordinates [rad or m].
        kp: stiffness gains [N·m/rad or N/m].
        kd: damping gains [N·m·s/rad or N·s/m].
        Tp: duration of the rest-to-rest motion, eq. (30) [s].
    """

    q0: tuple[float, ...] | None = None
    qd0: tuple[float, ...] | None = None
    qf: tuple[float, ...] | None = None
    kp: tuple[float, ...] | None = None
    kd: tuple[float, ...] | None = None
    Tp: float | None = None


@dataclass(frozen=True, eq=False)
class Robot:
    """A robot: joints, column names, units, defaults, backends and its Pinocchio model.

    Build one with :func:`rrt_pin.robot.robots.chapter_arm` (the chapter's RRT arm),
    :meth:`Robot.from_urdf` or :meth:`Robot.from_model`; don't call the
    constructor directly.

    Attributes:
        name: a short name for titles and summaries (``RRT arm``, the URDF's robot name).
        joints: the moving joints, in Pinocchio's order.
        q_names, qd_names, qdd_names, effort_names: column names, one per coordinate.
        defaults: the default task (:class:`RobotDefaults`).
        backends: backends that compute every task of theirs for this robot (see
            :mod:`rrt_pin.core.backends`).
        inverse_backends: further backends that compute it from code generated from its
            model: inverse dynamics and simulations (``compiled``'s generated RNEA and
            integrators, when every joint is revolute, prismatic or continuous).
        parameters: the chapter's symbols that apply to it (``--set`` accepts only these).
        params: the arm's :class:`~rrt_pin.robot.params.Params` (None for a URDF).
        source: the URDF file, or None for the generated arm.
        layout: ``chapter`` for the RRT arm's columns and frames, else ``generic``.
        regulator: the name of its default feedback law, for summaries.
        motion: the name of its default prescribed motion, for summaries.
    """

    name: str
    joints: tuple[Joint, ...]
    q_names: tuple[str, ...]
    qd_names: tuple[str, ...]
    qdd_names: tuple[str, ...]
    effort_names: tuple[str, ...]
    defaults: RobotDefaults
    backends: tuple[str, ...]
    parameters: tuple[str, ...]
    params: Params | None = None
    inverse_backends: tuple[str, ...] = ()
    source: Path | None = None
    layout: str = "generic"
    regulator: str = "PD plus gravity compensation"
    motion: str = "a rest-to-rest motion from q0 to qf"
    _model: Any = field(default=None, repr=False)
    _build: Any = field(default=None, repr=False)

    # ------------------------------------------------------------------ construction
    @classmethod
    def from_urdf(
        cls,
        path: str | Path,
        g: float = 9.81,
        *,
        q0: Any = None,
        qf: Any = None,
        kp: Any = None,
        kd: Any = None,
        Tp: float | None = None,
    ) -> Robot:
        """A robot from a URDF file, with gravity (0, 0, −g) in its world frame [m/s²].

        Raises:
            UrdfError: the file does not describe a usable fixed-base robot.
        """
        from rrt_pin.robot.model import load_urdf_model

        model = load_urdf_model(path)
        model.gravity.linear[:] = (0.0, 0.0, -float(g))
        return cls.from_model(model, source=Path(path), q0=q0, qf=qf, kp=kp, kd=kd, Tp=Tp)

    @classmethod
    def from_model(
        cls,
        model: pin.Model,
        *,
        name: str | None = None,
        source: Path | None = None,
        q0: Any = None,
        qf: Any = None,
        kp: Any = None,
        kd: Any = None,
        Tp: float | None = None,
    ) -> Robot:
        """A robot around an existing Pinocchio model (kept as given, gravity included).

        Columns are ``q_<joint>``, ``qd_<joint>``, ``qdd_<joint>``, ``tau_<joint>``;
        a model laid out as the chapter's arm (joints ``q1, q2, q3``: revolute,
        revolute, prismatic) keeps the chapter's names (``q1``, ``T01x`` …).

        Raises:
            InputError: ``model`` is not a Pinocchio model.
            UrdfError: a joint is of a kind rrt_pin does not handle (floating,
                planar, spherical).
        """
        import pinocchio

        if not isinstance(model, pinocchio.Model):
            raise InputError(f"model must be a pinocchio.Model, not {type(model).__name__}")
        joints = _joints_of(model)
        labels = [j.name if j.nv == 1 else None for j in joints]
        chapter = labels == ["q1", "q2", "q3"] and [j.kind for j in joints] == [
            "revolute",
            "revolute",
            "prismatic",
        ]
        if chapter:
            q, qd, qdd, eff = CHAPTER_COLUMNS
        else:
            coords = _coordinate_labels(joints)
            q = tuple(f"q_{s}" for s in coords)
            qd = tuple(f"qd_{s}" for s in coords)
            qdd = tuple(f"qdd_{s}" for s in coords)
            eff = tuple(f"tau_{s}" for s in coords)
        nv = model.nv
        defaults = RobotDefaults(
            q0=_maybe("q0", q0, nv),
            qd0=(0.0,) * nv,
            qf=_maybe("qf", qf, nv),
            kp=_maybe("kp", kp, nv),
            kd=_maybe("kd", kd, nv),
            Tp=Tp,
        )
        title = name or (str(model.name) if str(model.name) else None)
        if title is None and source is not None:
            title = Path(source).stem
        return cls(
            name=title or "robot",
            joints=joints,
            q_names=q,
            qd_names=qd,
            qdd_names=qdd,
            effort_names=eff,
            defaults=defaults,
            backends=("pinocchio",),
            inverse_backends=_generated_backends(model),
            parameters=("g", "Tp"),
            source=source,
            _model=model,
        )

    # ------------------------------------------------------------------ the model
    @property
    def model(self) -> pin.Model:
        """The Pinocchio model (built on first use for the generated arm)."""
        if self._model is None:
            object.__setattr__(self, "_model", self._build())
        return self._model

    @functools.cached_property
    def nv(self) -> int:
        """Number of joint coordinates (degrees of freedom)."""
        return sum(j.nv for j in self.joints)

    @functools.cached_property
    def nq(self) -> int:
        """Size of Pinocchio's configuration vector (> nv with continuous joints)."""
        return sum(j.nq for j in self.joints)

    @property
    def is_chapter_arm(self) -> bool:
        """Whether this is the chapter's RRT arm (its closed-form kernels apply)."""
        return self.params is not None

    def supports(self, backend: str, task: str | None = None) -> bool:
        """Whether ``backend`` computes ``task`` (``inverse`` or ``simulate``) for this robot.

        With ``task`` None: whether it has this robot's hand-derived kernels (the
        chapter's arm) or is its engine of record; a backend that computes it from
        generated code (:attr:`inverse_backends`) answers only for a task.
        """
        return backend in self.backends or (task is not None and backend in self.inverse_backends)

    # ------------------------------------------------------------------ units
    @property
    def units(self) -> dict[str, str]:
        """Unit of every column (coordinates, velocities, accelerations, efforts), and ``t``."""
        out = {"t": "s"}
        for k, unit in enumerate(self.coordinate_units):
            out[self.q_names[k]] = unit
            out[self.qd_names[k]] = _RATE[unit]
            out[self.qdd_names[k]] = _ACCEL[unit]
            out[self.effort_names[k]] = self.effort_units[k]
        return out

    @functools.cached_property
    def coordinate_units(self) -> tuple[str, ...]:
        """``rad`` or ``m`` per coordinate."""
        return tuple(j.unit for j in self.joints for _ in range(j.nv))

    @property
    def effort_units(self) -> tuple[str, ...]:
        """``N·m`` or ``N`` per coordinate."""
        return tuple(j.effort_unit for j in self.joints for _ in range(j.nv))

    @property
    def effort_docs(self) -> tuple[str, ...]:
        """What each effort is (may be empty strings), for plot titles."""
        return tuple(j.effort_doc for j in self.joints for _ in range(j.nv))

    # ------------------------------------------------------------------ coordinates
    @functools.cached_property
    def _continuous(self) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        plain_q = [j.idx_q + k for j in self.joints if j.kind != "continuous" for k in range(j.nq)]
        plain_v = [j.idx_v + k for j in self.joints if j.kind != "continuous" for k in range(j.nv)]
        cont_q = [j.idx_q for j in self.joints if j.kind == "continuous"]
        cont_v = [j.idx_v for j in self.joints if j.kind == "continuous"]
        return (np.array(plain_q, int), np.array(plain_v, int), np.array(cont_q, int),
                np.array(cont_v, int))  # fmt: skip

    @property
    def has_continuous_joints(self) -> bool:
        """Whether a joint is continuous (then nq > nv)."""
        return any(j.kind == "continuous" for j in self.joints)

    def configuration(self, coordinates: Any) -> np.ndarray:
        """Pinocchio configurations (…, nq) from joint coordinates (…, nv) [rad or m].

        A continuous joint's angle θ becomes (cos θ, sin θ); without continuous
        joints the array is returned as it is (no copy).
        """
        x = np.asarray(coordinates, dtype=float)
        if not self.has_continuous_joints:
            return x
        plain_q, plain_v, cont_q, cont_v = self._continuous
        q = np.empty((*x.shape[:-1], self.nq))
        q[..., plain_q] = x[..., plain_v]
        theta = x[..., cont_v]
        with np.errstate(invalid="ignore"):  # a non-finite angle is named by the caller's check
            q[..., cont_q] = np.cos(theta)
            q[..., cont_q + 1] = np.sin(theta)
        return q

    def coordinates(self, configuration: Any) -> np.ndarray:
        """Joint coordinates (…, nv) from Pinocchio configurations (…, nq).

        A continuous joint's (cos θ, sin θ) becomes θ = atan2(sin θ, cos θ) in (−π, π].
        """
        q = np.asarray(configuration, dtype=float)
        if not self.has_continuous_joints:
            return q
        plain_q, plain_v, cont_q, cont_v = self._continuous
        x = np.empty((*q.shape[:-1], self.nv))
        x[..., plain_v] = q[..., plain_q]
        x[..., cont_v] = np.arctan2(q[..., cont_q + 1], q[..., cont_q])
        return x

    def as_coordinates(self, name: str, value: Any, unit: str = "rad or m") -> np.ndarray:
        """A finite vector of joint coordinates (nv,), or Pinocchio's (nq,) converted.

        Raises:
            InputError: wrong length or a non-finite value.
        """
        nv = self.nv
        if self.nq != nv:
            arr = np.asarray(value, dtype=object) if not isinstance(value, np.ndarray) else value
            if np.shape(arr) == (self.nq,):
                return self.coordinates(validate.vector(name, value, self.nq, unit))
        return validate.vector(name, value, nv, unit)

    # ------------------------------------------------------------------ feedback and motion
    def with_defaults(self, **changes: Any) -> Robot:
        """A copy with some defaults replaced (``q0``, ``qd0``, ``qf``, ``kp``, ``kd``, ``Tp``)."""
        from dataclasses import replace

        values = {}
        for key, value in changes.items():
            if key == "Tp" or value is None:
                values[key] = value
            else:
                values[key] = _maybe(key, value, self.nv)
        return replace(self, defaults=replace(self.defaults, **values))

    def describe(self) -> str:
        """A table of the joints: name, kind, columns and units (``rrt-pin joints``)."""
        lines = [f"{self.name}: {len(self.joints)} joints, {self.nv} coordinates"]
        width = max(5, *(len(j.name) for j in self.joints))
        lines.append(
            f"  {'joint':<{width}}  {'kind':<11} {'coordinate':<16} {'unit':<4} {'effort':<16} unit"
        )
        k = 0
        for j in self.joints:
            for _ in range(j.nv):
                lines.append(
                    f"  {j.name:<{width}}  {j.kind:<11} {self.q_names[k]:<16} {j.unit:<4} "
                    f"{self.effort_names[k]:<16} {j.effort_unit}"
                )
                k += 1
        d = self.defaults
        if d.q0 is not None:
            lines.append(f"  default q0: {','.join(f'{v:g}' for v in d.q0)}")
        if d.qf is not None:
            lines.append(f"  default qf: {','.join(f'{v:g}' for v in d.qf)}")
        extra = [b for b in self.inverse_backends if b not in self.backends]
        also = f"; generated code also: {', '.join(extra)}" if extra else ""
        lines.append(f"  backends: {', '.join(self.backends)}{also}")
        return "\n".join(lines) + "\n"

    def load_labels(self) -> tuple[tuple[str, str], ...]:
        """Per joint, names of the magnitudes of its transmitted force and moment (summaries)."""
        if self.layout == "chapter":
            return (
                ("|F01| at A", "|T01| about A"),
                ("|F12| at B", "|T12| about B"),
                ("|F23| at C3", "|M23| about C3"),
            )
        return tuple((f"|f_{j.name}|", f"|m_{j.name}|") for j in self.joints)

    def xml(self) -> str:
        """The URDF text (generated for the arm, read from :attr:`source` otherwise)."""
        from rrt_pin.robot.urdf import urdf_xml

        if self.params is not None:
            return urdf_xml(self.params)
        if self.source is None:
            raise InputError(f"{self.name} was built from a model: it has no URDF text")
        return Path(self.source).read_text(encoding="utf-8")


def _maybe(name: str, value: Any, n: int) -> tuple[float, ...] | None:
    if value is None:
        return None

    arr = np.asarray(value, dtype=float) if not isinstance(value, str) else value
    if np.ndim(arr) == 0 and name in ("kp", "kd"):
        arr = np.full(n, validate.real(name, value))
    return tuple(float(v) for v in validate.vector(name, arr, n))


def _generated_backends(model: pin.Model) -> tuple[str, ...]:
    """``("compiled",)`` when its generated RNEA handles every joint of ``model``, else ()."""
    generated = [b for b in backends.BACKENDS.values() if "unsupported_joint" in dict(b.entries)]
    return tuple(b.name for b in generated if b.entry("unsupported_joint")(model) is None)


def _joints_of(model: pin.Model) -> tuple[Joint, ...]:
    joints = []
    for j in range(1, model.njoints):
        jm = model.joints[j]
        kind = _kind(jm.shortname())
        if kind is None:
            raise UrdfError(
                f"joint {model.names[j]!r} is a {jm.shortname().removeprefix('JointModel')} joint "
                f"(nq={jm.nq}, nv={jm.nv}); rrt-pin handles revolute, continuous, prismatic, "
                "helical and translation joints of a fixed-base robot"
            )
        joints.append(Joint(str(model.names[j]), kind, jm.nq, jm.nv, jm.idx_q, jm.idx_v))
    if not joints:
        raise UrdfError("the model has no moving joint")
    return tuple(joints)


def _coordinate_labels(joints: tuple[Joint, ...]) -> list[str]:
    labels = []
    for j in joints:
        labels += [j.name] if j.nv == 1 else [f"{j.name}_{k}" for k in range(j.nv)]
    return labels


def bare_model(function: str, model: Any, stacklevel: int = 3) -> bool:
    """Whether ``model`` is a bare ``pinocchio.Model`` (then warn: deprecated since 0.4).

    Public functions take a :class:`Robot`; a Pinocchio model goes through one explicit
    :meth:`Robot.from_model` (which names its columns and units, and turns continuous
    joints' (cos, sin) into angles). Until 0.5 a model is still accepted, with a
    :class:`DeprecationWarning` naming ``function``.
    """
    import sys

    pin = sys.modules.get("pinocchio")  # not imported: ``model`` cannot be one of its models
    if pin is None or not isinstance(model, pin.Model):
        return False
    warnings.warn(
        f"{function}() with a pinocchio.Model is deprecated: pass "
        "rrt_pin.Robot.from_model(model), or a robot of rrt_pin.robots",
        DeprecationWarning,
        stacklevel=stacklevel,
    )
    return True


def params_given(function: str, params: Any, stacklevel: int = 3) -> None:
    """Warn that one ``params=`` Params was given where a Robot carries them (since 0.4)."""
    if params is not None and not isinstance(params, (list, tuple)):
        warnings.warn(
            f"{function}(..., params=) is deprecated: a Robot carries its parameters; pass "
            "rrt_pin.chapter_arm(params) as the robot",
            DeprecationWarning,
            stacklevel=stacklevel,
        )
