"""Compiling C into a per-user cache: the kernel's libraries (kernel/c/*.c) here, the models' FMUs
through wavecosim.fmi.build. Every output sits in a folder named by a hash of its sources and flags,
so installed copies, clones and versions never overwrite each other's builds, and a finished
output is only ever moved into place whole (several processes may build at once). An installed
wheel holds the same folders, built by its build step (setup.py), in the package's _built/: a
build found there is used before the cache, so no compiler is needed at run time."""
import ctypes
import fcntl
import functools
import hashlib
import os
import subprocess
import sys
import tempfile
from contextlib import contextmanager
from pathlib import Path

from . import abi, contract
from ..errors import ConfigError, FmuError

SOURCES = Path(__file__).resolve().parent / "c"
PREBUILT = SOURCES.parent.parent / "_built"
COMPILER = "gcc"


def _sanitizer_flags(value):
    """$WAVECOSIM_SANITIZE (e.g. `address`): compile the kernel and the FMUs with that sanitizer, for a
    test run with its runtime preloaded (docs/troubleshooting.md); empty: none."""
    if not value:
        return []
    if not all(part.isalpha() for part in value.split(",")):
        raise FmuError(f"WAVECOSIM_SANITIZE: expected sanitizer names such as address, got {value!r}")
    return [f"-fsanitize={value}", "-fno-omit-frame-pointer", "-g"]


CFLAGS = ["-O2", "-std=c99", "-fPIC", "-ffp-contract=off", "-Wall", "-Wextra", "-Werror",
          *_sanitizer_flags(os.environ.get("WAVECOSIM_SANITIZE", ""))]
# C files compiled into another file's library: the routes built on the DR kernel's subsystem
# evaluation (classical.c, newton.c, certs.c) go into libdrkernel.so.
PART_OF_LIBRARY = {"classical.c": "drkernel", "newton.c": "drkernel", "certs.c": "drkernel", "portview.c": "drkernel",
                   "signals.c": "drkernel", "multirate.c": "drkernel"}
_loaded = {}
_verified = {}                   # {path: (size, mtime)} of cached builds whose checksum was checked here
_failed = {}         # library name -> why it could not be built or loaded
LOAD_HOOKS = []      # hook(lib) for every kernel library when it is loaded (kernel/fmicall.py)


class BuildError(RuntimeError):
    """A model or a kernel library failed to compile."""


def cache_dir() -> Path:
    """$WAVECOSIM_CACHE, else $XDG_CACHE_HOME/wavecosim, else ~/.cache/wavecosim: the first one given,
    made when missing. One that cannot be written gives a folder in the system's temporary directory,
    said in one warning on stderr (and put in $WAVECOSIM_CACHE, so child processes take it too)."""
    env = os.environ
    return _writable_cache(env.get("WAVECOSIM_CACHE", ""), env.get("XDG_CACHE_HOME", ""), env.get("HOME", ""))


@functools.lru_cache(maxsize=16)
def _writable_cache(chosen, xdg, home):
    """The cache for these values of $WAVECOSIM_CACHE, $XDG_CACHE_HOME and $HOME (see cache_dir)."""
    wanted = "~/.cache/wavecosim"
    try:
        wanted = Path(chosen) if chosen else Path(xdg or Path.home() / ".cache") / "wavecosim"
        wanted.mkdir(parents=True, exist_ok=True)
        tempfile.TemporaryFile(dir=wanted).close()
        return wanted
    except (OSError, RuntimeError) as exc:                  # RuntimeError: no home directory to be found
        reason = getattr(exc, "strerror", None) or str(exc)
    fallback = Path(tempfile.gettempdir()) / f"wavecosim-cache-{os.getuid()}"
    try:
        fallback.mkdir(mode=0o700, exist_ok=True)
        if fallback.is_symlink() or fallback.stat().st_uid != os.getuid():
            fallback = Path(tempfile.mkdtemp(prefix="wavecosim-cache-"))
    except OSError as exc:
        raise ConfigError(f"the cache {wanted} cannot be written ({reason}), nor {fallback} ({exc.strerror}): "
                          f"set $WAVECOSIM_CACHE to a writable folder") from None
    print(f"warning: the cache {wanted} cannot be written ({reason}); using {fallback} (set $WAVECOSIM_CACHE to "
          f"choose a folder)", file=sys.stderr)
    os.environ["WAVECOSIM_CACHE"] = str(fallback)
    return fallback


def fmi_headers() -> Path:
    """The official FMI headers shipped inside fmpy."""
    import fmpy
    return Path(fmpy.__file__).parent / "c-code"


def run(cmd, what):
    """Run a compiler command; its stdout, or a BuildError with the command and its stderr."""
    try:
        proc = subprocess.run([str(c) for c in cmd], capture_output=True, text=True)
    except FileNotFoundError:
        raise BuildError(f"{cmd[0]} was not found on PATH; it is needed to build {what}: install {cmd[0]}") from None
    if proc.returncode != 0:
        raise BuildError(f"building {what} failed: {' '.join(map(str, cmd))}\n{proc.stderr.strip()}")
    return proc.stdout


def stamp(files, extra="") -> str:
    """A hash of the files' names and bytes, the flags and `extra`: the name of a build's folder."""
    h = hashlib.sha256(" ".join(CFLAGS).encode() + extra.encode())
    for f in sorted(files, key=lambda p: (p.name, str(p))):
        h.update(f.name.encode())
        h.update(f.read_bytes())
    return h.hexdigest()[:20]


