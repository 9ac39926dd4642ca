"""The DR master's named options (master.relaxation, master.anderson, master.start, gamma: fastest).

Claims: each option gives the same numbers to the last bit in the C kernel and in the Python
reference, over whole runs (blocks of macro-steps included) on Table I and the stiff scene; relaxed
DR keeps the inner iterates Fejer monotone (eq. 28) for lambda in (0, 2); the Anderson safeguard
takes the plain step when an accelerated iterate does not cut the residual; the warm start starts
from P (2 b^n - b^{n-1}); relaxation: auto and gamma: fastest pick what the linearized operator
predicts is faster, within the FNE bounds; the Anderson memory keeps its differences across
macro-steps and the extrapolated b^* is exact on an affine map one query earlier (both bit-identical
in the kernel); bad values are one-line config errors.
"""
import dataclasses

import numpy as np
import pytest

from paths import ROOT
from wavecosim import simulate
from wavecosim.scenario.config import load_raw, load_scenario, parse_scenario
from wavecosim.errors import ConfigError
from wavecosim.core.gamma import FASTEST_SAFETY, choose_gamma, probe_scene
from wavecosim.kernel.linalg import matvec
from wavecosim.masters.dr import DRMaster, algorithm1
from wavecosim.masters.dr_options import ANDERSON_SAFEGUARD, Anderson
from wavecosim.masters.monolithic import solve_interface
from wavecosim.scenario.overrides import apply_overrides, parse_set
from wavecosim.run.runner import run
from wavecosim.core.scene import build_scene

from test_dr import frozen_benchmark  # noqa: F401  (Table I frozen after 40 steps)

STIFF = ROOT / "configs" / "two_oscillators_stiff.yaml"
OPTIONS = [dict(relaxation=1.5), dict(relaxation=0.6), dict(anderson=3), dict(anderson=1),
           dict(start="extrapolated"), dict(relaxation=1.3, anderson=2, start="extrapolated"), dict(start="previous"),
           dict(start="paper")]


@pytest.fixture(scope="module")
def table_i(built_fmus):
    return dataclasses.replace(load_scenario(), T=2.0)


@pytest.fixture(scope="module")
def stiff(built_fmus):
    return dataclasses.replace(load_scenario(STIFF), T=2.0)


def same_run(scenario, **master):
    ref = run(scenario.with_master(fast="false", **master), certificates=False)
    fast = run(scenario.with_master(fast="true", **master), certificates=False)
    assert ref.status == fast.status == "finished"
    assert ref.outputs.tobytes() == fast.outputs.tobytes(), "trajectories differ"
    for key in ref.steps.dtype.names:
        assert ref.steps[key].tobytes() == fast.steps[key].tobytes(), f"per-step {key} differs"
    assert ref.summary["fmu_calls"] == fast.summary["fmu_calls"]
    assert fast.summary["fast_path"] and not ref.summary["fast_path"]
    return ref


@pytest.mark.parametrize("options", OPTIONS, ids=lambda o: ",".join(f"{k}={v}" for k, v in o.items()))
def test_kernel_bit_identical_to_reference_table_i(table_i, options):
    ref = same_run(table_i, K=8, **options)
    assert ref.summary["relaxation"] == options.get("relaxation", 1.0)


@pytest.mark.parametrize("options", [dict(anderson=4), dict(relaxation=1.8, start="extrapolated")])
def test_kernel_bit_identical_to_reference_stiff(stiff, options):
    same_run(stiff.with_changes(gamma="auto"), K=12, **options)


def test_tolerance_exit_with_anderson_bit_identical(table_i):
    ref = same_run(table_i, K=40, eps=1e-11, anderson=3)
    assert max(ref.steps["iterations"]) < 40


def test_options_change_the_numbers(table_i):
    """Each option really acts (the bit-identity above would also hold for a no-op)."""
    plain = run(table_i.with_master(K=8, start="paper"), certificates=False).outputs
    for options in OPTIONS:
        if options != dict(start="paper"):
            changed = run(table_i.with_master(K=8, **{"start": "paper", **options}), certificates=False).outputs
            assert not np.array_equal(changed, plain), options


def test_anderson_reaches_roundoff_with_a_small_budget(table_i):
    plain = simulate(table_i.with_master(K=10), certificates=False).summary["max_error"]
    fast = simulate(table_i.with_master(K=10, anderson=3), certificates=False).summary["max_error"]
    assert plain > 1e-4 and fast < 1e-12


