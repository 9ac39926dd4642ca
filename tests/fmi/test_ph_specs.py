"""FMUs generated from port-Hamiltonian specs (specs/*.yaml, fmus/codegen/ph.py): they validate, are
discretely passive in both port modes, and the re-expressed teaching models follow the hand-written
ones to 1e-12; malformed specs are refused naming the file and the key."""
import zlib

import numpy as np
import pytest
from fmpy import extract
from fmpy.validation import validate_fmu

from paths import ROOT
from wavecosim.fmi import build

from wavecosim.errors import ConfigError
from conftest import Instance, channels, check_discrete_passivity, check_rollback, random_instance


# identifier -> (spec stem, dissipative parameter, random state scales, physical input scale)
SPECS = {
    "LinearSidePH": ("linear_side", "c2", {"q2": 0.5, "v2": 1.0}, 1.0),
    "ChainLinkPH": ("chain_link", "c", {"q": 0.5, "v": 1.0, "d": 0.3}, 1.0),
    "RLCCircuitPH": ("rlc_circuit", "R", {"q_C": 0.1, "i_L": 1.0}, 10.0),
    "DuffingSidePH": ("duffing_side", "c12", {"q1": 0.5, "v1": 1.0, "d": 0.3}, 1.0),
    "Pendulum": ("pendulum", "friction", {"theta": 2.0, "p": 3.0}, 1.0),
    "RigidBody": ("rigid_body", "friction", {"L1": 1.0, "L2": 1.0, "L3": 1.0}, 1.0),
    "PendulumCart": ("pendulum_cart", "friction", {"x": 1.0, "theta": 2.0, "p_x": 1.0, "p_theta": 1.0}, 1.0),
}
# generated identifier -> (hand-written identifier, folder in models/, parameter ranges)
TWINS = {
    "LinearSidePH": ("LinearSide", "linear_side", {"m2": (1, 8), "k2": (10, 100), "c2": (0, 2)}),
    "ChainLinkPH": ("ChainLink", "chain_link", {"m": (0.5, 2), "k": (10, 300), "c": (0, 2), "k0": (0, 50),
                                                "c0": (0, 1)}),
    "RLCCircuitPH": ("RLCCircuit", "rlc_circuit", {"L": (0.05, 0.2), "R": (0, 2), "C": (0.005, 0.02)}),
    "DuffingSidePH": ("DuffingSide", "duffing_side", {"m1": (4, 10), "k1": (50, 150), "c1": (0, 1),
                                                      "k12": (50, 200), "c12": (0, 0.5), "knl": (1e3, 1e4)}),
}


ph = build.codegen()


def generated_models(ident):
    """The cache folder holding the model folder generated from the spec of `ident`."""
    return build.generated(ROOT / "specs" / f"{SPECS[ident][0]}.yaml").parent


@pytest.fixture(scope="module")
def fmus(tmp_path_factory):
    """Every spec's FMU and the hand-written twins: {identifier: (fmu, unzip dir)}."""
    paths = {ident: build.build_spec(ROOT / "specs" / f"{stem}.yaml", log=lambda *_: None)
             for ident, (stem, *_) in SPECS.items()}
    paths.update({hand: build.build_model(ROOT / "models" / folder, log=lambda *_: None)
                  for hand, folder, _ in TWINS.values()})
    return {k: (p, extract(str(p), unzipdir=str(tmp_path_factory.mktemp(k)))) for k, p in paths.items()}


@pytest.mark.parametrize("ident", SPECS)
def test_validates(fmus, ident):
    assert validate_fmu(str(fmus[ident][0])) == []


@pytest.mark.parametrize("ident", SPECS)
@pytest.mark.parametrize("mode", [0, 1], ids=["wave", "physical"])
def test_discrete_passivity(fmus, ident, mode):
    """Condition 2 over 300 random (state, input, gamma, h), with the helper of test_models.py."""
    rng = np.random.default_rng(zlib.crc32(f"{ident}{mode}".encode()))
    chans = channels(SPECS[ident][0], models=generated_models(ident))
    worst = check_discrete_passivity(lambda damped: random_instance(fmus, ident, rng, mode, damped, SPECS),
                                     chans, SPECS[ident][3], mode, rng, instances=30)
    print(f"\n{ident} {'wave' if mode == 0 else 'physical'}: worst passivity residual {worst:.2e}")


