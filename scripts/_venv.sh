# Sourced by scripts/demo and scripts/test: make .venv and install the project
# with the given extras, reinstalling only when pyproject.toml or the extras change,
# then write the package's bytecode (.pyc) if any is missing or out of date.
# PYTHON=/path/to/python3.11 chooses the interpreter that creates .venv.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
py="${PYTHON:-python3}"
# The oldest Python rrt-pin supports, read from pyproject.toml (requires-python = ">=3.10").
need="$(sed -n 's/^requires-python *= *">= *\([0-9.]*\)".*/\1/p' pyproject.toml)"
need_tuple="(${need/./, })"
too_old() {  # exit status 0 when "$1" is missing, broken or older than $need
  ! "$1" -c "import sys; sys.exit(sys.version_info[:2] < $need_tuple)" >/dev/null 2>&1
}
if [ ! -x .venv/bin/python ]; then
  if too_old "$py"; then
    echo "rrt-pin needs Python >= $need; '$py' is $("$py" --version 2>&1 || echo missing)." >&2
    echo "choose another interpreter: PYTHON=python3.11 $0" >&2
    exit 2
  fi
  echo "creating .venv with $("$py" --version 2>&1)" >&2
  "$py" -m venv .venv
elif too_old .venv/bin/python; then
  echo "the existing .venv uses $(.venv/bin/python --version 2>&1 || echo a broken interpreter);" \
       "rrt-pin needs Python >= $need." >&2
  echo "recreate it: rm -rf .venv && PYTHON=python3.11 $0" >&2
  exit 2
fi
extras="$1"
stamp=".venv/.rrt-pin-installed"
want="$(cat pyproject.toml | sha256sum | cut -c1-16) $extras"
covered() {  # whether an install recorded in $stamp (same pyproject.toml) includes $extras
  [ -f "$stamp" ] || return 1
  grep -qxF "$want" "$stamp" && return 0
  .venv/bin/python - "$stamp" "$extras" <<'PY' 2>/dev/null
import sys, tomllib
stamp, wanted = sys.argv[1], sys.argv[2]
with open("pyproject.toml", "rb") as fh:
    extras = tomllib.load(fh)["project"]["optional-dependencies"]
def expand(names):  # an extra and the rrt-pin[...] extras it names, recursively
    out, todo = set(), list(names)
    while todo:
        name = todo.pop()
        if name in out or name not in extras:
            continue
        out.add(name)
        for req in extras[name]:
            if req.startswith("rrt-pin["):
                todo += req[len("rrt-pin["):req.index("]")].split(",")
    return out
digest = open("pyproject.toml", "rb").read()
import hashlib
head = hashlib.sha256(digest).hexdigest()[:16]
need = expand(wanted.split(","))
for line in open(stamp):
    h, _, have = line.strip().partition(" ")
    if h == head and need <= expand(have.split(",")):
        sys.exit(0)
sys.exit(1)
PY
}
if ! covered; then
  echo "installing rrt-pin[$extras] into .venv" >&2
  log=.venv/pip-install.log
  if ! { .venv/bin/python -m pip install --upgrade pip &&
         .venv/bin/python -m pip install -e ".[$extras]"; } >"$log" 2>&1; then
    tail -n 40 "$log" >&2
    echo "installing rrt-pin[$extras] failed; the whole log is in $log" >&2
    exit 1
  fi
  echo "$want" >> "$stamp"
fi
# The editable install leaves rrt_pin's .pyc to the first import, which a process may not
# write (PYTHONDONTWRITEBYTECODE=1, as containers and CI images often set, or a read-only
# checkout): it would then compile every module it imports, in every run. Write them here,
# as pip does for a wheel; compileall only redoes the files changed since (timestamps, as
# Python checks them at import, even when SOURCE_DATE_EPOCH is set).
# A module that does not compile (its error is printed) is left to fail where it is imported.
.venv/bin/python -m compileall -q --invalidation-mode timestamp rrt_pin >&2 ||
  echo "some of rrt_pin's modules did not compile (above): they fail when imported" >&2