@pytest.mark.parametrize("lam", [0.5, 1.5, 1.9])
def test_relaxed_iterates_are_fejer_monotone(frozen_benchmark, lam):
    """eq. (28) for the relaxed operator: |u^{k+1} - u*|^2 <= |u^k - u*|^2 - (2 - lam)/lam |u^{k+1} - u^k|^2."""
    scene, master = frozen_benchmark
    u_dag = np.array(master.P) @ solve_interface(scene, master.P, master.b)[0]
    iterates = []

    def recording_S(u):
        iterates.append(np.array(u))
        return scene.S(u)
    log = algorithm1(recording_S, master.P, master.J_L, master.b, K=60, lam=lam)
    iterates.append(np.array(log.uK))
    dist = [float(np.sum((u - u_dag) ** 2)) for u in iterates]
    for k in range(len(iterates) - 1):
        step = float(np.sum((iterates[k + 1] - iterates[k]) ** 2))
        assert dist[k + 1] <= dist[k] - (2.0 - lam) / lam * step + 1e-12 * (1 + dist[0])
    assert dist[-1] < 1e-6 * dist[0]


def test_anderson_safeguard_takes_the_plain_step():
    """An accelerated iterate whose residual does not fall by ANDERSON_SAFEGUARD is replaced by the
    plain step from the last accepted iterate; b^* is the response of the smaller residual."""
    acc = Anderson(2)
    f1, b1 = acc.next([0.0, 0.0], [1.0, 1.0], ["b1"])             # first iterate: the plain step
    assert f1 == [1.0, 1.0] and b1 == ["b1"] and not acc.candidate
    x2, b2 = acc.next([1.0, 1.0], [1.5, 1.25], ["b2"])             # accepted; an accelerated iterate follows
    assert acc.candidate and b2 == ["b2"] and x2 != [1.5, 1.25]
    g_acc = np.hypot(0.5, 0.25)
    x3, b3 = acc.next(x2, [x2[0] + g_acc, x2[1]], ["b3"])          # residual |g_acc|: not cut enough
    assert ANDERSON_SAFEGUARD < 1.0 and x3 == [1.5, 1.25] and b3 == ["b2"] and not acc.candidate and not acc.dG
    acc.next([1.5, 1.25], [1.75, 1.375], ["b4"])                   # plain, accepted; accelerated next
    g_acc = np.hypot(0.25, 0.125)
    x5 = acc.next([9.0, 9.0], [9.0 + 0.95 * g_acc, 9.0], ["b5"])   # not cut by 0.9, but smaller: its b^*
    assert x5 == ([1.75, 1.375], ["b5"]) and not acc.candidate


def test_anderson_on_a_linear_map_converges_at_once():
    """On an affine map of n channels Anderson with window n finds the fixed point in n + 1 steps."""
    rho, c = [0.6, 0.3], [1.0, -2.0]
    S = (lambda u: [r * x + ci for r, x, ci in zip(rho, u, c)])
    swap = [[0.0, 1.0], [1.0, 0.0]]
    J = np.linalg.inv(2 * np.eye(2) - np.array(swap)).tolist()
    b_star = np.linalg.solve(np.array([[1.0, -rho[0]], [-rho[1], 1.0]]), c)
    plain = algorithm1(S, swap, J, [0.0, 0.0], K=5)
    fast = algorithm1(S, swap, J, [0.0, 0.0], K=5, anderson=Anderson(2))
    exact = np.array(swap) @ b_star
    assert np.abs(np.array(fast.a_hat) - exact).max() < 1e-12 < np.abs(np.array(plain.a_hat) - exact).max()


def test_extrapolated_start_extrapolates_the_committed_wave(table_i):
    sc = table_i.with_master(K=3, start="extrapolated", fast="false", energy_guard="off")
    scene = build_scene(sc)
    try:
        master = DRMaster(scene, sc.master)
        b0 = master.b
        log0 = master.step(0, 0.0)
        assert log0.u0 == matvec(master.P, b0)                       # no b^{n-1} yet: the paper's P b^n
        b1 = master.b
        log1 = master.step(1, sc.dt)
        assert log1.u0 == matvec(master.P, [2.0 * x - y for x, y in zip(b1, b0)])
    finally:
        scene.close()


def test_previous_start_is_the_incident_wave_committed_the_step_before(table_i):
    """master.start: previous: u^{n,0} = a^{n-1} (the first step: the paper's P b^n); auto is previous
    under the ledger and the paper's start under the other guards."""
    sc = table_i.with_master(K=3, start="previous", fast="false", energy_guard="off")
    scene = build_scene(sc)
    try:
        master = DRMaster(scene, sc.master)
        log0 = master.step(0, 0.0)
        assert log0.u0 == matvec(master.P, [0.0] * scene.n_channels)
        log1 = master.step(1, sc.dt)
        assert log1.u0 == log0.a_hat and log1.u0 != matvec(master.P, master._committed_outputs)
    finally:
        scene.close()
    for guard, start in (("ledger", "previous"), ("off", "paper"), ("monolithic", "paper")):
        summary = run(table_i.with_master(K=1, energy_guard=guard), certificates=False, reference=None).summary
        assert summary["start"] == start, guard


