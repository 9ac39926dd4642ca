"""The scenes in configs/ beyond the benchmark, run through the unchanged master:

- chain.yaml      N ChainLink FMUs in a line, N - 1 two-port couplings (here for N = 2, 8, 16);
- star.yaml       a Duffing oscillator pulling three linear oscillators through one 0-junction;
- planar.yaml     a point mass on a 2-D spring: one vector port of two channels;
- rlc_motor.yaml  an RLC circuit driving a mechanical load through a gyrator (two domains).

For each: the energy certificates hold at roundoff for small K, the DR trajectory converges to the
monolithic reference as K grows, and `wavecosim run` / `compare` work on it. The monolithic
references of the linear scenes are also checked against the implicit midpoint rule of the
assembled system, which fixes every port sign; a lossy or rank-deficient coupling is rejected.
"""
import dataclasses
import json

import numpy as np
import pytest
import yaml

from wavecosim.cli import main
from wavecosim.sweeps.comparison import BUDGETS, compare
from wavecosim.scenario.config import load_scenario, parse_scenario
from wavecosim.errors import CouplingError
from wavecosim.run.runner import run
from wavecosim.sweeps.budget import reference_run

from paths import CONFIGS
T_TEST = 1.0                 # 100 macro-steps
CERT_KS = (0, 1, 3)
CONV_KS = (3, 10, 30, 100)
ROUNDOFF = 1e-12             # relative to the largest stored energy of the run


def raw_config(name):
    return yaml.safe_load((CONFIGS / f"{name}.yaml").read_text())


def chain_raw(N, **parameters):
    """configs/chain.yaml with N links (first one struck, the rest at rest), parameters overridden."""
    raw = raw_config("chain")
    first, rest = raw["subsystems"]["L0"], raw["subsystems"]["L1"]
    subs = {f"L{i}": dict(first if i == 0 else rest) for i in range(N)}
    for s in subs.values():
        s["parameters"] = {**s["parameters"], **parameters}
    raw["subsystems"] = subs
    raw["couplings"] = ([{"type": "free_end", "ports": ["L0[0]"]}] +
                        [{"type": "equal_effort_opposite_flow", "ports": [f"L{i}[1]", f"L{i + 1}[0]"]}
                         for i in range(N - 1)] +
                        [{"type": "clamped_end", "ports": [f"L{N - 1}[1]"]}])
    raw["outputs"] = {**{f"q{i}": f"L{i}.q" for i in range(N)}, **{f"v{i}": f"L{i}.v" for i in range(N)},
                      **{f"d{i}": f"L{i}.d" for i in range(N)}}
    raw["error"] = [f"q{i}" for i in range(N)]
    return raw


def scenario(raw, T=T_TEST, name="scene"):
    sc = parse_scenario(raw, f"<{name}>", CONFIGS)
    return dataclasses.replace(sc, T=T)


SCENES = {
    "chain_N2": lambda: chain_raw(2),
    "chain_N8": lambda: raw_config("chain"),
    "chain_N16": lambda: chain_raw(16),
    "star": lambda: raw_config("star"),
    "planar": lambda: raw_config("planar"),
    "rlc_motor": lambda: raw_config("rlc_motor"),
}


@pytest.fixture(scope="module", params=list(SCENES))
def sweep(request):
    """(name, reference, {K: RunResult}) of one scene over CERT_KS and CONV_KS."""
    sc = scenario(SCENES[request.param](), name=request.param)
    reference = reference_run(sc)
    runs = {K: run(sc.with_master(algorithm="dr", K=K), reference=reference, certificates=K in CERT_KS)
            for K in sorted(set(CERT_KS) | set(CONV_KS))}
    return request.param, reference, runs


def test_certificates_hold_at_roundoff_for_small_K(sweep):
    """Condition 2 per subsystem and Theorem 1 per macro-step, and sampled FNE margins > 0."""
    name, _, runs = sweep
    for K in CERT_KS:
        s = runs[K].summary
        scale = max(1.0, float(np.max(runs[K].energy)))
        assert s["status"] == "finished", (name, K, s["message"])
        assert s["max_passivity_pos"] <= ROUNDOFF * scale, (name, K, s["max_passivity_pos"])
        assert s["max_augmented_pos"] <= ROUNDOFF * scale, (name, K, s["max_augmented_pos"])
        assert s["min_fne_margin"] > 0.0, (name, K, s["min_fne_margin"])


