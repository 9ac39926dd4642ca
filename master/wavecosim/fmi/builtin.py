"""The package's own FMUs: those a wheel holds built, else built from its sources into the per-user
cache on first use."""
import sys
from pathlib import Path

from ..errors import FmuError
from ..kernel.build import BuildError, cache_dir, is_build
from . import build

_built = None


def build_all(force=False, log=None) -> dict:
    """Build every model and the kernel libraries; {identifier: fmu path}. Build failures are FmuErrors."""
    try:
        return build.build_all(force=force, log=log or (lambda msg: None))
    except BuildError as exc:
        raise FmuError(str(exc).splitlines()[0]) from None


def builtin_fmus() -> dict:
    """{identifier: path} of the FMUs built from the package's models (once per process, again when a
    file of the cache has gone); the first build in a cache says so on stderr, as it takes a while."""
    global _built
    if _built is None or not all(path.is_file() for path in _built.values()):     # the cache was emptied meanwhile
        told = []

        def tell(msg):
            if not told:
                told.append(msg)
                print(f"wavecosim: building the package's FMUs and C kernel into {cache_dir()} "
                      f"(once; about half a minute)", file=sys.stderr)
        _built = build_all(log=tell)
    return _built


def builtin_path(path: Path):
    """The built-in FMU a missing `.../build/fmus/<Id>.fmu` names (how SSP files refer to our own
    FMUs), else None."""
    path = Path(path)
    if path.exists() or path.parent.parts[-2:] != ("build", "fmus") or path.suffix != ".fmu":
        return None
    return builtin_fmus().get(path.stem)


def builtin_name(path: Path):
    """The name of the built-in FMU whose build `path` is, else None; a path outside the package's and
    the cache's FMU folders (another tool's FMU) builds nothing."""
    path = Path(path)
    return path.stem if is_build(path, "fmus") and builtin_fmus().get(path.stem) == path else None
