"""Helpers shared by the tests (tests import these, never each other).

* tolerances, seeded random states and parameter sets of the chapter's arm;
* the chapter's printed formulas, typed in independently of rrt_pin (corrected
  where the chapter errs; frame (0) components are (ı0, ȷ0, k0), ı0 vertical);
* the arms of example-robot-data (``robot_urdf("ur5")``), found at run time.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from rrt_pin.robot.params import Params

#: Tolerances, named once (relative unless the name says otherwise).
TIGHT = 1e-12
DERIVED = 1e-10


def random_states(rng: np.random.Generator, n: int):
    """n seeded states (q, q̇, q̈) of the RRT arm, q3 in [-0.5, 1] m."""
    q = np.column_stack(
        [rng.uniform(-np.pi, np.pi, n), rng.uniform(-np.pi, np.pi, n), rng.uniform(-0.5, 1.0, n)]
    )
    qd = rng.normal(0.0, 2.0, (n, 3))
    qdd = rng.normal(0.0, 5.0, (n, 3))
    return q, qd, qdd


def random_params(rng: np.random.Generator) -> Params:
    """Params with general (non-rod) central inertias; a, b, c >= 0 keep the triangle rule."""
    values = {
        "L1": rng.uniform(0.1, 1.0),
        "L2": rng.uniform(0.1, 1.0),
        "m1": rng.uniform(1.0, 100.0),
        "m2": rng.uniform(1.0, 100.0),
        "m3": rng.uniform(1.0, 100.0),
        "g": rng.uniform(1.0, 20.0),
    }
    for body in "123":
        a, b, c = rng.uniform(0.0, 5.0, 3)
        values.update({f"I{body}x": b + c, f"I{body}y": a + c, f"I{body}z": a + b})
    return Params(**values)


def rel_err(a: np.ndarray, b: np.ndarray) -> float:
    """Largest per-sample relative error ‖a − b‖ / ‖b‖ over the first axis."""
    a, b = np.asarray(a).reshape(len(a), -1), np.asarray(b).reshape(len(b), -1)
    return float(np.max(np.linalg.norm(a - b, axis=1) / np.linalg.norm(b, axis=1)))


# --- the chapter's printed formulas ---------------------------------------------------
def unit_vectors(q1: float, q2: float):
    """ı1, ȷ1, k1 (eq. 1) and ı2, ȷ2, k2 (eq. 3) in frame (0) components."""
    s1, c1, s2, c2 = np.sin(q1), np.cos(q1), np.sin(q2), np.cos(q2)
    i1 = np.array([1.0, 0.0, 0.0])
    j1 = np.array([0.0, c1, s1])
    k1 = np.array([0.0, -s1, c1])
    i2 = np.array([c2, s1 * s2, -c1 * s2])
    j2 = j1
    k2 = np.array([s2, -c2 * s1, c1 * c2])
    return i1, j1, k1, i2, j2, k2


def mass_centres(p, q):
    """rC1, rC2, rC3 in frame (0) (the position vectors above eqs. 9–11)."""
    _, _, k1, _, _, k2 = unit_vectors(q[0], q[1])
    rC1 = p.L1 * k1
    rC2 = p.LB * k1 + p.L2 * k2
    rC3 = rC2 + q[2] * k2
    return rC1, rC2, rC3


def seed_to_world(v):
    """The mount: ı0 → world z, ȷ0 → world x, k0 → world y."""
    return np.array([v[1], v[2], v[0]])


def kinetic_energy(p, q, qd):
    """T = T1 + T2 + T3 as printed, for the seed's uniform rods.

    T1: the seed prints 2/3·m1·L1·q̇1², missing the square on L1 (erratum);
    ½·m1·(L1·q̇1)² + ½·(m1·L1²/3)·q̇1² = 2/3·m1·L1²·q̇1².
    """
    L1, L2, q3 = p.L1, p.L2, q[2]
    c2, s2 = np.cos(q[1]), np.sin(q[1])
    T1 = 2.0 / 3.0 * p.m1 * L1**2 * qd[0] ** 2
    T2 = (
        p.m2
        / 3.0
        * (
            (6 * L1**2 + L2**2 + 6 * L1 * L2 * c2 + L2**2 * np.cos(2 * q[1])) * qd[0] ** 2
            + 2 * L2**2 * qd[1] ** 2
        )
    )
    T3 = 0.5 * (
        p.I3x * c2**2 * qd[0] ** 2
        + p.I3z * s2**2 * qd[0] ** 2
        + p.I3y * qd[1] ** 2
        + p.m3
        * (
            (2 * L1 + L2 * c2 + c2 * q3) ** 2 * qd[0] ** 2
            + (L2 + q3) ** 2 * qd[1] ** 2
            + qd[2] ** 2
        )
    )
    return T1 + T2 + T3


def holding_efforts(p, q):
    """Efforts that hold the arm still: minus the gravity parts of Q1, Q2, Q3 (eq. 15)."""
    c2, s2 = np.cos(q[1]), np.sin(q[1])
    return np.array([0.0, p.g * c2 * (p.m2 * p.L2 + p.m3 * (p.L2 + q[2])), p.g * p.m3 * s2])


# --- example-robot-data ------------------------------------------------------------
#: Robot name → URDF path inside example-robot-data's ``robots`` folder.
ROBOTS = {
    "ur5": "ur_description/urdf/ur5_robot.urdf",
    "panda": "panda_description/urdf/panda.urdf",
}


def robots_dir() -> Path | None:
    """``.../share/example-robot-data/robots`` of the installed package, or None."""
    from rrt_pin.robot.robots import example_robot_data_dir

    return example_robot_data_dir()


def package_dir() -> Path | None:
    """The folder that resolves ``package://example-robot-data/...`` mesh URIs.

    Pass it as ``package_dirs=[str(package_dir())]`` to ``pin.buildGeomFromUrdf``
    (only a viewer needs meshes; without it Pinocchio reports "Mesh ... could not
    be found").
    """
    base = robots_dir()
    return None if base is None else base.parent.parent


def robot_urdf(name: str) -> Path:
    """Path of one robot's URDF; skips the test when example-robot-data is missing."""
    base = robots_dir()
    if base is None:
        pytest.skip("example-robot-data is not installed (pip install rrt-pin[test])")
    path = base / ROBOTS[name]
    if not path.is_file():
        pytest.skip(f"example-robot-data has no {ROBOTS[name]}")
    return path


def call_graph(source: str) -> dict[str, set[str]]:
    """Each function of a generated module's source and the names it calls."""
    import ast

    out = {}
    for node in ast.parse(source).body:
        if isinstance(node, ast.FunctionDef):
            out[node.name] = {
                c.func.id
                for c in ast.walk(node)
                if isinstance(c, ast.Call) and isinstance(c.func, ast.Name)
            }
    return out


def reaches(calls: dict[str, set[str]], name: str) -> set[str]:
    """The functions of ``calls`` that ``name`` reaches, however deep (itself included)."""
    seen, todo = set(), [name]
    while todo:
        f = todo.pop()
        if f in seen or f not in calls:
            continue
        seen.add(f)
        todo.extend(calls[f])
    return seen
