"""The build cache mends itself: a cached library or FMU that was truncated, replaced or deleted is
found by the checksum written beside it and built again, and the run finishes. Each test works on a
copy of the cache ($WAVECOSIM_CACHE), never on the one other runs share."""
import os
import shutil
import subprocess

import pytest

from paths import CLI, CONFIGS
from wavecosim.kernel.build import build_library, cache_dir, checksum_file, reusable

RUN = ["run", str(CONFIGS / "two_oscillators.yaml"), "--T", "0.05", "--quiet", "--no-reference"]


@pytest.fixture
def cache(tmp_path, built_fmus):
    """A copy of the built cache, and the paths of the guard's library and of LinearSide's FMU in it."""
    copy = tmp_path / "cache"
    for part in ("lib", "fmus", "gen"):
        shutil.copytree(cache_dir() / part, copy / part)
    guard = build_library("guard", log=lambda msg: None)
    fmu = built_fmus["LinearSide"]
    return copy, copy / guard.relative_to(cache_dir()), copy / fmu.relative_to(cache_dir())


def run_with(cache_folder, folder, script=None):
    env = {**os.environ, "WAVECOSIM_CACHE": str(cache_folder)}
    args = CLI[:1] + ["-c", script] if script else CLI + RUN + ["--out", str(folder / "out")]
    return subprocess.run(args, capture_output=True, text=True, timeout=300, env=env, cwd=folder)


def test_a_truncated_library_and_fmu_are_built_again(cache, tmp_path):
    folder, guard, fmu = cache
    whole = {p: p.read_bytes() for p in (guard, fmu)}
    for path in whole:
        with open(path, "r+b") as f:
            f.truncate(100)
    done = run_with(folder, tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
    assert '"status": "finished"' in (tmp_path / "out" / "summary.json").read_text()
    for path in whole:
        assert path.stat().st_size > 100 and reusable(path)


def test_a_foreign_file_is_not_reused(cache):
    _, guard, _ = cache
    assert reusable(guard)
    guard.write_bytes(guard.read_bytes()[::-1])
    assert not reusable(guard)
    checksum_file(guard).unlink()
    assert not reusable(guard)


@pytest.mark.slow
def test_a_cache_deleted_mid_run_is_built_again(cache, tmp_path):
    """The FMUs are built and found, then the whole cache goes before the run opens them."""
    folder, _, _ = cache
    script = ("import shutil, wavecosim as wc\n"
              "from wavecosim.fmi.builtin import builtin_fmus\n"
              f"builtin_fmus(); shutil.rmtree({str(folder)!r})\n"
              "r = wc.simulate(None, T=0.05, reference=False)\n"
              "print(r.summary['status'])\n")
    done = run_with(folder, tmp_path, script)
    assert done.returncode == 0 and done.stdout.strip() == "finished", done.stderr[-2000:]
    done = run_with(folder, tmp_path)
    assert done.returncode == 0, done.stderr[-2000:]
