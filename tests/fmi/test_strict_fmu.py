"""StrictMass (models/strict_mass, fmus/layer/fmi2_strict.c): a mass that aborts the process on any
misuse of an instance or a saved state, as the least forgiving real exports crash on it. Each
misuse is made by a few raw FMI calls in a child process, which must die with the strict layer's
one line; used by the book, the FMU validates, steps exactly and restores bit for bit."""
import os
import subprocess
import sys
import tempfile
import textwrap

import numpy as np
import pytest
from fmpy import read_model_description
from fmpy.validation import validate_fmu

from wavecosim.fmi.fmu import Fmu

DT = 1e-3
# A child process: the FMU opened by wavecosim (two instances, A and B, of one binary), raw fmi2
# calls through their ctypes functions, then the case's own lines.
CHILD = """
import ctypes, sys
from wavecosim.fmi.fmu import Fmu
pool = {{}}
a, b = (Fmu(sys.argv[1], name, pool=pool) for name in ("A", "B"))
def fn(fmu, name):
    return fmu.raw_function(name)
def step(fmu, t, flag=0):
    return fn(fmu, "fmi2DoStep")(ctypes.c_void_p(fmu.component), ctypes.c_double(t), ctypes.c_double(1e-3), flag)
def save(fmu, handle):
    assert fn(fmu, "fmi2GetFMUstate")(ctypes.c_void_p(fmu.component), ctypes.byref(handle)) == 0
def restore(fmu, handle):
    return fn(fmu, "fmi2SetFMUstate")(ctypes.c_void_p(fmu.component), handle)
def free(fmu, handle):
    return fn(fmu, "fmi2FreeFMUstate")(ctypes.c_void_p(fmu.component), ctypes.byref(handle))
s = ctypes.c_void_p()
{case}
print("survived")
"""

MISUSES = {
    "NULL state handle": "restore(a, ctypes.c_void_p())",
    "was freed": "save(a, s); kept = ctypes.c_void_p(s.value); free(a, s); restore(a, kept)",
    "replaced by fmi2GetFMUstate": "save(a, s); kept = ctypes.c_void_p(s.value); save(a, s); restore(a, kept)",
    "belongs to instance A (a foreign state)": "save(a, s); restore(b, s)",
    "is not where the instance is": "step(a, 0.0); step(a, 0.0)",
    "is not where the instance is (0)": "save(a, s); step(a, 0.0); step(a, 1e-3); restore(a, s); step(a, 1e-3)",
    "where a doStep was given noSetFMUStatePriorToCurrentPoint = true":
        "save(a, s); step(a, 0.0, 1); step(a, 1e-3, 1); restore(a, s)",
    "not allowed in error": "fn(a, 'fmi2SetReal')(ctypes.c_void_p(a.component), (ctypes.c_uint * 1)(a.vr('F')), 1, "
                            "(ctypes.c_double * 1)(2e6)); step(a, 0.0); a.slave.terminate()",
    "m cannot be set in step mode": "fn(a, 'fmi2SetReal')(ctypes.c_void_p(a.component), (ctypes.c_uint * 1)(a.vr('m')), 1, "
                                "(ctypes.c_double * 1)(2.0))",
    "is not a live instance of this FMU": "comp = a.component; a.close(); fn(b, 'fmi2DoStep')(ctypes.c_void_p(comp), "
                                          "ctypes.c_double(0.0), ctypes.c_double(1e-3), 0)",
}


def child(path, case):
    """Run `case` in a child process; its unpacked FMUs go to a temporary folder removed afterwards (an
    aborted child cannot remove them itself)."""
    with tempfile.TemporaryDirectory() as tmp:
        return subprocess.run([sys.executable, "-c", CHILD.format(case=textwrap.dedent(case)), str(path)],
                              capture_output=True, text=True, timeout=60, env={**os.environ, "TMPDIR": tmp})


