"""The shared FMI layer (fmus/layer/) across every built FMU: fmpy's validation, a rebuild from the
FMU's own sources/ with fmpy's CMake build, and error messages that name the bad value."""

import ctypes
import os
import shutil
import sys
from pathlib import Path

import numpy as np
import pytest
from fmpy.fmi1 import FMICallException
from fmpy import extract, simulate_fmu
from fmpy.build import build_platform_binary
from fmpy.validation import validate_fmu

from wavecosim.errors import FmuError
from wavecosim.fmi.fmu import Fmu

# one model with a wave port and a header of its own (newton.h), one plain physical-causality model,
# one generated from a port-Hamiltonian spec (specs/pendulum_cart.yaml, with ph_step.h)
REBUILT = {"DuffingSide": {}, "ForeignMass": {"v": 1.0, "c": 0.5}, "PendulumCart": {"theta": 1.0}}


def test_every_built_fmu_validates(built_fmus):
    problems = {ident: validate_fmu(str(path)) for ident, path in built_fmus.items()}
    assert problems == {ident: [] for ident in built_fmus}


@pytest.mark.parametrize("ident", REBUILT)
def test_rebuilt_from_its_sources_gives_the_same_outputs(built_fmus, ident, tmp_path, monkeypatch):
    """fmpy's CMake build of sources/ (what `fmpy compile` runs) replaces the binary, and the
    rebuilt FMU simulates to the same numbers as the original (bit-identical on x86-64 gcc, where
    neither build fuses multiply-adds; the tolerance leaves room for a compiler that does)."""
    monkeypatch.setenv("PATH", f"{Path(sys.executable).parent}{os.pathsep}{os.environ['PATH']}")  # pip's cmake
    unzipdir = Path(extract(str(built_fmus[ident]), unzipdir=str(tmp_path / "fmu")))
    shutil.rmtree(unzipdir / "binaries")
    (tmp_path / "cmake").mkdir()
    build_platform_binary(unzipdir, build_dir=tmp_path / "cmake")
    assert list((unzipdir / "binaries").rglob(f"{ident}.*"))
    runs = [simulate_fmu(str(path), stop_time=0.05, output_interval=0.01, start_values=REBUILT[ident])
            for path in (built_fmus[ident], unzipdir)]
    names = runs[0].dtype.names
    assert len(runs[0]) == 6 and names == runs[1].dtype.names
    for name in names:
        np.testing.assert_allclose(runs[1][name], runs[0][name], rtol=1e-14, atol=0.0, err_msg=name)


def fmu_error(built_fmus, ident, reals=None, integers=None):
    """The message of the FmuError raised while setting up an instance."""
    with pytest.raises(FmuError) as info:
        Fmu(built_fmus[ident], "test", reals, integers)
    return str(info.value)


def test_bad_port_mode_is_named_with_its_value(built_fmus):
    message = fmu_error(built_fmus, "LinearSide", integers={"port_mode": 7})
    assert "port_mode must be 0 (wave) or 1 (physical), got 7" in message


def test_bad_gamma_is_named_with_its_value(built_fmus):
    assert "gamma must be > 0, got -2" in fmu_error(built_fmus, "LinearSide", reals={"gamma": -2.0})


def test_bad_parameter_of_a_plain_model_is_named_with_its_value(built_fmus):
    assert "substeps must be >= 1, got 0" in fmu_error(built_fmus, "ForeignMass", integers={"substeps": 0})


def test_out_of_range_value_reference_is_named(built_fmus):
    fmu = Fmu(built_fmus["LinearSide"], "test")
    n_reals = sum(v.type == "Real" for v in fmu.description.modelVariables)
    with pytest.raises(FmuError):
        fmu.set_real([17], [1.0])
    assert fmu.last_message() == f"fmi2SetReal: value reference 17 out of range (have {n_reals} reals)"
    fmu.close()


def test_non_finite_input_of_a_plain_model_is_named_with_its_value(built_fmus):
    fmu = Fmu(built_fmus["ForeignSpring"], "test")
    set_real = fmu.raw_function("fmi2SetReal")  # Fmu.set_real refuses NaN itself
    status = set_real(ctypes.c_void_p(fmu.component), (ctypes.c_uint * 1)(fmu.vr("v")), ctypes.c_size_t(1),
                      (ctypes.c_double * 1)(float("nan")))
    assert status == 0
    with pytest.raises(FMICallException):
        fmu.slave.doStep(0.0, 0.01)
    assert fmu.last_message() == "fmi2DoStep: at t = 0: input v is not finite (v = nan)"
    fmu.close()


def test_call_in_the_wrong_state_names_the_state(built_fmus):
    fmu = Fmu(built_fmus["ForeignMass"], "test")
    with pytest.raises(FMICallException):
        fmu.slave.setupExperiment(startTime=0.0)
    assert fmu.last_message() == "fmi2SetupExperiment: not allowed in the current state (step mode)"
    with pytest.raises(FMICallException):
        fmu.slave.setInteger([fmu.vr("substeps")], [3])
    assert fmu.last_message() == "fmi2SetInteger: variable substeps (value reference 1000) cannot be set in step mode"
    fmu.close()


def test_integer_boolean_and_string_variables_by_value_reference(built_fmus):
    """The layer's get and set of every type: inputs set in step mode, outputs refused, a string
    longer than the layer holds refused naming the variable, a state restored with its strings."""
    fmu = Fmu(built_fmus["SignalSink"], "test")
    fmu.set_values("Integer", [fmu.vr("n")], [4])
    fmu.set_values("Boolean", [fmu.vr("on")], [True])
    fmu.set_values("String", [fmu.vr("text")], ["héllo, \"you\""])
    state = fmu.slave.getFMUstate()
    fmu.slave.doStep(0.0, 0.1)
    assert fmu.get_values("Integer", [fmu.vr("shifted"), fmu.vr("length")]) == [14, 13]     # bytes of UTF-8
    assert fmu.get_values("Boolean", [fmu.vr("off")]) == [False]
    assert fmu.get_values("String", [fmu.vr("echo")]) == ['héllo, "you"']
    fmu.set_values("String", [fmu.vr("text")], ["other"])
    fmu.slave.setFMUstate(state)
    assert fmu.get_values("String", [fmu.vr("text")]) == ['héllo, "you"']
    for kind, name, value in (("Boolean", "off", True), ("String", "echo", "x"), ("Integer", "shifted", 1)):
        with pytest.raises(FmuError, match=f"test: fmi2Set{kind} failed: fmi2Set{kind}: variable {name} "
                                           fr"\(value reference {fmu.vr(name)}\) cannot be set in step mode"):
            fmu.set_values(kind, [fmu.vr(name)], [value])
    with pytest.raises(FmuError, match="fmi2SetString: text takes a string of at most 127 bytes"):
        fmu.set_values("String", [fmu.vr("text")], ["x" * 200])
    with pytest.raises(FMICallException):
        fmu.slave.getBoolean([2999])
    assert fmu.last_message() == "fmi2GetBoolean: value reference 2999 out of range (have 2000..2001)"
    fmu.slave.freeFMUState(state)
    fmu.close()
