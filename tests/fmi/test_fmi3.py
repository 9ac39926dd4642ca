"""FMI 3.0 co-simulation FMUs (the Reference FMUs) with every master, the Python path and the C kernel.

Claims: an FMI 3 FMU loads with parameters of every FMI 3 type that maps to YAML, its state
restores bit for bit through both call routes (wavecosim/fmi/fmi3.py, kernel/c/fmi3shim.c); a doStep
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

from paths import ROOT
from wavecosim.cli import main
from wavecosim.scenario.config import load_scenario
from wavecosim.errors import FmuError
from wavecosim.fmi.fmu import Fmu
from wavecosim.core.frozen_port_map import PortSpec, Subsystem
from wavecosim.masters.dr_fast import FastDRMaster
from wavecosim.run.runner import run
from wavecosim.core.scene import Scene, build_scene, coupling_structure

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
    """kernel/c/fmi3shim.c's functions (what the C kernel calls), as ctypes functions."""
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


def damper(fmu_dir=FMI3, T=1.0, **master):
    """configs/fmi3_damper.yaml, with the Feedthrough of `fmu_dir` (FMI 3 or FMI 2) and a master."""
    scenario = load_scenario(DAMPER)
    sub = next(s for s in scenario.subsystems if s.name == "D")
    sub = dataclasses.replace(sub, fmu_path=fmu_dir / "Feedthrough.fmu")
    scenario = dataclasses.replace(scenario, T=T, subsystems=[s if s.name != "D" else sub for s in scenario.subsystems])
    return scenario.with_master(**master) if master else scenario


@pytest.mark.parametrize("algorithm", ["explicit", "gauss-seidel-iter", "dr"])
def test_the_damper_scene_gives_the_numbers_of_the_fmi2_build(algorithm):
    """Feedthrough's FMI 3 and FMI 2 builds in the same scene: the same numbers to the last bit."""
    three = run(damper(FMI3, algorithm=algorithm), certificates=False)
    two = run(damper(FMI2, algorithm=algorithm), certificates=False)
    assert three.status == two.status == "finished"
    assert bits(three.outputs) == bits(two.outputs) and bits(three.steps["iterations"]) == bits(two.steps["iterations"])
    q2, v2 = three.outputs[:, 0], three.outputs[:, 1]
    energy = 0.5 * 50.0 * q2 ** 2 + 0.5 * 4.0 * v2 ** 2                         # k2 = 50, m2 = 4
    assert np.abs(v2).max() > 0.2 and energy[-1] < 0.85 * energy[0]             # it moves, and the damper takes energy


def test_the_dr_error_falls_with_K():
    ref = run(damper(T=2.0, algorithm="newton"), certificates=False)
    errors = []
    for K in (0, 5, 20):
        res = run(damper(T=2.0, K=K), certificates=False)
        errors.append(float(np.abs(res.outputs[:, :2] - ref.outputs[:, :2]).max()))
    assert errors[0] > 1e-3 and errors[1] < errors[0] / 10 and errors[2] < 1e-10, errors


def wire_scene(T=0.5):
    """The paper's two oscillators joined through an FMI 3 'wire': Feedthrough as a wave 2-port that
    swaps its incident waves (b_0 = a_1, b_1 = a_0), a lossless zero-length line. A, W[0] and W[1], B
    meet like A and B in configs/two_oscillators.yaml. Scenes cannot declare a wave port on an FMU
    without one, so the scene is put together here from its parts."""
    scenario = dataclasses.replace(load_scenario(ROOT / "configs" / "two_oscillators.yaml"), T=T)
    pair = build_scene(scenario)
    A, B = pair.subsystems
    port = PortSpec(wave_in=["Float64_continuous_input", "Float64_discrete_input"],
                    wave_out=["Float64_discrete_output", "Float64_continuous_output"],
                    effort=[], flow=[], energy=None)
    W = Subsystem("W", Fmu(FMI3 / "Feedthrough.fmu", "W"), port, scenario.dt)
    E2, F2, _ = coupling_structure(scenario, [1, 1])
    E, F = np.zeros((4, 4)), np.zeros((4, 4))
    for k in (0, 2):
        E[k:k + 2, k:k + 2], F[k:k + 2, k:k + 2] = E2, F2
    return Scene(scenario, [A, W, B], [0, 1, 3], E, F, True, {"A": 0.4, "W": 0.4, "B": 0.4}), pair


def wire_run(fast, K, steps):
    scene, pair = wire_scene()
    settings = dataclasses.replace(scene.scenario.master, K=K, fast=fast)
    master = FastDRMaster(scene, settings)
    try:
        assert master.fast == (fast == "true")
        logs = [master.step(n, n * scene.scenario.dt) for n in range(steps)]
        A, B = scene.subsystems[0], scene.subsystems[2]
        return logs, list(master.b), list(A.read(["q1", "v1"])) + list(B.read(["q2", "v2"]))
    finally:
        master.close()
        scene.close()


