"""The FMI 2 and FMI 3 variable types as wavecosim carries them: which values of a scenario each
type accepts, the category a type belongs to (what a signal may connect it to and how it is
recorded) and the range of each integer type. The one table of types: signals, sources, start
values and recorded outputs all ask here."""

REAL, INTEGER, BOOLEAN, STRING, BINARY = "real", "integer", "boolean", "string", "binary"

# FMI type (both versions) -> category
CATEGORY = {"Real": REAL, "Float64": REAL, "Float32": REAL, "Integer": INTEGER, "Enumeration": INTEGER,
            **{f"{sign}Int{bits}": INTEGER for sign in ("", "U") for bits in (8, 16, 32, 64)},
            "Boolean": BOOLEAN, "String": STRING, "Binary": BINARY}
NUMBERS = (REAL, INTEGER, BOOLEAN)          # recorded as numbers; STRING and BINARY as text


def category(fmi_type):
    """REAL, INTEGER, BOOLEAN, STRING or BINARY; None for a type wavecosim does not carry (Clock)."""
    return CATEGORY.get(fmi_type)


def integer_range(fmi_type, enumeration_bits=32):
    """(lowest, highest) value of an integer type (Integer is 32 bits; an Enumeration has the bits
    its FMI version gives it: 32 in FMI 2, 64 in FMI 3)."""
    name = {"Integer": "Int32", "Enumeration": f"Int{enumeration_bits}"}.get(fmi_type, fmi_type)
    bits = int(name.lstrip("UInt"))
    return (0, (1 << bits) - 1) if name.startswith("U") else (-(1 << (bits - 1)), (1 << (bits - 1)) - 1)


def is_number(v):
    """A Real (Float64, Float32) value: an int or a float, not a bool."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def is_whole(v):
    """An Integer or Enumeration value: an int, not a bool."""
    return isinstance(v, int) and not isinstance(v, bool)


def as_python(kind, value):
    """A value an FMU returned (through fmpy) as the Python value of its category: float, int,
    bool, str (UTF-8 decoded) or bytes."""
    if kind == REAL:
        return float(value)
    if kind == INTEGER:
        return int(value)
    if kind == BOOLEAN:
        return bool(value)
    if kind == STRING:
        return value.decode("utf-8", "replace") if isinstance(value, bytes) else ("" if value is None else str(value))
    return bytes(value)
