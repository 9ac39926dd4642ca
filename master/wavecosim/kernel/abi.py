"""The C structs the bindings mirror with ctypes, checked against C once per library.

Every ctypes Structure of the package names the C struct it mirrors and the kernel libraries that
define it (`@mirrors("drkernel", "DRStep")`); each such library exports `size_t DRStep_struct_size(void)`
(kernel/c/abi.h, MIRRORED). When a library is loaded (kernel/build.py, helper_library) every mirror
of it is compared with that size, and a mirror defined after the load is compared when defined: a
layout that drifted apart is a one-line FmuError (LayoutError) naming the struct, never a run on
garbage and never a quiet fall back to the Python reference.
"""
import ctypes

from ..errors import FmuError

MIRRORS = {}         # library name -> the Structure classes mirroring its structs
CHECKED = set()      # the Structure classes compared with their C struct (in every library of theirs)
_libraries = {}      # library name -> the loaded library, once its mirrors were checked


class LayoutError(FmuError):
    """A mirrored struct differs from its C struct (or cannot be checked): the build is broken."""


def mirrors(*names):
    """Class decorator: this Structure mirrors the C struct names[-1] of the libraries names[:-1]."""
    *libraries, struct = names

    def mark(cls):
        cls.c_struct, cls.c_libraries = struct, tuple(libraries)
        for name in libraries:
            if name in _libraries:
                check(name, _libraries[name], cls)
        for name in libraries:
            MIRRORS.setdefault(name, []).append(cls)
        return cls
    return mark


def check(name, lib, cls):
    """Compare one mirror with the size lib<name>.so gives for its struct; FmuError on a mismatch."""
    try:
        size_of = getattr(lib, f"{cls.c_struct}_struct_size")
    except AttributeError:
        raise LayoutError(f"lib{name}.so does not export {cls.c_struct}_struct_size: the layout of struct "
                       f"{cls.c_struct} ({cls.__module__}.{cls.__qualname__}) cannot be checked") from None
    size_of.restype, size_of.argtypes = ctypes.c_size_t, []
    size, mine = size_of(), ctypes.sizeof(cls)
    if size != mine:
        raise LayoutError(f"struct {cls.c_struct} has {size} bytes in lib{name}.so but {mine} in its mirror "
                       f"{cls.__module__}.{cls.__qualname__}: the layouts differ")
    if all(other == name or other in _libraries for other in cls.c_libraries):
        CHECKED.add(cls)


def loaded(name, lib):
    """lib<name>.so was just loaded: check every mirror of its structs (FmuError on a mismatch)."""
    for cls in MIRRORS.get(name, ()):
        check(name, lib, cls)
    _libraries[name] = lib
    return lib
