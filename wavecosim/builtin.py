"""The repository's own FMUs: where the sources live and the one loader of the build loop
(fmus/build.py, a script outside the package), which builds them on demand."""
import ctypes
import importlib.util
from pathlib import Path

from .errors import FmuError

ROOT = Path(__file__).resolve().parent.parent
_build = None
_built = None
_helpers = {}


def build_module():
    """fmus/build.py loaded as a module (it is also a script run on its own)."""
    global _build
    if _build is None:
        spec = importlib.util.spec_from_file_location("wavecosim_fmu_build", ROOT / "fmus" / "build.py")
        _build = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(_build)
    return _build


def build_all(force=False, log=None) -> dict:
    """Build every model and the kernel library; {identifier: fmu path}. Build failures are FmuErrors."""
    build = build_module()
    try:
        return build.build_all(force=force, log=log or (lambda msg: None))
    except build.BuildError as exc:
        raise FmuError(str(exc).splitlines()[0]) from None


def builtin_fmus() -> dict:
    """{identifier: path} of the FMUs built from models/, rebuilt (once per process) when sources changed."""
    global _built
    if _built is None:
        _built = build_all()
    return _built


def helper_library(name):
    """fmus/kernel/<name>.c as a ctypes library (build/lib/lib<name>.so, built on first use when
    missing or stale); None when it cannot be built (no C compiler)."""
    if name not in _helpers:
        build = build_module()
        try:
            _helpers[name] = ctypes.CDLL(str(build.kernel_library(name, log=lambda msg: None)))
        except (build.BuildError, OSError):
            _helpers[name] = None
    return _helpers[name]


def kernel_library(name, what):
    """helper_library(name), or an FmuError naming `what` when it cannot be built or loaded."""
    lib = helper_library(name)
    if lib is None:
        raise FmuError(f"{what} {ROOT / 'build' / 'lib' / f'lib{name}.so'} could not be built")
    return lib
