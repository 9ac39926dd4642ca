#!/usr/bin/env bash
# The arithmetic, kernel and route tests under every OpenBLAS kernel this CPU can run (OPENBLAS_CORETYPE
# names one; a kernel needs its instructions): no result may depend on which one numpy picks.
set -euo pipefail
cd "$(dirname "$0")/.."
flags=$(grep -m1 '^flags' /proc/cpuinfo || true)
for pair in avx512f:SkylakeX avx2:Haswell avx:Sandybridge; do
  case " $flags " in
    *" ${pair%%:*} "*)
      echo "OPENBLAS_CORETYPE=${pair#*:}" >&2
      OPENBLAS_CORETYPE=${pair#*:} .venv/bin/python -m pytest -q -p no:cacheprovider tests/kernel \
        tests/core/test_readings.py tests/core/test_scale.py tests/masters/test_routes.py tests/test_dcmotor.py ;;
  esac
done
