# Sourced by scripts/demo and scripts/test: make .venv and install the project
# with the given extras, reinstalling only when pyproject.toml or the extras change.
set -euo pipefail
root="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
cd "$root"
py="${PYTHON:-python3}"
if [ ! -x .venv/bin/python ]; then
  echo "creating .venv with $($py --version 2>&1)" >&2
  "$py" -m venv .venv
fi
extras="$1"
stamp=".venv/.rrt-pin-installed"
want="$(cat pyproject.toml | sha256sum | cut -c1-16) $extras"
if [ ! -f "$stamp" ] || ! grep -qxF "$want" "$stamp"; then
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
