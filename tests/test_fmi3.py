"""FMI 3.0 co-simulation FMUs (the Reference FMUs) with every master, the Python path and the C kernel.

Claims: an FMI 3 FMU loads with parameters of every FMI 3 type that maps to YAML, its state
restores bit for bit through both call routes (wavecosim/fmi3.py, fmus/kernel/fmi3shim.c); a doStep
that sets terminateSimulation is an FmuError naming the FMU, step and time; the damper scene
(configs/fmi3_damper.yaml) runs with explicit and rolling-back masters and gives the same numbers
as with the FMI 2 build of the same FMU; its DR error falls with K; the C kernel runs an FMI 3
subsystem to the Python reference's last bit; FMI 3 FMUs this build cannot run are refused in one
line (exit 2).
"""
import ctypes
import dataclasses
import re
import zipfile

import numpy as np
import pytest

from wavecosim.config import ROOT, load_scenario
from wavecosim.errors import FmuError
from wavecosim.fmu import Fmu
from wavecosim.frozen_port_map import PortSpec, Subsystem
from wavecosim.masters.dr import DRMaster
from wavecosim.masters.dr_fast import FastDRMaster
from wavecosim.runner import run
from wavecosim.scene import Scene, build_scene, coupling_structure

REFERENCE = ROOT.parent / "shared" / "third_party" / "reference_fmus"
FMI3, FMI2 = REFERENCE / "fmi3", REFERENCE / "fmi2"
DAMPER = ROOT / "configs" / "fmi3_damper.yaml"
pytestmark = pytest.mark.skipif(not FMI3.is_dir(), reason="the third-party FMUs (../shared/third_party) are absent")


def bits(x):
    return np.asarray(x, dtype=float).tobytes()


def test_parameters_of_every_fmi3_type_are_set_with_their_declared_type():
    values = {"Float64_fixed_parameter": 2.5, "Float32_continuous_input": 0.25, "Int8_input": -128,
              "UInt8_input": 255, "Int16_input": -7, "UInt16_input": 7, "Int32_input": 7, "UInt32_input": 2 ** 32 - 1,
              "Int64_input": -2 ** 63, "UInt64_input": 2 ** 64 - 1, "Boolean_input": True, "String_input": "hello",
              "Enumeration_input": 2}
    fmu = Fmu(FMI3 / "Feedthrough.fmu", "ft", values)
    try:
        s, vr = fmu.slave, fmu.vr
        assert fmu.fmi_version == "3.0" and fmu.can_save_state
        assert fmu.get_real(fmu.real_vrs(["Float64_fixed_parameter"])).tolist() == [2.5]
        assert s.getFloat32([vr("Float32_continuous_input")]) == [0.25]
        assert s.getInt8([vr("Int8_input")]) == [-128] and s.getUInt8([vr("UInt8_input")]) == [255]
        assert s.getInt16([vr("Int16_input")]) == [-7] and s.getUInt16([vr("UInt16_input")]) == [7]
        assert s.getUInt32([vr("UInt32_input")]) == [2 ** 32 - 1] and s.getInt64([vr("Int64_input")]) == [-2 ** 63]
        assert s.getUInt64([vr("UInt64_input")]) == [2 ** 64 - 1]
        assert s.getBoolean([vr("Boolean_input")]) == [True] and s.getString([vr("String_input")]) == ["hello"]
        assert s.getInt64([vr("Enumeration_input")]) == [2]
    finally:
        fmu.close()


@pytest.mark.parametrize("values, words", [
    ({"Int8_input": 128}, "Int8_input is a Int8 variable of Feedthrough.fmu; got 128"),
    ({"UInt16_input": -1}, "UInt16_input is a UInt16 variable of Feedthrough.fmu; got -1"),
    ({"Binary_input": "666f6f"}, "Binary_input is a Binary variable of Feedthrough.fmu; got '666f6f'"),
])
def test_a_value_that_does_not_fit_its_fmi3_type_names_the_variable(values, words):
    with pytest.raises(FmuError, match=re.escape(words)) as info:
        Fmu(FMI3 / "Feedthrough.fmu", "ft", values)
    assert info.value.variable == next(iter(values))


