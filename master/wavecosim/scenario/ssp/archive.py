"""Where an SSP system lives: a `.ssd` file, a folder holding SystemStructure.ssd, or a zipped
`.ssp` archive (extracted once into a cache folder named by its checksum, so the FMU paths of the
imported scenario stay valid for the run and for sweep workers; the cache is bounded)."""
import hashlib
import os
import shutil
import zipfile
from pathlib import Path

from ...errors import ConfigError
from ...fmi.unpack import prune, touch, unpack
from ...kernel.build import cache_dir

SSD_NAME = "SystemStructure.ssd"
CACHE_KEEP = 16                  # unpacked .ssp archives the cache keeps (the ones used last)
CACHE_BYTES = 4 << 30            # and at most this many bytes of them


def is_ssp(path) -> bool:
    """True for what `wavecosim run` reads as SSP: a .ssd or .ssp file, or a folder with SystemStructure.ssd."""
    path = Path(path)
    return path.suffix.lower() in (".ssd", ".ssp") or (path.is_dir() and (path / SSD_NAME).exists())


def ssp_only(path, ports, parameter_set):
    """A ConfigError when `ports` or `parameter_set` is given for an input that is not SSP."""
    if (ports is not None or parameter_set is not None) and not (path is not None and is_ssp(path)):
        raise ConfigError("ports and parameter_set: only for an SSP input (.ssd, .ssp or a folder)")


def locate_ssd(path) -> Path:
    """The .ssd file to read for `path` (a .ssd, a folder or a .ssp archive)."""
    path = Path(path)
    if not path.exists():
        raise ConfigError(f"{path}: SSP file not found")
    if path.is_dir():
        ssd = path / SSD_NAME
        if not ssd.exists():
            raise ConfigError(f"{path}: the folder has no {SSD_NAME}")
        return ssd
    if path.suffix.lower() == ".ssp":
        return extract_ssp(path) / SSD_NAME
    return path


def cache_root() -> Path:
    """Where .ssp archives are unpacked: the package's cache (kernel/build.py: cache_dir)."""
    return cache_dir() / "ssp"


def extract_ssp(path) -> Path:
    """Extract a .ssp archive into the cache (once per content), refusing members that would escape and
    an archive that unpacks to too much (fmi/unpack.py); the cache keeps the CACHE_KEEP archives used
    last (at most CACHE_BYTES)."""
    path = Path(path)
    digest = hashlib.sha256()
    with open(path, "rb") as f:
        for chunk in iter(lambda: f.read(1 << 20), b""):
            digest.update(chunk)
    target = cache_root() / f"{path.stem}-{digest.hexdigest()[:16]}"
    if (target / SSD_NAME).exists():
        touch(target)
        return target
    if not zipfile.is_zipfile(path):
        raise ConfigError(f"{path}: not an SSP archive (not a zip file)")
    with zipfile.ZipFile(path) as archive:
        if SSD_NAME not in archive.namelist():
            raise ConfigError(f"{path}: the archive has no {SSD_NAME} at its top level")
    partial = target.with_name(target.name + f".part{os.getpid()}")
    try:
        unpack(path, partial, ConfigError)
        partial.replace(target)
    except ConfigError:
        shutil.rmtree(partial, ignore_errors=True)
        raise
    except OSError:                      # another process extracted the same archive first
        shutil.rmtree(partial, ignore_errors=True)
    prune(cache_root(), CACHE_KEEP, CACHE_BYTES)
    return target
