"""Sweep specs: sizes counted before anything is made, sections of the wrong type, the guarded
loader, numpy values, failing inverse variants, --plot checked first, --config for sweep and bench.
"""

from __future__ import annotations

import itertools
import os
import stat
import subprocess
import sys
import threading
from pathlib import Path

import numpy as np
import pyarrow.parquet as pq
import pytest

import rrt_pin.io._read
from rrt_pin.cli.app import main
from rrt_pin.core.errors import SpecError
from rrt_pin.sweeps.run import sweep
from rrt_pin.sweeps.spec import MAX_VARIANTS, Axis, load_spec, spec_from_dict

ROOT = Path(__file__).resolve().parents[1]
BASE = "[sweep]\ntf = 1.0\ndt = 0.1\n"


def _one_line(info: pytest.ExceptionInfo) -> str:
    text = str(info.value)
    assert "\n" not in text and len(text) < 400, text
    return text


# --------------------------------------------------------------------------- sizes
@pytest.mark.parametrize(
    "kind, args",
    [
        ("linspace", (30.0, 50.0, 5.0)),
        ("linspace", (-3.0, 2.0, 1001.0)),
        ("linspace", (0.0, 1e-320, 4.0)),  # a step that underflows: numpy's other branch
        ("linspace", (1.0, 1.0, 3.0)),
        ("linspace", (5.0, 7.0, 1.0)),
        ("logspace", (2.0, 3.0, 4.0)),
        ("logspace", (-300.0, 300.0, 17.0)),
        ("values", (3.0, -1.0, 2.5)),
    ],
)
def test_a_chunk_takes_grid_values_bit_for_bit_without_the_grid(kind, args):
    axis = Axis("x", kind, args)
    k = np.arange(axis.size)
    rng = np.random.default_rng(3)
    picked = rng.permutation(k)[: max(1, axis.size // 2)]
    assert np.array_equal(axis.take(k).view(np.int64), axis.grid().view(np.int64))
    assert np.array_equal(axis.take(picked).view(np.int64), axis.grid()[picked].view(np.int64))


def test_values_of_any_range_are_those_of_the_full_product():
    spec = spec_from_dict(
        {
            "sweep": {"tf": 1.0, "dt": 0.1, "chunk": 7},
            "vary": {
                "m3": [30.0, 40.0, 50.0],
                "gamma01": {"linspace": [200.0, 400.0, 5]},
                "beta01": {"logspace": [2.0, 3.0, 4]},
            },
        }
    )
    grids = [a.grid() for a in spec.grid_axes]
    full = np.array(list(itertools.product(*grids)))  # first axis slowest
    assert spec.variants == len(full) == 60
    for start, stop in [(0, 60), (5, 12), (59, 60), (13, 41)]:
        values = spec.values(start, stop)
        got = np.column_stack([values[a.name] for a in spec.grid_axes])
        assert np.array_equal(got, full[start:stop])


_HUGE = """
import sys, time
from rrt_pin.core.errors import SpecError
from rrt_pin.sweeps.spec import spec_from_dict
for n in [10**9, 10**18, 1e300, 2**63 - 1]:
    spec = {"sweep": {"tf": 1.0, "dt": 0.1}, "vary": {"m3": {"linspace": [30, 50, n]}}}
    try:
        spec_from_dict(spec)
    except SpecError as e:
        print(e)
    else:
        print("accepted", n)
try:
    spec_from_dict({"sweep": {"tf": 1.0, "dt": 0.1},
                    "vary": {"m3": {"linspace": [30, 50, 100_000]},
                             "m2": {"linspace": [1, 5, 100_000]}}})
except SpecError as e:
    print(e)
"""


def test_grid_sizes_are_counted_before_any_array_is_made():
    """Under a 1.5 GB address-space cap: 7.7 GB of grid would end in MemoryError."""
    import resource

    def cap() -> None:
        limit = 1536 << 20
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    proc = subprocess.run(
        [sys.executable, "-c", _HUGE], capture_output=True, text=True, cwd=ROOT,
        preexec_fn=cap, timeout=120, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"},
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    lines = proc.stdout.splitlines()
    assert len(lines) == 5, proc.stdout
    assert all(f"over the limit of {MAX_VARIANTS:,}" in line for line in lines), proc.stdout
    assert "1,000,000,000 variants" in lines[0]
    assert "about 1e+18 variants" in lines[1] and "about 1e+300 variants" in lines[2]
    assert "about 9.2e+18 variants" in lines[3]
    assert "m3: 100,000 × [vary] m2: 100,000" in lines[4]


def test_chunks_are_counted_too():
    spec = {
        "sweep": {"tf": 1.0, "dt": 0.1, "chunk": 1},
        "vary": {"m3": {"linspace": [30, 50, 10**6]}},
    }
    with pytest.raises(SpecError) as info:
        spec_from_dict(spec)
    assert "chunk=1 makes 1,000,000 chunks" in _one_line(info)


# --------------------------------------------------------------------------- sections
@pytest.mark.parametrize(
    "toml, words",
    [
        (BASE + "[[vary]]\nm3 = [1, 2]\n", "[vary] must be a table of name = values or "
         "{ kind = [...] }, not an array of tables"),
        ("[[sweep]]\ntf = 1.0\n", "[sweep] must be a table of options"),
        ('vary = "m3"\n' + BASE, "[vary] must be a table of name = values or { kind = [...] }, "
         "not the string 'm3'"),
        ("sweep = 3\n", "[sweep] must be a table of options (task, tf, dt, count …), not int 3"),
        ("base = 3\n" + BASE, "[base] must be a table of name = value, not int 3"),
        ("keep = 3\n" + BASE, "[keep] must be a table (metrics = [...], trajectories = [...]), "
         "not int 3"),
        (BASE + "[base]\ng = [1, 2]\n", "[base] g = [1, 2] must be a number"),
        (BASE + "[base]\nm3 = { a = 1 }\n", "[base] m3={'a': 1} must be a number"),
        (BASE + "task = ['inverse']\n", "task=['inverse'] is not one of simulate, inverse"),
        (BASE + "method = 3\n", "method=3 must be a method's name"),
        (BASE + '[keep]\nmetrics = [["x"]]\n', "metric ['x'] is not one of"),
        (BASE + "[vary]\nm3 = [1" + "0" * 400 + "]\n", "vary.m3[0] is an integer of about 401 "
         "digits, beyond TOML's 64-bit range"),
    ],
)  # fmt: skip
def test_sections_of_the_wrong_type_are_one_line(tmp_path, toml, words):
    path = tmp_path / "s.toml"
    path.write_text(toml)
    with pytest.raises(SpecError) as info:
        load_spec(path)
    assert words in _one_line(info)


def test_a_robot_is_named_from_the_registry():
    spec = spec_from_dict({"sweep": {"tf": 1.0, "dt": 0.1, "robot": "ur5"}})
    assert spec.robot == "ur5" and not spec.chapter_arm and spec.urdf_file().endswith(".urdf")
    assert spec_from_dict({"sweep": {"tf": 1.0, "dt": 0.1, "robot": "rrt"}}).chapter_arm
    assert spec_from_dict({"sweep": {"tf": 1.0, "dt": 0.1}}).chapter_arm
    with pytest.raises(SpecError, match=r"robot='nope' is not one of rrt, "):
        spec_from_dict({"sweep": {"tf": 1.0, "dt": 0.1, "robot": "nope"}})
    with pytest.raises(SpecError, match="names a robot and a urdf: give one"):
        spec_from_dict({"sweep": {"tf": 1.0, "dt": 0.1, "robot": "ur5", "urdf": "a.urdf"}})


def test_a_urdf_base_list_is_only_for_per_joint_values():
    spec = {"sweep": {"tf": 1.0, "dt": 0.1, "urdf": "arm.urdf"}, "base": {"g": [1.0, 2.0]}}
    with pytest.raises(SpecError) as info:
        spec_from_dict(spec)
    assert (
        "[base] g = [1.0, 2.0] must be a number (lists of values per joint are for a URDF's q0"
        in (_one_line(info))
    )
    spec["base"] = {"qf": [0.1, 0.2]}
    assert spec_from_dict(spec).base == {"qf": [0.1, 0.2]}


def test_numpy_values_in_a_dict_spec(tmp_path):
    plain = {"sweep": {"tf": 1.0, "dt": 0.1, "seed": 3}, "base": {"m3": 40.0},
             "vary": {"m2": [20.0, 25.0], "gamma01": {"linspace": [200, 400.0, 3]}}}  # fmt: skip
    numpy = {"sweep": {"tf": np.float64(1.0), "dt": np.float64(0.1), "seed": np.int64(3)},
             "base": {"m3": np.float64(40.0)},
             "vary": {"m2": np.array([20.0, 25.0]),
                      "gamma01": {"linspace": (np.int32(200), 400.0, np.uint8(3))}}}  # fmt: skip
    a, b = spec_from_dict(plain), spec_from_dict(numpy)
    assert b.source == a.source and b.digest() == a.digest()
    result = sweep(numpy, tmp_path / "out", workers=1, progress=False)
    assert result.variants == 6 and result.computed == 1


@pytest.mark.parametrize("value", [None, [1, 2], 3, b"s.toml"])
def test_the_library_refuses_a_spec_of_another_type(tmp_path, value):
    with pytest.raises(TypeError) as info:
        sweep(value, tmp_path / "out", workers=1, progress=False)
    assert "spec= must be a Spec, a dict or a TOML file's path" in _one_line(info)
    assert not (tmp_path / "out").exists()


# --------------------------------------------------------------------------- the loader
def test_a_device_spec_is_refused_without_reading(tmp_path):
    node = tmp_path / "zero"
    try:  # our own /dev/zero (1, 5), never the machine's
        os.mknod(node, stat.S_IFCHR | 0o600, os.makedev(1, 5))
    except (PermissionError, OSError) as e:
        pytest.skip(f"cannot make a device node here: {e}")
    with pytest.raises(SpecError) as info:
        load_spec(node)
    assert "it is a character device, not a regular file" in _one_line(info)


def test_a_fifo_spec_nobody_writes_is_refused_not_waited_for(tmp_path, monkeypatch):
    monkeypatch.setattr(rrt_pin.io._read, "FIFO_TIMEOUT", 0.3)
    fifo = tmp_path / "spec.fifo"
    os.mkfifo(fifo)
    with pytest.raises(SpecError) as info:
        load_spec(fifo)
    assert "it is a FIFO and nothing came through it for 0.3 s" in _one_line(info)


def test_a_fifo_spec_with_a_writer_is_read(tmp_path):
    fifo = tmp_path / "spec.fifo"
    os.mkfifo(fifo)

    def write() -> None:
        with open(fifo, "w") as fh:
            fh.write(BASE + "[vary]\nm3 = [30, 40]\n")

    writer = threading.Thread(target=write)
    writer.start()
    try:
        assert load_spec(fifo).variants == 2
    finally:
        writer.join(timeout=10)


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda p: p.write_text(BASE + "x = " + "[" * 100_000 + "]" * 100_000 + "\n"),
         "is not valid TOML: nested too deeply"),
        (lambda p: open(p, "wb").truncate((1 << 20) + 1), "larger than the 1 MB allowed"),
        (lambda p: p.write_bytes(b"[sweep]\n# caf\xe9\n"), "is not UTF-8 text (byte 0xe9"),
        (lambda p: p.mkdir(), "it is a folder"),
    ],
)  # fmt: skip
def test_the_spec_loader_has_the_run_file_guards(tmp_path, make, words):
    path = tmp_path / "spec.toml"
    make(path)
    with pytest.raises(SpecError) as info:
        load_spec(path)
    assert words in _one_line(info)


