"""The teaching models in models/: each FMU validates, takes one discrete-passive step per doStep
(Condition 2 of the paper at roundoff, in both port modes and for any gamma and step size), rolls
back bit-identically from a saved state, and simulates standalone with fmpy.

Condition 2 is checked as H(x1) - H(x0) = h sum_j e_j f_j - dissipation with dissipation >= 0, and
in wave mode also as the scattering identity e + gamma f = sqrt(2 gamma / h) a, so that
h sum_j e_j f_j = (|a|^2 - |b|^2)/2.
"""
import importlib.util
import re
import zlib
from pathlib import Path

import numpy as np
import pytest
from fmpy import extract, read_model_description, simulate_fmu
from fmpy.fmi2 import FMU2Slave
from fmpy.validation import validate_fmu

ROOT = Path(__file__).resolve().parent.parent

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
PASSIVITY_RTOL = 1e-12


def channels(folder, models=ROOT / "models"):
    """Port channels (wave_in, wave_out, effort, flow, physical_in, kind) from config.h."""
    text = (models / folder / "config.h").read_text()
    return re.findall(r"X\((\w+), (\w+), (\w+), (\w+), (\w+), (FLOW_INPUT|EFFORT_INPUT)\)", text)


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """Builds the models of this file with fmus/build.py; returns {identifier: (fmu, unzip dir)}."""
    spec = importlib.util.spec_from_file_location("wavecosim_fmus_build", ROOT / "fmus" / "build.py")
    build = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(build)
    out = {}
    for ident, (folder, *_) in MODELS.items():
        path = build.build_model(ROOT / "models" / folder, log=lambda *_: None)
        out[ident] = (path, extract(str(path), unzipdir=str(tmp_path_factory.mktemp(ident))))
    return out


class Instance:
    """One FMU instance addressed by variable names, initialized with the given start values."""

    def __init__(self, fmus, ident, name="test", reals=None, ints=None):
        path, unzipped = fmus[ident]
        md = read_model_description(str(path))
        self.vr = {v.name: v.valueReference for v in md.modelVariables}
        self.reals = [v.name for v in md.modelVariables if v.type == "Real"]
        self.fmu = FMU2Slave(guid=md.guid, unzipDirectory=unzipped,
                             modelIdentifier=md.coSimulation.modelIdentifier, instanceName=name)
        self.fmu.instantiate()
        self.fmu.setupExperiment(startTime=0.0)
        self.fmu.enterInitializationMode()
        for k, v in (ints or {}).items():
            self.fmu.setInteger([self.vr[k]], [int(v)])
        self.set(**(reals or {}))
        self.fmu.exitInitializationMode()
        self.t = 0.0

    def set(self, **values):
        if values:
            self.fmu.setReal([self.vr[k] for k in values], [float(v) for v in values.values()])

    def get(self, *names):
        return np.array(self.fmu.getReal([self.vr[k] for k in names]))

    def step(self, h):
        self.fmu.doStep(self.t, h)
        self.t += h

    def free(self):
        self.fmu.terminate()
        self.fmu.freeInstance()


def random_instance(fmus, ident, rng, mode, damped, models=MODELS):
    folder, damper, states, _ = models[ident]
    reals = {k: s * rng.standard_normal() for k, s in states.items()}
    reals["gamma"] = 10.0 ** rng.uniform(-1.5, 1.5)
    ints = {"port_mode": mode}
    if ident == "HeavyChain":
        ints.update(n=int(rng.integers(1, 40)), newton_sweeps=1)
        reals["amplitude"] = rng.uniform(-0.6, 0.6)
    reals[damper] = rng.uniform(0.0, 2.0) if damped else 0.0
    return Instance(fmus, ident, reals=reals, ints=ints)


@pytest.mark.parametrize("ident", MODELS)
def test_validates(fmus, ident):
    assert validate_fmu(str(fmus[ident][0])) == []


