#!/usr/bin/env python3
"""Write docs/bad-input.md: each bad input of tests/bad_inputs.py and the error it gets.

python scripts/bad_input_table.py          # rewrite the table
python scripts/bad_input_table.py --check  # exit 1 if the committed table is stale
"""

from __future__ import annotations

import contextlib
import io
import os
import re
import sys
import tempfile
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT))

from rrt_pin.cli.app import main  # noqa: E402
from tests.bad_inputs import CASES, make_files  # noqa: E402

DOC = ROOT / "docs" / "bad-input.md"


def table() -> str:
    os.environ.setdefault("RRT_PIN_BACKEND", "pinocchio")  # see the page's introduction
    rows = [
        "# Bad input and what it gets",
        "",
        "Every case prints one line on stderr, exits with status 2 and writes nothing",
        "(`tests/test_bad_inputs.py` checks each; `python scripts/bad_input_table.py`",
        'regenerates this page). `TMP` stands for the folder holding the files; "…"',
        "stands for figures of the machine it ran on (its free memory). The default",
        "backend is Pinocchio here (`RRT_PIN_BACKEND=pinocchio`, as on a machine where",
        "no compiled code is built yet); once it is, the default runs compiled and a",
        "message may name its method (DOP853) instead of odepack.",
        "",
        "| problem | command | exit | message |",
        "| --- | --- | --- | --- |",
    ]
    with tempfile.TemporaryDirectory() as d:
        tmp = Path(d).resolve()
        make_files(tmp)
        for case in CASES:
            err = io.StringIO()
            saved = {m: sys.modules.get(m) for m in case.missing}
            sys.modules.update(dict.fromkeys(case.missing))  # None: the import fails
            environ = {name: os.environ.get(name) for name, _ in case.env}
            os.environ.update(dict(case.env))
            try:
                with contextlib.redirect_stderr(err), contextlib.redirect_stdout(io.StringIO()):
                    code = main(case.args(tmp))
            finally:
                for name, value in environ.items():
                    if value is None:
                        os.environ.pop(name, None)
                    else:
                        os.environ[name] = value
                for m, module in saved.items():
                    if module is None:
                        sys.modules.pop(m, None)
                    else:
                        sys.modules[m] = module
            message = err.getvalue().strip()
            for pattern in case.machine:  # figures of this machine (its free memory)
                message = re.sub(pattern, "…", message)
            message = message.replace(str(tmp), "TMP").replace("|", "\\|")
            variables = "".join(f"{name}={value} " for name, value in case.env)
            command = variables + "rrt-pin " + " ".join(case.argv).replace("{tmp}", "TMP")
            rows.append(f"| {case.problem} | `{command}` | {code} | `{message}` |")
    return "\n".join(rows) + "\n"


if __name__ == "__main__":
    text = table()
    if "--check" in sys.argv[1:]:
        if not DOC.exists() or DOC.read_text(encoding="utf-8") != text:
            print(f"{DOC} is stale: run python scripts/bad_input_table.py", file=sys.stderr)
            sys.exit(1)
        sys.exit(0)
    DOC.write_text(text, encoding="utf-8")
    print(f"wrote {DOC}")
