"""Where an SSP system lives: a `.ssd` file, a folder holding SystemStructure.ssd, or a zipped
`.ssp` archive (extracted once into a cache folder named by its checksum, so the FMU paths of the
imported scenario stay valid for the run and for sweep workers)."""
import hashlib
import os
import shutil
import zipfile
from pathlib import Path

from ...errors import ConfigError

SSD_NAME = "SystemStructure.ssd"


def is_ssp(path) -> bool:
    """True for what `wavecosim run` reads as SSP: a .ssd or .ssp file, or a folder with SystemStructure.ssd."""
    path = Path(path)
    return path.suffix.lower() in (".ssd", ".ssp") or (path.is_dir() and (path / SSD_NAME).exists())


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
    return Path(os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache") / "wavecosim" / "ssp"


def extract_ssp(path) -> Path:
    """Extract a .ssp archive into the cache (once per content), refusing members that would escape."""
    path = Path(path)
    data = path.read_bytes()
    target = cache_root() / f"{path.stem}-{hashlib.sha256(data).hexdigest()[:16]}"
    if (target / SSD_NAME).exists():
        return target
    if not zipfile.is_zipfile(path):
        raise ConfigError(f"{path}: not an SSP archive (not a zip file)")
    with zipfile.ZipFile(path) as archive:
        names = archive.namelist()
        if SSD_NAME not in names:
            raise ConfigError(f"{path}: the archive has no {SSD_NAME} at its top level")
        partial = target.with_name(target.name + f".part{os.getpid()}")
        base = partial.resolve()
        for member in names:
            if base not in (partial / member).resolve().parents:
                raise ConfigError(f"{path}: archive member {member!r} escapes the extraction folder")
        archive.extractall(partial)
    try:
        partial.replace(target)
    except OSError:                      # another process extracted the same archive first
        shutil.rmtree(partial, ignore_errors=True)
    return target
