"""The built FMUs against the issue's "Done when" list: fmpy validation and stand-alone runs,
discrete passivity in both port modes, bit-identical rollback, the frozen port map being firmly
nonexpansive (Condition 1) at gamma = 0.4 and not at gamma = 5, error statuses that commit
nothing, and the wave-port closure e + gamma f = sqrt(2 gamma / dt) a."""

import numpy as np
import pytest
from fmpy import simulate_fmu
from fmpy.fmi1 import FMICallException
from fmpy.validation import validate_fmu

MODELS = ("DuffingSide", "LinearSide")
WAVE, PHYSICAL = 0, 1
STATES = {"DuffingSide": ("q1", "v1", "d"), "LinearSide": ("q2", "v2")}
PHYSICAL_INPUT = {"DuffingSide": "u", "LinearSide": "F"}
DAMPERS = {"DuffingSide": ("c1", "c12"), "LinearSide": ("c2",)}
STEP_SIZES = (1e-4, 1e-2, 1e-1)
ROUNDOFF = 1e-12


def test_every_model_is_built(built_fmus):
    assert set(MODELS) <= set(built_fmus)


# ---- 1. fmpy's validation and a stand-alone run ----

@pytest.mark.parametrize("ident", MODELS)
def test_fmpy_validation_reports_nothing(built_fmus, ident):
    assert validate_fmu(str(built_fmus[ident])) == []


@pytest.mark.parametrize("ident, start", [("DuffingSide", {}), ("LinearSide", {"v2": 1.0})])
def test_simulates_alone_and_energy_never_grows(built_fmus, ident, start):
    """With a = 0 the port only absorbs (Delta H = -b^2/2 - dissipation), so H is nonincreasing."""
    result = simulate_fmu(str(built_fmus[ident]), stop_time=1.0, step_size=0.01, start_values=start)
    assert len(result) == 101
    for name in result.dtype.names:
        assert np.all(np.isfinite(result[name])), name
    H = result["H"]
    assert H[0] > 0
    assert np.all(np.diff(H) <= ROUNDOFF * H[0])
    assert H[-1] < 0.99 * H[0]  # energy does leave through the port


# ---- 2. discrete passivity ----

def random_case(rng, ident, mode):
    """Start values (states, dampers, gamma), step size and port input for one passivity trial."""
    big = lambda: rng.choice([-1, 1]) * 10 ** rng.uniform(-3, 3)
    if ident == "DuffingSide":
        start = dict(q1=rng.uniform(-3, 3), v1=rng.uniform(-30, 30), d=rng.uniform(-1, 1))
    else:
        start = dict(q2=rng.uniform(-3, 3), v2=rng.uniform(-30, 30))
    damped = rng.random() < 0.5
    start.update({c: rng.uniform(0.0, 5.0) if damped else 0.0 for c in DAMPERS[ident]})
    start.update(gamma=10 ** rng.uniform(-2, 2), port_mode=mode)
    h = float(rng.choice(STEP_SIZES))
    inputs = {"a" if mode == WAVE else PHYSICAL_INPUT[ident]: big()}
    return start, h, inputs, damped


def dissipation(ident, start, v_before, v_after, f, h):
    """h times the damper power at the stage; vbar is the midpoint velocity of the mass."""
    vbar = 0.5 * (v_before + v_after)
    if ident == "DuffingSide":  # the coupling dashpot sees the port flow f = v2 minus vbar = v1
        return h * (start["c1"] * vbar ** 2 + start["c12"] * (f - vbar) ** 2)
    return h * start["c2"] * vbar ** 2


@pytest.mark.parametrize("mode", [WAVE, PHYSICAL], ids=["wave", "physical"])
@pytest.mark.parametrize("ident", MODELS)
def test_discrete_passivity(open_fmu, ident, mode):
    """Delta H - supply <= 0 to roundoff, and it equals minus the damper dissipation."""
    fmu = open_fmu(ident)
    velocity = STATES[ident][1]
    rng = np.random.default_rng(1 + mode + 10 * MODELS.index(ident))
    damped_residuals = []
    for _ in range(200):
        start, h, inputs, damped = random_case(rng, ident, mode)
        fmu.start(**start)
        H0, v0 = fmu.get("H", velocity)
        fmu.set(**inputs)
        fmu.step(h)
        H1, v1, e, f, b = fmu.get("H", velocity, "e", "f", "b")
        if mode == WAVE:
            a = inputs["a"]
            supply = 0.5 * (a * a - b * b)
            scale = max(H0, H1, 0.5 * a * a, 0.5 * b * b, 1.0)
        else:
            supply = h * e * f
            scale = max(H0, H1, h * abs(e * f), 1.0)
        residual = (H1 - H0 - supply) / scale
        loss = dissipation(ident, start, v0, v1, f, h) / scale
        assert residual <= ROUNDOFF, (start, h, inputs, residual)
        assert abs(residual + loss) <= ROUNDOFF, (start, h, inputs, residual, loss)
        if damped:
            damped_residuals.append(residual)
    assert min(damped_residuals) < -1e-3  # dampers visibly dissipate, so the check can tell


# ---- 3. rollback ----

