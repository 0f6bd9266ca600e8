"""The package's shape: imports flow one way, commands hold no robot-specific branch,
the CLI and the compiled loop read the registries, and the public API is complete."""

from __future__ import annotations

import ast
import re
from pathlib import Path

import pytest

import rrt_pin
from rrt_pin.core import backends
from rrt_pin.simulate import codes, methods

PACKAGE = Path(rrt_pin.__file__).parent


def _module_name(path: Path) -> str:
    parts = path.relative_to(PACKAGE.parent).with_suffix("").parts
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def _imports(path: Path) -> set[str]:
    """Every rrt_pin module ``path`` imports, at module level or inside functions.

    ``import a.b.c`` and ``from a.b import c`` also run the packages ``a`` and
    ``a.b``: they count as imports of those packages.
    """
    tree = ast.parse(path.read_text(encoding="utf-8"))
    me = _module_name(path)
    package = me if path.name == "__init__.py" else me.rsplit(".", 1)[0]
    found: set[str] = set()
    for node in ast.walk(tree):
        names: list[str] = []
        if isinstance(node, ast.Import):
            names = [a.name for a in node.names]
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                base = ".".join(package.split(".")[: len(package.split(".")) - node.level + 1])
                base = f"{base}.{node.module}" if node.module else base
            names = [base] + [f"{base}.{a.name}" for a in node.names]
        for name in names:
            if name.startswith("rrt_pin"):
                parts = name.split(".")
                found |= {".".join(parts[: i + 1]) for i in range(len(parts))}
    return found


def _graph() -> dict[str, set[str]]:
    """Module -> the rrt_pin modules it imports.

    A module's own ancestor packages are left out as targets: Python has
    initialised them before the module runs (so the root ``rrt_pin``, whose
    ``__init__`` imports only leaf modules, checked below, never is one).
    Another package's ``__init__`` counts (``rrt_pin.simulate`` for
    ``rrt_pin.compiled.integrate``).
    """
    files = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    graph = {}
    for name, path in files.items():
        ancestors = {name.rsplit(".", k)[0] for k in range(1, name.count(".") + 1)}
        graph[name] = {m for m in _imports(path) if m in files and m not in ancestors | {name}}
    return graph


def _cycle(graph: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}
    stack: list[str] = []

    def visit(node: str) -> list[str] | None:
        state[node] = 1
        stack.append(node)
        for nxt in sorted(graph[node]):
            if state.get(nxt) == 1:
                return stack[stack.index(nxt) :] + [nxt]
            if nxt not in state:
                found = visit(nxt)
                if found:
                    return found
        stack.pop()
        state[node] = 2
        return None

    for node in sorted(graph):
        if node not in state:
            found = visit(node)
            if found:
                return found
    return None


def test_the_import_walker_sees_function_local_imports_and_finds_cycles():
    graph = _graph()
    # a function-local import, and the package that `import rrt_pin.simulate.results` runs
    assert "rrt_pin.robot.model" in graph["rrt_pin.simulate.api"]
    assert "rrt_pin.simulate" in graph["rrt_pin.compiled.integrate"]
    assert _cycle({"a": {"b"}, "b": {"c"}, "c": {"a"}}) == ["a", "b", "c", "a"]
    assert _cycle({"a": {"b"}, "b": set()}) is None


#: What ``import rrt_pin`` runs (besides the standard library).
ROOT_IMPORTS = {
    "rrt_pin.core", "rrt_pin.core.errors", "rrt_pin.core.expr", "rrt_pin.core._logging",
    "rrt_pin.robot", "rrt_pin.robot.params", "rrt_pin._version", "rrt_pin._moved",
}  # fmt: skip


def test_no_import_cycle_in_the_package():
    """Data flows one way: no module imports (even inside a function) one that imports it."""
    graph = _graph()
    assert _cycle(graph) is None
    # the root package imports a closed set of small modules (no subpackage, nothing that
    # imports pinocchio or numpy), so leaving it out as a target above hides no cycle
    closure, todo = set(), list(graph["rrt_pin"])
    while todo:
        m = todo.pop()
        if m not in closure:
            closure.add(m)
            todo += graph[m]
    assert closure <= ROOT_IMPORTS, closure - ROOT_IMPORTS


#: Names that would mean a command treats one robot apart (help strings may mention them).
ROBOT_SPECIFIC = {
    "is_rrt", "rrt", "is_chapter_arm", "layout", "T01x", "T12y", "F23z", "q1f",
    "gamma01", "beta01", "rrt_model", "chapter_arm", "seed_controller", "chapter_controller",
    "pd_gravity_controller", "ChapterController", "PDGravityController", "shortname",
}  # fmt: skip


