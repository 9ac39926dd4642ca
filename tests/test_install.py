"""The compiled parts of an installed wavecosim: a wheel holds the C kernel libraries and the package's
own FMUs built (setup.py), found before the cache when their sources' stamp matches; without them and
without a compiler, what needs one says so in one line. The slow case builds a wheel, installs it into
a fresh venv and runs it with gcc hidden from PATH and an empty cache."""
import json
import os
import shutil
import subprocess
import sys
import tempfile
import zipfile
from pathlib import Path

import pytest

from paths import ROOT, THIRD_PARTY
from wavecosim.errors import FmuError
from wavecosim.fmi import builtin
from wavecosim.kernel import build

VANDERPOL = THIRD_PARTY / "reference_fmus" / "fmi2" / "VanDerPol.fmu"


@pytest.fixture(scope="module")
def cached():
    """{name: path} of two kernel libraries built into the cache (before `bare` hides the compiler)."""
    return {name: build.build_library(name, log=lambda msg: None) for name in ("csvfmt", "guard")}


@pytest.fixture
def bare(tmp_path, monkeypatch):
    """No compiler on PATH, an empty cache, and an empty package folder of prebuilt parts: its path."""
    monkeypatch.setenv("PATH", str(tmp_path / "bin"))
    monkeypatch.delenv("WAVECOSIM_CACHE", raising=False)
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "cache"))
    monkeypatch.setattr(build, "PREBUILT", tmp_path / "_built")
    monkeypatch.setattr(build, "_loaded", {})
    monkeypatch.setattr(build, "_failed", {})
    monkeypatch.setattr(builtin, "_built", None)
    return tmp_path / "_built"


def files(folder: Path):
    """The files under `folder` (none when it is missing)."""
    return [p for p in folder.rglob("*") if p.is_file()]


def ship(prebuilt, built: Path, key=None):
    """A copy of a cache build (<kind>/<key>/<name>) in the package folder `prebuilt`, under another
    key if given."""
    kind, stamp = built.parent.parent.name, key or built.parent.name
    (prebuilt / kind / stamp).mkdir(parents=True)
    return Path(shutil.copy2(built, prebuilt / kind / stamp / built.name))


def test_a_prebuilt_library_with_the_sources_stamp_is_used_without_a_compiler(cached, bare):
    shipped = ship(bare, cached["csvfmt"])
    assert shutil.which("gcc") is None
    assert build.build_library("csvfmt", log=lambda msg: None) == shipped
    assert build.kernel_library("csvfmt", "the CSV formatter")._name == str(shipped)


def test_a_prebuilt_library_of_other_sources_is_not_used_and_the_missing_compiler_is_one_line(cached, bare):
    ship(bare, cached["guard"], key="0" * 20)
    with pytest.raises(FmuError) as err:
        build.kernel_library("guard", "containment")
    assert str(err.value) == ("containment: the kernel library libguard.so is not in the package and could not be "
                              "built: gcc was not found on PATH; it is needed to build the kernel library guard: "
                              "install gcc")


def test_another_tools_fmu_is_not_taken_for_a_builtin_one_and_builds_nothing(bare, tmp_path):
    foreign = tmp_path / "fmus" / "0123" / "Oscillator.fmu"
    assert builtin.builtin_name(foreign) is None
    assert not files(tmp_path / "cache")


def test_a_supervised_run_without_the_guard_library_is_one_line_naming_the_compiler(built_fmus, tmp_path):
    """A clone without gcc and without builds: the CLI's containment needs libguard.so; the run stops
    before it starts, in one line, with the FMU error's exit code."""
    env = {"PATH": str(tmp_path / "bin"), "HOME": str(tmp_path), "XDG_CACHE_HOME": str(tmp_path / "cache"),
           "PYTHONPATH": str(ROOT / "master")}
    done = subprocess.run([sys.executable, "-m", "wavecosim", "run", str(built_fmus["Oscillator"]), "--T", "0.1",
                           "--dt", "0.01", "--out", "out"], cwd=tmp_path, env=env, capture_output=True, text=True)
    assert done.returncode == 3
    assert done.stderr.strip() == ("error: containment: the kernel library libguard.so is not in the package and could "
                                   "not be built: gcc was not found on PATH; it is needed to build the kernel library "
                                   "guard: install gcc")