@pytest.mark.parametrize("ident", SPECS)
def test_rollback_is_bit_identical(fmus, ident):
    """With the linear steps' cached affine map inside the saved state."""
    rng = np.random.default_rng(7)
    inst = random_instance(fmus, ident, rng, 0, True, SPECS)
    try:
        check_rollback(inst, channels(SPECS[ident][0], models=generated_models(ident)), rng)
    finally:
        inst.free()


def _drive(fmus, ident, reals, mode, inputs, h, names):
    """Trajectory of `names` over len(inputs) steps with the given per-step input values."""
    inst = Instance(fmus, ident, reals=reals, ints={"port_mode": mode})
    try:
        rows = []
        for values in inputs:
            inst.set(**values)
            inst.step(h)
            rows.append(inst.get(*names))
        return np.array(rows)
    finally:
        inst.free()


@pytest.mark.parametrize("ident", TWINS)
@pytest.mark.parametrize("mode", [0, 1], ids=["wave", "physical"])
def test_generated_matches_hand_written(fmus, ident, mode):
    """300 steps with the same random parameters, start state and inputs: every state and port
    variable agrees to 1e-12 relative to its largest magnitude over the run."""
    hand, folder, ranges = TWINS[ident]
    rng = np.random.default_rng(zlib.crc32(f"twin{ident}{mode}".encode()))
    chans = channels(folder)
    states = SPECS[ident][2]
    reals = {k: rng.uniform(*r) for k, r in ranges.items()}
    reals.update({k: s * rng.standard_normal() for k, s in states.items()}, gamma=10.0 ** rng.uniform(-1, 1))
    col = 0 if mode == 0 else 4
    inputs = [{c[col]: 0.5 * rng.standard_normal() for c in chans} for _ in range(300)]
    names = [*states, *(c[k] for c in chans for k in (1, 2, 3)), "H"]
    got = _drive(fmus, ident, reals, mode, inputs, 0.01, names)
    want = _drive(fmus, hand, reals, mode, inputs, 0.01, names)
    scale = np.abs(want).max(axis=0) + 1e-300
    rel = (np.abs(got - want) / scale).max()
    print(f"\n{ident} vs {hand} ({'wave' if mode == 0 else 'physical'}): max relative deviation {rel:.1e}")
    assert rel <= 1e-12


def test_discrete_gradient_follows_the_form_of_H():
    kinds = {stem: ph.classify(ph.load(ROOT / "specs" / f"{stem}.yaml")) for stem, *_ in SPECS.values()}
    assert kinds == {"linear_side": "quadratic", "chain_link": "quadratic", "rlc_circuit": "quadratic",
                     "duffing_side": "separable", "pendulum": "separable", "rigid_body": "quadratic", "pendulum_cart": "general"}


def test_pendulum_swings_at_constant_energy(fmus):
    """Large swing, free port held at zero torque: H constant to roundoff, period near the
    large-amplitude value 2 pi sqrt(l/g) (1 + theta0^2/16) for theta0 = 1."""
    inst = Instance(fmus, "Pendulum", reals={"theta": 1.0, "p": 0.0}, ints={"port_mode": 1})
    try:
        H0, h, theta, H = inst.get("H")[0], 1e-3, [], []
        for _ in range(3000):
            inst.step(h)
            theta.append(inst.get("theta")[0])
            H.append(inst.get("H")[0])
    finally:
        inst.free()
    assert np.abs(np.array(H) - H0).max() <= 1e-12 * H0
    crossings = np.flatnonzero(np.diff(np.sign(theta)) != 0)
    period = 2 * (crossings[1] - crossings[0]) * h
    assert abs(period / (2 * np.pi * np.sqrt(1 / 9.81) * (1 + 1 / 16)) - 1) < 0.01