@pytest.mark.parametrize("ident", MODELS)
def test_rollback_and_serialized_state_repeat_bit_identically(open_fmu, ident):
    rng = np.random.default_rng(7)
    inputs = rng.uniform(-2, 2, size=8)
    fmu = open_fmu(ident).start()

    def run(instance, waves):
        rows = []
        for a in waves:
            instance.set(a=a)
            instance.step(0.01)
            rows.append(instance.all_reals())
        return np.array(rows).tobytes()

    run(fmu, inputs[:3])
    saved, t_saved = fmu.fmu.getFMUstate(), fmu.t
    first = run(fmu, inputs[3:])
    fmu.fmu.setFMUstate(saved)
    fmu.t = t_saved
    assert run(fmu, inputs[3:]) == first

    other = open_fmu(ident)  # a fresh instance restored from the bytes
    other.fmu.setFMUstate(other.fmu.deSerializeFMUstate(fmu.fmu.serializeFMUstate(saved)))
    other.t = t_saved
    assert run(other, inputs[3:]) == first
    fmu.fmu.freeFMUstate(saved)


# ---- 4. frozen port map: firmly nonexpansive (Condition 1) ----

def fne_margins(fmu, gamma, h=0.01):
    """Delta(alpha, beta) = (S(alpha) - S(beta))(alpha - beta) - (S(alpha) - S(beta))^2 over
    (alpha - beta)^2, for the frozen port map S(a) = b of one step from the Table I state."""
    fmu.start(gamma=gamma)
    initial = fmu.fmu.getFMUstate()

    def S(a):
        fmu.fmu.setFMUstate(initial)
        fmu.set(a=a)
        fmu.fmu.doStep(0.0, h)
        return fmu.get("b")[0]

    rng = np.random.default_rng(3)
    margins = []
    for width in (0.5, 50.0):
        for alpha, beta in rng.uniform(-width, width, size=(100, 2)):
            dS = S(alpha) - S(beta)
            margins.append((dS * (alpha - beta) - dS * dS) / (alpha - beta) ** 2)
    fmu.fmu.freeFMUstate(initial)
    return np.array(margins)


@pytest.mark.parametrize("ident", MODELS)
def test_frozen_port_map_is_fne_at_table_one(open_fmu, ident):
    assert fne_margins(open_fmu(ident), gamma=0.4).min() >= -ROUNDOFF


def test_frozen_port_map_fne_depends_on_gamma(open_fmu):
    """At gamma = 5 the Duffing side breaks Condition 1; the linear side still meets it."""
    assert fne_margins(open_fmu("DuffingSide"), gamma=5.0).min() < -1e-2
    assert fne_margins(open_fmu("LinearSide"), gamma=5.0).min() >= -ROUNDOFF


# ---- 5. failures return an error status and commit nothing ----

@pytest.mark.parametrize("mode", [WAVE, PHYSICAL], ids=["wave", "physical"])
@pytest.mark.parametrize("ident", MODELS)
def test_nan_input_is_an_error_that_commits_nothing(open_fmu, ident, mode):
    fmu = open_fmu(ident).start(port_mode=mode)
    fmu.set(a=0.3, **{PHYSICAL_INPUT[ident]: 0.3})
    fmu.step(0.01)
    before = fmu.all_reals()
    name = "a" if mode == WAVE else PHYSICAL_INPUT[ident]
    fmu.set(**{name: float("nan")})
    with pytest.raises(FMICallException):
        fmu.step(0.01)
    after = fmu.all_reals()
    changed = [n for n, x, y in zip(fmu.reals, before, after) if x.tobytes() != y.tobytes()]
    assert changed == [name]
    assert f"input {name} is not finite" in fmu.messages[-1]


def test_newton_failure_is_an_error_that_commits_nothing(open_fmu):
    fmu = open_fmu("DuffingSide")
    fmu.start(q1=3.0)
    fmu.step(0.01)  # the default iteration limit solves this step
    fmu.start(q1=3.0, newton_max_iter=1)
    fmu.set(a=1.0)
    before = fmu.all_reals()
    with pytest.raises(FMICallException):
        fmu.step(0.01)
    assert fmu.all_reals().tobytes() == before.tobytes()
    assert "did not converge in 1 iterations" in fmu.messages[-1]


# ---- 6. the wave closure holds at the stage ----

@pytest.mark.parametrize("ident", MODELS)
def test_stage_values_satisfy_the_wave_closure(open_fmu, ident):
    fmu = open_fmu(ident)
    rng = np.random.default_rng(5)
    for _ in range(100):
        start, h, inputs, _ = random_case(rng, ident, WAVE)
        fmu.start(**start)
        fmu.set(**inputs)
        fmu.step(h)
        e, f, b = fmu.get("e", "f", "b")
        gamma, a = start["gamma"], inputs["a"]
        alpha = np.sqrt(2 * gamma / h) * a
        assert abs(e + gamma * f - alpha) <= ROUNDOFF * max(abs(e), abs(gamma * f), abs(alpha))
        outgoing = np.sqrt(h) * (e - gamma * f) / np.sqrt(2 * gamma)
        assert abs(b - outgoing) <= ROUNDOFF * max(abs(b), abs(outgoing))