def test_options_auto_chooses_from_the_scene_and_the_kernel_is_the_reference(table_i):
    """options: auto: gamma from the probe, lambda from the linearized operator, an Anderson window of one
    difference per channel with memory and extrapolation, reported; kernel and reference bit for bit."""
    ref = same_run(table_i, K=4, options="auto")
    s = ref.summary
    assert s["options"] == "auto" and s["gamma_mode"] == "auto" and s["gamma_guaranteed"]
    assert s["anderson"] == 2 and s["anderson_memory"] and s["anderson_extrapolate"]
    assert 0.0 < s["relaxation"] < 2.0 and "relaxation_rates" in s
    manual = run(table_i.with_master(K=4), certificates=False).summary
    assert manual["options"] == "manual" and manual["anderson"] == 0 and manual["gamma_mode"] == "fixed"
    from wavecosim.masters.dr_options import ANDERSON_MAX, auto_settings
    auto = dataclasses.replace(table_i.master, options="auto")
    assert [auto_settings(auto, n).anderson for n in (1, 5, 16, 40)] == [1, 5, 16, ANDERSON_MAX]


def test_relaxation_auto_picks_a_faster_lambda(table_i):
    r = run(table_i.with_master(K=8, relaxation="auto"), certificates=False)
    lam, rates = r.summary["relaxation"], r.summary["relaxation_rates"]
    assert 0.0 < lam < 2.0 and lam != 1.0
    assert rates["rate_relaxed"] < rates["rate_plain"] < 1.0


def test_gamma_fastest_within_the_fne_bounds_and_faster_than_auto(stiff):
    scene = build_scene(stiff.with_changes(gamma="auto"))
    try:
        probes = probe_scene(scene, [0.0] * scene.n_channels, 0, 0.0)
        auto = choose_gamma(scene, probes, "auto")
        fastest = choose_gamma(scene, probes, "fastest")
    finally:
        scene.close()
    assert fastest.guaranteed
    assert all(g <= FASTEST_SAFETY * fastest.bounds[k] * (1 + 1e-12) for k, g in fastest.gammas.items())
    assert fastest.rate <= auto.rate


def test_dr_options_from_yaml_and_set(table_i):
    raw = load_raw(ROOT / "configs" / "two_oscillators.yaml")
    for option in ("master.relaxation=auto", "master.anderson=3", "master.start=previous"):
        key, values = parse_set(option)
        sc = parse_scenario(apply_overrides(raw, [(key, values[0])]))
        assert getattr(sc.master, key.split(".")[1]) == values[0]
    old = parse_scenario(apply_overrides(raw, [("master.warm_start", True)]))      # old files
    assert old.master.start == "extrapolated"
    for key, value, says in (("relaxation", 2.0, "(0, 2)"), ("relaxation", "fast", "number"),
                             ("anderson", 17, "at most 16"), ("anderson", -1, ">= 0"), ("warm_start", 1, "true or false"),
                             ("start", "warm", "one of auto, paper, extrapolated, previous")):
        with pytest.raises(ConfigError, match=f"master.{key}.*{says}" if says[0] != "(" else f"master.{key}"):
            parse_scenario(apply_overrides(raw, [(f"master.{key}", value)]))