# --------------------------------------------------------------------------- inverse failures
def test_an_overflowing_inverse_variant_fails_alone(tmp_path, capsys):
    spec = tmp_path / "inv.toml"
    spec.write_text('[sweep]\ntask = "inverse"\ntf = 2.0\ndt = 0.1\n[vary]\nq1f = [0.5, 1e300]\n')
    assert main(["sweep", str(spec), "--out", str(tmp_path / "out"), "--workers", "1",
                 "--no-progress"]) == 0  # fmt: skip
    out = capsys.readouterr().out
    assert "diverged: 1" in out and "settled" not in out
    table = pq.read_table(tmp_path / "out" / "chunks").sort_by("variant")
    rows = {name: table.column(name).to_pylist() for name in table.column_names}
    assert rows["diverged"] == [False, True]
    assert rows["diverged_reason"][0] == "" and "the efforts overflow" in rows["diverged_reason"][1]
    assert rows["diverged_coordinate"] == ["", "efforts"]
    assert np.isfinite(rows["peak_effort_T01x"][0]) and np.isnan(rows["peak_effort_T01x"][1])


# --------------------------------------------------------------------------- the command
@pytest.mark.parametrize(
    "metric, words",
    [
        ("nope", "--plot 'nope' is not a column; valid: final_error_q1"),
        ("diverged_reason", "--plot 'diverged_reason' is a column of text; plot one of numbers"),
    ],
)
def test_plot_is_checked_before_the_sweep_runs(tmp_path, capsys, metric, words):
    spec = tmp_path / "s.toml"
    spec.write_text(BASE + "[vary]\nm3 = [30, 40]\n")
    code = main(["sweep", str(spec), "--out", str(tmp_path / "out"), "--plot", metric])
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and words in err, err
    assert not (tmp_path / "out").exists()