@pytest.mark.parametrize("why", list(MISUSES))
def test_a_misuse_aborts_the_process_with_one_line_naming_it(built_fmus, why):
    """Each misuse kills the child (SIGABRT) with 'StrictMass (strict FMU): <call> on instance <name>: ...'."""
    proc = child(built_fmus["StrictMass"], MISUSES[why])
    assert proc.returncode < 0 and "survived" not in proc.stdout, proc.stderr
    line = proc.stderr.strip().splitlines()[-1]
    assert line.startswith("StrictMass (strict FMU): fmi2") and why in line, proc.stderr


def test_used_by_the_book_it_survives(built_fmus):
    """The same calls in the right order: a state replaced by fmi2GetFMUstate in place, restored at
    its own time, freed once; steps where the instance is."""
    case = ("save(a, s); step(a, 0.0); save(a, s); step(a, 1e-3); assert restore(a, s) == 0; step(a, 1e-3); "
            "free(a, s); assert s.value is None; free(a, s); step(b, 0.0, 1); save(b, s); assert restore(b, s) == 0")
    proc = child(built_fmus["StrictMass"], case)
    assert proc.returncode == 0 and "survived" in proc.stdout, proc.stderr


def test_validates_and_declares_no_serialization(built_fmus):
    assert validate_fmu(str(built_fmus["StrictMass"])) == []
    cs = read_model_description(str(built_fmus["StrictMass"])).coSimulation
    assert cs.canGetAndSetFMUstate and not cs.canSerializeFMUstate


@pytest.fixture
def mass(built_fmus):
    made = []

    def _open(**values):
        made.append(Fmu(built_fmus["StrictMass"], "A", values))
        return made[-1]
    yield _open
    for fmu in made:
        fmu.close()


def test_steps_are_exact_for_a_held_force(mass):
    """c = 0: v = v0 + F t / m and x = x0 + v0 t + F t^2 / (2 m); c > 0: the exponential approach to F / c."""
    for c in (0.0, 0.5):
        fmu = mass(m=2.0, c=c, v=0.3, x=0.1)
        fmu.set_real([fmu.vr("F")], [1.5])
        for n in range(100):
            fmu.slave.doStep(n * DT, DT)
        x, v = fmu.get_real([fmu.vr("x"), fmu.vr("v")])
        t, v_end = 100 * DT, (1.5 / c if c else None)
        if c == 0.0:
            assert (x, v) == pytest.approx((0.1 + 0.3 * t + 1.5 * t * t / 4.0, 0.3 + 1.5 * t / 2.0), rel=1e-13)
        else:
            tau = 2.0 / c
            assert v == pytest.approx(v_end + (0.3 - v_end) * np.exp(-t / tau), rel=1e-13)
            assert x == pytest.approx(0.1 + v_end * t + (0.3 - v_end) * tau * (1 - np.exp(-t / tau)), rel=1e-12)


BEYOND_F_MAX = ("fn(a, 'fmi2SetReal')(ctypes.c_void_p(a.component), (ctypes.c_uint * 1)(a.vr('F')), 1, "
                "(ctypes.c_double * 1)(2e6)); status = step(a, 0.0); assert status == 3; "
                "a.status_error('fmi2DoStep', status); ")


def test_closing_after_an_error_frees_without_terminate(built_fmus):
    """doStep past F_max returns fmi2Error; Fmu.close then frees the instance without fmi2Terminate,
    as the FMI 2 state machine asks; the child survives."""
    proc = child(built_fmus["StrictMass"], BEYOND_F_MAX + "assert a.phase == 'error'; a.close(); b.close()")
    assert proc.returncode == 0 and "survived" in proc.stdout, proc.stderr


def test_closing_as_before_after_an_error_aborts(built_fmus):
    """The same with the error not noted (how every instance was closed before): fmi2Terminate in the
    error state, which the strict FMU, like real ones, does not survive."""
    proc = child(built_fmus["StrictMass"], BEYOND_F_MAX.replace("a.status_error('fmi2DoStep', status); ", "")
                 + "a.close()")
    assert proc.returncode < 0 and "fmi2Terminate on instance A: not allowed in error" in proc.stderr
