"""A catalogue of bad inputs across the CLI, each with the words its one-line error must contain.

Shared by ``tests/test_bad_inputs.py`` (every case: exit 2, one line on stderr,
nothing written) and ``scripts/bad_input_table.py`` (the table in
``docs/bad-input.md``). Files a case needs are made in a scratch folder by
:func:`make_files`; ``{tmp}`` in an argument stands for that folder.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

from rrt_pin.robot.urdf import urdf_xml

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
    rows = "".join(f"{k / 10},{k * 9},0,0\n" for k in range(8))  # q1 in degrees
    (tmp / "degrees.csv").write_text("t,q1,q2,q3\n" + rows)
    (tmp / "extra_joint.csv").write_text(
        "t,q1,q2,q3,q4\n" + "".join(f"{k / 10},0,0,0,0\n" for k in range(8))
    )
    (tmp / "boom_law.py").write_text('raise RuntimeError("the law module failed")\n')
    (tmp / "sparse.csv").write_text("t,q1,q2,q3\n" + "".join(f"{k},0,0,0\n" for k in range(5)))
    (tmp / "half_qd.csv").write_text(
        "t,q1,q2,q3,qd1\n" + "".join(f"{k},0,0,0,0\n" for k in range(8))
    )
    (tmp / "bad.toml").write_text("[params\nm1 = 1\n")
    (tmp / "opt_wrenches.toml").write_text('[options]\nwrenches = "false"\n')
    (tmp / "opt_size.toml").write_text("[options]\nscreenshot-size = [100000, 100000]\n")
    (tmp / "opt_serve.toml").write_text("[options]\nserve-for = -1\n")
    (tmp / "opt_format.toml").write_text('[options]\nformat = "bogus"\n')
    (tmp / "opt_q0.toml").write_text('[options]\nq0 = "a,b"\n')
    (tmp / "twice.csv").write_text("t,q1,q1,q2,q3\n0,0,0,0,0\n1,1,1,1,1\n")
    (tmp / "huge.csv").write_text("t,q1,q2,q3\n0,0,0,0\n1,1e308,0,0\n")
    # viewer and CSV reading
    head = "t,q1,q2,q3\n0,0,0,0\n"
    (tmp / "word.csv").write_text(head + "1,0,abc,0\n")
    (tmp / "gap.csv").write_text(head + "1,0,,0\n")
    (tmp / "short.csv").write_text(head + "1,0,0\n")
    (tmp / "long.csv").write_text(head + "1,0,0,0,7\n")
    (tmp / "blank_nan.csv").write_text("t,q1,q2,q3\n\n0,0,0,0\n\n1,0,0,nan\n")
    (tmp / "backwards.csv").write_text(head + "2,0,0,0\n1,0,0,0\n")
    (tmp / "empty.csv").write_text("")
    (tmp / "folder.csv").mkdir()
    sweep = "[sweep]\ntf = 1.0\ndt = 0.1\n"
    (tmp / "sweep_ok.toml").write_text(sweep + "[vary]\nm3 = [30, 40]\n")
    (tmp / "sweep_unknown.toml").write_text(sweep + "[vary]\nmass = [1, 2]\n")
    (tmp / "sweep_empty.toml").write_text(sweep + "[vary]\nm3 = []\n")
    (tmp / "sweep_robot.toml").write_text(sweep + 'robot = "ur6"\n[vary]\nkp_1 = [1, 2]\n')
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
    (tmp / "chain1000.urdf").write_text(chain_urdf(1000))
    zeros = ",".join(["0"] * 1000)
    # 0.1 s: the memory it needs is refused, whatever the disk's room for its 15 MB of output
    (tmp / "chain1000.toml").write_text(f'[options]\nq0 = "{zeros}"\nqf = "{zeros}"\ntf = 0.1\n')
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
    # sweep output folder
    import json

    from rrt_pin.sweeps.spec import load_spec

    ok = load_spec(tmp / "sweep_ok.toml")
    started = json.dumps({"spec_hash": ok.digest(), "chunk": ok.chunk, "done": []})
    (tmp / "sweep_dangling").symlink_to(tmp / "nowhere")
    (tmp / "sweep_stale" / "chunks").mkdir(parents=True)
    (tmp / "sweep_stale" / "chunks" / "chunk-000000.parquet").write_bytes(b"old rows")
    for name, text in (("list", "[]"), ("keys", '{"spec_hash": "x"}'),
                       ("types", '{"spec_hash": 3, "chunk": 2, "done": []}'),
                       ("chunksfile", started), ("stray", started),
                       ("backend", started.replace('"done"', '"backend": "compiled", "done"'))):  # fmt: skip
        (tmp / f"sweep_{name}").mkdir()
        (tmp / f"sweep_{name}" / "manifest.json").write_text(text)
    (tmp / "sweep_chunksfile" / "chunks").write_text("not a folder")
    (tmp / "sweep_stray" / "chunks").mkdir()
    (tmp / "sweep_stray" / "chunks" / "extra.parquet").write_bytes(b"someone else's")
    (tmp / "sweep_link").mkdir()
    (tmp / "sweep_link" / "manifest.json").symlink_to(tmp / "sweep_ok.toml")
    # sweep specs, Dask and the sweep command
    for name, text in (
        ("aot_vary", sweep + "[[vary]]\nm3 = [1, 2]\n"),
        ("aot_sweep", "[[sweep]]\ntf = 1.0\n"),
        ("vary_str", 'vary = "m3"\n' + sweep),
        ("sweep_int", "sweep = 3\n"),
        ("base_int", "base = 3\n" + sweep),
        ("keep_int", "keep = 3\n" + sweep),
        ("base_list", sweep + "[base]\ng = [1, 2]\n"),
        ("n1e9", sweep + "[vary]\nm3 = { linspace = [30, 50, 1e9] }\n"),
        ("n1e18", sweep + "[vary]\nm3 = { linspace = [30, 50, 1e18] }\n"),
        ("n1e300", sweep + "[vary]\nm3 = { linspace = [30, 50, 1e300] }\n"),
        ("n2p63", sweep + "[vary]\nm3 = { linspace = [30, 50, 9223372036854775807] }\n"),
        ("product", sweep + "[vary]\nm3 = { linspace = [30, 50, 100000] }\n"
         "m2 = { linspace = [1, 5, 100000] }\n"),
        ("chunks", sweep + "chunk = 1\n[vary]\nm3 = { linspace = [30, 50, 1e6] }\n"),
        ("deep", sweep + "x = " + "[" * 100_000 + "]" * 100_000 + "\n"),
        ("bigint", sweep + "[vary]\nm3 = [1" + "0" * 400 + "]\n"),
    ):  # fmt: skip
        (tmp / f"spec_{name}.toml").write_text(text)
    (tmp / "run_params.toml").write_text("[params]\nm3 = 50\n")
    (tmp / "run_bench_quick.toml").write_text('[bench]\nquick = "yes"\n')
    # limits, damping and friction
    (tmp / "limit_lower_above.urdf").write_text(good.replace('lower="-', 'lower="9', 1))
    dynamics = 'velocity="1e6"/>\n    <dynamics {}/>'
    for name, attr in (("damping_negative", 'damping="-0.5"'), ("friction_negative",
                       'friction="-0.5"')):  # fmt: skip
        (tmp / f"{name}.urdf").write_text(
            good.replace('velocity="1e6"/>', dynamics.format(attr), 1)
        )
    (tmp / "limit_nan.urdf").write_text(good.replace('effort="1e9"', 'effort="nan"', 1))


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
    #: Patterns of the message that depend on the machine (its free memory): the table
    #: in docs/bad-input.md shows "…" in their place; ``words`` must not overlap them.
    machine: tuple[str, ...] = ()
    #: Environment variables set for the case (name, value).
    env: tuple[tuple[str, str], ...] = ()

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
    Case(
        "NaN in a CSV",
        ("view", "--trajectory", "{tmp}/nan.csv", "--serve-for", "0"),
        "nan.csv' line 3, column 'q1': 'nan' is not a finite number",
    ),
    Case(
        "inf in a CSV",
        ("view", "--trajectory", "{tmp}/inf.csv", "--serve-for", "0"),
        "inf.csv' line 3, column 'q2': 'inf' is not a finite number",
    ),
    Case(
        "CSV without a q column",
        ("view", "--trajectory", "{tmp}/missing.csv", "--serve-for", "0"),
        "q3",
    ),
    Case(
        "inverse --trajectory: a joint's column missing",
        ("inverse", "--trajectory", "{tmp}/missing.csv", "--csv", OUT),
        "missing.csv' lacks column 'q3'; it needs t and q1,q2,q3; it has t,q1,q2",
    ),
    Case(
        "inverse --trajectory: NaN in the file",
        ("inverse", "--trajectory", "{tmp}/nan.csv", "--csv", OUT),
        "nan.csv' line 3, column 'q1': 'nan' is not a finite number",
    ),
    Case(
        "inverse --trajectory: degrees for radians",
        ("inverse", "--trajectory", "{tmp}/degrees.csv", "--csv", OUT),
        "q1 reaches 63, more than two turns (12.57 rad) for a revolute joint: given in degrees?",
    ),
    Case(
        "inverse --trajectory: too few samples to differentiate",
        ("inverse", "--trajectory", "{tmp}/sparse.csv", "--csv", OUT),
        "5 samples are too few to differentiate (qd and qdd not given)",
    ),
    Case(
        "inverse --trajectory: some velocity columns only",
        ("inverse", "--trajectory", "{tmp}/half_qd.csv", "--csv", OUT),
        "half_qd.csv' has some qd columns but lacks 'qd2'",
    ),
    Case(
        "inverse --trajectory: times that go back",
        ("inverse", "--trajectory", "{tmp}/backwards.csv", "--csv", OUT),
        "backwards.csv' line 4, column 't': times must increase strictly, but 1 s follows 2 s",
    ),
    Case(
        "view --path-frame that the robot does not have",
        ("view", "--path-frame", "nope", "--serve-for", "0"),
        "--path-frame='nope' is not a frame of the robot; its last frames: mount, link0",
    ),
    Case(
        "simulate: two laws at once",
        ("simulate", "--passive", "--track", "{tmp}/nan.csv", "--csv", OUT),
        "--passive and --track both choose the law: give one",
    ),
    Case(
        "simulate --controller: a module that is not there",
        ("simulate", "--controller", "no_such_law_module:law", "--csv", OUT),
        "--controller 'no_such_law_module:law': module 'no_such_law_module' not found",
    ),
    Case(
        "simulate --controller: a module that raises when imported",
        ("simulate", "--controller", "{tmp}/boom_law.py:law", "--csv", OUT),
        "boom_law.py' raised RuntimeError: the law module failed",
    ),
    Case(
        "inverse --trajectory: a joint the robot does not have",
        ("inverse", "--trajectory", "{tmp}/extra_joint.csv", "--csv", OUT),
        "has column 'q4', which is not one of RRT arm's 3 joints (q1,q2,q3)",
    ),
    Case(
        "simulate --controller without a function name",
        ("simulate", "--controller", "mylaw", "--csv", OUT),
        "--controller 'mylaw' must be MODULE:FUNCTION",
    ),
    Case(
        "simulate --efforts: an effort column missing",
        ("simulate", "--efforts", "{tmp}/missing.csv", "--csv", OUT),
        "missing.csv' lacks column 'T01x'; it needs t and T01x,T12y,F23z",
    ),
    Case(
        "simulate --track with a target",
        ("simulate", "--track", "{tmp}/nan.csv", "--qf", "1,1,1", "--csv", OUT),
        "--qf does not apply with --track: --track sets the law",
    ),
    Case(
        "simulate --passive with a gain",
        ("simulate", "--passive", "--kd", "3", "--csv", OUT),
        "--kd does not apply with --passive: no controller acts",
    ),
    Case(
        "inverse --trajectory with --tf",
        ("inverse", "--trajectory", "{tmp}/nan.csv", "--tf", "3", "--csv", OUT),
        "--tf does not apply with --trajectory: the file gives the times",
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
        "run file not TOML",
        ("inverse", "--config", "{tmp}/bad.toml", "--csv", OUT),
        "not valid TOML",
    ),
    Case(
        "unknown name in a run file",
        ("simulate", "--config", "{tmp}/unknown.toml", "--csv", OUT),
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
        "run file larger than 1 MB",
        ("inverse", "--config", "{tmp}/huge.toml", "--csv", OUT),
        "larger than the 1 MB allowed",
    ),
    Case(
        "run file not UTF-8",
        ("inverse", "--config", "{tmp}/latin1.toml", "--csv", OUT),
        "not UTF-8",
    ),
    Case(
        "run file nested too deeply",
        ("inverse", "--config", "{tmp}/deep.toml", "--csv", OUT),
        "nested too deeply",
    ),
    Case(
        "run-file integer beyond 64 bits",
        ("inverse", "--config", "{tmp}/bigint.toml", "--csv", OUT),
        "beyond TOML's 64-bit range",
    ),
    Case(
        "power tower in a run file",
        ("inverse", "--config", "{tmp}/power.toml", "--csv", OUT),
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
        "sweep: a robot name the registry does not know",
        ("sweep", "{tmp}/sweep_robot.toml", "--out", "{tmp}/sweep"),
        "robot='ur6' is not one of rrt, ",
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
    Case(
        "a default backend that does not exist",
        ("inverse", "--csv", OUT),
        "RRT_PIN_BACKEND='fastest' is not one of pinocchio, symbolic, compiled, auto",
        env=(("RRT_PIN_BACKEND", "fastest"),),
    ),
    Case(
        "a default backend that is not a name",
        ("simulate", "--tf", "1", "--csv", OUT),
        "RRT_PIN_BACKEND='1e9' is not one of pinocchio, symbolic, compiled, auto",
        env=(("RRT_PIN_BACKEND", "1e9"),),
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
    Case(
        "a model whose Pinocchio data does not fit in memory (1,000 joints)",
        (
            "inverse",
            "--urdf",
            "{tmp}/chain1000.urdf",
            "--config",
            "{tmp}/chain1000.toml",
            "--csv",
            OUT,
        ),
        "inverse dynamics of a 1000-joint model needs 64.8 GB (32.3 GB a copy of Pinocchio's Data",
        machine=(r"(?<=more than the )[\d.]+ [kMGT]?B it may use: .*$",),
    ),
    # viewer and CSV reading
    Case(
        "CSV value that is not a number",
        ("view", "--trajectory", "{tmp}/word.csv", "--serve-for", "0"),
        "word.csv' line 3, column 'q2': 'abc' is not a number",
    ),
    Case(
        "CSV value missing (empty field)",
        ("view", "--trajectory", "{tmp}/gap.csv", "--serve-for", "0"),
        "gap.csv' line 3, column 'q2': the value is missing",
    ),
    Case(
        "CSV line with too few fields",
        ("view", "--trajectory", "{tmp}/short.csv", "--serve-for", "0"),
        "short.csv' line 3 has 3 fields but line 1 names 4 columns: the value of column 'q3' "
        "is missing",
    ),
    Case(
        "CSV line with too many fields",
        ("view", "--trajectory", "{tmp}/long.csv", "--serve-for", "0"),
        "long.csv' line 3 has 5 fields but line 1 names 4 columns: an extra value '7' follows "
        "the last column 'q3'",
    ),
    Case(
        "CSV NaN after blank lines (line numbers as an editor counts)",
        ("view", "--trajectory", "{tmp}/blank_nan.csv", "--serve-for", "0"),
        "blank_nan.csv' line 5, column 'q3': 'nan' is not a finite number",
    ),
    Case(
        "CSV times that go back",
        ("view", "--trajectory", "{tmp}/backwards.csv", "--serve-for", "0"),
        "backwards.csv' line 4, column 't': times must increase strictly, but 1 s follows 2 s "
        "(line 3)",
    ),
    Case(
        "empty CSV",
        ("view", "--trajectory", "{tmp}/empty.csv", "--serve-for", "0"),
        "empty.csv' is empty: line 1 must name the columns",
    ),
    Case(
        "CSV that is a folder",
        ("view", "--trajectory", "{tmp}/folder.csv", "--serve-for", "0"),
        "folder.csv': expected inverse, simulate or the path of a CSV file",
    ),
    # sweep output folder
    Case(
        "sweep: empty --out",
        ("sweep", "{tmp}/sweep_ok.toml", "--out", ""),
        "argument --out: must not be empty",
    ),
    Case(
        "sweep: --out a dangling symbolic link",
        ("sweep", "{tmp}/sweep_ok.toml", "--out", "{tmp}/sweep_dangling"),
        "sweep_dangling' is a symbolic link to nothing",
    ),
    Case(
        "sweep: --out a folder with files and no manifest",
        ("sweep", "{tmp}/sweep_ok.toml", "--out", "{tmp}/sweep_stale"),
        "sweep_stale' is not empty and holds no sweep",
    ),
    Case(
        "sweep: a manifest that is a JSON list",
        ("sweep", "{tmp}/sweep_ok.toml", "--out", "{tmp}/sweep_list", "--resume"),
        "is not a sweep's manifest: a JSON list, not an object",
    ),
    Case(
        "sweep: a manifest missing keys",
        ("sweep", "{tmp}/sweep_ok.toml", "--out", "{tmp}/sweep_keys", "--resume"),
        "is not a sweep's manifest: it has no 'chunk'",
    ),
    Case(
        "sweep: a manifest with values of the wrong type",
        ("sweep", "{tmp}/sweep_ok.toml", "--out", "{tmp}/sweep_types", "--resume"),
        "is not a sweep's manifest: 'spec_hash' must be a string, not int",
    ),
    Case(
        "sweep: --resume with chunks a file",
        ("sweep", "{tmp}/sweep_ok.toml", "--out", "{tmp}/sweep_chunksfile", "--resume"),
        "chunks' is a regular file, not a folder",
    ),
    Case(
        "sweep: --resume with a stray file in chunks",
        ("sweep", "{tmp}/sweep_ok.toml", "--out", "{tmp}/sweep_stray", "--resume"),
        "extra.parquet' is not a chunk of this sweep",
    ),
    Case(
        "sweep: --resume on another backend than the sweep ran on",
        ("sweep", "{tmp}/sweep_ok.toml", "--out", "{tmp}/sweep_backend", "--resume"),
        "it ran on backend 'compiled', which this process would not use (now 'pinocchio')",
    ),
    Case(
        "sweep: a manifest that is a symbolic link",
        ("sweep", "{tmp}/sweep_ok.toml", "--out", "{tmp}/sweep_link"),
        "manifest.json': it is a symbolic link (not followed)",
    ),
    # user laws, simulation runs and their messages
    Case(
        "simulate: an output interval odepack cannot start on (--tf 1e-300 --dt 1e-300)",
        ("simulate", "--tf", "1e-300", "--dt", "1e-300", "--csv", OUT),
        "method 'odepack' cannot start on a first output interval of 1e-300 s",
    ),
    Case(
        "simulate: a fixed step of 1e-9 s (1.5e10 steps of rk4)",
        ("simulate", "--method", "rk4", "--step", "1e-9", "--csv", OUT),
        "would take 1.5e+10 steps",
    ),
    Case(
        "simulate: a fixed-step grid of more steps than the limit (leapfrog, --dt 1e-5)",
        ("simulate", "--method", "leapfrog", "--tf", "20", "--dt", "1e-5", "--csv", OUT),
        "more than the 1,000,000 a run may take on backend 'pinocchio'",
    ),
    # sweep specs, Dask and the sweep command
    Case(
        "sweep spec: [[vary]], an array of tables",
        ("sweep", "{tmp}/spec_aot_vary.toml", "--out", "{tmp}/sweep"),
        "[vary] must be a table of name = values or { kind = [...] }, not an array of tables",
    ),
    Case(
        "sweep spec: [[sweep]], an array of tables",
        ("sweep", "{tmp}/spec_aot_sweep.toml", "--out", "{tmp}/sweep"),
        "[sweep] must be a table of options (task, tf, dt, count …), not an array of tables",
    ),
    Case(
        'sweep spec: vary = "m3", a string',
        ("sweep", "{tmp}/spec_vary_str.toml", "--out", "{tmp}/sweep"),
        "[vary] must be a table of name = values or { kind = [...] }, not the string 'm3'",
    ),
    Case(
        "sweep spec: sweep = 3",
        ("sweep", "{tmp}/spec_sweep_int.toml", "--out", "{tmp}/sweep"),
        "[sweep] must be a table of options (task, tf, dt, count …), not int 3",
    ),
    Case(
        "sweep spec: base = 3",
        ("sweep", "{tmp}/spec_base_int.toml", "--out", "{tmp}/sweep"),
        "[base] must be a table of name = value, not int 3",
    ),
    Case(
        "sweep spec: keep = 3",
        ("sweep", "{tmp}/spec_keep_int.toml", "--out", "{tmp}/sweep"),
        "[keep] must be a table (metrics = [...], trajectories = [...]), not int 3",
    ),
    Case(
        "sweep spec: [base] g = [1, 2] for the arm",
        ("sweep", "{tmp}/spec_base_list.toml", "--out", "{tmp}/sweep"),
        "[base] g = [1, 2] must be a number (lists of values per joint are for a URDF sweep)",
    ),
    Case(
        "sweep spec: a grid of 1e9 points (counted, never made)",
        ("sweep", "{tmp}/spec_n1e9.toml", "--out", "{tmp}/sweep"),
        "1,000,000,000 variants ([vary] m3: 1,000,000,000) is over the limit of 100,000,000",
    ),
    Case(
        "sweep spec: a grid of 1e18 points",
        ("sweep", "{tmp}/spec_n1e18.toml", "--out", "{tmp}/sweep"),
        "about 1e+18 variants ([vary] m3: about 1e+18) is over the limit",
    ),
    Case(
        "sweep spec: a grid of 1e300 points",
        ("sweep", "{tmp}/spec_n1e300.toml", "--out", "{tmp}/sweep"),
        "about 1e+300 variants ([vary] m3: about 1e+300) is over the limit",
    ),
    Case(
        "sweep spec: a grid of 2**63-1 points",
        ("sweep", "{tmp}/spec_n2p63.toml", "--out", "{tmp}/sweep"),
        "about 9.2e+18 variants ([vary] m3: about 9.2e+18) is over the limit",
    ),
    Case(
        "sweep spec: two grids whose product is over the limit",
        ("sweep", "{tmp}/spec_product.toml", "--out", "{tmp}/sweep"),
        "10,000,000,000 variants ([vary] m3: 100,000 × [vary] m2: 100,000) is over the limit",
    ),
    Case(
        "sweep spec: chunks of 1 variant, a million of them",
        ("sweep", "{tmp}/spec_chunks.toml", "--out", "{tmp}/sweep"),
        "chunk=1 makes 1,000,000 chunks of 1,000,000 variants, over the limit of 100,000",
    ),
    Case(
        "sweep spec: arrays nested 100,000 deep",
        ("sweep", "{tmp}/spec_deep.toml", "--out", "{tmp}/sweep"),
        "is not valid TOML: nested too deeply",
    ),
    Case(
        "sweep spec: an integer of 401 digits",
        ("sweep", "{tmp}/spec_bigint.toml", "--out", "{tmp}/sweep"),
        "vary.m3[0] is an integer of about 401 digits, beyond TOML's 64-bit range",
    ),
    Case(
        "sweep --plot: not a column (checked before the sweep)",
        ("sweep", "{tmp}/sweep_ok.toml", "--out", "{tmp}/sweep", "--plot", "nope"),
        "--plot 'nope' is not a column; valid: final_error_q1",
    ),
    Case(
        "sweep --plot: a column of text",
        ("sweep", "{tmp}/sweep_ok.toml", "--out", "{tmp}/sweep", "--plot", "diverged_reason"),
        "--plot 'diverged_reason' is a column of text; plot one of numbers",
    ),
    Case(
        "sweep --scheduler tls:// without TLS settings",
        (
            "sweep",
            "{tmp}/sweep_ok.toml",
            "--out",
            "{tmp}/sweep",
            "--scheduler",
            "tls://127.0.0.1:9",
        ),
        "tls:// needs Dask's TLS settings",
    ),
    Case(
        "sweep --scheduler ucx:// without UCX",
        (
            "sweep",
            "{tmp}/sweep_ok.toml",
            "--out",
            "{tmp}/sweep",
            "--scheduler",
            "ucx://127.0.0.1:9",
        ),
        "the ucx:// transport is not available here",
    ),
    Case(
        "sweep --scheduler with an unknown scheme",
        ("sweep", "{tmp}/sweep_ok.toml", "--out", "{tmp}/sweep", "--scheduler", "foo://host:1"),
        "'foo://host:1': not an address like tcp://host:port",
    ),
    Case(
        "sweep without --out",
        ("sweep", "{tmp}/sweep_ok.toml"),
        "sweep needs --out DIR",
    ),
    Case(
        "sweep --worker-timeout 0",
        ("sweep", "{tmp}/sweep_ok.toml", "--out", "{tmp}/sweep", "--worker-timeout", "0"),
        "argument --worker-timeout",
    ),
    Case(
        "sweep --config: a run file's [params]",
        (
            "sweep",
            "{tmp}/sweep_ok.toml",
            "--out",
            "{tmp}/sweep",
            "--config",
            "{tmp}/run_params.toml",
        ),
        "[params] do not apply to 'rrt-pin sweep'",
    ),
    Case(
        "bench --config: a run file's [params]",
        ("bench", "--config", "{tmp}/run_params.toml", "--out", "{tmp}/bench"),
        "[params] do not apply to 'rrt-pin bench'",
    ),
    Case(
        'bench --config: [bench] quick = "yes"',
        ("bench", "--config", "{tmp}/run_bench_quick.toml", "--out", "{tmp}/bench"),
        "[bench]: --quick = 'yes' must be true or false",
    ),
    # simulate --accuracy
    Case(
        "simulate --accuracy 0",
        ("simulate", "--accuracy", "0", "--csv", OUT),
        "argument --accuracy: must lie in (0, 1) [rad or m]: '0'",
    ),
    Case(
        "simulate --accuracy 1",
        ("simulate", "--accuracy", "1", "--csv", OUT),
        "argument --accuracy: must lie in (0, 1) [rad or m]: '1'",
    ),
    Case(
        "simulate --accuracy nan",
        ("simulate", "--accuracy", "nan", "--csv", OUT),
        "argument --accuracy: must be finite: 'nan'",
    ),
    Case(
        "simulate --accuracy abc",
        ("simulate", "--accuracy", "abc", "--csv", OUT),
        "argument --accuracy: not a number: 'abc'",
    ),
    # limits, damping and friction
    Case(
        "URDF limit lower > upper",
        (
            "simulate",
            "--urdf",
            "{tmp}/limit_lower_above.urdf",
            "--passive",
            "--q0",
            "0,0,0",
            "--csv",
            OUT,
        ),  # fmt: skip
        "joint 'q1' <limit lower upper>: lower 912.566 is above upper 12.5664",
    ),
    Case(
        "URDF negative damping",
        (
            "simulate",
            "--urdf",
            "{tmp}/damping_negative.urdf",
            "--passive",
            "--q0",
            "0,0,0",
            "--csv",
            OUT,
        ),  # fmt: skip
        "joint 'q1' <dynamics damping>: negative, -0.5",
    ),
    Case(
        "URDF negative friction",
        (
            "simulate",
            "--urdf",
            "{tmp}/friction_negative.urdf",
            "--passive",
            "--q0",
            "0,0,0",
            "--csv",
            OUT,
        ),  # fmt: skip
        "joint 'q1' <dynamics friction>: negative, -0.5",
    ),
    Case(
        "URDF NaN limit",
        (
            "simulate",
            "--urdf",
            "{tmp}/limit_nan.urdf",
            "--passive",
            "--q0",
            "0,0,0",
            "--csv",
            OUT,
        ),  # fmt: skip
        "joint 'q1' <limit effort=\"nan\">: not finite",
    ),
    # adams (the generated integrators' Adams method)
    Case(
        "adams on the chapter's arm",
        ("simulate", "--method", "adams", "--backend", "compiled", "--csv", OUT),
        "--method adams runs the generated integrators of other robots",
    ),
    # compiled BDF (SciPy's BDF in the generated integrators)
    Case(
        "BDF on the chapter's arm compiled",
        ("simulate", "--method", "BDF", "--backend", "compiled", "--csv", OUT),
        "--method BDF runs the generated integrators of other robots",
    ),
)