def test_sweep_takes_its_options_from_a_run_file(tmp_path, capsys):
    spec = tmp_path / "s.toml"
    spec.write_text(BASE + "[vary]\nm3 = [30, 40]\n")
    run = tmp_path / "run.toml"
    out = tmp_path / "out"
    run.write_text(f'[sweep]\nspec = "{spec}"\nout = "{out}"\nworkers = 1\nno-progress = true\n'
                   'plot = "control_energy"\n')  # fmt: skip
    assert main(["sweep", "--config", str(run)]) == 0
    assert "sweep of 2 variants" in capsys.readouterr().out
    assert (out / "control_energy.png").is_file()


@pytest.mark.parametrize(
    "command, table, words",
    [
        ("sweep", "[params]\nm3 = 50\n", "[params] do not apply to 'rrt-pin sweep'"),
        ("bench", "[params]\nm3 = 50\n", "[params] do not apply to 'rrt-pin bench'"),
        ("bench", '[bench]\nquick = "yes"\n', "[bench]: --quick = 'yes' must be true or false"),
        ("bench", "[bench]\nfast = true\n", "[bench] 'fast' is not an option of 'rrt-pin bench'"),
        ("sweep", "[sweep]\nworker-timeout = -1\n", "--worker-timeout = -1"),
    ],
)
def test_run_files_for_sweep_and_bench(tmp_path, capsys, command, table, words):
    spec = tmp_path / "s.toml"
    spec.write_text(BASE + "[vary]\nm3 = [30, 40]\n")
    run = tmp_path / "run.toml"
    run.write_text(table)
    argv = [command, "--config", str(run)]
    if command == "sweep":
        argv += [str(spec), "--out", str(tmp_path / "out")]
    else:
        argv += ["--out", str(tmp_path / "bench")]
    code = main(argv)
    err = capsys.readouterr().err
    assert code == 2 and err.count("\n") == 1 and words in err, err
    assert sorted(p.name for p in tmp_path.iterdir()) == ["run.toml", "s.toml"]


