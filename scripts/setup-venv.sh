#!/usr/bin/env bash
# Create .venv at the repository root and install wavecosim into it (editable), once per change
# of pyproject.toml; `setup-venv.sh test` also installs the test extra (and the peers extra where
# the system has libtbb.so.12, which Ecos needs). The FMUs and the C kernel
# are built on demand by the commands themselves.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${PYTHON:-python3}
if [ ! -x .venv/bin/python ]; then
  echo "setting up .venv (first time: a minute or two)" >&2
  "$PY" -m venv .venv
fi
extras=${1:-}
# the test extra with the peers (Ecos too) where the system has Ecos's libtbb.so.12
if [ "$extras" = test ] && /sbin/ldconfig -p 2>/dev/null | grep -q 'libtbb\.so\.12'; then
  extras=test,peers
fi
target=.
[ -n "$extras" ] && target=".[$extras]"
stamp=.venv/.wavecosim-installed${extras:+-$extras}
if [ ! -f "$stamp" ] || [ pyproject.toml -nt "$stamp" ]; then
  echo "installing wavecosim${extras:+[$extras]} into .venv" >&2
  .venv/bin/python -m pip install --quiet --upgrade pip
  .venv/bin/python -m pip install --quiet -e "$target"
  touch "$stamp"
fi