def test_rigid_body_tumbles_keeping_energy_and_casimir(fmus):
    """Spun near the intermediate axis with the port free: L2 flips sign (the tennis-racket
    effect) while H and |L|^2 stay within 1e-12 of their start values over 2000 steps."""
    inst = Instance(fmus, "RigidBody", ints={"port_mode": 1})
    try:
        H0, C0 = inst.get("H", "casimir")
        rows = []
        for _ in range(2000):
            inst.step(0.01)
            rows.append(inst.get("H", "casimir", "L2"))
    finally:
        inst.free()
    H, C, L2 = np.array(rows).T
    assert np.abs(H - H0).max() <= 1e-12 * H0 and np.abs(C - C0).max() <= 1e-12 * C0
    assert L2.min() < -1.9 and L2.max() > 1.9


def test_newton_budget_is_reported(fmus):
    from fmpy.fmi1 import FMICallException

    inst = Instance(fmus, "PendulumCart", reals={"theta": 2.5, "p_theta": 3.0},
                    ints={"newton_max_iter": 1, "port_mode": 1})
    try:
        before = inst.get("x", "theta", "p_x", "p_theta").tobytes()
        with pytest.raises(FMICallException):
            inst.step(0.05)
        assert "Newton did not converge (newton_max_iter = 1)" in inst.messages[-1]
        assert inst.get("x", "theta", "p_x", "p_theta").tobytes() == before
    finally:
        inst.free()


BASE = (ROOT / "specs" / "linear_side.yaml").read_text()


@pytest.mark.parametrize("change, key", [
    (("J: [[0, 1/m2], [-1/m2, 0]]", "J: [[0, 1/m2], [1/m2, 0]]"), "J: is not skew-symmetric"),
    (("R: [[0, 0], [0, c2/m2**2]]", "R: [[0, 0], [0, -1]]"), "R: [[R, P], [P^T, S]] is not positive"),
    (("H: m2*v2**2/2 + k2*q2**2/2", "H: m2*v2**2/2 - k2*q2**2/2"), "H: H = -"),
    (("G: [[0], [-1/m2]]", "G: [[0, 1], [-1/m2, 0]]"), "G: must be a 2 x 1 list of rows"),
    (("H: m2*v2**2/2 + k2*q2**2/2", "H: m2*v2**2/2 + k3*q2**2/2"), "H: unknown symbol(s) k3"),
    (("  c2: [0.0,", "  F: [0.0,"), "ports[0].F: name already used"),
    (("causality: effort_in", "causality: effort"), "ports[0].causality: must be effort_in or flow_in"),
    (("model: LinearSidePH\n", ""), "model: missing"),
])
def test_bad_spec_names_file_and_key(tmp_path, change, key):
    path = tmp_path / "bad.yaml"
    text = BASE.replace(*change)
    assert text != BASE
    path.write_text(text)
    with pytest.raises(ConfigError) as info:
        ph.load(path)
    assert str(info.value).startswith(f"{path}: {key}")


def test_build_all_lists_generated_fmus():
    built = build.build_all(log=lambda *_: None)
    for ident in SPECS:
        assert built[ident] == build.build_spec(ROOT / "specs" / f"{SPECS[ident][0]}.yaml")


@pytest.fixture(scope="module")
def pendulum_cart_scene():
    import wavecosim as wc
    return wc.load(ROOT / "configs" / "pendulum_cart.yaml", T=2.0)


def test_pendulum_cart_scene_converges_with_K(pendulum_cart_scene):
    """The spec-generated cart-pendulum coupled to the Duffing side: DR errors fall with K to the
    monolithic answer, Condition 2 at roundoff."""
    import wavecosim as wc
    errors = [wc.simulate(pendulum_cart_scene, K=K, certificates=False).summary for K in (0, 20, 50, 100)]
    assert [s["max_error"] for s in errors] == sorted((s["max_error"] for s in errors), reverse=True)
    assert errors[-1]["max_error"] < 1e-12 and errors[0]["max_error"] > 0.1
    assert max(s["max_passivity_pos"] for s in errors) < 1e-11


@pytest.mark.parametrize("master", ["explicit", "gauss-seidel", "jacobi-iter", "gauss-seidel-iter", "newton", "dr"])
def test_pendulum_cart_scene_runs_with_every_master(pendulum_cart_scene, master):
    import wavecosim as wc
    result = wc.simulate(pendulum_cart_scene, master=master, K=5, certificates=False)
    assert result.status == "finished" and np.isfinite(result.summary["max_error"])
