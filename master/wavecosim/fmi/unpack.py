"""Unpacking archives (FMUs, SSP files) safely: no member may land outside the target folder, and an
archive may not unpack to more than MAX_BYTES or MAX_RATIO times its own size (a zip bomb is refused
in one line before anything is written, and again while writing should its sizes lie)."""
import os
import shutil
import stat
import zipfile
from pathlib import Path

MAX_BYTES = 2 << 30            # 2 GB
MAX_RATIO = 100
CHUNK = 1 << 20


def regular_file(path, error, most_bytes=None):
    """The resolved path of an existing regular file, else error(message) naming it: a special file
    (a FIFO, a device) would hang or never end when read, a symbolic link loop never resolves, and a
    file over most_bytes would not fit in memory. None when nothing is there."""
    path = Path(path)
    try:
        resolved = path.resolve()
        info = resolved.stat()
    except FileNotFoundError:
        return None
    except (RuntimeError, OSError) as exc:              # RuntimeError: a symbolic link loop (Python < 3.13)
        raise error(f"{path}: cannot be read ({getattr(exc, 'strerror', None) or 'a symbolic link loop'})") from None
    if not stat.S_ISREG(info.st_mode):
        raise error(f"{path}: not a regular file (a folder, FIFO or device): refused")
    if most_bytes is not None and info.st_size > most_bytes:
        raise error(f"{path}: {info.st_size / 1e6:.0f} MB, over the limit of {most_bytes / 1e6:.0f} MB for this "
                    f"file: refused before reading it")
    return resolved


def limit(size):
    """The most bytes an archive of `size` bytes may unpack to."""
    return min(MAX_BYTES, MAX_RATIO * max(size, CHUNK))


def unpack(path, target, error):
    """Extract the zip archive `path` into the folder `target`; error(message) is the exception to
    raise (naming the file) for a member that escapes or an archive that unpacks to too much."""
    path, target = Path(path), Path(target)
    most = limit(path.stat().st_size)
    with zipfile.ZipFile(path) as archive:
        members = archive.infolist()
        declared = sum(m.file_size for m in members)
        if declared > most:
            raise error(f"{path}: unpacks to {declared / 1e6:.0f} MB, over the limit of {most / 1e6:.0f} MB "
                        f"({MAX_RATIO} times the archive, at most {MAX_BYTES >> 30} GB): not unpacked")
        root = target.resolve()
        for member in members:
            dest = (target / member.filename).resolve()
            if dest != root and root not in dest.parents:
                raise error(f"{path}: archive member {member.filename!r} escapes the extraction folder")
        written = 0
        for member in members:
            written = _write(archive, member, target, written, most, lambda: error(
                f"{path}: unpacks to more than its sizes say (over {most / 1e6:.0f} MB): not unpacked"))


def _write(archive, member, target, written, most, too_much):
    dest = target / member.filename
    if member.is_dir():
        dest.mkdir(parents=True, exist_ok=True)
        return written
    dest.parent.mkdir(parents=True, exist_ok=True)
    with archive.open(member) as src, open(dest, "wb") as out:
        while True:
            chunk = src.read(CHUNK)
            if not chunk:
                return written
            written += len(chunk)
            if written > most:
                raise too_much()
            out.write(chunk)


def remove(folder):
    """Remove a folder made for an unpacked archive (nothing if it is gone)."""
    shutil.rmtree(folder, ignore_errors=True)


def folder_bytes(folder):
    """Bytes of the files under a folder."""
    return sum(f.stat().st_size for f in Path(folder).rglob("*") if f.is_file() and not f.is_symlink())


def prune(root, keep, most_bytes):
    """Keep the `keep` most recently used folders under root (and at most most_bytes of them); remove the
    rest. A folder's time is its modification time (touch it when used)."""
    root = Path(root)
    if not root.is_dir():
        return
    folders = sorted((p for p in root.iterdir() if p.is_dir() and ".part" not in p.name),
                     key=lambda p: p.stat().st_mtime, reverse=True)
    total = 0
    for k, folder in enumerate(folders):
        total += folder_bytes(folder)
        if k >= keep or (k > 0 and total > most_bytes):
            remove(folder)


def touch(folder):
    try:
        os.utime(folder)
    except OSError:
        pass
