"""A mass and a wall spring-damper in the style of other tools' exports (models/foreign_mass,
models/foreign_spring): physical causality, their own substep solvers, no H, no wave port. They
validate, run under fmpy alone, restore bit-identically, couple by hand, and carry the port
orientation real pairs have: the spring's output is power-out (dF/dv < 0), the mass's power-in
(dv/dF > 0)."""

import numpy as np
import pytest
from fmpy import read_model_description, simulate_fmu
from fmpy.validation import validate_fmu

from wavecosim.fmi.fmu import Fmu

PAIR = ("ForeignMass", "ForeignSpring")
INPUT = {"ForeignMass": "F", "ForeignSpring": "v"}
OUTPUT = {"ForeignMass": "v", "ForeignSpring": "F"}
WAVE_PORT_NAMES = {"gamma", "port_mode", "H", "a", "b"}
DT = 1e-3


def get(fmu, name):
    return fmu.get_real([fmu.vr(name)])[0]


def put(fmu, name, value):
    fmu.set_real([fmu.vr(name)], [value])


def all_reals(fmu):
    return fmu.get_real([v.valueReference for v in fmu.description.modelVariables if v.type == "Real"])


@pytest.fixture
def opened(built_fmus):
    """Opens initialized instances by identifier with real parameters/start values; closes them."""
    made = []

    def _open(ident, **reals):
        made.append(Fmu(built_fmus[ident], ident, reals))
        return made[-1]

    yield _open
    for fmu in made:
        fmu.close()


@pytest.mark.parametrize("ident", PAIR)
def test_validates_and_looks_like_a_tool_export(built_fmus, ident):
    """No problems for fmpy; physical causality only, state save/restore, a substeps parameter."""
    assert validate_fmu(str(built_fmus[ident])) == []
    md = read_model_description(str(built_fmus[ident]))
    names = {v.name for v in md.modelVariables}
    assert not names & WAVE_PORT_NAMES
    assert md.coSimulation.canGetAndSetFMUstate
    assert [v.causality for v in md.modelVariables if v.name == "substeps"] == ["parameter"]


def test_mass_alone_under_fmpy_decays_as_the_exact_solution(built_fmus):
    """fmpy's own simulate_fmu, no input: m v' = -c v, so v = v0 exp(-c t / m), x = v0 m / c (1 - exp(-c t / m))."""
    m, c, v0 = 2.0, 0.5, 1.0
    res = simulate_fmu(str(built_fmus["ForeignMass"]), stop_time=1.0, output_interval=0.01,
                       start_values={"m": m, "c": c, "v": v0}, output=["x", "v"])
    decay = np.exp(-c * res["time"] / m)
    np.testing.assert_allclose(res["v"], v0 * decay, rtol=1e-12)
    np.testing.assert_allclose(res["x"], v0 * m / c * (1.0 - decay), rtol=1e-12, atol=1e-15)


def test_spring_alone_under_fmpy_follows_a_held_velocity(built_fmus):
    """fmpy's own simulate_fmu with a constant input v: x = x0 + v t and F = -(k x + d v)."""
    k, d, x0, v = 100.0, 0.5, 0.1, 0.2
    signal = np.array([(0.0, v), (1.0, v)], dtype=[("time", np.float64), ("v", np.float64)])
    res = simulate_fmu(str(built_fmus["ForeignSpring"]), stop_time=1.0, output_interval=0.01, input=signal,
                       start_values={"k": k, "d": d, "x": x0}, output=["x", "F"])
    np.testing.assert_allclose(res["x"], x0 + v * res["time"], rtol=1e-13)
    np.testing.assert_allclose(res["F"][1:], -(k * res["x"][1:] + d * v), rtol=1e-13)


@pytest.mark.parametrize("ident", PAIR)
def test_restore_is_bit_identical(opened, ident):
    """Step, save, step, restore, step again with the same input: the same bytes."""
    fmu = opened(ident, x=0.05)
    for n in range(5):
        put(fmu, INPUT[ident], 0.3 * n)
        fmu.slave.doStep(n * DT, DT)
    saved = fmu.slave.getFMUstate()
    put(fmu, INPUT[ident], -1.7)
    fmu.slave.doStep(5 * DT, DT)
    first = all_reals(fmu)
    fmu.slave.setFMUstate(saved)
    put(fmu, INPUT[ident], -1.7)
    fmu.slave.doStep(5 * DT, DT)
    assert all_reals(fmu).tobytes() == first.tobytes()
    fmu.slave.freeFMUstate(saved)


