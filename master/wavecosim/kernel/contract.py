"""The C contract of the kernel libraries, read from their headers (kernel/c/*.h).

A library's header declares every function it exports (its C files include it, so the compiler
holds the definitions to it) and the named enums whose members Python names (REASONS, STARTS,
the ledger's actions and log rows). When a library is loaded (kernel/build.py, helper_library)
every prototype of its headers becomes the ctypes argtypes and restype of its function, so no
binding restates a signature; `names` turns a named enum into the Python tuple of its members and `constant` gives one
enum member's or #define's value.
Pointers of every kind are c_void_p: callers pass arrays, byref() or raw addresses, and the structs
behind them are checked by kernel/abi.py.
"""
import ctypes
import functools
import re
from pathlib import Path

from ..errors import FmuError

HEADERS = Path(__file__).resolve().parent / "c"
SCALARS = {"void": None, "int": ctypes.c_int, "unsigned": ctypes.c_uint, "unsigned int": ctypes.c_uint,
           "long": ctypes.c_long, "size_t": ctypes.c_size_t, "double": ctypes.c_double, "char": ctypes.c_char,
           "int32_t": ctypes.c_int32, "uint32_t": ctypes.c_uint32, "uint64_t": ctypes.c_uint64,
           "fmi2Real": ctypes.c_double, "fmi2Integer": ctypes.c_int, "fmi2Boolean": ctypes.c_int,
           "fmi2Status": ctypes.c_int, "fmi2ValueReference": ctypes.c_uint, "fmi2Component": ctypes.c_void_p,
           "fmi2FMUstate": ctypes.c_void_p, "fmi2ComponentEnvironment": ctypes.c_void_p,
           "fmi2String": ctypes.c_char_p}
QUALIFIERS = {"const", "volatile", "struct", "enum", "extern"}
_COMMENT = re.compile(r"/\*.*?\*/|//[^\n]*", re.S)
_DIRECTIVE = re.compile(r"^[ \t]*#(?:[^\n]*\\\n)*[^\n]*", re.M)
_BLOCK = re.compile(r"\{[^{}]*\}")
_ENUM = re.compile(r"\benum\s*(\w*)\s*\{([^{}]*)\}")
_PROTOTYPE = re.compile(r"^(?P<ret>[\w\s*]*?[\w*])\s*\b(?P<name>\w+)\s*\((?P<params>[^()]*)\)$")


class ContractError(FmuError):
    """A header the contract cannot read, or a library that does not export what its header declares."""


@functools.lru_cache(maxsize=None)
def _text(header):
    """The header's text without comments and preprocessor lines."""
    return _DIRECTIVE.sub("", _COMMENT.sub(" ", (HEADERS / header).read_text(encoding="utf-8")))


def ctype(declaration, header):
    """The ctypes type of a C declaration (a parameter or a return type, its name optional)."""
    if "*" in declaration or "[" in declaration:
        return ctypes.c_void_p
    words = [w for w in declaration.split() if w not in QUALIFIERS]
    if len(words) > 1 and words[-1] not in SCALARS and " ".join(words[-2:]) not in SCALARS:
        words = words[:-1]                                           # the parameter's name
    base = " ".join(words)
    if re.search(rf"typedef[^;]*\(\s*\*\s*{re.escape(base)}\s*\)", _text(header)):
        return ctypes.c_void_p                                       # a function pointer's typedef
    if base not in SCALARS:
        raise ContractError(f"{HEADERS / header}: the kernel's contract does not know the C type {base!r}")
    return SCALARS[base]


@functools.lru_cache(maxsize=None)
def prototypes(header):
    """{name: (restype, argtypes)} of every function `header` declares (not the static ones it defines)."""
    text = _text(header)
    while _BLOCK.search(text):
        text = _BLOCK.sub(";", text)
    found = {}
    for statement in (" ".join(s.split()) for s in text.split(";")):
        match = _PROTOTYPE.match(statement)
        if match is None or statement.split()[0] in ("typedef", "static"):
            continue
        params = [p for p in match["params"].split(",") if p.strip() not in ("void", "...")]   # varargs: the fixed ones
        found[match["name"]] = (ctype(match["ret"], header), [ctype(p, header) for p in params])
    return found


@functools.lru_cache(maxsize=None)
def enum(header, tag):
    """[(member, value)] of `enum tag { ... }` in `header`, in the order written."""
    for name, body in _ENUM.findall(_text(header)):
        if name == tag:
            return _members(body)
    raise ContractError(f"{HEADERS / header} declares no enum {tag}")


def _members(body):
    """[(member, value)] of an enum's body, the values counted on from the last one given."""
    members, value = [], -1
    for item in filter(None, (m.strip() for m in body.split(","))):
        member, _, given = (part.strip() for part in item.partition("="))
        value = int(given, 0) if given else value + 1
        members.append((member, value))
    return members


def names(header, tag, prefix, dash=False):
    """The members of enum `tag` that start with `prefix`, as Python names (prefix dropped, lower
    case, '_' as '-' when dash), in the order of their values, which must be 0, 1, 2, ..."""
    members = [(value, member[len(prefix):].lower()) for member, value in enum(header, tag)
               if member.startswith(prefix)]
    if sorted(value for value, _ in members) != list(range(len(members))):
        raise ContractError(f"{HEADERS / header}: enum {tag}'s {prefix}* values are not 0 .. {len(members) - 1}")
    return tuple(name.replace("_", "-") if dash else name for _, name in sorted(members))


def constant(header, name):
    """The integer value of `name` in `header`: an enum member or a `#define name value`."""
    for member, value in (m for _, body in _ENUM.findall(_text(header)) for m in _members(body)):
        if member == name:
            return value
    raw = _COMMENT.sub(" ", (HEADERS / header).read_text(encoding="utf-8"))
    match = re.search(rf"^[ \t]*#define[ \t]+{name}[ \t]+\(?(-?\w+)\)?[ \t]*$", raw, re.M)
    if match is None:
        raise ContractError(f"{HEADERS / header} defines no integer {name}")
    return int(match[1], 0)


def declared(headers):
    """{name: (restype, argtypes)} of every function the headers declare."""
    return {name: sig for header in headers for name, sig in prototypes(header).items()}


def bind(name, lib, headers):
    """Give every function of lib<name>.so declared in `headers` its ctypes signature; ContractError
    when one is missing from the library (its header and its C files disagree)."""
    for function, (restype, argtypes) in declared(headers).items():
        try:
            entry = getattr(lib, function)
        except AttributeError:
            raise ContractError(f"lib{name}.so does not export {function}, which "
                                f"{', '.join(headers)} declares: the build is broken") from None
        entry.restype, entry.argtypes = restype, argtypes
    return lib
