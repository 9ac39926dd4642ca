#!/usr/bin/env bash
# The tests that compare blocks of macro-steps with the Python reference, on another interpreter:
#   scripts/test-other-python.sh /path/to/python3.12 [pytest args]
# (e.g. pyenv's ~/.pyenv/versions/3.12.*/bin/python, or `uv python install 3.12`). The venv goes to
# .venv-<version> beside .venv; builtin sum() adds with compensation from Python 3.12 on, and the
# reference's sums (linalg.total) must not care.
set -euo pipefail
cd "$(dirname "$0")/.."
PY=${1:?usage: $0 PYTHON [pytest args]}
shift
version=$("$PY" -c 'import sys; print("%d.%d" % sys.version_info[:2])')
venv=.venv-$version
[ -x "$venv/bin/python" ] || "$PY" -m venv "$venv"
"$venv/bin/python" -m pip install --quiet -e ".[test]"
if [ $# -eq 0 ]; then
  set -- tests/run/test_runner.py tests/kernel/test_physical_route.py tests/masters/test_routes.py \
         tests/kernel/test_drkernel.py tests/run/test_certificates.py
fi
"$venv/bin/python" -m pytest -q "$@"