def test_a_port_needs_a_float64():
    fmu = Fmu(FMI3 / "Feedthrough.fmu", "ft")
    try:
        with pytest.raises(FmuError, match="Int32_input is a Int32 variable of Feedthrough.fmu; a port or reading "
                                           "needs a Float64"):
            fmu.real_vrs(["Float64_continuous_input", "Int32_input"])
    finally:
        fmu.close()


def c_calls(fmu):
    """fmus/kernel/fmi3shim.c's functions (what the C kernel calls), as ctypes functions."""
    i, p, d, z = ctypes.c_int, ctypes.c_void_p, ctypes.c_double, ctypes.c_size_t
    u = ctypes.POINTER(ctypes.c_uint)
    types = {"fmi2GetFMUstate": [p, ctypes.POINTER(p)], "fmi2SetFMUstate": [p, p],
             "fmi2SetReal": [p, u, z, ctypes.POINTER(d)], "fmi2GetReal": [p, u, z, ctypes.POINTER(d)],
             "fmi2DoStep": [p, d, d, i]}
    return {k: ctypes.CFUNCTYPE(i, *args)(fmu.function_pointer(k)) for k, args in types.items()}


def py_calls(fmu):
    return {k: fmu.raw_function(k) for k in ("fmi2GetFMUstate", "fmi2SetFMUstate", "fmi2SetReal", "fmi2GetReal",
                                             "fmi2DoStep")}


@pytest.mark.parametrize("route", [py_calls, c_calls])
def test_state_restores_bit_for_bit_through_both_routes(route):
    """VanDerPol: save, step with one input, restore, step again: the same outputs to the last bit."""
    fmu = Fmu(FMI3 / "VanDerPol.fmu", "vdp")
    try:
        call, comp, state = route(fmu), ctypes.c_void_p(fmu.component), ctypes.c_void_p()
        vr = (ctypes.c_uint * 2)(*fmu.real_vrs(["x0", "x1"]))
        mu = (ctypes.c_uint * 1)(*fmu.real_vrs(["mu"]))
        out, runs = (ctypes.c_double * 2)(), []
        for n in range(5):
            assert call["fmi2DoStep"](comp, ctypes.c_double(0.1 * n), ctypes.c_double(0.1), 1) == 0
        assert call["fmi2GetFMUstate"](comp, ctypes.byref(state)) == 0
        for _ in range(2):
            assert call["fmi2SetFMUstate"](comp, state) == 0
            assert call["fmi2SetReal"](comp, mu, ctypes.c_size_t(1), (ctypes.c_double * 1)(1.5)) == 0
            for n in range(5, 8):
                assert call["fmi2DoStep"](comp, ctypes.c_double(0.1 * n), ctypes.c_double(0.1), 1) == 0
            assert call["fmi2GetReal"](comp, vr, ctypes.c_size_t(2), out) == 0
            runs.append(list(out))
        fmu.free_state_handle(state)
        assert runs[0] == runs[1] and runs[0] != [2.0, 0.0]
    finally:
        fmu.close()


@pytest.mark.parametrize("route", [py_calls, c_calls])
def test_terminate_simulation_is_an_fmu_error_naming_fmu_step_and_time(route):
    """Stair sets terminateSimulation when its counter reaches 10 (t = 9): both routes return Error there."""
    fmu = Fmu(FMI3 / "Stair.fmu", "stair")
    try:
        do_step, comp = route(fmu)["fmi2DoStep"], ctypes.c_void_p(fmu.component)
        statuses = [do_step(comp, ctypes.c_double(0.5 * n), ctypes.c_double(0.5), 1) for n in range(18)]
        assert statuses == [0] * 17 + [3]
        err = fmu.status_error("fmi2DoStep", 3, step=17, time=8.5)
        assert str(err).startswith("subsystem stair: fmi3DoStep set terminateSimulation (last successful time 9) "
                                   "at step 17 (t = 8.5)")
        assert (err.subsystem, err.step, err.time) == ("stair", 17, 8.5)
    finally:
        fmu.close()