def test_converges_to_the_monolithic_reference(sweep):
    """Max error over the run falls strictly with K and reaches roundoff level by K = 100
    (measured at T = 1: 2e-2..8e-2 at K = 3, 8e-5..2e-3 at K = 10, 7e-14..5e-8 at K = 30,
    6e-16..6e-14 at K = 100)."""
    name, _, runs = sweep
    errors = [runs[K].summary["max_error"] for K in CONV_KS]
    assert all(a > b for a, b in zip(errors, errors[1:])), (name, errors)
    assert errors[CONV_KS.index(10)] < 1e-2, (name, errors)
    assert errors[CONV_KS.index(30)] < 1e-6, (name, errors)
    assert errors[-1] < 1e-11, (name, errors)


def midpoint(A, x0, h, n):
    """n steps of the implicit midpoint rule for x' = A x."""
    step = np.linalg.solve(np.eye(len(x0)) - 0.5 * h * A, np.eye(len(x0)) + 0.5 * h * A)
    xs = [np.asarray(x0, float)]
    for _ in range(n):
        xs.append(step @ xs[-1])
    return np.array(xs)


def test_chain_reference_is_the_midpoint_rule_of_the_whole_chain():
    """Six ChainLinks with ground springs and dampers, coupled by the master (interface Newton),
    step for step equal to the midpoint rule of the assembled 6-mass chain: signs and ends right."""
    N, p = 6, dict(m=1.5, k=80.0, c=0.2, k0=5.0, c0=0.1)
    sc = scenario(chain_raw(N, **p), T=0.5)
    ref = reference_run(sc)
    # x = (q, v, d); T_i = k d_i + c (v_{i+1} - v_i), v_N = 0 (wall);
    # m v_i' = -k0 q_i - c0 v_i - T_{i-1} + T_i (T_{-1} = 0, free end); d_i' = v_{i+1} - v_i
    I, Z = np.eye(N), np.zeros((N, N))
    Dv = np.eye(N, k=1) - I                       # (Dv v)_i = v_{i+1} - v_i, last row -v_{N-1}
    tension_d, tension_v = p["k"] * I, p["c"] * Dv
    left = np.eye(N, k=-1)                        # (left T)_i = T_{i-1}
    net = I - left                                # T_i - T_{i-1}
    A = np.block([[Z, I, Z],
                  [-p["k0"] / p["m"] * I, (-p["c0"] * I + net @ tension_v) / p["m"], net @ tension_d / p["m"]],
                  [Z, Dv, Z]])
    x0 = np.concatenate([np.zeros(N), [1.0] + [0.0] * (N - 1), np.zeros(N)])
    want = midpoint(A, x0, sc.dt, sc.n_steps)
    got = np.stack([ref.column(f"{v}{i}") for v in "qvd" for i in range(N)], axis=1)
    assert np.abs(got - want).max() < 1e-11


def test_rlc_motor_reference_is_the_midpoint_rule_of_the_drive():
    """The gyrator as compiled gives u = Km omega, tau = -Km i: the reference equals the midpoint
    rule of L i' = Km omega - R i - q/C, J omega' = -Km i - friction omega - stiffness theta."""
    raw = raw_config("rlc_motor")
    sc = scenario(raw)
    ref = reference_run(sc)
    C, M = raw["subsystems"]["C"]["parameters"], raw["subsystems"]["M"]["parameters"]
    Km = raw["couplings"][0]["ratio"]
    A = np.array([[0.0, 1.0, 0.0, 0.0],                                            # q_C
                  [-1.0 / (C["L"] * C["C"]), -C["R"] / C["L"], 0.0, Km / C["L"]],  # i_L
                  [0.0, 0.0, 0.0, 1.0],                                            # theta
                  [0.0, -Km / M["J"], -M["stiffness"] / M["J"], -M["friction"] / M["J"]]])
    start = {**raw["subsystems"]["C"]["start"], **raw["subsystems"]["M"]["start"]}
    x0 = [start["q_C"], start["i_L"], start["theta"], start["omega"]]
    want = midpoint(A, x0, sc.dt, sc.n_steps)
    got = np.stack([ref.column(c) for c in ("q_C", "i_L", "theta", "omega")], axis=1)
    assert np.abs(got - want).max() < 1e-11


