"""One exception hierarchy for rrt_pin.

Every error the package raises on purpose derives from :class:`RrtPinError`.
The CLI turns any of them into one line on stderr and exit status 2.
"""

from __future__ import annotations

__all__ = [
    "ArgumentTypeError",
    "ClusterError",
    "ControllerError",
    "DivergenceError",
    "InputError",
    "MemoryLimitError",
    "OverrideError",
    "ParameterError",
    "RrtPinError",
    "RunFileError",
    "SceneError",
    "SpecError",
    "UrdfError",
    "ViewerError",
]


class RrtPinError(Exception):
    """Base class of every error raised by rrt_pin."""


class ParameterError(RrtPinError, ValueError):
    """A physical parameter is invalid.

    Attributes:
        name: the parameter's name (the chapter's symbol, e.g. ``m1``).
        value: the rejected value.
    """

    def __init__(self, name: str, value: object, problem: str) -> None:
        self.name = name
        self.value = value
        self.problem = problem
        super().__init__(f"parameter {name}={value!r}: {problem}")


class SceneError(RrtPinError, ValueError):
    """Deprecated name, kept for one release: catch its subclasses instead.

    It used to name run-file, sweep-spec and override errors at once; it is now the
    base of :class:`RunFileError`, :class:`SpecError` and :class:`OverrideError`.
    """


class RunFileError(SceneError):
    """A run file (``--config``) cannot be used: unreadable, not TOML, or a bad entry."""


class SpecError(SceneError):
    """A sweep spec (a TOML file, a dict or a :class:`~rrt_pin.sweeps.Spec`) cannot be used."""


class InputError(RrtPinError, ValueError):
    """An array, time grid, CSV or command-line value is invalid."""


class OverrideError(InputError, SceneError):
    """A parameter override or a number typed as text cannot be used.

    ``--set NAME=VALUE``, ``Params.with_overrides`` and values such as ``"pi/3"``:
    an unknown name, or text that is not a number.
    """


class UrdfError(RrtPinError, ValueError):
    """A URDF does not parse or does not describe a usable model."""


class DivergenceError(RrtPinError, ArithmeticError):
    """A simulation produced a non-finite state, or its integrator stopped.

    The message says "diverged" for a non-finite state and "stopped" for an
    integrator that gave up (step size underflow, work budget spent, tolerances
    float64 cannot meet). The message prints ``t`` to 6 significant digits: the
    last digits of a time found by an integrator differ between CPUs; ``t`` holds
    the exact value.

    Attributes:
        t: the time at which it happened [s].
        coordinate: the name of the offending coordinate (e.g. ``q2`` or ``qd3``).
    """

    def __init__(self, t: float, coordinate: str, problem: str, verb: str = "diverged") -> None:
        self.t = t
        self.coordinate = coordinate
        super().__init__(f"simulation {verb} at t={t:.6g} s in {coordinate}: {problem}")


class MemoryLimitError(RrtPinError, MemoryError):
    """A run would need more memory than this process may take (checked before allocating).

    Attributes:
        need: the bytes it would need at least.
        limit: the bytes left under the limit it exceeds.
        source: that limit (``MemAvailable``, ``ulimit -v (RLIMIT_AS)``, the cgroup's).
    """

    def __init__(self, message: str, *, need: int, limit: int, source: str) -> None:
        self.need = need
        self.limit = limit
        self.source = source
        super().__init__(message)


class ArgumentTypeError(InputError, TypeError):
    """An argument of a library function has a type it does not accept (e.g. a str for a model).

    Attributes:
        argument: the argument's name (``model``, ``params``…).
    """

    def __init__(self, argument: str, message: str) -> None:
        self.argument = argument
        super().__init__(message)


class ControllerError(InputError):
    """A user's law broke its contract (:class:`rrt_pin.simulate.control.Controller`).

    A result of the wrong shape or type (``efforts``, ``efforts_many``, ``jacobian``),
    a complex or non-finite Jacobian, a batch form that disagrees with ``efforts``, or a
    law that writes into its ``q`` or ``qd``.

    Attributes:
        law: the law's name (its function or class name).
    """

    def __init__(self, law: str, message: str) -> None:
        self.law = law
        super().__init__(message)


class ViewerError(RrtPinError, RuntimeError):
    """The viewer could not start, serve or render."""


class ClusterError(RrtPinError, RuntimeError):
    """A Dask cluster cannot be used: unreachable, not speaking Dask, or without workers.

    Attributes:
        address: the scheduler's address (``tcp://host:port``; the local cluster's).
        seconds: how long was waited [s] (None: it failed at once).
    """

    def __init__(self, address: str, message: str, seconds: float | None = None) -> None:
        self.address = address
        self.seconds = seconds
        super().__init__(message)
