"""Every ctypes Structure of the package mirrors a C struct and is checked against it when its
library loads (kernel/abi.py, kernel/c/abi.h); a mirror whose layout drifted from C is a one-line
FmuError naming the struct."""
import ctypes
import importlib
import pkgutil
import subprocess
import sys

import pytest

import wavecosim
from wavecosim.errors import FmuError
from wavecosim.kernel import abi, build


def package_structures():
    """Every ctypes Structure or Union class defined in a module of the package."""
    found = set()
    for info in pkgutil.walk_packages(wavecosim.__path__, "wavecosim."):
        if info.name.endswith("__main__"):
            continue
        module = importlib.import_module(info.name)
        found |= {value for value in vars(module).values()
                  if isinstance(value, type) and issubclass(value, (ctypes.Structure, ctypes.Union))
                  and value.__module__ == info.name}
    return found


def test_every_structure_mirrors_a_c_struct_and_is_checked():
    structures = package_structures()
    assert len(structures) >= 10
    mirrored = {cls for classes in abi.MIRRORS.values() for cls in classes}
    assert sorted(c.__qualname__ for c in structures - mirrored) == [], "Structures no C struct checks"
    for name in build.library_names():
        if build.helper_library(name) is None:
            pytest.skip(f"lib{name}.so cannot be built here")
    assert sorted(c.__qualname__ for c in structures - abi.CHECKED) == []


def test_a_mirror_that_differs_from_c_is_a_one_line_error():
    if build.helper_library("drkernel") is None or build.helper_library("blocks") is None:
        pytest.skip("the kernel libraries cannot be built here")
    with pytest.raises(FmuError) as info:
        @abi.mirrors("drkernel", "DRStep")
        class DRStep(ctypes.Structure):              # one field short of drkernel.h's
            _fields_ = [("t", ctypes.c_double), ("dt", ctypes.c_double)]
    message = str(info.value)
    assert "\n" not in message and message.startswith("struct DRStep has ") and "libdrkernel.so" in message
    with pytest.raises(FmuError, match="libblocks.so does not export NoSuchStruct_struct_size"):
        @abi.mirrors("blocks", "NoSuchStruct")
        class Missing(ctypes.Structure):
            _fields_ = [("x", ctypes.c_int)]
    assert not any(cls.__module__ == __name__ for classes in abi.MIRRORS.values() for cls in classes)


def test_a_run_over_a_mirror_that_differs_stops_with_one_line_and_the_fmu_exit_code(tmp_path, built_fmus):
    """Not a quiet fall back to the Python reference: the run stops before its first step."""
    script = "\n".join([
        "import ctypes",
        "from wavecosim.kernel.abi import mirrors",
        "@mirrors('drkernel', 'DRStep')",
        "class Short(ctypes.Structure):",
        "    _fields_ = [('t', ctypes.c_double)]",
        "from wavecosim.cli import main",
        "main(['run', '--T', '0.1', '--no-reference', '--quiet', '--out', 'out'])"])
    done = subprocess.run([sys.executable, "-c", script], cwd=tmp_path, capture_output=True, text=True)
    assert done.returncode == FmuError.exit_code
    lines = done.stderr.strip().splitlines()
    assert len(lines) == 1 and "struct DRStep has " in lines[0] and "but 8 in its mirror __main__.Short" in lines[0]
