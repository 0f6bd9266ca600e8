"""The README's library example runs, and its CLI table names real commands."""

import re
from pathlib import Path

from rrt_pin.cli.app import build_parser

ROOT = Path(__file__).resolve().parents[1]
README = (ROOT / "README.md").read_text(encoding="utf-8")


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


def test_no_issue_numbers_in_code_docs_or_help():
    """Readers have no issue tracker: code, docs and help never say "issue N"."""
    import re
    import subprocess

    files = subprocess.run(
        ["git", "ls-files", "*.py", "*.md", "*.toml", "scripts/*"],
        capture_output=True, text=True, cwd=ROOT, check=True,
    ).stdout.split()  # fmt: skip
    pattern = re.compile(r"\bissues?\s*#?\d", re.IGNORECASE)
    found = []
    for name in files:
        path = ROOT / name
        if path.is_file():
            for n, line in enumerate(
                path.read_text(encoding="utf-8", errors="replace").splitlines()
            ):
                if pattern.search(line):
                    found.append(f"{name}:{n + 1}: {line.strip()[:80]}")
    assert files and not found, "\n".join(found)


def test_cli_reference_names_every_option():
    """Each command's row of the README's CLI table names every long option it takes."""
    from rrt_pin.cli.app import build_parser

    _, subparsers = build_parser()
    shared = {"--help", "--verbose", "--quiet", "--set", "--config", "--scene"}  # described once
    rows: dict[str, str] = {}
    for line in README.splitlines():  # the CLI reference's row: the first naming the command
        if m := re.match(r"\| `rrt-pin (\w+)", line):
            rows.setdefault(m.group(1), line)
    missing = []
    for name, parser in subparsers.items():
        for action in parser._actions:
            for flag in action.option_strings:
                if flag.startswith("--") and flag not in shared and flag not in rows.get(name, ""):
                    missing.append(f"{name} {flag}")
    assert not missing, missing
    for flag in ("--set", "--config", "-v", "-q"):
        assert f"`{flag}" in README, flag