def target(kind, key, name) -> Path:
    """Where a build of `name` whose stamp is `key` lives in the cache."""
    return cache_dir() / kind / key / name


def checksum_file(path: Path) -> Path:
    """Where the SHA-256 of a cached build is written, beside it."""
    return path.with_name(path.name + ".sha256")


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def reusable(path: Path) -> bool:
    """Whether the cached build at `path` can be used as it is: present, and its bytes those whose
    checksum was written beside it when it was built (a truncated, replaced or deleted file, or one
    without its checksum, is built again). Hashed once per process for a file of unchanged size and time."""
    try:
        info = path.stat()
        expected = checksum_file(path).read_text().strip()
    except OSError:
        return False
    seen = (info.st_size, info.st_mtime_ns)
    if _verified.get(path) == seen:
        return True
    if _sha256(path) != expected:
        return False
    _verified[path] = seen
    return True


@contextmanager
def build_lock(path: Path):
    """The cache's lock of one build (a file beside it): one process builds, the others wait and reuse it."""
    try:
        path.parent.mkdir(parents=True, exist_ok=True)
        lock = open(path.with_name(f".{path.name}.lock"), "a")
    except OSError:                    # a cache that cannot be written: the build itself says why
        yield
        return
    with lock:
        fcntl.flock(lock, fcntl.LOCK_EX)
        yield


def prebuilt(kind, key, name):
    """The package's own build of `name` whose stamp is `key` (a wheel's _built/, laid out as the
    cache), else None."""
    path = PREBUILT / kind / key / name
    return path if path.exists() else None


def is_build(path, kind) -> bool:
    """Whether `path` is a build of `kind` (<root>/<kind>/<stamp>/<name>) in the package or the cache."""
    folder = Path(path).parent.parent
    return folder == PREBUILT / kind or folder == cache_dir() / kind


def place(build, path: Path):
    """Call build(tmp) for a file made in a private temporary path, then move it to `path` whole, its
    checksum beside it (written first: a build without its checksum is never taken as whole)."""
    path.parent.mkdir(parents=True, exist_ok=True)
    fd, tmp = tempfile.mkstemp(dir=path.parent, prefix=f".{path.name}.", suffix=path.suffix)
    os.close(fd)
    try:
        build(Path(tmp))
        checksum = checksum_file(path)
        checksum.with_name(f".{checksum.name}.part").write_text(_sha256(Path(tmp)) + "\n")
        os.replace(checksum.with_name(f".{checksum.name}.part"), checksum)
        os.replace(tmp, path)
    finally:
        if os.path.exists(tmp):
            os.unlink(tmp)
    return path


def cached(path: Path, build, force=False, log=print) -> Path:
    """The build at `path`: reused when reusable(), else made by build() under the build's lock."""
    if not force and reusable(path):
        return path
    with build_lock(path):
        if force or not reusable(path):
            log(f"building {path}")
            build()
    return path


def library_sources(name):
    """kernel/c/<name>.c, the files PART_OF_LIBRARY puts into it and the kernel's headers."""
    parts = sorted(SOURCES / f for f, lib in PART_OF_LIBRARY.items() if lib == name)
    return [SOURCES / f"{name}.c", *parts, *sorted(SOURCES.glob("*.h"))]


def library_headers(name):
    """The headers that declare lib<name>.so's functions (its contract): <file>.h of each of its C files."""
    files = [f"{name}.c", *sorted(f for f, lib in PART_OF_LIBRARY.items() if lib == name)]
    return [f"{Path(f).stem}.h" for f in files if (SOURCES / f"{Path(f).stem}.h").exists()]


def library_names():
    """Every kernel library: one per C file that is not part of another's."""
    return sorted(c.stem for c in SOURCES.glob("*.c") if c.name not in PART_OF_LIBRARY)


def build_library(name, force=False, log=print) -> Path:
    """lib<name>.so from library_sources(name), built into the cache unless it is there."""
    sources = library_sources(name)
    key = stamp(sources)
    if not force and (shipped := prebuilt("lib", key, f"lib{name}.so")):
        return shipped
    path = target("lib", key, f"lib{name}.so")
    return cached(path, lambda: place(lambda tmp: run([COMPILER, *CFLAGS, "-shared", "-I", fmi_headers(),
                                                       *[s for s in sources if s.suffix == ".c"], "-o", tmp, "-lm",
                                                       "-ldl"], f"the kernel library {name}"), path), force, log)


def helper_library(name):
    """lib<name>.so loaded with ctypes (built on first use), its functions given the signatures its
    headers declare (contract.py) and its mirrored structs checked (abi.py; FmuError on a mismatch);
    None when it cannot be built (no C compiler)."""
    if name not in _loaded:
        try:
            lib = ctypes.CDLL(str(build_library(name, log=lambda msg: None)))
        except (BuildError, OSError) as exc:
            lib, _failed[name] = None, str(exc).splitlines()[0]
        _loaded[name] = lib and abi.loaded(name, contract.bind(name, lib, library_headers(name)))
        for hook in LOAD_HOOKS if _loaded[name] is not None else ():
            hook(_loaded[name])
    return _loaded[name]


def loaded_libraries():
    """The kernel libraries this process has loaded."""
    return [lib for lib in _loaded.values() if lib is not None]


def kernel_library(name, what):
    """helper_library(name), or an FmuError naming `what` when it cannot be built or loaded."""
    lib = helper_library(name)
    if lib is None:
        raise FmuError(f"{what}: the kernel library lib{name}.so is not in the package and could not be built: "
                       f"{_failed[name]}")
    return lib