def test_compare_with_dr_options_finds_the_cheapest_budget(table_i, tmp_path):
    from wavecosim.sweeps.comparison import cheapest, compare
    from wavecosim.plots import compare_plots
    sc = dataclasses.replace(table_i, T=0.5)
    reference, results, rows = compare(sc, tmp_path, masters=["gauss-seidel-iter", "dr"], Ks=[2, 5],
                                       certificates=False, options=["anderson", "fastest-relaxed"])
    assert [(r["master"], r["option"], r["K"]) for r in rows] == [
        ("gauss-seidel-iter", "", 2), ("gauss-seidel-iter", "", 5), ("dr", "", 2), ("dr", "", 5),
        ("dr", "anderson", 2), ("dr", "anderson", 5), ("dr", "fastest-relaxed", 2), ("dr", "fastest-relaxed", 5)]
    assert all(r["doSteps_per_step"] == r["doStep"] / r["steps"] for r in rows)
    best = cheapest(rows, (1e-6,))["1e-06"]
    for name, entry in best.items():
        reached = [r for r in rows if (r["master"] + (":" + r["option"] if r["option"] else "")) == name
                   and r["max_error"] <= 1e-6 and r["energy_safe"] == "yes"]
        assert entry["doSteps_per_step"] == min(r["doSteps_per_step"] for r in reached)
    assert "dr:anderson" in best and "dr" not in best          # plain DR at K = 5 stays above 1e-6
    paths = compare_plots(rows, results, reference, tmp_path)
    assert all(p.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" for p in paths)


def test_options_through_the_cli(tmp_path, capsys, built_fmus):
    """`sweep --set master.anderson=...` varies an option; `compare --options` refuses an unknown name in one line."""
    import csv

    from wavecosim.cli import main
    config = str(ROOT / "configs" / "two_oscillators.yaml")
    with pytest.raises(SystemExit) as exc:
        main(["sweep", config, "--out", str(tmp_path / "s"), "--K", "4", "--T", "0.5", "--workers", "1",
              "--set", "master.anderson=0,2", "--quiet"])
    assert exc.value.code == 0, capsys.readouterr().err
    with open(tmp_path / "s" / "runs.csv") as fh:
        rows = list(csv.DictReader(fh))
    assert [r["master.anderson"] for r in rows] == ["0", "2"]
    assert float(rows[1]["max_error"]) < 1e-3 * float(rows[0]["max_error"])
    capsys.readouterr()
    with pytest.raises(SystemExit) as exc:
        main(["compare", config, "--out", str(tmp_path / "c"), "--options", "relaxed,nope", "--quiet"])
    err = capsys.readouterr().err.strip()
    assert exc.value.code == 2 and "nope" in err and len(err.splitlines()) == 1


MODES = [dict(anderson=2, anderson_memory=True), dict(anderson=2, anderson_extrapolate=True),
         dict(anderson=3, relaxation=1.7, anderson_memory=True, anderson_extrapolate=True)]


@pytest.mark.parametrize("options", MODES, ids=lambda o: ",".join(f"{k}={v}" for k, v in o.items()))
def test_anderson_modes_bit_identical_to_reference(table_i, stiff, options):
    """The Anderson memory and the extrapolated b^* in the kernel and the reference, both scenes,
    the second with a tolerance exit; and each mode changes the numbers of plain Anderson."""
    ref = same_run(table_i, K=3, **options)
    same_run(stiff.with_changes(gamma="auto"), K=6, eps=1e-9, **options)
    plain = run(table_i.with_master(K=3, anderson=options["anderson"], relaxation=options.get("relaxation", 1.0)),
                certificates=False)
    assert not np.array_equal(ref.outputs, plain.outputs)
    assert ref.summary["anderson_memory"] == options.get("anderson_memory", False)


def test_extrapolated_b_star_is_exact_on_a_linear_map_one_query_earlier():
    """On an affine map of 2 channels: the Anderson combination of the responses gives the exact b^*
    after 3 queries, where the last response (plain Anderson) needs 4."""
    rho, c = [0.6, 0.3], [1.0, -2.0]
    S = (lambda u: [r * x + ci for r, x, ci in zip(rho, u, c)])
    swap = [[0.0, 1.0], [1.0, 0.0]]
    J = np.linalg.inv(2 * np.eye(2) - np.array(swap)).tolist()
    exact = np.array(swap) @ np.linalg.solve(np.array([[1.0, -rho[0]], [-rho[1], 1.0]]), c)
    err = {x: np.abs(np.array(algorithm1(S, swap, J, [0.0, 0.0], K=3, anderson=Anderson(2, extrapolate=x)).a_hat)
                     - exact).max() for x in (False, True)}
    assert err[True] < 1e-10 < 1e-4 < err[False]     # roundoff of the regularized least squares


def test_anderson_memory_keeps_the_differences_across_steps():
    """With memory a new macro-step keeps dF, dG, dB (and accelerates its first query); without, forgets them."""
    for memory in (False, True):
        acc = Anderson(2, memory=memory)
        acc.next([0.0, 0.0], [1.0, 1.0], [0.0, 0.0])
        acc.next([1.0, 1.0], [1.5, 1.25], [1.0, 0.0])
        acc.reset()
        assert (len(acc.dG), acc.g_acc) == ((1, None) if memory else (0, None))
        first, _ = acc.next([0.0, 0.0], [1.0, 1.0], [0.0, 0.0])
        assert (first != [1.0, 1.0]) == memory


def test_anderson_modes_need_a_window():
    raw = load_raw(ROOT / "configs" / "two_oscillators.yaml")
    for key in ("anderson_memory", "anderson_extrapolate"):
        with pytest.raises(ConfigError, match=f"master.{key}.*Anderson window"):
            parse_scenario(apply_overrides(raw, [(f"master.{key}", True)]))