def test_the_c_kernel_runs_an_fmi3_subsystem_to_the_last_bit():
    """The kernel calls W through kernel/c/fmi3shim.c, the reference through wavecosim/fmi/fmi3.py."""
    ref, fast = wire_run("false", 8, 40), wire_run("true", 8, 40)
    assert bits(ref[1]) == bits(fast[1]) and bits(ref[2]) == bits(fast[2])
    for a, b in zip(ref[0], fast[0]):
        assert (a.iterations, a.reason) == (b.iterations, b.reason)
        assert bits(a.a_hat) == bits(b.a_hat) and bits(a.residual) == bits(b.residual)


def test_the_fmi3_wire_is_lossless():
    """Converged, the wire joins A and B as the direct coupling does: the same states."""
    _, _, wired = wire_run("true", 100, 50)
    scenario = load_scenario(ROOT / "configs" / "two_oscillators.yaml").with_master(K=100)
    direct = run(dataclasses.replace(scenario, T=0.5), certificates=False)
    cols = [direct.columns.index(c) for c in ("q1", "v1", "q2", "v2")]
    assert np.abs(np.array(wired) - direct.outputs[-1, cols]).max() < 1e-9


def rewritten_feedthrough(tmp_path, name, rename=None, description=None):
    """A copy of the FMI 3 Feedthrough with members renamed or its modelDescription.xml changed, and
    configs/fmi3_damper.yaml pointing at it; returns the config's path."""
    target = tmp_path / f"{name}.fmu"
    with zipfile.ZipFile(FMI3 / "Feedthrough.fmu") as src, zipfile.ZipFile(target, "w") as dst:
        for item in src.infolist():
            data, member = src.read(item.filename), item.filename
            if rename and member.startswith(rename[0]):
                member = rename[1] + member[len(rename[0]):]
            if description and member == "modelDescription.xml":
                assert description[0] in data.decode()
                data = data.decode().replace(*description).encode()
            dst.writestr(member, data)
    config = tmp_path / f"{name}.yaml"
    config.write_text(DAMPER.read_text().replace("../../shared/third_party/reference_fmus/fmi3/Feedthrough.fmu",
                                                 str(target)).replace("T: 5.0", "T: 0.2"))
    return config


def cli_run(config, tmp_path, capsys, *options):
    with pytest.raises(SystemExit) as info:
        main(["run", str(config), "--out", str(tmp_path / "out"), "--quiet", *options])
    return info.value.code, capsys.readouterr().err.strip().splitlines()


@pytest.mark.parametrize("algorithm", ["dr", "explicit"])
def test_an_fmi3_fmu_without_a_binary_for_this_platform_is_one_line_and_exit_2(tmp_path, capsys, algorithm):
    config = rewritten_feedthrough(tmp_path, "NoBinary", rename=("binaries/x86_64-linux/", "binaries/aarch64-darwin/"))
    fmu = tmp_path / "NoBinary.fmu"                  # and no sources (with them it is built from them)
    with zipfile.ZipFile(fmu) as src:
        members = {item.filename: src.read(item) for item in src.infolist() if not item.filename.startswith("sources/")}
    with zipfile.ZipFile(fmu, "w") as dst:
        for name, data in members.items():
            dst.writestr(name, data)
    code, err = cli_run(config, tmp_path, capsys, "--master", algorithm)
    assert code == 2 and len(err) == 1
    assert ("subsystems.D.fmu: NoBinary.fmu has no binary for this platform (x86_64-linux; it has: "
            "aarch64-darwin)") in err[0]


def test_an_fmi3_fmu_without_state_save_runs_only_with_masters_that_do_not_iterate(tmp_path, capsys):
    config = rewritten_feedthrough(tmp_path, "NoState", description=('canGetAndSetFMUState="true"',
                                                                      'canGetAndSetFMUState="false"'))
    for algorithm in ("dr", "gauss-seidel-iter"):
        code, err = cli_run(config, tmp_path, capsys, "--master", algorithm)
        assert code == 2 and len(err) == 1 and "subsystems.D.fmu: NoState.fmu cannot get and set its state" in err[0]
    code, err = cli_run(config, tmp_path, capsys, "--master", "explicit")          # its reference rolls back
    assert code == 2 and len(err) == 1 and "(needed by the monolithic reference; --no-reference runs" in err[0]
    with pytest.raises(SystemExit) as info:
        main(["run", str(config), "--out", str(tmp_path / "out"), "--quiet", "--master", "explicit", "--no-reference"])
    assert info.value.code in (0, None)