def _code_names(path: Path) -> list[tuple[int, str]]:
    """Identifiers and attribute names in code (strings and comments excluded)."""
    return _code_names_of(ast.parse(path.read_text(encoding="utf-8")))


def test_commands_hold_no_robot_specific_branch():
    """Commands parse, call the library, write: the robot decides columns, units and laws."""
    for path in sorted((PACKAGE / "cli" / "commands").glob("*.py")):
        for line, name in _code_names(path):
            assert name not in ROBOT_SPECIFIC, f"{path.name}:{line}: {name}"
            assert name != "urdf is None", f"{path.name}:{line}"


#: Names that, in a condition, ask which robot this is.
IDENTITY = {
    "is_rrt", "is_chapter_arm", "chapter_arm", "names_chapter_arm", "rrt_model", "shortname",
    "layout", "urdf is None", "'rrt'",
}  # fmt: skip
#: The packages whose code runs every robot alike, and the one function each may ask in
#: (the others call it: ``compiled.runs_arm_kernel`` through the backend's ``arm_kernel``).
IDENTITY_PACKAGES = ("simulate", "sweeps", "viewer", "compiled", "cli/commands")
ASKED_HERE = {
    ("compiled/__init__.py", "runs_arm_kernel"),  # the arm's closed form, or generated code
    ("sweeps/variants.py", "family_for"),  # what a sweep varies
}


def _identity_conditions(path: Path) -> list[tuple[int, str, str]]:
    """(line, function, name) of every identity name inside a condition of ``path``.

    Conditions: ``if``/``while``/conditional expressions, comprehension filters and the
    operands of ``and``/``or``.
    """
    tree = ast.parse(path.read_text(encoding="utf-8"))
    out = []

    def visit(node: ast.AST, function: str) -> None:
        if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            function = node.name
        tests: list[ast.AST] = []
        if isinstance(node, (ast.If, ast.IfExp, ast.While)):
            tests.append(node.test)
        elif isinstance(node, ast.comprehension):
            tests += node.ifs
        elif isinstance(node, ast.BoolOp):
            tests += node.values
        for test in tests:
            for _, name in _code_names_of(test):
                if name in IDENTITY:
                    out.append((test.lineno, function, name))
        for child in ast.iter_child_nodes(node):
            visit(child, function)

    visit(tree, "<module>")
    return out


def _code_names_of(node: ast.AST) -> list[tuple[int, str]]:
    """Identifiers, attribute names, ``'rrt'`` and ``….urdf is None`` under ``node``."""
    out = []
    for sub in ast.walk(node):
        if isinstance(sub, ast.Name):
            out.append((sub.lineno, sub.id))
        elif isinstance(sub, ast.Attribute):
            out.append((sub.lineno, sub.attr))
        elif isinstance(sub, ast.Constant) and sub.value == "rrt":
            out.append((sub.lineno, "'rrt'"))
        elif isinstance(sub, ast.Compare) and any(
            isinstance(c, ast.Constant) and c.value is None for c in sub.comparators
        ):
            if isinstance(sub.left, ast.Attribute) and sub.left.attr == "urdf":
                out.append((sub.lineno, "urdf is None"))
    return out


def test_which_robot_is_asked_in_one_place():
    """Simulations, sweeps, the viewer, the compiled code and the commands run every robot
    alike: "is this the chapter's arm" is asked in one function each where the answer
    changes the code that runs (the arm's closed form; what a sweep varies)."""
    found = []
    for package in IDENTITY_PACKAGES:
        for path in sorted((PACKAGE / package).rglob("*.py")):
            where = path.relative_to(PACKAGE).as_posix()
            for line, function, name in _identity_conditions(path):
                if (where, function) not in ASKED_HERE:
                    found.append(f"{where}:{line} ({function}): {name}")
    assert not found, found
    # each allowed place does ask (else it is stale)
    for where, function in ASKED_HERE:
        assert any(f == function for _, f, _ in _identity_conditions(PACKAGE / where)), where


def test_auto_is_decided_in_one_place():
    """``backends.choose`` is the one ``auto`` policy: no other module compares with "auto"."""
    found = []
    for path in sorted(PACKAGE.rglob("*.py")):
        if path.relative_to(PACKAGE).as_posix() == "core/backends.py":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            if isinstance(node, ast.Compare) and any(
                isinstance(c, ast.Constant) and c.value == "auto"
                for c in (node.left, *node.comparators)
            ):
                found.append(f"{path.name}:{node.lineno}")
    assert not found, found


