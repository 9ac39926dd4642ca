"""A missing optional dependency is one line naming the extra that installs it, never a traceback:
the command line run in a real subprocess with the package hidden (a module of its name on the path
that raises ImportError, as Python does for one not installed)."""
import os
import subprocess

import pytest

from paths import CLI, CONFIGS, THIRD_PARTY
from wavecosim.bench.peers import Refused, peer_run
from wavecosim.errors import ConfigError, optional


def hidden(tmp_path, *modules):
    """The environment of a subprocess in which `modules` do not import."""
    folder = tmp_path / "hidden"
    folder.mkdir(exist_ok=True)
    for module in modules:
        (folder / f"{module}.py").write_text(f"raise ImportError({'No module named ' + repr(module)!r})\n")
    return {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in (str(folder), os.environ.get("PYTHONPATH")) if p)}


def test_a_sweep_on_dask_without_distributed_names_the_extra(tmp_path):
    done = subprocess.run([*CLI, "sweep", str(CONFIGS / "two_oscillators.yaml"), "--set", "master.K=1,2",
                           "--T", "0.02", "--scheduler", "local", "--quiet", "--out", str(tmp_path / "out")],
                          capture_output=True, text=True, timeout=60, env=hidden(tmp_path, "distributed"))
    assert done.returncode == 2, done.stderr
    lines = done.stderr.strip().splitlines()
    assert lines == ["error: --scheduler (a sweep on Dask) needs distributed, which is not installed here: "
                     "pip install 'wavecosim[dask]'"], done.stderr


def test_the_helper_imports_or_names_the_extra():
    assert optional("json", "peers", "x").dumps([1]) == "[1]"
    with pytest.raises(ConfigError, match=r"^the bench needs no_such_module, which is not installed here: "
                                          r"pip install 'wavecosim\[peers\]'$"):
        optional("no_such_module.sub", "peers", "the bench")


@pytest.mark.slow
@pytest.mark.skipif(not (THIRD_PARTY / "omsimulator").is_dir(), reason="the third-party systems are not here")
def test_the_bench_without_libcosimpy_says_which_extra(tmp_path):
    done = subprocess.run([*CLI, "bench", "--only", "real_fmus", "--quick"], capture_output=True, encoding="utf-8",
                          timeout=600, env=hidden(tmp_path, "libcosimpy"))
    assert "Traceback" not in done.stdout + done.stderr
    notes = [line.strip() for line in done.stdout.splitlines() if line.strip().startswith("libcosim:")]
    assert notes and set(notes) == {"libcosim: the libcosim peer needs libcosimpy, which is not installed here: "
                                    "pip install 'wavecosim[peers]'"}, done.stdout


def test_a_peer_that_is_not_installed_is_one_line(tmp_path, monkeypatch):
    monkeypatch.setenv("PYTHONPATH", hidden(tmp_path, "libcosimpy")["PYTHONPATH"])
    with pytest.raises(Refused, match=r"^the libcosim peer needs libcosimpy, which is not installed here: "
                                      r"pip install 'wavecosim\[peers\]'$"):
        peer_run("libcosim", CONFIGS / "two_oscillators.ssd", 0.01, 2, [])