def test_a_builtin_fmus_build_is_known_by_its_path(built_fmus):
    assert builtin.builtin_name(built_fmus["Oscillator"]) == "Oscillator"


@pytest.fixture(scope="module")
def installed():
    """A wheel of this tree installed into a fresh venv: (its folder, a bin folder holding only the
    venv's python and wavecosim, the wheel). Every file of these tests lies in that folder: pytest's
    own may be cleared by other pytest sessions during the minutes this takes."""
    with tempfile.TemporaryDirectory(prefix="wavecosim-wheel-") as folder:
        yield _install(Path(folder))


def _install(tmp: Path):
    subprocess.run([sys.executable, "-m", "pip", "wheel", str(ROOT), "-w", str(tmp / "dist"), "--no-deps", "-q"],
                   check=True)
    wheel = next((tmp / "dist").glob("wavecosim-*.whl"))
    venv = tmp / "venv"
    subprocess.run([sys.executable, "-m", "venv", str(venv)], check=True)
    alone = {k: v for k, v in os.environ.items() if k != "PYTHONPATH"}     # no other wavecosim in sight
    subprocess.run([str(venv / "bin" / "python"), "-m", "pip", "install", "-q", str(wheel)], check=True, env=alone)
    shown = tmp / "bin"
    shown.mkdir()
    for tool in ("python", "wavecosim"):
        (shown / tool).symlink_to(venv / "bin" / tool)
    return tmp, shown, wheel


@pytest.fixture
def work(installed):
    """A fresh folder beside the venv to run in."""
    return Path(tempfile.mkdtemp(dir=installed[0]))


def hidden_gcc(installed, work, *args):
    """`wavecosim *args` in `work` with PATH = only the venv's python and wavecosim (no compiler) and an
    empty cache under `work`."""
    env = {"PATH": str(installed[1]), "HOME": str(work / "home"), "XDG_CACHE_HOME": str(work / "home" / ".cache")}
    return subprocess.run(["wavecosim", *args], cwd=work, env=env, capture_output=True, text=True, timeout=300)


@pytest.mark.slow  # builds a wheel and installs it with its dependencies: minutes
def test_the_wheel_holds_every_kernel_library_and_builtin_fmu(installed):
    names = zipfile.ZipFile(installed[2]).namelist()
    libraries = {Path(n).name for n in names if "/_built/lib/" in n}
    fmus = {Path(n).stem for n in names if "/_built/fmus/" in n}
    assert libraries == {f"lib{name}.so" for name in build.library_names()}
    assert fmus == set(builtin.builtin_fmus())


@pytest.mark.slow
@pytest.mark.parametrize("what", ["third-party FMU", "built-in benchmark"])
def test_the_installed_wheel_runs_on_the_c_kernel_without_a_compiler(installed, work, what):
    if what == "third-party FMU" and not VANDERPOL.exists():
        pytest.skip("the Reference FMUs (../shared/third_party) are absent")
    args = [str(VANDERPOL), "--T", "1"] if what == "third-party FMU" else ["--T", "0.1"]
    done = hidden_gcc(installed, work, "run", *args, "--out", "out")
    assert done.returncode == 0, done.stderr
    summary = json.loads((work / "out" / "summary.json").read_text())
    assert summary["status"] == "finished" and summary["fast_note"] == "C kernel"
    assert not files(work / "home")                                   # nothing built into the cache


@pytest.mark.slow
def test_an_fmu_shipped_as_sources_needs_the_compiler_and_says_so_in_one_line(installed, work):
    with zipfile.ZipFile(installed[2]) as wheel:
        member = next(n for n in wheel.namelist() if n.endswith("/ForeignMass.fmu"))
        (work / "shipped.fmu").write_bytes(wheel.read(member))
    with zipfile.ZipFile(work / "shipped.fmu") as src, zipfile.ZipFile(work / "Sources.fmu", "w") as out:
        for item in src.infolist():
            if not item.filename.startswith("binaries/"):
                out.writestr(item, src.read(item))
    done = hidden_gcc(installed, work, "run", "Sources.fmu", "--T", "0.1", "--dt", "0.01", "--out", "out")
    errors = [line for line in done.stderr.splitlines() if line.startswith("error")]
    assert done.returncode == 2 and len(errors) == 1, done.stderr          # an FMU refused at set-up
    assert "its sources did not build: gcc was not found on PATH; it is needed to build ForeignMass.so: install gcc" \
        in errors[0]