def test_star_with_one_cart_is_the_paper_benchmark():
    """A 0-junction over two channels is the two-port e_A = e_B, f_A + f_B = 0: the star with only
    cart B1 (at the benchmark's gamma) reproduces configs/two_oscillators.yaml, reference and DR."""
    raw = raw_config("star")
    raw["subsystems"] = {k: v for k, v in raw["subsystems"].items() if k in ("A", "B1")}
    raw["subsystems"]["B1"]["gamma"] = 0.4
    raw["couplings"] = [{"type": "zero_junction", "ports": ["A", "B1"]}]
    raw["outputs"] = {"q1": "A.q1", "q2": "B1.q2"}
    raw["error"] = ["q1", "q2"]
    star = scenario(raw, T=0.5)
    bench = dataclasses.replace(load_scenario(CONFIGS / "two_oscillators.yaml"), T=0.5)
    for sc_star, sc_bench in ((star.with_master(algorithm="newton"), bench.with_master(algorithm="newton")),
                              (star.with_master(algorithm="dr", K=5), bench.with_master(algorithm="dr", K=5))):
        a, b = run(sc_star, certificates=False), run(sc_bench, certificates=False)
        for col in ("q1", "q2"):
            assert np.abs(a.column(col) - b.column(col)).max() < 1e-13


def dirac_scene(tmp_path, E, F):
    """configs/rlc_motor.yaml with its gyrator written as a general Dirac structure E e + F f = 0."""
    raw = raw_config("rlc_motor")
    raw["couplings"] = [{"type": "dirac", "ports": ["C", "M"], "E": E, "F": F}]
    path = tmp_path / "dirac.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


def test_general_dirac_coupling_equals_the_named_gyrator(tmp_path):
    Km = raw_config("rlc_motor")["couplings"][0]["ratio"]
    dirac = dataclasses.replace(load_scenario(dirac_scene(tmp_path, [[1, 0], [0, 1]], [[0, -Km], [Km, 0]])), T=0.5)
    named = dataclasses.replace(load_scenario(CONFIGS / "rlc_motor.yaml"), T=0.5)
    a = run(dirac.with_master(algorithm="dr", K=4), certificates=False)
    b = run(named.with_master(algorithm="dr", K=4), certificates=False)
    assert a.columns == b.columns and np.array_equal(a.outputs, b.outputs)


@pytest.mark.parametrize("E, F, message", [
    ([[1, 0], [0, 1]], [[0.5, -0.1], [0.1, 0]], "not lossless"),  # a 0.5 Ohm resistor in the gyrator
    ([[1, 0], [2, 0]], [[0, -0.1], [0, -0.2]], "full rank"),      # the second row repeats the first
])
def test_a_lossy_or_rank_deficient_dirac_coupling_is_rejected(tmp_path, capsys, E, F, message):
    path = dirac_scene(tmp_path, E, F)
    with pytest.raises(CouplingError, match=message):
        run(load_scenario(path), certificates=False)
    with pytest.raises(SystemExit) as exit_info:
        main(["validate", str(path)])
    assert exit_info.value.code == 2
    err = capsys.readouterr().err.strip()
    assert message in err and "couplings[0]" in err and len(err.splitlines()) == 1


SCENE_FILES = ("chain", "star", "planar", "rlc_motor")


@pytest.mark.parametrize("name", SCENE_FILES)
def test_compare_runs_every_master_on_the_scene(name, tmp_path):
    sc = dataclasses.replace(load_scenario(CONFIGS / f"{name}.yaml"), T=0.2)
    compare(sc, tmp_path, Ks=[0, 2], certificates=False)
    rows = json.loads((tmp_path / "compare.json").read_text())["runs"]
    assert {r["master"] for r in rows} == set(BUDGETS)
    for r in rows:
        if r["master"] in ("dr", "newton"):
            assert r["finite"] == "yes" and r["diverged"] == "no", r
    assert next(r for r in rows if r["master"] == "newton")["max_error"] < 1e-12


@pytest.mark.parametrize("name", SCENE_FILES)
def test_cli_run_and_compare_on_the_scene(name, tmp_path, capsys):
    config = str(CONFIGS / f"{name}.yaml")
    for argv in (["run", config, "--T", "0.1", "--K", "5", "--quiet", "--out", str(tmp_path / "run")],
                 ["compare", config, "--T", "0.1", "--Ks", "0,2", "--masters", "explicit,dr", "--quiet",
                  "--no-certificates", "--out", str(tmp_path / "compare")]):
        with pytest.raises(SystemExit) as exit_info:
            main(argv)
        assert exit_info.value.code == 0, capsys.readouterr().err
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["status"] == "finished" and summary["steps"] == 10
    runs = json.loads((tmp_path / "compare" / "compare.json").read_text())["runs"]
    assert [(r["master"], r["K"]) for r in runs] == [("explicit", "-"), ("dr", 0), ("dr", 2)]
