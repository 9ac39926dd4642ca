"""The teaching models in models/: each FMU validates, takes one discrete-passive step per doStep
(Condition 2 of the paper at roundoff, in both port modes and for any gamma and step size), rolls
back bit-identically from a saved state, and simulates standalone with fmpy.

Condition 2 is checked as H(x1) - H(x0) = h sum_j e_j f_j - dissipation with dissipation >= 0, and
in wave mode also as the scattering identity e + gamma f = sqrt(2 gamma / h) a, so that
h sum_j e_j f_j = (|a|^2 - |b|^2)/2.
"""
import zlib

import numpy as np
import pytest
from fmpy import extract, simulate_fmu
from fmpy.validation import validate_fmu

from paths import ROOT
from conftest import Instance, channels, check_discrete_passivity, check_rollback, random_instance
from wavecosim.fmi import build


# identifier -> (folder, dissipative parameter, random state scales, physical input scale)
MODELS = {
    "Oscillator": ("oscillator", "c", {"q": 0.5, "v": 1.0}, 1.0),
    "SpringDamper": ("coupler_spring", "c", {"delta": 0.3}, 1.0),
    "PlanarMass": ("planar_mass", "drag", {"x": 1.0, "y": 1.0, "vx": 1.0, "vy": 1.0}, 1.0),
    "PlanarSpring": ("planar_spring", "damping", {"x": 0.5, "y": 0.5}, 1.0),
    "RLCCircuit": ("rlc_circuit", "R", {"q_C": 0.1, "i_L": 1.0}, 10.0),
    "DCMotorLoad": ("dc_motor_load", "friction", {"theta": 1.0, "omega": 5.0}, 1.0),
    "HeavyChain": ("heavy_chain", "c", {}, 10.0),
    "ChainLink": ("chain_link", "c", {"q": 0.5, "v": 1.0, "d": 0.3}, 1.0),
}


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """Builds the models of this file with wavecosim.fmi.build; returns {identifier: (fmu, unzip dir)}."""
    out = {}
    for ident, (folder, *_) in MODELS.items():
        path = build.build_model(ROOT / "models" / folder, log=lambda *_: None)
        out[ident] = (path, extract(str(path), unzipdir=str(tmp_path_factory.mktemp(ident))))
    return out


@pytest.mark.parametrize("ident", MODELS)
def test_validates(fmus, ident):
    assert validate_fmu(str(fmus[ident][0])) == []


@pytest.mark.parametrize("ident", MODELS)
@pytest.mark.parametrize("mode", [0, 1], ids=["wave", "physical"])
def test_discrete_passivity(fmus, ident, mode):
    """Condition 2 over 100 random (state, input, gamma, h): equality when undamped."""
    rng = np.random.default_rng(zlib.crc32(f"{ident}{mode}".encode()))
    worst = check_discrete_passivity(lambda damped: random_instance(fmus, ident, rng, mode, damped, MODELS),
                                     channels(MODELS[ident][0]), MODELS[ident][3], mode, rng)
    print(f"\n{ident} {'wave' if mode == 0 else 'physical'}: worst passivity residual {worst:.2e}")


@pytest.mark.parametrize("ident", MODELS)
def test_rollback_is_bit_identical(fmus, ident):
    rng = np.random.default_rng(7)
    inst = random_instance(fmus, ident, rng, 0, True, MODELS)
    try:
        check_rollback(inst, channels(MODELS[ident][0]), rng)
    finally:
        inst.free()


@pytest.mark.parametrize("ident", MODELS)
def test_standalone_simulation_stays_finite(fmus, ident):
    result = simulate_fmu(str(fmus[ident][0]), stop_time=1.0, output_interval=0.01, fmi_type="CoSimulation")
    for name in result.dtype.names:
        assert np.all(np.isfinite(result[name])), (ident, name)
    assert result["H"][-1] <= result["H"][0] * (1 + 1e-12)  # a = 0 is a matched load: H cannot grow


def test_heavy_chain_sweeps_change_cost_not_physics(fmus):
    """Newton sweeps past convergence move the solution by roundoff only."""
    runs = []
    for sweeps in (1, 30):
        inst = Instance(fmus, "HeavyChain", ints={"n": 60, "newton_sweeps": sweeps, "port_mode": 1})
        try:
            for k in range(20):
                inst.set(F=np.sin(0.3 * k))
                inst.step(0.01)
            runs.append(inst.get("q_first", "q_last", "H", "e", "f"))
        finally:
            inst.free()
    assert np.allclose(runs[0], runs[1], rtol=1e-10, atol=1e-13)


def test_heavy_chain_at_rest_driven_from_the_port(fmus):
    """Zero initial state and a nonzero input: the Newton tolerance is relative to the iterate."""
    inst = Instance(fmus, "HeavyChain", reals={"amplitude": 0.0}, ints={"port_mode": 1, "newton_sweeps": 1})
    try:
        inst.set(F=1e-3)
        inst.step(0.01)
        assert inst.get("f")[0] > 0.0  # pushed towards -x by the reaction -F: f = -v > 0
    finally:
        inst.free()


def test_failures_report_and_keep_the_state(fmus):
    from fmpy.fmi1 import FMICallException

    inst = Instance(fmus, "PlanarSpring", reals={"kxy": 100.0})
    try:
        with pytest.raises(FMICallException):
            inst.step(0.01)
        assert "convex potential" in inst.messages[-1]
    finally:
        inst.free()

    inst = Instance(fmus, "HeavyChain", reals={"amplitude": 0.6},
                    ints={"n": 20, "newton_max_iter": 1, "newton_sweeps": 1})
    try:
        H0 = inst.get("H", "q_first", "q_last")
        with pytest.raises(FMICallException):
            inst.step(0.05)
        assert "did not converge" in inst.messages[-1]
        assert inst.get("H", "q_first", "q_last").tobytes() == H0.tobytes()
    finally:
        inst.free()

    with pytest.raises(FMICallException) as info:
        Instance(fmus, "HeavyChain", ints={"n": 5000})
    assert "parameter n must be between 1 and 1000, got 5000" in info.value.fmu_messages[-1]


