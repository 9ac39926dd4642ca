"""Which values of a scenario a variable of each FMI type accepts."""


def is_number(v):
    """A Real (Float64, Float32) value: an int or a float, not a bool."""
    return isinstance(v, (int, float)) and not isinstance(v, bool)


def is_whole(v):
    """An Integer or Enumeration value: an int, not a bool."""
    return isinstance(v, int) and not isinstance(v, bool)


def is_int32(v):
    """An FMI 2 Integer: a whole number that fits in 32 bits (a larger one would wrap)."""
    return is_whole(v) and -2 ** 31 <= v < 2 ** 31
