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
    (tmp / "unknown.toml").write_text("[params]\nmass = 1\n")


@dataclass(frozen=True)
class Case:
    """One bad input: what a user typed and what the one-line error must say."""

    problem: str
    argv: tuple[str, ...]
    words: str

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
)