def coupled_energy(mass, spring, steps):
    """Jacobi (explicit) exchange at DT: each FMU gets the other's output of the last step. Returns
    the energy 1/2 m v^2 + 1/2 k x^2 (v of the mass, x the spring's elongation) at every step."""
    m, k = get(mass, "m"), get(spring, "k")
    energy = [0.5 * m * get(mass, "v") ** 2 + 0.5 * k * get(spring, "x") ** 2]
    for n in range(steps):
        force, velocity = get(spring, "F"), get(mass, "v")
        put(mass, "F", force)
        put(spring, "v", velocity)
        mass.slave.doStep(n * DT, DT)
        spring.slave.doStep(n * DT, DT)
        energy.append(0.5 * m * get(mass, "v") ** 2 + 0.5 * k * get(spring, "x") ** 2)
    return np.array(energy)


def jacobi_growth_bound(m, k, steps):
    """Undamped, the Jacobi exchange of this pair is explicit Euler on the oscillator
    (v' = v - DT k x / m, x' = x + DT v), whose energy grows by exactly 1 + (k / m) DT^2 per step."""
    return (1.0 + k / m * DT ** 2) ** steps


def test_undamped_jacobi_coupling_injects_exactly_the_explicit_euler_energy(opened):
    """1 s at DT = 1e-3 with no damping: H(1) / H(0) = (1 + w^2 DT^2)^1000 = 1.10517 to roundoff
    (measured 5e-15 apart), so the exchange is the plain explicit one and both solvers are exact."""
    mass, spring = opened("ForeignMass", c=0.0), opened("ForeignSpring", d=0.0)
    energy = coupled_energy(mass, spring, 1000)
    bound = jacobi_growth_bound(get(mass, "m"), get(spring, "k"), 1000)
    assert energy[-1] / energy[0] == pytest.approx(bound, rel=1e-12)


def test_damped_jacobi_coupling_grows_no_more_than_the_undamped_exchange(opened):
    """Default parameters (spring damper d = 0.5): the energy never rises above H(0) times the
    undamped explicit exchange's growth, and the damper takes out more than the exchange puts in
    over 1 s (measured: at most 1.0022 H(0), H(1) = 0.686 H(0), against the undamped 1.105 H(0))."""
    mass, spring = opened("ForeignMass"), opened("ForeignSpring")
    energy = coupled_energy(mass, spring, 1000)
    steps = np.arange(len(energy))
    assert np.all(energy <= energy[0] * jacobi_growth_bound(get(mass, "m"), get(spring, "k"), steps))
    assert energy[-1] < energy[0]


def step_map_slope(fmu, ident, u, du):
    """d(output)/d(input) of one doStep from the current state, by a finite difference of two
    steps from the same restored state."""
    saved = fmu.slave.getFMUstate()
    outputs = []
    for value in (u, u + du):
        fmu.slave.setFMUstate(saved)
        put(fmu, INPUT[ident], value)
        fmu.slave.doStep(0.0, DT)
        outputs.append(get(fmu, OUTPUT[ident]))
    fmu.slave.setFMUstate(saved)
    fmu.slave.freeFMUstate(saved)
    return (outputs[1] - outputs[0]) / du


def test_mass_port_is_power_in(opened):
    """Input force on the mass, output its velocity: dv/dF = DT / m > 0 (undamped)."""
    mass = opened("ForeignMass", m=2.0, v=0.4)
    slope = step_map_slope(mass, "ForeignMass", 1.0, 1e-3)
    assert slope > 0.0
    assert slope == pytest.approx(DT / 2.0, rel=1e-9)


def test_spring_port_is_power_out(opened):
    """Input velocity of the mass, output the force on it: dF/dv = -(k DT + d) < 0."""
    spring = opened("ForeignSpring", k=100.0, d=0.5, x=0.1)
    slope = step_map_slope(spring, "ForeignSpring", 0.3, 1e-3)
    assert slope < 0.0
    assert slope == pytest.approx(-(100.0 * DT + 0.5), rel=1e-9)
