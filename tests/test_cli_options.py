"""Options of `run` and `sweep` through the real command line: --out naming a file (exit 7 as the
table says), `run --set KEY=VALUE`, `sweep --ports` for an SSP system with an overlay, and a cache
that cannot be written."""
import json
import os
import subprocess
import sys
import tempfile
from pathlib import Path

import pytest

from paths import CLI, CONFIGS

SSD = CONFIGS / "two_oscillators.ssd"


def cli(*args, cwd=None):
    proc = subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True, timeout=120, cwd=cwd)
    return proc.returncode, proc.stdout, proc.stderr


def test_out_naming_a_file_is_an_output_error(tmp_path):
    (tmp_path / "taken").write_text("a file\n")
    code, _, err = cli("run", "--T", "0.05", "--quiet", "--out", tmp_path / "taken")
    assert code == 7 and err.splitlines() == [f"error: {tmp_path / 'taken'}: is a file, not a folder; choose another "
                                              f"--out"], err


def test_run_set_gives_a_key_one_value(tmp_path, built_fmus):
    code, out, err = cli("run", "--T", "0.05", "--quiet", "--no-reference", "--set", "master.K=7",
                         "--set", "subsystems.A.parameters.k1=2.5", "--out", tmp_path / "o")
    assert code == 0 and "dr K=7" in out, err
    scenario = json.loads((tmp_path / "o" / "metadata.json").read_text())["scenario"]
    assert scenario["master"]["K"] == 7 and scenario["subsystems"][0]["parameters"]["k1"] == 2.5


def test_run_set_refuses_a_list_and_an_unknown_key(tmp_path):
    code, _, err = cli("run", "--T", "0.05", "--quiet", "--set", "master.K=7,8", "--out", tmp_path / "o")
    assert code == 2 and err.splitlines() == ["error: --set master.K: a run takes one value (a sweep takes lists and "
                                              "distributions)"], err
    code, _, err = cli("run", "--T", "0.05", "--quiet", "--set", "master.Kx=7", "--out", tmp_path / "o")
    assert code == 2 and len(err.splitlines()) == 1 and "master.Kx: unknown key" in err, err


@pytest.mark.slow
def test_sweep_takes_an_ssp_system_with_its_ports_overlay(tmp_path, built_fmus):
    """The overlay's dt and T reach every run, of a general sweep and of the sweep over K."""
    (tmp_path / "ports.yaml").write_text("dt: 0.005\nT: 0.05\n")
    code, _, err = cli("sweep", SSD, "--ports", tmp_path / "ports.yaml", "--set", "master.K=0,3", "--workers", "1",
                       "--quiet", "--out", tmp_path / "general")
    assert code == 0, err
    runs = json.loads((tmp_path / "general" / "runs.json").read_text())["runs"]
    assert [(r["master.K"], r["dt"], r["steps"]) for r in runs] == [(0, 0.005, 10), (3, 0.005, 10)]
    code, _, err = cli("sweep", SSD, "--ports", tmp_path / "ports.yaml", "--K", "3", "--quiet", "--out", tmp_path / "K")
    assert code == 0, err
    runs = json.loads((tmp_path / "K" / "summary.json").read_text())["runs"]
    assert [(r["K"], r["dt"], r["steps"]) for r in runs] == [(3, 0.005, 10)]


def unwritable_cache(tmp_path):
    """An environment whose cache cannot be made (XDG_CACHE_HOME below a regular file: even root cannot
    write there) and that has no HOME."""
    (tmp_path / "a_file").write_text("")
    env = {k: v for k, v in os.environ.items() if k not in ("HOME", "WAVECOSIM_CACHE")}
    return {**env, "XDG_CACHE_HOME": str(tmp_path / "a_file" / "cache")}


def test_an_unwritable_cache_falls_back_to_a_temporary_one_with_one_warning(tmp_path):
    code = "from wavecosim.kernel.build import cache_dir; import os; print(cache_dir(), cache_dir(), " \
           "os.environ['WAVECOSIM_CACHE'])"
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=60,
                          env=unwritable_cache(tmp_path))
    fallback = Path(tempfile.gettempdir()) / f"wavecosim-cache-{os.getuid()}"
    assert proc.returncode == 0 and proc.stdout.split() == [str(fallback)] * 3, proc.stderr
    assert proc.stderr.splitlines() == [f"warning: the cache {tmp_path}/a_file/cache/wavecosim cannot be written "
                                        f"(Not a directory); using {fallback} (set $WAVECOSIM_CACHE to choose a "
                                        f"folder)"]


@pytest.mark.slow
def test_a_run_with_an_unwritable_cache_finishes_without_a_traceback(tmp_path):
    """The first run builds the package into the temporary cache (about a minute on 2 CPUs)."""
    proc = subprocess.run([*CLI, "run", "--T", "0.05", "--quiet", "--out", tmp_path / "o"], capture_output=True,
                          text=True, timeout=600, env=unwritable_cache(tmp_path))
    assert proc.returncode == 0 and "Traceback" not in proc.stderr, proc.stderr
    assert len([line for line in proc.stderr.splitlines() if line.startswith("warning: the cache ")]) == 1