def _solve_affine_interface(evaluate, n):
    """Root of the affine residual r(z) = evaluate(z) - z (z in R^n) from n + 1 evaluations;
    evaluates once more at the root so that the committed step is the converged one."""
    z0 = np.zeros(n)
    r0 = evaluate(z0) - z0
    jac = np.column_stack([evaluate(np.eye(n)[j]) - np.eye(n)[j] - r0 for j in range(n)])
    z = np.linalg.solve(jac, -r0)
    return z, evaluate(z) - z


def _midpoint(A, x, h, steps):
    eye = np.eye(len(x))
    for _ in range(steps):
        x = np.linalg.solve(eye - 0.5 * h * A, (eye + 0.5 * h * A) @ x)
    return x


def test_oscillator_chain_matches_monolithic_midpoint(fmus):
    """Oscillator.right - SpringDamper.left, SpringDamper.right - Oscillator.left with e_A = e_B,
    f_A + f_B = 0 solved exactly each step equals the implicit midpoint of the whole chain."""
    mA, kA, cA, mB, kB, cB, ks, cs, h = 1.0, 10.0, 0.1, 2.0, 5.0, 0.0, 20.0, 0.3, 0.02
    x = np.array([0.2, 0.0, -0.1, 0.5, 0.05])  # qA, vA, qB, vB, delta
    A = np.array([[0, 1, 0, 0, 0], [-kA / mA, -(cA + cs) / mA, 0, cs / mA, ks / mA], [0, 0, 0, 1, 0],
                  [0, cs / mB, -kB / mB, -(cB + cs) / mB, -ks / mB], [0, -1, 0, 1, 0]])
    ints = {"port_mode": 1}
    osc_a = Instance(fmus, "Oscillator", "A", {"m": mA, "k": kA, "c": cA, "q": x[0], "v": x[1]}, ints)
    osc_b = Instance(fmus, "Oscillator", "B", {"m": mB, "k": kB, "c": cB, "q": x[2], "v": x[3]}, ints)
    spring = Instance(fmus, "SpringDamper", "S", {"k": ks, "c": cs, "delta": x[4]}, ints)
    parts = (osc_a, osc_b, spring)
    try:
        for _ in range(25):
            saved = [p.fmu.getFMUState() for p in parts]

            def evaluate(z):
                for p, s in zip(parts, saved):
                    p.fmu.setFMUState(s)
                tension = z[0]
                osc_a.set(F_right=tension, F_left=0.0)
                osc_b.set(F_left=tension, F_right=0.0)
                osc_a.fmu.doStep(osc_a.t, h)
                osc_b.fmu.doStep(osc_b.t, h)
                spring.set(u_left=-osc_a.get("f_right")[0], u_right=-osc_b.get("f_left")[0])
                spring.fmu.doStep(spring.t, h)
                return spring.get("e_left")

            _, res = _solve_affine_interface(evaluate, 1)
            assert abs(res[0]) < 1e-12
            for p, s in zip(parts, saved):
                p.t += h
                p.fmu.freeFMUState(s)
        got = np.concatenate([osc_a.get("q", "v"), osc_b.get("q", "v"), spring.get("delta")])
        assert np.allclose(got, _midpoint(A, x, h, 25), rtol=1e-12, atol=1e-13)
    finally:
        for p in parts:
            p.free()


def test_rlc_and_motor_through_a_gyrator_match_monolithic_midpoint(fmus):
    """RLCCircuit and DCMotorLoad, both effort-in, joined by u = Km omega, tau = -Km i."""
    L, R, C, J, fr, kt, km, h = 0.1, 1.0, 0.01, 0.01, 0.01, 1.0, 0.1, 0.01
    x = np.array([0.1, 0.0, 0.0, 0.0])  # q_C, i_L, theta, omega
    A = np.array([[0, 1, 0, 0], [-1 / (L * C), -R / L, 0, km / L], [0, 0, 0, 1], [0, -km / J, -kt / J, -fr / J]])
    ints = {"port_mode": 1}
    rlc = Instance(fmus, "RLCCircuit", "rlc", {"L": L, "R": R, "C": C, "q_C": x[0], "i_L": x[1]}, ints)
    motor = Instance(fmus, "DCMotorLoad", "motor", {"J": J, "friction": fr, "stiffness": kt}, ints)
    try:
        for _ in range(25):
            saved = [p.fmu.getFMUState() for p in (rlc, motor)]

            def evaluate(z):  # z = (u, tau), the held efforts of both sides
                for p, s in zip((rlc, motor), saved):
                    p.fmu.setFMUState(s)
                rlc.set(u=z[0])
                motor.set(tau=z[1])
                rlc.fmu.doStep(rlc.t, h)
                motor.fmu.doStep(motor.t, h)
                return np.array([km * motor.get("f")[0], -km * rlc.get("f")[0]])

            _, res = _solve_affine_interface(evaluate, 2)
            assert np.abs(res).max() < 1e-12
            for p, s in zip((rlc, motor), saved):
                p.t += h
                p.fmu.freeFMUState(s)
        got = np.concatenate([rlc.get("q_C", "i_L"), motor.get("theta", "omega")])
        assert np.allclose(got, _midpoint(A, x, h, 25), rtol=1e-12, atol=1e-13)
    finally:
        rlc.free()
        motor.free()