_RANDOM = """
import sys
from rrt_pin.core.errors import MemoryLimitError
from rrt_pin.sweeps.spec import spec_from_dict
uniform = {"uniform": [30.0, 50.0]}
spec = spec_from_dict({"sweep": {"tf": 1.0, "dt": 0.1, "count": int(sys.argv[1])},
                       "vary": {"m3": uniform, "m2": uniform, "m1": {"lhs": [1.0, 5.0]}}})
try:
    table = spec.random_table()
except MemoryLimitError as e:
    print("refused:", e)
else:
    print("drawn", sorted((k, v.size) for k, v in table.items()))
"""


@pytest.mark.parametrize("count, refused", [(100_000_000, True), (1000, False)])
def test_random_samples_are_refused_before_they_exceed_memory(count, refused):
    """4 columns of 10^8 samples (3.2 GB) under a 1.5 GB cap: refused before any is drawn."""
    import resource

    def cap() -> None:
        limit = 1536 << 20
        resource.setrlimit(resource.RLIMIT_AS, (limit, limit))

    proc = subprocess.run(
        [sys.executable, "-c", _RANDOM, str(count)], capture_output=True, text=True, cwd=ROOT,
        preexec_fn=cap, timeout=120, env={**os.environ, "OPENBLAS_NUM_THREADS": "1"},
    )  # fmt: skip
    assert proc.returncode == 0, proc.stderr
    if refused:
        assert proc.stdout.startswith(
            "refused: drawing the random samples of 100,000,000 variants needs 3.2 GB "
            "(3 random axes of 800 MB each, and the Latin hypercube they come from)"
        ), proc.stdout
    else:
        assert proc.stdout.startswith("drawn [('m1', 1000), ('m2', 1000), ('m3', 1000)]")


def test_the_column_checks_are_params_own():
    """A sweep checks its arm variants column by column: the same verdicts as Params(**row)."""
    from dataclasses import fields

    from rrt_pin.core.errors import RrtPinError
    from rrt_pin.robot.params import Params, check_columns, checked

    rng = np.random.default_rng(5)
    base = Params()
    names = [f.name for f in fields(Params)]
    n = 400
    table = {k: np.full(n, float(getattr(base, k))) for k in names}
    for k in ("m3", "L1", "I3x", "I2z", "beta01", "gamma23", "Tp", "q10"):
        with np.errstate(invalid="ignore"):  # 0·inf: a NaN on purpose
            table[k] = table[k] * rng.choice([1.0, 1.5, -0.5, 3.0, np.inf, np.nan, 0.0], n)
    table["L1"][:3] = [1e308, 9e307, 1e307]  # LB = 2·L1 overflows for the first two
    bad, why = check_columns(table)
    assert 0 < bad.sum() < n
    for i in range(n):
        row = {k: float(table[k][i]) for k in names}
        try:
            made = Params(**row)
        except RrtPinError:
            assert bad[i] and why[i], (i, row)
            continue
        assert not bad[i] and why[i] is None, (i, why[i])
        assert checked(row) == made
