/* The structs the Python side mirrors field for field (ctypes Structures in wavecosim/kernel and
 * wavecosim/fmi): MIRRORED(T) exports `size_t T_struct_size(void)`, which wavecosim/kernel/abi.py
 * compares with the mirror's size once, when the library is loaded. */
#ifndef WAVECOSIM_ABI_H
#define WAVECOSIM_ABI_H
#include <stddef.h>

#define MIRRORED(T) \
    size_t T##_struct_size(void); \
    size_t T##_struct_size(void) { return sizeof(T); }

#endif
