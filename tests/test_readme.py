"""The README's library example runs, and its CLI table names real commands."""

import re
from pathlib import Path

from rrt_pin.cli import build_parser

README = (Path(__file__).resolve().parents[1] / "README.md").read_text(encoding="utf-8")


def test_library_example_runs(capsys):
    blocks = re.findall(r"```python\n(.*?)```", README, re.S)
    assert blocks, "the README has no Python example"
    namespace: dict = {}
    exec(compile(blocks[0], "README.md", "exec"), namespace)
    assert namespace["tau"].shape == (15001, 3)
    assert namespace["run"].q.shape == (1501, 3)
    assert namespace["eom"].mass_matrix.shape == (3, 3)


def test_cli_reference_names_every_command():
    _, subparsers = build_parser()
    for name in subparsers:
        assert f"`rrt-pin {name}" in README, name
    for name in re.findall(r"`rrt-pin ([a-z]+)", README):
        assert name in subparsers, name


def test_quick_start_is_the_two_scripts():
    quick = README.split("## Quick start", 1)[1].split("```sh", 1)[1].split("```", 1)[0]
    commands = [line.split("#")[0].strip() for line in quick.strip().splitlines()]
    assert commands == ["scripts/demo", "scripts/test"]