def test_the_identity_detector_can_fail(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text(
        "def run(robot, spec):\n"
        "    x = robot.is_chapter_arm and 1\n"
        "    return [r for r in spec if r.robot == 'rrt'] if spec.urdf is None else x\n"
    )
    names = {n for _, _, n in _identity_conditions(bad)}
    assert names == {"is_chapter_arm", "'rrt'", "urdf is None"}


def test_the_branch_detector_can_fail(tmp_path):
    bad = tmp_path / "bad.py"
    bad.write_text("def run(args):\n    if args.urdf is None:\n        return rrt_model()\n")
    names = {n for _, n in _code_names(bad)}
    assert "urdf is None" in names and "rrt_model" in names


def test_cli_choices_and_help_come_from_the_registries(capsys):
    from rrt_pin.cli.app import build_parser

    _, sub = build_parser()
    for task in ("inverse", "simulate"):
        action = next(a for a in sub[task]._actions if a.dest == "backend")
        assert tuple(action.choices) == (*backends.names(task), "auto")
        for b in backends.BACKENDS.values():
            assert (b.summary in action.help) == b.runs(task)
    epilog = sub["simulate"].epilog
    for m in methods.METHODS.values():
        assert m.name in epilog and m.summary in epilog


def test_compiled_codes_have_one_source():
    """The registry's codes are the compiled loop's, and the loop compares no literal codes."""
    assert methods.get("DOP853").code == codes.METHOD_DOP853
    assert methods.get("rk4").code == codes.METHOD_RK4
    assert len({m.code for m in methods.METHODS.values() if m.code is not None}) == len(
        methods.names("compiled")
    )
    for name in ("_jit_integrators.py", "_jit_batch.py", "_jit_dynamics.py", "integrate.py"):
        text = (PACKAGE / "compiled" / name).read_text(encoding="utf-8")
        assert not re.search(r"(method|kind|status)\s*[=!<>]=?\s*\d", text), name
        assert "see _jit" not in text


def test_every_method_has_a_runner():
    """Each registry line is enough: scipy knows the adaptive names, fixed-step ones resolve."""
    import importlib

    import scipy.integrate

    for m in methods.METHODS.values():
        if m.family == methods.SCIPY:
            assert m.name in scipy.integrate._ivp.ivp.METHODS
        if m.family == methods.FIXED_STEP:
            module, _, name = m.runner.partition(":")
            assert callable(getattr(importlib.import_module(module), name))
        assert (m.rtol is not None) == m.adaptive


def test_public_api_is_complete():
    for name in rrt_pin.__all__:
        assert getattr(rrt_pin, name) is not None, name
    assert re.fullmatch(r"\d+\.\d+\.\d+", rrt_pin.__version__)
    assert callable(rrt_pin.simulate) and callable(rrt_pin.simulate.simulate_batch)
    for module in ("simulate.control", "simulate.methods", "core.backends", "robot.robots",
                   "robot.robot", "robot", "core.validate", "simulate.metrics"):  # fmt: skip
        mod = __import__(f"rrt_pin.{module}", fromlist=["__all__"])
        for name in mod.__all__:
            assert hasattr(mod, name), f"rrt_pin.{module}.{name}"


@pytest.mark.parametrize("name", ["seed_controller", "SeedController"])
def test_deprecated_aliases_still_work(name):
    import rrt_pin.simulate.control as control

    assert getattr(control, name) in (control.chapter_controller, control.ChapterController)


# --- no measured timings in docstrings or --help: they live in docs/benchmarks.md ------

#: A measured duration as docs write it ("~0.2 ms", "1.5 µs", "~0.4 s"); settings such
#: as "every 50 ms" are told apart by the words before them (see _TIMING_ALLOWED).
_TIMING = re.compile(r"(?:~ ?|about |\b)\d+(?:\.\d+)? ?(?:ms|µs|us|ns)\b|~ ?\d+(?:\.\d+)? ?s\b")
_TIMING_ALLOWED = ("looked up again every", "as a person would write it", "The estimate, ~0.3 ns")


def _timings(text: str) -> list[str]:
    return [
        m.group(0)
        for line in text.splitlines()
        for m in _TIMING.finditer(line)
        if not any(allowed in line for allowed in _TIMING_ALLOWED)
    ]


def _docstrings(path: Path) -> list[tuple[int, str]]:
    """Every docstring of a module and the ``#:`` doc-comments of its constants."""
    source = path.read_text(encoding="utf-8")
    tree = ast.parse(source)
    out = []
    for node in ast.walk(tree):
        if isinstance(node, (ast.Module, ast.ClassDef, ast.FunctionDef, ast.AsyncFunctionDef)):
            doc = ast.get_docstring(node, clean=False)
            if doc:
                out.append((getattr(node, "lineno", 1), doc))
    for number, line in enumerate(source.splitlines(), 1):
        if line.lstrip().startswith("#:"):
            out.append((number, line))
    return out


def test_docstrings_hold_no_measured_timings():
    found = [
        f"{path.relative_to(PACKAGE)}:{line}: {hit}"
        for path in sorted(PACKAGE.rglob("*.py"))
        for line, doc in _docstrings(path)
        for hit in _timings(doc)
    ]
    assert not found, "timings belong in docs/benchmarks.md: " + "; ".join(found)


def test_help_holds_no_measured_timings(capsys):
    from rrt_pin.cli.app import main

    commands = ("urdf", "joints", "inverse", "simulate", "equations", "sweep", "view", "bench")
    for command in commands:
        with pytest.raises(SystemExit):
            main([command, "--help"])
        text = capsys.readouterr().out
        assert "usage:" in text and not _timings(text), (command, _timings(text))


def test_the_timing_detector_can_fail():
    assert _timings('"""A run then takes ~0.2 ms instead of ~3 ms."""') == ["~0.2 ms", "~3 ms"]
    assert _timings("costs about 1 µs an output time; loads in ~0.8 s") == ["about 1 µs", "~0.8 s"]
    assert _timings("dt: time step [s]; 3×3 matrices; at most 15 s of output") == []


def test_run_files_and_specs_have_their_own_names_and_the_old_ones_still_work(tmp_path):
    from rrt_pin.cli.runfile import RunFile, load_runfile
    from rrt_pin.core import errors

    for new in (errors.RunFileError, errors.SpecError, errors.OverrideError):
        assert issubclass(new, errors.SceneError) and issubclass(new, ValueError)
    assert issubclass(errors.OverrideError, errors.InputError)
    assert not issubclass(errors.SpecError, errors.RunFileError)
    with pytest.warns(DeprecationWarning, match="rrt_pin.cli.runfile"):
        import importlib
        import sys

        sys.modules.pop("rrt_pin.scene", None)
        scene = importlib.import_module("rrt_pin.scene")
    assert scene.Scene is RunFile and scene.load_scene is load_runfile
    path = tmp_path / "run.toml"
    path.write_text("[inverse]\ndt = 0.01\n")
    with pytest.raises(
        errors.RunFileError, match="unknown table 'inverse'; valid: params, options$"
    ):
        load_runfile(path)  # a library caller names the tables it takes
    assert load_runfile(path, tables=("inverse",)).commands == {"inverse": {"dt": 0.01}}
    assert "load_scene" not in rrt_pin.__all__ and "load_runfile" in rrt_pin.__all__


def test_the_viewers_drawing_and_the_rnea_source_have_their_names_and_old_ones_warn():
    import importlib
    import sys

    import rrt_pin.viewer as viewer
    from rrt_pin.dynamics import rnea_source
    from rrt_pin.viewer.drawing import RobotDrawing, build_drawing

    with pytest.warns(DeprecationWarning, match="rrt_pin.viewer.RobotDrawing"):
        assert viewer.ArmScene is RobotDrawing
    with pytest.warns(DeprecationWarning, match="rrt_pin.viewer.build_drawing"):
        assert viewer.build_scene is build_drawing
    for old, new in (("rrt_pin.viewer.scene", "rrt_pin.viewer.drawing"),
                     ("rrt_pin.codegen", "rrt_pin.dynamics.rnea_source")):  # fmt: skip
        sys.modules.pop(old, None)
        with pytest.warns(DeprecationWarning, match=new):
            module = importlib.import_module(old)
        for name in module.__all__:
            assert getattr(module, name) is not None
    assert importlib.import_module("rrt_pin.codegen").rnea_source is rnea_source.rnea_source
    from rrt_pin.simulate import accuracy

    assert accuracy.SCENES is accuracy.PROBLEMS and accuracy.Scene is accuracy.Problem
    assert "SCENES" not in accuracy.__all__ and "PROBLEMS" in accuracy.__all__


# --- one list per kind of name ----------------------------------------------------------


def test_the_plants_parameter_order_is_one_list():
    from rrt_pin.dynamics import kernel
    from rrt_pin.robot import params

    assert kernel.PARAM_ORDER is params.PLANT_FIELDS
    symbols = pytest.importorskip("rrt_pin.dynamics.symbolic.symbols")
    assert symbols.PARAM_NAMES is params.PLANT_FIELDS


def test_the_generated_file_holds_only_expressions():
    source = (PACKAGE / "dynamics" / "_kernel_terms.py").read_text(encoding="utf-8")
    tree = ast.parse(source)
    functions = {n.name for n in tree.body if isinstance(n, ast.FunctionDef)}
    assert functions == {"terms", "inverse_constants", "inverse_terms", "forward_terms"}
    imports = {ast.unparse(n) for n in tree.body if isinstance(n, (ast.Import, ast.ImportFrom))}
    assert imports == {"from __future__ import annotations", "from numpy import cos, sin"}


def test_metric_names_units_and_help_come_from_the_registry(capsys):
    from rrt_pin.cli.app import main
    from rrt_pin.simulate import metrics
    from rrt_pin.sweeps import spec

    assert spec.METRICS["simulate"] == metrics.for_task("simulate")
    assert spec.METRICS["inverse"] == metrics.for_task("inverse")
    assert spec.TEXT_COLUMNS == metrics.TEXT_COLUMNS == ("diverged_coordinate", "diverged_reason")
    names = metrics.column_names(["peak_effort", "diverged"], ["a", "b"], ["Fa", "Fb"])
    assert names == ["peak_effort_Fa", "peak_effort_Fb", "peak_effort_time_Fa",
                     "peak_effort_time_Fb", "diverged", "diverged_time", "diverged_coordinate",
                     "diverged_reason"]  # fmt: skip
    units = metrics.column_units(
        ["final_error", "settling_time"], ["a", "b"], [], {"a": "rad", "b": "m"}
    )
    assert units == {"final_error_a": "rad", "final_error_b": "m", "settling_time_a": "s",
                     "settling_time_b": "s"}  # fmt: skip
    with pytest.raises(SystemExit):
        main(["sweep", "--help"])
    help_text = capsys.readouterr().out
    for metric in metrics.METRICS.values():
        assert f"  {metric.name}" in help_text
        for column in metric.columns:
            assert column.prefix in help_text


def test_the_arms_column_names_are_typed_once():
    """Outside robot.py (and the URDF and the symbolic derivation that name the joints),
    no module spells the chapter's column names as a literal list."""
    literal = re.compile(r"""["'](?:T01x|qd1|qdd1)["']|["']q1["'],\s*["']q2["']""")
    allowed = {"robot.py", "urdf.py", "_kernel_terms.py"}
    found = [
        f"{path.relative_to(PACKAGE)}:{n}"
        for path in sorted(PACKAGE.rglob("*.py"))
        if path.name not in allowed and "symbolic" not in path.parts
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        if literal.search(line) and not line.lstrip().startswith("#")
    ]
    assert not found, found
    assert literal.search('names = ("q1", "q2", "q3")') and literal.search("x = 'T01x'")


def test_one_cache_variable(monkeypatch, tmp_path):
    from rrt_pin.simulate import reference

    monkeypatch.delenv("RRT_PIN_CACHE", raising=False)
    monkeypatch.setenv("RRT_PIN_CACHE_DIR", str(tmp_path))
    assert reference._cache_dir() == tmp_path / "references"
    monkeypatch.delenv("RRT_PIN_CACHE_DIR")
    monkeypatch.setenv("RRT_PIN_CACHE", str(tmp_path / "old"))
    with pytest.warns(DeprecationWarning, match="RRT_PIN_CACHE_DIR"):
        assert reference._cache_dir() == tmp_path / "old"


# --- imports at the top ------------------------------------------------------------------

#: Libraries slow to import or optional: imported inside the function that needs them.
HEAVY_LIBRARIES = {
    "pinocchio", "numba", "llvmlite", "scipy", "matplotlib", "sympy", "meshcat", "dask",
    "distributed", "pyarrow", "pandas", "selenium", "tornado", "mpmath", "yourdfpy",
    "example_robot_data", "zmq", "psutil", "tqdm",
}  # fmt: skip
#: The package's own optional parts: they pull in one of those libraries or a backend
#: when used, so they are imported where they are used, like the libraries.
OPTIONAL_PARTS = (
    "rrt_pin.compiled", "rrt_pin.viewer", "rrt_pin.sweeps", "rrt_pin.dynamics.symbolic",
    "rrt_pin.cli.bench_report", "rrt_pin.cli.bench_measure", "rrt_pin.cli.flops", "rrt_pin.simulate.reference",
    "rrt_pin.simulate.accuracy", "rrt_pin.simulate._odepack", "rrt_pin.simulate.scipy_runs",
    "rrt_pin.simulate.integrators", "rrt_pin.simulate.symplectic",  # their method families only
    "rrt_pin.robot.model", "rrt_pin.robot.urdf", "rrt_pin.robot.urdf_check",  # URDF, Pinocchio
    "rrt_pin.dynamics.rnea_source",  # the generator of any robot's compiled RNEA
)  # fmt: skip
#: Where a function-level import is the design: a command imports what it runs when it
#: runs (cli/app.py, cli/commands/), and a package's __init__ offers its names lazily.
LAZY_BY_DESIGN = ("rrt_pin.cli.app", "rrt_pin.cli.commands")


def _module_level_imports(tree: ast.Module) -> set[int]:
    """The import nodes run when the module is imported (not those for type checkers)."""
    out: set[int] = set()

    def walk(body: list[ast.stmt]) -> None:
        for node in body:
            if isinstance(node, (ast.Import, ast.ImportFrom)):
                out.add(id(node))
            elif isinstance(node, ast.If) and "TYPE_CHECKING" not in ast.unparse(node.test):
                walk(node.body)
                walk(node.orelse)
            elif isinstance(node, ast.Try):
                walk(node.body)
                for handler in node.handlers:
                    walk(handler.body)
                walk(node.orelse)
                walk(node.finalbody)

    walk(tree.body)
    for node in ast.walk(tree):
        if isinstance(node, ast.If) and "TYPE_CHECKING" in ast.unparse(node.test):
            out |= {id(n) for n in ast.walk(node) if isinstance(n, (ast.Import, ast.ImportFrom))}
    return out


def _targets(node: ast.Import | ast.ImportFrom) -> list[str]:
    if isinstance(node, ast.Import):
        return [a.name for a in node.names]
    return [node.module or ""] + [f"{node.module}.{a.name}" for a in node.names]


def _heavy_modules(sources: dict[str, str]) -> set[str]:
    """Own modules that are optional parts or import a heavy library at module level."""
    tops = {}
    for name, text in sources.items():
        tree = ast.parse(text)
        level = _module_level_imports(tree)
        tops[name] = [t for n in ast.walk(tree) if id(n) in level for t in _targets(n)]
    heavy = {m for m in sources if any(m == o or m.startswith(o + ".") for o in OPTIONAL_PARTS)}
    changed = True
    while changed:
        changed = False
        for name, targets in tops.items():
            if name not in heavy and any(
                t.split(".")[0] in HEAVY_LIBRARIES or (t in heavy and t != name) for t in targets
            ):
                heavy.add(name)
                changed = True
    return heavy


def _late_imports(sources: dict[str, str]) -> list[str]:
    """Function-level imports of own modules that are neither heavy nor lazy by design."""
    heavy = _heavy_modules(sources)
    found = []
    for name, text in sorted(sources.items()):
        if name.endswith("__init__") or any(
            name == p or name.startswith(p + ".") for p in LAZY_BY_DESIGN
        ):
            continue
        tree = ast.parse(text)
        level = _module_level_imports(tree)
        for node in ast.walk(tree):
            if not isinstance(node, (ast.Import, ast.ImportFrom)) or id(node) in level:
                continue
            targets = [t for t in _targets(node) if t in sources]
            if targets and not any(t in heavy for t in targets):
                found.append(f"{name}:{node.lineno}: {ast.unparse(node)}")
    return found


def test_imports_are_at_the_top():
    files = {_module_name(p): p for p in PACKAGE.rglob("*.py")}
    sources = {name: path.read_text(encoding="utf-8") for name, path in files.items()}
    sources = {
        f"{k}.__init__" if files[k].name == "__init__.py" else k: v for k, v in sources.items()
    }
    found = _late_imports(sources)
    assert not found, "move these imports to the top of their module: " + "; ".join(found)


def test_the_import_rule_can_fail():
    sources = {
        "rrt_pin.core.errors": "class InputError(ValueError): ...\n",
        "rrt_pin.robot.model": "import pinocchio\n",
        "rrt_pin.viewer.show": "x = 1\n",
        "rrt_pin.a": (
            "def f():\n    from rrt_pin.core.errors import InputError\n    return InputError\n"
            "def g():\n    from rrt_pin.robot.model import build\n"
            "def h():\n    from rrt_pin.viewer.show import show\n"
        ),
    }
    assert _late_imports(sources) == ["rrt_pin.a:2: from rrt_pin.core.errors import InputError"]


def test_run_files_see_every_option_of_every_command_without_argparse_privates():
    from rrt_pin.cli.app import build_parser

    parser, subparsers = build_parser()
    for name, sub in subparsers.items():
        recorded = {a.dest for a in sub.options}
        needs_command = ["x.toml"] if name == "sweep" else []
        defaults = set(vars(sub.parse_known_args(needs_command)[0]))
        missing = defaults - recorded - {"command_run", "verbose", "quiet", "spec", "help"}
        assert not missing, (name, missing)
    source = (PACKAGE / "cli" / "app.py").read_text(encoding="utf-8")
    assert "._actions" not in source and "argparse._" not in source


# --- layers: packages that read bottom to top ---------------------------------------------

#: The layers, bottom to top. Each package's ``__init__`` docstring says what it may
#: import ("May import: rrt_pin.core, …"): the test reads the rule from there.
LAYERS = ("core", "io", "robot", "dynamics", "simulate", "compiled", "viewer", "sweeps", "cli")
#: What stays at the top level besides the layers: the front (``import rrt_pin``).
TOP_LEVEL = {"__init__.py", "__main__.py", "_version.py", "_moved.py", "py.typed"}


def _may_import(docstring: str) -> set[str]:
    match = re.search(r"May import: (.*?)(?:\.\s*$|\.\n)", docstring, re.S | re.M)
    assert match, "no 'May import:' line"
    return set(re.findall(r"rrt_pin\.(\w+)", match.group(1)))


def _declared() -> dict[str, set[str]]:
    return {
        layer: _may_import(
            ast.get_docstring(ast.parse((PACKAGE / layer / "__init__.py").read_text())) or ""
        )
        for layer in LAYERS
    }


def _layer(module: str) -> str | None:
    parts = module.split(".")
    return parts[1] if len(parts) > 1 and parts[1] in LAYERS else None


def _crossings(graph: dict[str, set[str]], declared: dict[str, set[str]]) -> list[str]:
    """Imports from one layer into another that its ``May import`` line does not allow."""
    return [
        f"{module} -> {target}"
        for module, targets in sorted(graph.items())
        for target in sorted(targets)
        if _layer(module)
        and _layer(target) not in (None, _layer(module))
        and _layer(target) not in declared[_layer(module)]
    ]


def test_the_top_level_holds_only_the_layers_and_the_front():
    entries = {p.name for p in PACKAGE.iterdir() if p.name != "__pycache__"}
    assert entries == TOP_LEVEL | set(LAYERS), entries ^ (TOP_LEVEL | set(LAYERS))


def test_each_layer_imports_only_the_layers_below_it():
    """Every import, even inside a function or for type checkers, goes down the stack."""
    declared = _declared()
    for k, layer in enumerate(LAYERS):
        assert declared[layer] <= set(LAYERS[:k]), (layer, declared[layer] - set(LAYERS[:k]))
    assert not _crossings(_graph(), declared)
    # the modules at the top level import only the front's small modules and the CLI
    graph = _graph()
    assert graph["rrt_pin.__main__"] <= {"rrt_pin.cli", "rrt_pin.cli.app"}
    assert graph["rrt_pin._moved"] == set()


def test_the_layer_rule_can_fail():
    declared = _may_import('"""Things.\n\nMay import: rrt_pin.core, rrt_pin.robot.\n"""')
    assert declared == {"core", "robot"}
    graph = {
        "rrt_pin.simulate.api": {"rrt_pin.compiled.integrate", "rrt_pin.core.errors"},
        "rrt_pin.compiled.integrate": {"rrt_pin.simulate.options"},
    }
    found = _crossings(graph, {**_declared(), "simulate": {"core"}})
    assert found == ["rrt_pin.simulate.api -> rrt_pin.compiled.integrate"]


def test_the_front_doors_reach_a_backend_through_the_registry():
    """Each backend's entries import and sit in a layer at or above the front doors."""
    for backend in backends.BACKENDS.values():
        for job, where in backend.entries:
            found = backend.entry(job)
            assert callable(found) or hasattr(found, "__file__"), (backend.name, job)
            assert _layer(where.partition(":")[0]) in ("dynamics", "simulate", "compiled"), where
    with pytest.raises(KeyError):
        backends.get("pinocchio").entry("inverse_generated")


def test_every_backend_offers_the_same_runs():
    """The front doors hand over without asking which backend: each offers the same functions."""
    import inspect

    shapes = {}
    for backend in backends.BACKENDS.values():
        if not backend.runs("simulate"):
            continue
        runs = backend.entry("simulate_runs")
        assert isinstance(runs.RECORDS_FAILURES, bool)
        assert isinstance(runs.EFFORTS_ALWAYS, bool)
        shapes[backend.name] = tuple(
            tuple(inspect.signature(getattr(runs, f)).parameters)
            for f in ("prepare", "single", "batch")
        )
    assert len(shapes) >= 2 and len(set(shapes.values())) == 1, shapes
    inverse = {
        b.name: tuple(inspect.signature(b.entry("inverse_runs")).parameters)
        for b in backends.BACKENDS.values()
        if b.runs("inverse")
    }
    assert len(inverse) == 3 and len(set(inverse.values())) == 1, inverse


def test_old_module_paths_warn_and_give_the_modules_at_their_new_place():
    import importlib
    import sys
    import warnings

    from rrt_pin import _moved

    for old, new in [*_moved.MOVED.items(), ("rrt_pin.symbolic.kane", "rrt_pin.dynamics.symbolic.kane"),
                     ("rrt_pin.commands.inverse", "rrt_pin.cli.commands.inverse")]:  # fmt: skip
        sys.modules.pop(old, None)
        if old in _moved.PUBLIC:  # public API: the same module, no warning
            with warnings.catch_warnings():
                warnings.simplefilter("error")
                module = importlib.import_module(old)
        else:
            with pytest.warns(DeprecationWarning, match=re.escape(new)):
                module = importlib.import_module(old)
        assert module is importlib.import_module(new), old
    not_moved = {"rrt_pin.simulate", "rrt_pin.compiled", "rrt_pin.derivatives"}
    assert _moved.PUBLIC == {f"rrt_pin.{n}" for n in rrt_pin._MODULES} - not_moved
    # the three 0.3 modules that became packages offer their old names
    from rrt_pin.cli import main
    from rrt_pin.robot import Robot

    assert Robot is importlib.import_module("rrt_pin.robot.robot").Robot
    assert main is importlib.import_module("rrt_pin.cli.app").main
    with pytest.warns(DeprecationWarning, match="rrt_pin.io.files"):
        from rrt_pin.io import atomic_write
    assert atomic_write is importlib.import_module("rrt_pin.io.files").atomic_write
    # a name that never existed is still an error
    with pytest.raises(ModuleNotFoundError):
        importlib.import_module("rrt_pin.nothing_here")


#: Modules that may exceed :data:`MAX_LINES`: the numba kernels (each integrator's loop
#: kept whole in one function for the compiler, their branches side by side), and the
#: template of any robot's integrators and its lanes, which become one generated module a
#: robot.
LONG_KERNELS = {
    "compiled/_jit_integrators.py",
    "compiled/_jit_batch.py",
    "compiled/_robot_template.py",
    "compiled/_robot_lanes.py",
}
MAX_LINES = 600


def _too_long(root: Path, allowed: set[str]) -> list[str]:
    return [
        f"{path.relative_to(root)}: {n} lines"
        for path in sorted(root.rglob("*.py"))
        if str(path.relative_to(root)) not in allowed
        and (n := len(path.read_text(encoding="utf-8").splitlines())) > MAX_LINES
    ]


def test_no_module_is_over_600_lines_but_the_numba_kernels():
    assert not _too_long(PACKAGE, LONG_KERNELS)
    for name in LONG_KERNELS:
        assert "@" in (PACKAGE / name).read_text(encoding="utf-8")  # still jitted kernels


def test_the_length_rule_can_fail(tmp_path):
    (tmp_path / "long.py").write_text("x = 1\n" * (MAX_LINES + 1))
    (tmp_path / "short.py").write_text("x = 1\n" * MAX_LINES)
    assert _too_long(tmp_path, set()) == [f"long.py: {MAX_LINES + 1} lines"]


def test_a_backends_missing_package_is_said_in_one_place():
    """``Backend.require`` raises every backend's MissingExtra (one wording, one hint)."""
    said = [
        f"{path.relative_to(PACKAGE)}:{n}"
        for path in sorted(PACKAGE.rglob("*.py"))
        for n, line in enumerate(path.read_text(encoding="utf-8").splitlines(), 1)
        for b in backends.BACKENDS.values()
        if f'MissingExtra("{b.requires}"' in line
    ]
    assert not said, said
    with pytest.raises(ImportError, match=r"no_such_module_here not found .*\[fast\]"):
        backends.Backend(
            "x", "", (), (), None, requires="no_such_module_here", extra="fast"
        ).require()