def check_discrete_passivity(new_instance, chans, phys_scale, mode, rng, instances=10):
    """Condition 2 over `instances` instances from new_instance(damped) x 10 random (input, gamma,
    h): equality when undamped, the wave closure in wave mode. Returns the worst residual."""
    worst = 0.0
    for trial in range(instances):
        damped = trial % 2 == 1
        inst = new_instance(damped)
        try:
            for _ in range(10):
                h = 10.0 ** rng.uniform(-3, -1)
                gamma = 10.0 ** rng.uniform(-1.5, 1.5)
                inst.set(gamma=gamma)
                H0 = inst.get("H")[0]
                if mode == 0:
                    a = rng.standard_normal(len(chans)) * np.sqrt(h * (abs(H0) + 1.0))
                    inst.set(**{c[0]: x for c, x in zip(chans, a)})
                else:
                    inst.set(**{c[4]: phys_scale * rng.standard_normal() for c in chans})
                inst.step(h)
                H1 = inst.get("H")[0]
                e = inst.get(*[c[2] for c in chans])
                f = inst.get(*[c[3] for c in chans])
                supply = h * float(e @ f)
                scale = abs(H0) + abs(H1) + abs(supply) + 1e-300
                resid = (H1 - H0 - supply) / scale
                assert resid <= PASSIVITY_RTOL, (mode, resid)
                if not damped:
                    assert abs(resid) <= PASSIVITY_RTOL, (mode, resid)
                worst = max(worst, abs(resid) if not damped else resid)
                if mode == 0:  # the step honours the wave closure, so supply = (|a|^2 - |b|^2)/2
                    b = inst.get(*[c[1] for c in chans])
                    target = np.sqrt(2.0 * gamma / h) * a
                    assert np.allclose(e + gamma * f, target, rtol=1e-11, atol=1e-11 * np.abs(target).max())
                    assert abs(0.5 * (a @ a - b @ b) - supply) <= 1e-11 * (a @ a + b @ b + 1e-300)
        finally:
            inst.free()
    return worst


@pytest.mark.parametrize("ident", MODELS)
@pytest.mark.parametrize("mode", [0, 1], ids=["wave", "physical"])
def test_discrete_passivity(fmus, ident, mode):
    """Condition 2 over 100 random (state, input, gamma, h): equality when undamped."""
    rng = np.random.default_rng(zlib.crc32(f"{ident}{mode}".encode()))
    worst = check_discrete_passivity(lambda damped: random_instance(fmus, ident, rng, mode, damped),
                                     channels(MODELS[ident][0]), MODELS[ident][3], mode, rng)
    print(f"\n{ident} {'wave' if mode == 0 else 'physical'}: worst passivity residual {worst:.2e}")


def check_rollback(inst, chans, rng):
    """Step, save, step, restore (directly and via serialization), step: identical outputs."""
    h = 0.01
    for _ in range(3):
        inst.set(**{c[0]: 0.1 * rng.standard_normal() for c in chans})
        inst.step(h)
    inputs = {c[0]: 0.1 * rng.standard_normal() for c in chans}
    state = inst.fmu.getFMUState()
    blob = inst.fmu.serializeFMUState(state)
    restored = inst.fmu.deserializeFMUState(blob)
    runs = []
    for saved in (None, state, restored):
        if saved is not None:
            inst.fmu.setFMUState(saved)
            inst.t -= 2 * h
        inst.set(**inputs)
        inst.step(h)
        inst.step(h)
        runs.append(inst.get(*inst.reals).tobytes())
    inst.fmu.freeFMUState(state)
    inst.fmu.freeFMUState(restored)
    assert runs[0] == runs[1] == runs[2]


@pytest.mark.parametrize("ident", MODELS)
def test_rollback_is_bit_identical(fmus, ident):
    rng = np.random.default_rng(7)
    inst = random_instance(fmus, ident, rng, mode=0, damped=True)
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


def test_failures_report_and_keep_the_state(fmus, capfd):
    from fmpy.fmi1 import FMICallException

    inst = Instance(fmus, "PlanarSpring", reals={"kxy": 100.0})
    try:
        with pytest.raises(FMICallException):
            inst.step(0.01)
        assert "convex potential" in capfd.readouterr().out
    finally:
        inst.free()

    inst = Instance(fmus, "HeavyChain", reals={"amplitude": 0.6},
                    ints={"n": 20, "newton_max_iter": 1, "newton_sweeps": 1})
    try:
        H0 = inst.get("H", "q_first", "q_last")
        with pytest.raises(FMICallException):
            inst.step(0.05)
        assert "did not converge" in capfd.readouterr().out
        assert inst.get("H", "q_first", "q_last").tobytes() == H0.tobytes()
    finally:
        inst.free()

    with pytest.raises(FMICallException):
        Instance(fmus, "HeavyChain", ints={"n": 5000})
    assert "parameter n must be between 1 and 1000, got 5000" in capfd.readouterr().out


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
