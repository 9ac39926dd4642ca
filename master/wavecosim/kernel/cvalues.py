"""C values for the calls the parts above the kernel make through ctypes (the FMUs' own fmi2
functions, the kernel libraries' entry points), so that no module outside kernel/ and fmi/ imports
ctypes: scalars and arrays made once and passed as they are."""
import ctypes

double, size, pointer = ctypes.c_double, ctypes.c_size_t, ctypes.c_void_p     # one C value each
ref, address = ctypes.byref, ctypes.addressof          # a C value by reference; the address it lives at


def doubles(values):
    """A C double array: of these values, or of `values` zeros when it is a count."""
    if isinstance(values, int):
        return (ctypes.c_double * values)()
    return (ctypes.c_double * len(values))(*values)


def ints(values):
    """A C int array of these values (at least one element)."""
    return (ctypes.c_int * max(1, len(values)))(*values)


def uints(values):
    """A C unsigned int array of these values (value references)."""
    return (ctypes.c_uint * len(values))(*values)


def element(array, i):
    """A double * to element i of a C double array."""
    return ctypes.cast(ctypes.addressof(array) + 8 * i, ctypes.POINTER(ctypes.c_double))
