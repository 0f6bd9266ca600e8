"""A catalogue of bad inputs across the CLI, each with the words its one-line error must contain.

Shared by ``tests/test_bad_inputs.py`` (every case: exit 2, one line on stderr,
nothing written) and ``scripts/bad_input_table.py`` (the table in
``docs/bad-input.md``). Files a case needs are made in a scratch folder by
:func:`make_files`; ``{tmp}`` in an argument stands for that folder.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rrt_pin.urdf import urdf_xml

_NO_INERTIALS = (
    '<robot name="bare"><link name="a"/><link name="b"/>'
    '<joint name="j" type="revolute"><parent link="a"/><child link="b"/><axis xyz="0 0 1"/>'
    '<limit lower="-3" upper="3" effort="1" velocity="1"/></joint></robot>\n'
)


def make_files(tmp: Path) -> None:
    """Write the bad files the cases refer to into ``tmp``."""
    good = urdf_xml()
    (tmp / "rrt.urdf").write_text(good)
    (tmp / "malformed.urdf").write_text(good.replace("</robot>", ""))
    (tmp / "no_inertials.urdf").write_text(_NO_INERTIALS)
    (tmp / "zero_axis.urdf").write_text(good.replace('<axis xyz="0 1 0"/>', '<axis xyz="0 0 0"/>'))
    (tmp / "negative_mass.urdf").write_text(
        good.replace('<mass value="90.0"/>', '<mass value="-90.0"/>')
    )
    (tmp / "nan.csv").write_text("t,q1,q2,q3\n0,0.1,0.2,0.3\n1,nan,0.2,0.3\n")
    (tmp / "inf.csv").write_text("t,q1,q2,q3\n0,0.1,0.2,0.3\n1,0.1,inf,0.3\n")
    (tmp / "missing.csv").write_text("t,q1,q2\n0,0.1,0.2\n1,0.1,0.2\n")
    (tmp / "bad.toml").write_text("[params\nm1 = 1\n")
    (tmp / "opt_wrenches.toml").write_text('[options]\nwrenches = "false"\n')
    (tmp / "opt_size.toml").write_text("[options]\nscreenshot-size = [100000, 100000]\n")
    (tmp / "opt_serve.toml").write_text("[options]\nserve-for = -1\n")
    (tmp / "opt_format.toml").write_text('[options]\nformat = "bogus"\n')
    (tmp / "opt_q0.toml").write_text('[options]\nq0 = "a,b"\n')
    (tmp / "twice.csv").write_text("t,q1,q1,q2,q3\n0,0,0,0,0\n1,1,1,1,1\n")
    (tmp / "huge.csv").write_text("t,q1,q2,q3\n0,0,0,0\n1,1e308,0,0\n")
    sweep = "[sweep]\ntf = 1.0\ndt = 0.1\n"
    (tmp / "sweep_ok.toml").write_text(sweep + "[vary]\nm3 = [30, 40]\n")
    (tmp / "sweep_unknown.toml").write_text(sweep + "[vary]\nmass = [1, 2]\n")
    (tmp / "sweep_empty.toml").write_text(sweep + "[vary]\nm3 = []\n")
    (tmp / "sweep_count.toml").write_text(
        sweep.replace("dt = 0.1", "dt = 0.1\ncount = -5") + "[vary]\nm3 = { uniform = [1, 2] }\n"
    )
    (tmp / "sweep_mass.toml").write_text(sweep + "[vary]\nm1 = { linspace = [-10, 10, 5] }\n")
    (tmp / "unknown.toml").write_text("[params]\nmass = 1\n")
    # expressions and URDF files
    mass = '<mass value="90.0"/>'
    (tmp / "mass_ninety.urdf").write_text(good.replace(mass, '<mass value="ninety"/>'))
    (tmp / "mass_nan.urdf").write_text(good.replace(mass, '<mass value="nan"/>'))
    origin = '<origin xyz="0 0 0.4" rpy="0 0 0"/>\n      <mass'
    (tmp / "origin_nan.urdf").write_text(
        good.replace(origin, origin.replace("0 0 0.4", "0 nan 0.4"), 1)
    )
    (tmp / "entity.urdf").write_text(good.replace("<robot ", _LAUGHS + "<robot ", 1))
    (tmp / "triangle.urdf").write_text(good.replace('izz="1.0"', 'izz="10.0"'))
    (tmp / "chain10000.urdf").write_text(chain_urdf(10_000))
    (tmp / "chain300.urdf").write_text(chain_urdf(300))
    (tmp / "chain65.urdf").write_text(chain_urdf(65))
    zeros = ",".join(["0"] * 65)
    (tmp / "chain65.toml").write_text(f'[options]\nq0 = "{zeros}"\nqf = "{zeros}"\n')
    (tmp / "latin1.urdf").write_bytes(
        good.replace("RRT arm", "RRT arm (caf\xe9)").encode("latin-1")
    )
    with open(tmp / "huge.urdf", "wb") as fh:  # sparse: 20 MB + 1 byte, no disk used
        fh.truncate((20 << 20) + 1)
    with open(tmp / "huge.toml", "wb") as fh:
        fh.truncate((1 << 20) + 1)
    (tmp / "latin1.toml").write_bytes("[params]\n# caf\xe9\nm3 = 50\n".encode("latin-1"))
    (tmp / "deep.toml").write_text("[options]\nq0 = " + "[" * 3000 + "]" * 3000 + "\n")
    (tmp / "bigint.toml").write_text("[params]\nm3 = 1" + "0" * 400 + "\n")
    (tmp / "power.toml").write_text('[params]\nm3 = "9**9**9"\n')
    (tmp / "opt_nobody.toml").write_text("[options]\nfrobnicate = 1\n")
    (tmp / "table_wrong.toml").write_text("[inverse]\nmethod = 'rk4'\n")
    (tmp / "table_unknown.toml").write_text("[simulation]\ndt = 0.1\n")


#: A "billion laughs" document type declaration.
_LAUGHS = (
    '<!DOCTYPE robot [<!ENTITY a "ha"><!ENTITY b "&a;&a;&a;&a;&a;&a;&a;&a;&a;&a;">'
    '<!ENTITY c "&b;&b;&b;&b;&b;&b;&b;&b;&b;&b;">]>\n'
)


def chain_urdf(n: int) -> str:
    """A URDF chain of ``n`` revolute joints (Pinocchio segfaults on 10,000 of them)."""
    inertial = (
        '<inertial><mass value="1"/>'
        '<inertia ixx="0.1" ixy="0" ixz="0" iyy="0.1" iyz="0" izz="0.1"/></inertial>'
    )
    parts = ['<robot name="chain"><link name="l0"/>']
    for i in range(1, n + 1):
        parts.append(
            f'<link name="l{i}">{inertial}</link><joint name="j{i}" type="revolute">'
            f'<parent link="l{i - 1}"/><child link="l{i}"/><origin xyz="0 0 0.1"/>'
            '<axis xyz="0 0 1"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint>'
        )
    parts.append("</robot>\n")
    return "".join(parts)


@dataclass(frozen=True)
class Case:
    """One bad input: what a user typed and what the one-line error must say."""

    problem: str
    argv: tuple[str, ...]
    words: str
    #: Modules made unimportable for the case (an optional extra not installed).
    missing: tuple[str, ...] = ()

    def args(self, tmp: Path) -> list[str]:
        """The argv with ``{tmp}`` filled in."""
        return [a.replace("{tmp}", str(tmp)) for a in self.argv]


OUT = "{tmp}/out.csv"

CASES = (
    Case(
        "malformed URDF",
        (
            "inverse",
            "--urdf",
            "{tmp}/malformed.urdf",
            "--q0",
            "0,0,0",
            "--qf",
            "1,1,1",
            "--csv",
            OUT,
        ),
        "does not parse",
    ),
    Case(
        "URDF without inertials",
        ("inverse", "--urdf", "{tmp}/no_inertials.urdf", "--q0", "0", "--qf", "1", "--csv", OUT),
        "moves no mass",
    ),
    Case(
        "zero joint axis",
        (
            "simulate",
            "--urdf",
            "{tmp}/zero_axis.urdf",
            "--q0",
            "0,0,0",
            "--qf",
            "1,1,0",
            "--kp",
            "1",
            "--kd",
            "1",
            "--csv",
            OUT,
        ),
        "zero axis",
    ),
    Case(
        "negative mass (--set)", ("inverse", "--set", "m1=-1", "--csv", OUT), "m1=-1.0: must be > 0"
    ),
    Case(
        "negative mass (URDF)",
        (
            "inverse",
            "--urdf",
            "{tmp}/negative_mass.urdf",
            "--q0",
            "0,0,0",
            "--qf",
            "1,1,0",
            "--csv",
            OUT,
        ),
        "negative mass",
    ),
    Case("NaN in --set", ("simulate", "--set", "g=nan", "--csv", OUT), "g=nan: must be finite"),
    Case("inf in --set", ("inverse", "--set", "L1=inf", "--csv", OUT), "L1=inf: must be finite"),
    Case("NaN in a CSV", ("view", "--trajectory", "{tmp}/nan.csv", "--serve-for", "0"), "nan"),
    Case("inf in a CSV", ("view", "--trajectory", "{tmp}/inf.csv", "--serve-for", "0"), "inf"),
    Case(
        "CSV without a q column",
        ("view", "--trajectory", "{tmp}/missing.csv", "--serve-for", "0"),
        "q3",
    ),
    Case("unknown --set name", ("simulate", "--set", "mass=1", "--csv", OUT), "unknown parameter"),
    Case("--set without =", ("urdf", "--set", "m1", "-o", "{tmp}/out.urdf"), "NAME=VALUE"),
    Case("negative gain", ("simulate", "--set", "beta01=-1", "--csv", OUT), "beta01=-1.0"),
    Case("--dt <= 0", ("inverse", "--dt", "0", "--csv", OUT), "dt"),
    Case("--dt > --tf", ("inverse", "--tf", "1", "--dt", "2", "--csv", OUT), "dt"),
    Case("--tf <= 0", ("simulate", "--tf", "-1", "--csv", OUT), "tf"),
    Case("--tf not finite", ("simulate", "--tf", "inf", "--csv", OUT), "inf"),
    Case(
        "q0 of the wrong length",
        ("inverse", "--urdf", "{tmp}/rrt.urdf", "--q0", "0,0", "--qf", "1,1,1", "--csv", OUT),
        "q0",
    ),
    Case("unknown method", ("simulate", "--method", "euler", "--csv", OUT), "euler"),
    Case(
        "scene file not TOML",
        ("inverse", "--scene", "{tmp}/bad.toml", "--csv", OUT),
        "not valid TOML",
    ),
    Case(
        "unknown name in a scene file",
        ("simulate", "--scene", "{tmp}/unknown.toml", "--csv", OUT),
        "unknown parameter 'mass'",
    ),
    Case(
        "missing URDF file",
        ("inverse", "--urdf", "{tmp}/nope.urdf", "--q0", "0", "--qf", "1", "--csv", OUT),
        "cannot read",
    ),
    Case("output folder missing", ("inverse", "--csv", "{tmp}/no/such/dir/out.csv"), "no/such/dir"),
    # expressions and URDF files
    Case("power tower in --set", ("inverse", "--set", "L1=9**9**9", "--csv", OUT), "overflows"),
    Case(
        "power tower in --q0",
        ("simulate", "--urdf", "{tmp}/rrt.urdf", "--q0", "10**10**10,0,0", "--csv", OUT),
        "'10**10**10'",
    ),
    Case(
        "deeply nested --set",
        ("inverse", "--set", "L1=" + "(" * 100 + "1" + ")" * 100, "--csv", OUT),
        "201 characters long",
    ),
    Case("complex --set", ("inverse", "--set", "L1=1j", "--csv", OUT), "complex numbers"),
    Case(
        "overflowing rod inertia (--set)",
        ("inverse", "--set", "L1=1e200", "--csv", OUT),
        "L1=1e+200: too large",
    ),
    Case(
        "URDF mass not a number",
        (
            "inverse",
            "--urdf",
            "{tmp}/mass_ninety.urdf",
            "--q0",
            "0,0,0",
            "--qf",
            "0,0,0",
            "--csv",
            OUT,
        ),
        "link 'link1' <inertial><mass value=\"ninety\">: not a number",
    ),
    Case(
        "URDF mass NaN",
        (
            "inverse",
            "--urdf",
            "{tmp}/mass_nan.urdf",
            "--q0",
            "0,0,0",
            "--qf",
            "0,0,0",
            "--csv",
            OUT,
        ),
        '<mass value="nan">: not finite',
    ),
    Case(
        "URDF origin with NaN",
        (
            "inverse",
            "--urdf",
            "{tmp}/origin_nan.urdf",
            "--q0",
            "0,0,0",
            "--qf",
            "0,0,0",
            "--csv",
            OUT,
        ),
        "link 'link1' <inertial><origin xyz=\"0 nan 0.4\">",
    ),
    Case(
        "URDF with entities",
        ("inverse", "--urdf", "{tmp}/entity.urdf", "--q0", "0,0,0", "--qf", "0,0,0", "--csv", OUT),
        "entities and DTDs are not accepted",
    ),
    Case(
        "URDF inertia breaks the triangle inequality",
        (
            "inverse",
            "--urdf",
            "{tmp}/triangle.urdf",
            "--q0",
            "0,0,0",
            "--qf",
            "0,0,0",
            "--csv",
            OUT,
        ),
        "link 'link3' <inertial><inertia>",
    ),
    Case(
        "URDF with 10,000 joints",
        (
            "inverse",
            "--urdf",
            "{tmp}/chain10000.urdf",
            "--q0",
            "0,0,0",
            "--qf",
            "0,0,0",
            "--csv",
            OUT,
        ),
        "at most 1000 joints are supported",
    ),
    Case(
        "URDF not UTF-8",
        ("inverse", "--urdf", "{tmp}/latin1.urdf", "--q0", "0,0,0", "--qf", "0,0,0", "--csv", OUT),
        "not UTF-8",
    ),
    Case(
        "URDF larger than 20 MB",
        ("inverse", "--urdf", "{tmp}/huge.urdf", "--q0", "0,0,0", "--qf", "0,0,0", "--csv", OUT),
        "larger than the 20 MB allowed",
    ),
    Case(
        "URDF is a folder",
        ("inverse", "--urdf", "{tmp}/", "--q0", "0,0,0", "--qf", "0,0,0", "--csv", OUT),
        "it is a folder",
    ),
    Case(
        "scene file larger than 1 MB",
        ("inverse", "--scene", "{tmp}/huge.toml", "--csv", OUT),
        "larger than the 1 MB allowed",
    ),
    Case(
        "scene file not UTF-8",
        ("inverse", "--scene", "{tmp}/latin1.toml", "--csv", OUT),
        "not UTF-8",
    ),
    Case(
        "scene file nested too deeply",
        ("inverse", "--scene", "{tmp}/deep.toml", "--csv", OUT),
        "nested too deeply",
    ),
    Case(
        "scene integer beyond 64 bits",
        ("inverse", "--scene", "{tmp}/bigint.toml", "--csv", OUT),
        "beyond TOML's 64-bit range",
    ),
    Case(
        "power tower in a scene file",
        ("inverse", "--scene", "{tmp}/power.toml", "--csv", OUT),
        "m3='9**9**9' is not a number",
    ),
    # output paths
    Case(
        "urdf -o into a missing folder",
        ("urdf", "-o", "{tmp}/nofolder/x.urdf"),
        "nofolder' does not exist",
    ),
    Case("urdf -o onto a folder", ("urdf", "-o", "{tmp}"), "it is a folder"),
    Case("--csv onto a folder", ("simulate", "--csv", "{tmp}"), "--csv"),
    Case("--csv ending in '/'", ("inverse", "--csv", "{tmp}/new/"), "names a folder"),
    Case(
        "urdf -o under a file",
        ("urdf", "-o", "{tmp}/rrt.urdf/x.urdf"),
        "rrt.urdf' is not a folder",
    ),
    Case(
        "urdf -o file name over 255 bytes",
        ("urdf", "-o", "{tmp}/" + "u" * 300 + ".urdf"),
        "305 bytes long, over the 255",
    ),
    Case(
        "--plot file name over 255 bytes",
        ("inverse", "--plot", "{tmp}/" + "p" * 300 + ".png"),
        "--plot",
    ),
    # sweeps
    Case(
        "sweep: unknown symbol",
        ("sweep", "{tmp}/sweep_unknown.toml", "--out", "{tmp}/sweep"),
        "[vary] mass: unknown name",
    ),
    Case(
        "sweep: empty range",
        ("sweep", "{tmp}/sweep_empty.toml", "--out", "{tmp}/sweep"),
        "[vary] m3 is an empty list",
    ),
    Case(
        "sweep: negative count",
        ("sweep", "{tmp}/sweep_count.toml", "--out", "{tmp}/sweep"),
        "count=-5 must be an integer >= 1",
    ),
    Case(
        "sweep: a range that makes a mass negative",
        ("sweep", "{tmp}/sweep_mass.toml", "--out", "{tmp}/sweep"),
        "[vary] m1 reaches -10",
    ),
    Case(
        "sweep: unreachable scheduler",
        (
            "sweep",
            "{tmp}/sweep_ok.toml",
            "--out",
            "{tmp}/sweep",
            "--scheduler",
            "tcp://127.0.0.1:9",
        ),
        "cannot reach the Dask scheduler 'tcp://127.0.0.1:9'",
    ),
    # run-file options pass the flags' own parsers
    Case(
        "run file: a flag's boolean as a string",
        ("inverse", "--config", "{tmp}/opt_wrenches.toml", "--csv", OUT),
        "--wrenches = 'false' must be true or false",
    ),
    Case(
        "run file: a screenshot size out of range",
        ("view", "--config", "{tmp}/opt_size.toml", "--serve-for", "0"),
        "--screenshot-size = [100000, 100000]",
    ),
    Case(
        "run file: a negative serve-for",
        ("view", "--config", "{tmp}/opt_serve.toml"),
        "--serve-for = -1: must be >= 0",
    ),
    Case(
        "run file: a format not among the choices",
        ("equations", "--config", "{tmp}/opt_format.toml"),
        "--format = 'bogus' is not one of",
    ),
    Case(
        "run file: q0 not numbers",
        ("simulate", "--config", "{tmp}/opt_q0.toml", "--csv", OUT),
        "--q0 = 'a,b'",
    ),
    # empty strings never change meaning
    Case("empty --csv", ("inverse", "--csv", ""), "argument --csv: must not be empty"),
    Case("empty --host", ("view", "--host", "", "--serve-for", "0"), "--host: must not be empty"),
    Case("empty --config", ("simulate", "--config", "", "--csv", OUT), "must not be empty"),
    # results that overflow, CSVs a viewer cannot use
    Case(
        "inverse efforts that overflow",
        ("inverse", "--set", "q1f=1e300", "--csv", OUT),
        "the efforts overflow: T01x",
    ),
    Case(
        "CSV naming a column twice",
        ("view", "--trajectory", "{tmp}/twice.csv", "--serve-for", "0"),
        "names column 'q1' twice",
    ),
    Case(
        "CSV value beyond ±1e30",
        ("view", "--trajectory", "{tmp}/huge.csv", "--serve-for", "0"),
        "is beyond ±1e+30",
    ),
    # optional extras not installed: one line with the command that installs them here
    Case(
        "viewer without the viewer extra",
        ("view", "--trajectory", "simulate", "--serve-for", "0"),
        "meshcat not found (needed for the viewer): ",
        missing=("meshcat",),
    ),
    Case(
        "plot without the plot extra",
        ("inverse", "--plot", "{tmp}/out.png"),
        "matplotlib not found (needed for plots): ",
        missing=("matplotlib",),
    ),
    Case(
        "bench without the symbolic extra",
        ("bench", "--quick", "--out", "{tmp}/bench"),
        "sympy not found (needed for the benchmark's 30-digit reference): ",
        missing=("sympy",),
    ),
    Case(
        "compiled backend without numba",
        ("inverse", "--backend", "compiled", "--csv", OUT),
        "numba not found (needed for backend 'compiled'): ",
        missing=("numba",),
    ),
    # plots: the format follows the suffix
    Case(
        "--plot with a suffix no writer has",
        ("inverse", "--plot", "{tmp}/efforts.jpg"),
        "suffix '.jpg' is not an image format rrt-pin writes; use .png, .svg, .pdf",
    ),
    Case(
        "--plot without a suffix",
        ("simulate", "--plot", "{tmp}/efforts"),
        "no suffix names an image format",
    ),
    # run files shared by the commands: [options] and one table per command
    Case(
        "run file: [options] key no command has",
        ("urdf", "--config", "{tmp}/opt_nobody.toml"),
        "[options] 'frobnicate' is not an option of any command",
    ),
    Case(
        "run file: a command's table with another command's option",
        ("simulate", "--config", "{tmp}/table_wrong.toml", "--csv", OUT),
        "[inverse] 'method' is not an option of 'rrt-pin inverse'",
    ),
    Case(
        "run file: a table named after no command",
        ("inverse", "--config", "{tmp}/table_unknown.toml", "--csv", OUT),
        "unknown table 'simulation'",
    ),
    Case(
        "--step with an adaptive method",
        ("simulate", "--method", "DOP853", "--step", "0.001", "--csv", OUT),
        "--step=0.001 sets the step of the fixed-step methods; DOP853 is adaptive",
    ),
    # streaming outputs: absurd grids, clashing outputs
    Case(
        "inverse grid of over 10^9 samples",
        ("inverse", "--tf", "1e6", "--dt", "1e-6", "--csv", OUT),
        "makes 1,000,000,000,001 samples, over the 1,000,000,000 allowed",
    ),
    Case(
        "inverse motion time Tp=1e300",
        ("inverse", "--set", "Tp=1e300", "--csv", OUT),
        "Tp (the --tf)/--dt: tf=1e+300 s at dt=0.001 s makes 1e+303 samples",
    ),
    Case(
        "simulate output grid of over 10^7 samples",
        ("simulate", "--tf", "1e5", "--dt", "1e-3", "--csv", OUT),
        "over the 10,000,000 a simulation keeps in memory",
    ),
    Case(
        "--csv and --json naming one file",
        ("inverse", "--csv", OUT, "--json", OUT),
        "--csv and --json name the same file",
    ),
    Case(
        "--csv - and --json - both on stdout",
        ("simulate", "--csv", "-", "--json", "-"),
        "--csv and --json name the same file '-'",
    ),
    # tolerances an integrator cannot honour, and runs that cannot go on
    Case(
        "rtol below the integrator's floor",
        ("simulate", "--rtol", "1e-15", "--csv", OUT),
        "rtol=1e-15 is below odepack's floor of 2.22e-14",
    ),
    Case(
        "rtol and atol of 1e-300",
        ("simulate", "--method", "DOP853", "--rtol", "1e-300", "--atol", "1e-300", "--csv", OUT),
        "rtol=1e-300 is below DOP853's floor of 2.22e-14",
    ),
    Case(
        "derivatives too large to take a first step",
        ("simulate", "--tf", "2", "--set", "gamma01=1e300", "--csv", OUT),
        "the first step would be shorter than float64 can resolve",
    ),
    Case(
        "an explicit method on a stiff scene",
        (
            "simulate",
            "--method",
            "RK45",
            "--tf",
            "2",
            "--set",
            "gamma23=1e12",
            "--set",
            "beta23=1e9",
            "--no-error-estimate",
            "--csv",
            OUT,
        ),
        "RK45 gave up after 120,000 evaluations",
    ),  # fmt: skip
    Case(
        "a fixed step too long for a stiff scene (compiled)",
        (
            "simulate",
            "-q",
            "--backend",
            "compiled",
            "--method",
            "rk4",
            "--set",
            "gamma23=1e9",
            "--no-error-estimate",
            "--csv",
            OUT,
        ),
        "the step 0.01 s is too long for this scene",
    ),  # fmt: skip
    Case(
        "keyframes beyond counting",
        ("view", "--set", "Tp=1e300", "--serve-for", "0"),
        "would be 3e+301 keyframes; at most 100,000",
    ),
    Case(
        "compiled inverse dynamics of a robot with too many joints",
        (
            "inverse",
            "--urdf",
            "{tmp}/chain65.urdf",
            "--config",
            "{tmp}/chain65.toml",
            "--backend",
            "compiled",
            "--csv",
            OUT,
        ),
        "--backend compiled: the model has 65 joints; the generated RNEA is made for at most 64",
    ),
    Case(
        "a long joint list in a message",
        ("inverse", "--urdf", "{tmp}/chain300.urdf", "--csv", OUT),
        "(300 names))",
    ),
)
