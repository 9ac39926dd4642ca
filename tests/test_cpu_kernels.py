"""The same bits whatever BLAS kernel numpy's OpenBLAS picks for the CPU: the shipped scenes' outputs
(scripts/outputs_digest.py) are identical under every OPENBLAS_CORETYPE this CPU can run."""
import os
import subprocess
import sys

import pytest

from paths import ROOT

SCENES = ["two_oscillators", "two_oscillators_stiff", "chain", "foreign_pair", "dcmotor"]


def core_types():
    """The OpenBLAS kernels this CPU can run (a kernel needs its instructions)."""
    flags = set(open("/proc/cpuinfo").read().split()) if os.path.exists("/proc/cpuinfo") else set()
    wanted = [("avx512f", "SkylakeX"), ("avx2", "Haswell"), ("avx", "Sandybridge")]
    return [name for flag, name in wanted if flag in flags]


def digests(core_type):
    env = {**os.environ, "OPENBLAS_CORETYPE": core_type}
    out = subprocess.run([sys.executable, str(ROOT / "scripts" / "outputs_digest.py"), "--T", "0.1", *SCENES],
                         env=env, capture_output=True, text=True, timeout=600)
    assert out.returncode == 0, out.stderr[-2000:]
    return out.stdout.splitlines()


@pytest.mark.slow
def test_the_scenes_have_the_same_bits_under_every_blas_kernel():
    kinds = core_types()
    if len(kinds) < 2:
        pytest.skip("this CPU runs one OpenBLAS kernel only")
    first = digests(kinds[0])
    assert len(first) >= 3 * 7
    for kind in kinds[1:]:
        assert digests(kind) == first, kind
