"""The package's build step (pyproject.toml holds the metadata): a wheel, or `pip install .`, holds the C
kernel libraries and the package's own FMUs built, in wavecosim/_built/, by the same functions that
build them into the per-user cache (wavecosim.kernel.build, wavecosim.fmi.build), so an installed
wavecosim runs any prebuilt FMU with no C compiler. An editable install builds them on first use."""
import importlib
import os
import shutil
import sys
import time
import types
from pathlib import Path

from setuptools import Distribution, setup
from setuptools.command.bdist_wheel import bdist_wheel
from setuptools.command.build_py import build_py

COMPILER = "gcc"


def _fmi_build(package: Path):
    """wavecosim.fmi.build of the copy at `package`, imported without the package's __init__ (whose
    dependencies the build environment does not hold)."""
    stub = types.ModuleType("wavecosim")
    stub.__path__ = [str(package)]
    sys.modules["wavecosim"] = stub
    return importlib.import_module("wavecosim.fmi.build")


def build_binaries(package: Path):
    """Every kernel library and built-in FMU into package/_built/, laid out as the cache."""
    os.environ.pop("WAVECOSIM_SANITIZE", None)
    os.environ["WAVECOSIM_CACHE"] = str(package / "_built")
    start = time.perf_counter()
    _fmi_build(package).build_all(log=lambda msg: None)
    for kept in [*(package / "_built").rglob(".*.lock"), *(package / "_built").rglob("*.sha256")]:
        kept.unlink()                    # what the cache keeps beside its builds: its locks and checksums
    print(f"wavecosim: the C kernel and the package's FMUs built into {package / '_built'} "
          f"in {time.perf_counter() - start:.0f} s")


class BuildWithBinaries(build_py):
    """build_py, then the compiled parts into the built package (not for an editable install)."""

    def run(self):
        super().run()
        package = Path(self.build_lib) / "wavecosim"
        shutil.rmtree(package / "_built", ignore_errors=True)          # never an earlier build's parts
        if getattr(self, "editable_mode", False):
            return
        if shutil.which(COMPILER):
            build_binaries(package)
        else:
            print(f"wavecosim: {COMPILER} was not found on PATH: the package holds no compiled parts and builds "
                  f"them on first use (install {COMPILER} and build again for a package that needs none)")


class WithBinaries(Distribution):
    """A distribution holding shared libraries (when they can be built): installed as platform files."""

    def has_ext_modules(self):
        return shutil.which(COMPILER) is not None


class PlatformWheel(bdist_wheel):
    """A wheel holding shared libraries is for this platform, and any Python 3: py3-none-<platform>."""

    def get_tag(self):
        python, abi, platform = super().get_tag()
        return (python, abi, platform) if self.root_is_pure else ("py3", "none", platform)


setup(distclass=WithBinaries, cmdclass={"build_py": BuildWithBinaries, "bdist_wheel": PlatformWheel})
