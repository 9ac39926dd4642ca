"""The repository's own FMUs: where the sources live and the one loader of the build loop
(fmus/build.py, a script outside the package), which builds them on demand."""
import ctypes
import importlib.util
from pathlib import Path

from .errors import FmuError

ROOT = Path(__file__).resolve().parent.parent
_build = None
_built = None


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


def kernel_library(name, what):
    """build/lib/lib<name>.so (from fmus/kernel/<name>.c), built with the FMUs if missing or stale,
    loaded; raises FmuError naming `what` if it cannot be."""
    builtin_fmus()                           # fmus/build.py compiles every fmus/kernel/*.c
    path = ROOT / "build" / "lib" / f"lib{name}.so"
    if not path.exists():
        raise FmuError(f"{what} {path} was not built")
    return ctypes.CDLL(str(path))
