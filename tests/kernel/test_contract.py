"""The kernel's C contract (kernel/contract.py): every function a kernel library exports is declared in
its headers, every declared one is exported, the bindings take their ctypes signatures and name lists
from the headers, and the header reader understands what our headers write."""
import ctypes
import shutil
import subprocess

import pytest

from wavecosim.kernel import abi, build, contract
from wavecosim.kernel.drkernel import LEDGER_ACTIONS, LEDGER_LOG, REASONS, STARTS

HEADER = """/* a header */
#ifndef X_H
#define X_H
#include <stddef.h>
typedef struct { int a; double b; } Pair;        /* a struct */
typedef void PassFn(void *args, int n);
enum Color { C_RED = 0, C_GREEN, C_BLUE = 2 };
enum Gap { G_A = 0, G_B = 2 };
enum { X_ONE = 1, X_TWO };
#define X_LIMIT (-2)
#define X_ROOM 64
static inline double twice(double x) { if (x) { return 2 * x; } return 0.0; }
Pair *x_create(int n, const double *values, unsigned int count);
void x_run(Pair *p, long ld, size_t k, fmi2Component comp,
           const fmi2ValueReference vr[]);
long x_count(void);
#endif
"""


def built(name):
    lib = build.helper_library(name)
    if lib is None:
        pytest.skip(f"lib{name}.so cannot be built here")
    return lib


def exported(name):
    """The functions lib<name>.so exports (nm -D)."""
    if shutil.which("nm") is None:
        pytest.skip("nm is not installed")
    out = subprocess.run(["nm", "-D", "--defined-only", str(build.build_library(name, log=lambda m: None))],
                         capture_output=True, text=True, check=True).stdout
    return {line.split()[-1] for line in out.splitlines() if line.split()[1:2] == ["T"]}


@pytest.mark.parametrize("name", build.library_names())
def test_every_exported_function_is_declared_in_the_librarys_headers(name):
    built(name)
    declared = contract.declared(build.library_headers(name))
    undeclared = {f for f in exported(name) - set(declared) if not f.endswith("_struct_size")}   # abi.py's
    assert sorted(undeclared) == [], f"lib{name}.so exports functions no header declares"
    assert set(declared) <= exported(name)


@pytest.mark.parametrize("name", build.library_names())
def test_every_binding_has_the_headers_signature(name):
    """A binding may narrow a pointer to a typed one (guard.py), nothing else."""
    lib = built(name)
    for function, (restype, argtypes) in contract.declared(build.library_headers(name)).items():
        entry = getattr(lib, function)
        assert entry.restype == restype or restype is ctypes.c_void_p and hasattr(entry.restype, "contents"), function
        assert len(entry.argtypes) == len(argtypes), function
        for mine, theirs in zip(entry.argtypes, argtypes):
            assert mine == theirs or theirs is ctypes.c_void_p and hasattr(mine, "contents"), function


def test_the_reader_takes_prototypes_and_enums_as_our_headers_write_them(tmp_path, monkeypatch):
    (tmp_path / "x.h").write_text(HEADER)
    monkeypatch.setattr(contract, "HEADERS", tmp_path)
    found = contract.prototypes.__wrapped__("x.h")
    assert found == {
        "x_create": (ctypes.c_void_p, [ctypes.c_int, ctypes.c_void_p, ctypes.c_uint]),
        "x_run": (None, [ctypes.c_void_p, ctypes.c_long, ctypes.c_size_t, ctypes.c_void_p, ctypes.c_void_p]),
        "x_count": (ctypes.c_long, [])}
    assert contract.enum.__wrapped__("x.h", "Color") == [("C_RED", 0), ("C_GREEN", 1), ("C_BLUE", 2)]
    contract.enum.cache_clear()
    contract._text.cache_clear()
    try:
        assert contract.names("x.h", "Color", "C_") == ("red", "green", "blue")
        assert [contract.constant("x.h", c) for c in ("X_TWO", "C_BLUE", "X_LIMIT", "X_ROOM")] == [2, 2, -2, 64]
        with pytest.raises(contract.ContractError, match="defines no integer X_NONE"):
            contract.constant("x.h", "X_NONE")
        with pytest.raises(contract.ContractError, match="enum Gap's G_\\* values are not 0 .. 1"):
            contract.names("x.h", "Gap", "G_")
        with pytest.raises(contract.ContractError, match="declares no enum Shade"):
            contract.names("x.h", "Shade", "S_")
        (tmp_path / "y.h").write_text("float y_half(float x);\n")
        unknown = r"y\.h: the kernel's contract does not know the C type 'float'"
        with pytest.raises(contract.ContractError, match=unknown):
            contract.prototypes.__wrapped__("y.h")
    finally:
        contract.enum.cache_clear()
        contract._text.cache_clear()


def test_a_function_the_header_declares_but_the_library_lacks_is_a_one_line_error(tmp_path, monkeypatch):
    lib = built("queries")
    (tmp_path / "q.h").write_text("int fq_queries_twice(int n);\n")
    monkeypatch.setattr(contract, "HEADERS", tmp_path)
    contract.prototypes.cache_clear()
    try:
        with pytest.raises(contract.ContractError) as info:
            contract.bind("queries", lib, ["q.h"])
    finally:
        contract.prototypes.cache_clear()
    assert str(info.value) == "libqueries.so does not export fq_queries_twice, which q.h declares: the build is broken"
    assert isinstance(info.value, abi.FmuError)


def test_the_name_lists_are_the_headers_enums():
    assert REASONS == ("budget", "tolerance", "deadline", "explicit", "converged", "energy-guard")
    assert LEDGER_LOG == ("supplied", "ledger", "traffic", "scale", "action", "rounds", "step_s", "round_s", "cpu_s")
    assert LEDGER_ACTIONS == ("kept", "scaled", "zero", "iterated", "projected", "blended", "anchored")
    assert STARTS == ("paper", "extrapolated", "previous")
    assert dict(contract.enum("drkernel.h", "DRLedgerLog"))["DR_LEDGER_COLUMNS"] == len(LEDGER_LOG)
