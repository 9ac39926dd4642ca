"""The tolerance mode (master.tolerance, masters/adaptive.py): a varying macro-step chosen from an
error estimate, rejected steps redone from the saved states, the fine reference's true error."""
import json
import subprocess

import numpy as np
import pytest

import yaml

from paths import CLI, CONFIGS, THIRD_PARTY
from wavecosim import api
from wavecosim.errors import ConfigError
from wavecosim.run.fine import Extrapolated, fine_reference, true_error
from wavecosim.run.runner import LiveRun
from wavecosim.scenario.config import load_scenario, parse_scenario


def scenario(name, T, **master):
    return load_scenario(CONFIGS / f"{name}.yaml").with_changes("test", T=T).with_master(**master)


def drive(sc, forced=None):
    """Run sc step by step: (accepted step sizes, trajectory rows, rejected steps). forced: the step
    sizes to make, one by one, with no rejection."""
    live = LiveRun(sc, None, certificates=False)
    try:
        live.start()
        n, steps = 0, []
        while live.more(n):
            if forced is not None:
                c = live.master.control
                c.h = c.h_min = c.h_max = forced[n]
                live.master.can_reject = False
            live.step(n)
            steps.append(live.master.step_record.dt)
            n += 1
        return np.array(steps), live.trajectory.array().copy(), live.master.rejected
    finally:
        live.finish("finished", "")


@pytest.mark.parametrize("name, master, options, tol", [("foreign_pair", "gauss-seidel", "manual", 1e-2),
                                                        ("two_oscillators", "dr", "manual", 1e-3),
                                                        ("two_oscillators", "dr", "auto", 1e-3),
                                                        ("foreign_pair", "explicit", "manual", 1e-2)])
def test_a_rejected_step_leaves_every_fmu_where_it_was(name, master, options, tol):
    """The same accepted steps made again without a rejection give the same numbers to the last bit
    (DR's Anderson differences kept across steps included)."""
    sc = scenario(name, 0.1, algorithm=master, tolerance=tol, options=options)
    steps, rows, rejected = drive(sc)
    assert rejected > 0
    again, rows_again, none = drive(sc, forced=list(steps))
    assert none == 0 and np.array_equal(again, steps)
    assert np.array_equal(rows, rows_again)


def with_a_signal(T):
    """Table I's pair and a third oscillator C without a port, driven by a signal from A's q1."""
    raw = yaml.safe_load((CONFIGS / "two_oscillators.yaml").read_text())
    raw["subsystems"]["C"] = {"fmu": "LinearSide", "parameters": {"m2": 1.0, "k2": 40.0}}
    raw["signals"] = [{"from": "A.q1", "to": "C.F", "factor": 30.0}]
    raw["outputs"]["qC"] = "C.q2"
    return parse_scenario({**raw, "T": T}, str(CONFIGS / "two_oscillators.yaml"))


@pytest.mark.parametrize("estimate", ["predictor", "doubling"])
def test_a_rejected_step_puts_back_the_subsystems_without_a_port(estimate):
    """A signal-only subsystem steps with each try's h and is put back with the others: the same
    accepted steps made again without a rejection give the same numbers, C's included."""
    sc = with_a_signal(0.1).with_master(tolerance=1e-4, estimate=estimate)
    steps, rows, rejected = drive(sc)
    assert rejected > 0 and len(np.unique(steps)) > 3
    again, rows_again, none = drive(sc, forced=list(steps))
    assert none == 0 and np.array_equal(rows, rows_again)
    fine = api.simulate(sc.with_master(tolerance=None).with_changes("test", dt=1e-4), reference=False,
                        certificates=False).trajectory["qC"]
    assert abs(rows[-1, -1] - fine[-1]) < 1e-2 * np.ptp(fine)


def test_the_coupling_estimate_puts_each_fmu_back():
    """`estimate: coupling` makes each FMU again from the step's start with the other end of its held
    inputs and puts it back: the same steps made without it give the same numbers to the last bit."""
    sc = scenario("foreign_pair", 0.1, algorithm="gauss-seidel", tolerance=1e-3, estimate="coupling")
    steps, rows, _ = drive(sc)
    assert len(np.unique(steps)) > 3
    _, rows_again, _ = drive(sc.with_master(estimate="predictor"), forced=list(steps))
    assert np.array_equal(rows, rows_again)


def test_the_coupling_estimate_is_refused_for_a_master_that_iterates():
    with pytest.raises(ConfigError, match="coupling needs a master that holds its inputs over the step"):
        api.simulate(scenario("foreign_pair", 0.1, algorithm="dr", tolerance=1e-3, estimate="coupling"),
                     reference=False, certificates=False)


def from_rest(T, **master):
    """Table I's pair with both masses at their rest position, A moving: every watched value is zero at t0."""
    raw = yaml.safe_load((CONFIGS / "two_oscillators.yaml").read_text())
    raw["subsystems"]["A"]["start"] = {"q1": 0.0, "v1": 1.0, "d": 0.0}
    return parse_scenario({**raw, "T": T}, str(CONFIGS / "two_oscillators.yaml")).with_master(**master)


def test_a_run_from_rest_takes_its_sizes_from_pilot_steps_and_puts_everything_back():
    """With every watched value zero at t0 the pilot's steps give the sizes, and the FMUs are back at t0
    after them: the same steps made without the pilot give the same numbers to the last bit."""
    sc = from_rest(0.5, algorithm="gauss-seidel", tolerance=1e-2)
    result = api.simulate(sc, reference=False, certificates=False)
    assert result.summary["pilot"] is True
    steps, rows, _ = drive(sc)
    _, rows_again, _ = drive(sc, forced=list(steps))
    assert np.array_equal(rows, rows_again)


@pytest.mark.skipif(not (THIRD_PARTY / "dcmotor").exists(), reason="the third-party dcmotor FMUs are absent")
def test_the_coupling_estimate_follows_the_held_inputs_on_the_dcmotor():
    """The Dymola FMUs integrate to their tolerance inside each step: `auto` takes the coupling estimate,
    which lands the true error near the tolerance with fewer doSteps than the predictor, whose error is
    larger (it follows the current's own curvature, which the machine's solver resolves, and misses the
    torque's lag behind the held speed)."""
    sc = scenario("dcmotor", 0.02, algorithm="gauss-seidel", tolerance=1e-2)
    coupled = api.simulate(sc, reference=False, certificates=False)
    assert coupled.summary["estimate"] == "coupling" and coupled.summary["pilot"] is True
    reference = fine_reference(sc, coupled, dt=1e-4)
    err = true_error(coupled, reference)["true_error"]
    assert 1e-3 <= err <= 1e-2
    predicted = api.simulate(sc.with_master(estimate="predictor"), reference=False, certificates=False)
    assert predicted.summary["fmu_calls"]["doStep"] > 1.3 * coupled.summary["fmu_calls"]["doStep"]
    assert true_error(predicted, reference)["true_error"] > 1.5 * err


def test_the_fmus_are_set_up_below_the_tolerance_asked_for():
    """An FMU set up with a tolerance (A: 1e-4; B has none) is tightened to fmu_tolerance, `auto`:
    FMU_SHARE x the tolerance mode's, in the run and in its fine reference; a fixed step or
    fmu_tolerance null keeps the given one, a number caps it, and a bad value is one line."""
    raw = yaml.safe_load((CONFIGS / "foreign_pair.yaml").read_text())
    raw["subsystems"]["A"]["tolerance"] = 1e-4
    sc = parse_scenario({**raw, "T": 0.02}, str(CONFIGS / "foreign_pair.yaml")).with_master(
        algorithm="gauss-seidel", tolerance=1e-2)

    def set_up(s):
        return api.simulate(s, reference=False, certificates=False)

    tight = set_up(sc)
    assert tight.summary["fmu_tolerance"] == {"A": 1e-5}
    assert fine_reference(sc, tight, dt=1e-3).summary["fmu_tolerance"] == {"A": 1e-5}
    assert set_up(sc.with_master(fmu_tolerance=None)).summary["fmu_tolerance"] == {"A": 1e-4}
    assert set_up(sc.with_master(tolerance=None)).summary["fmu_tolerance"] == {"A": 1e-4}
    assert set_up(sc.with_master(tolerance=None, fmu_tolerance=1e-7)).summary["fmu_tolerance"] == {"A": 1e-7}
    with pytest.raises(ConfigError, match=r"master.fmu_tolerance: .*tight"):
        parse_scenario({**raw, "master": {"fmu_tolerance": "tight"}}, str(CONFIGS / "foreign_pair.yaml"))


@pytest.mark.slow
@pytest.mark.skipif(not (THIRD_PARTY / "dcmotor").exists(), reason="the third-party dcmotor FMUs are absent")
def test_the_dcmotor_fmus_set_up_below_the_tolerance_lift_its_floor():
    """The Dymola FMUs restart their solver at every doStep: set up at their given 1e-5 under a
    tolerance of 1e-3, their own error is most of the torque's true error; set up at 1e-6 (`auto`)
    it is not, with the same steps."""
    sc = scenario("dcmotor", 0.02, algorithm="gauss-seidel", tolerance=1e-3)
    tight = api.simulate(sc, reference=False, certificates=False)
    given = api.simulate(sc.with_master(fmu_tolerance=None), reference=False, certificates=False)
    assert set(tight.summary["fmu_tolerance"].values()) == {1e-6}
    assert set(given.summary["fmu_tolerance"].values()) == {1e-5}
    reference = fine_reference(sc, tight, dt=1e-5)
    assert true_error(tight, reference)["true_error_by_column"]["M"] < \
        0.6 * true_error(given, reference)["true_error_by_column"]["M"]


@pytest.mark.skipif(not (THIRD_PARTY / "dcmotor").exists(), reason="the third-party dcmotor FMUs are absent")
def test_the_dcmotor_runs_in_the_tolerance_mode():
    """The dcmotor's stimuli FMU (no port) and its signals follow the varying step; the ledger holds."""
    sc = scenario("dcmotor", 0.002, tolerance=1e-2, options="auto")
    result = api.simulate(sc, reference=False, certificates=False)
    s = result.summary
    assert s["status"] == "finished" and s["accepted_steps"] == len(result.steps["dt"])
    assert len(np.unique(result.steps["dt"])) > 3 and result.t[-1] == 0.002
    assert s["max_ledger"] <= s["ledger_tolerance"]
    assert result.trajectory["U"][-1] == 12.0


def test_a_system_of_signals_only_runs_in_the_tolerance_mode():
    """The foreign pair wired by signals (no power bond): the explicit master's steps vary, the
    outputs of subsystems without a port are watched, and the fine reference is the explicit master
    (no bond to solve) extrapolated: the true error lands near the tolerance."""
    raw = yaml.safe_load((CONFIGS / "foreign_pair.yaml").read_text())
    for sub in raw["subsystems"].values():
        del sub["port"]
    raw.update(T=0.2, couplings=[], master={"tolerance": 1e-3},
               signals=[{"from": "B.F", "to": "A.F"}, {"from": "A.v", "to": "B.v"}], outputs={"x": "A.x", "v": "A.v"})
    sc = parse_scenario(raw, str(CONFIGS / "foreign_pair.yaml"))
    result = api.simulate(sc, reference=False, certificates=False)
    s = result.summary
    assert s["master"] == "explicit" and s["status"] == "finished" and s["accepted_steps"] == len(result.steps["dt"])
    assert len(np.unique(result.steps["dt"])) > 3 and result.t[-1] == 0.2
    reference = fine_reference(sc, result)
    assert reference.summary["master"] == "explicit" and isinstance(reference, Extrapolated)
    assert 1e-4 <= true_error(result, reference)["true_error"] <= 1e-2
    raw["subsystems"]["A"]["tolerance"] = 1e-4            # no port input to vary: the predictor, not coupling
    solved = api.simulate(parse_scenario(raw, str(CONFIGS / "foreign_pair.yaml")), reference=False, certificates=False)
    assert solved.summary["estimate"] == "predictor" and solved.summary["status"] == "finished"
    from wavecosim.sweeps.tolerances import plan
    assert {run.master.algorithm for mode, run in plan(sc, (1e-2,), refine=(1, 4))} == {"explicit"}


def test_a_step_kept_over_its_allowance_is_counted_and_told(capfd):
    """At dt_min a step is kept whatever its estimate: summary.json counts such steps, and the first
    is told on stderr, so a run that could not hold its tolerance does not pass for one that did."""
    held = api.simulate(scenario("foreign_pair", 0.2, algorithm="gauss-seidel", tolerance=1e-4, dt_min=1e-3),
                        reference=False, certificates=False)
    assert held.summary["steps_over_tolerance"] > 0 and held.summary["status"] == "finished"
    assert "x its allowance (dt_min = 0.001 s); the error can exceed the tolerance" in capfd.readouterr().err
    free = api.simulate(scenario("foreign_pair", 0.2, algorithm="gauss-seidel", tolerance=1e-2), reference=False,
                        certificates=False)
    assert free.summary["steps_over_tolerance"] == 0


def test_steps_follow_the_tolerance_and_end_on_T():
    loose = api.simulate(scenario("foreign_pair", 0.2, algorithm="gauss-seidel", tolerance=1e-1), reference=False,
                         certificates=False)
    tight = api.simulate(scenario("foreign_pair", 0.2, algorithm="gauss-seidel", tolerance=1e-3), reference=False,
                         certificates=False)
    assert tight.summary["accepted_steps"] > 3 * loose.summary["accepted_steps"]
    for r in (loose, tight):
        assert r.t[-1] == 0.2 and np.all(np.diff(r.t) > 0)
        dt = r.steps["dt"]
        assert np.allclose(np.diff(r.t), dt, rtol=1e-12, atol=0)
        assert len(np.unique(dt)) > 3
        assert r.summary["accepted_steps"] == len(dt)


def test_steps_end_on_the_output_times():
    sc = scenario("foreign_pair", 0.1, algorithm="gauss-seidel", tolerance=1e-1, dt_max=0.05, output_step=0.02)
    t = api.simulate(sc, reference=False, certificates=False).t
    assert all(k * 0.02 in t for k in range(6))
    free = api.simulate(sc.with_master(output_step=None), reference=False, certificates=False).t
    assert not all(k * 0.02 in free for k in range(6))


def test_true_error_is_near_the_tolerance_and_the_ledger_holds():
    sc = scenario("two_oscillators", 1.0, algorithm="dr", tolerance=1e-3)
    result = api.simulate(sc, reference=False, certificates=False)
    reference = fine_reference(sc, result, dt=1e-4)
    err = true_error(result, reference)["true_error"]
    assert 1e-4 <= err <= 1e-2
    assert result.summary["max_ledger"] <= 1e-9
    fixed = true_error(api.simulate(sc.with_master(tolerance=None), reference=False, certificates=False),
                       reference)["true_error"]
    assert fixed > 10 * err                     # dt = 0.01 alone is far from the tolerance


def test_the_fine_reference_is_second_order_where_the_monolithic_step_is_first():
    """Over physical ports (the wave adapter holds the inputs) the monolithic step is first order: the
    reference is its Richardson extrapolation with a run at half the step. Over own wave ports it is
    second order and runs once."""
    sc = load_scenario(CONFIGS / "foreign_pair.yaml").with_changes("test", T=0.2)
    coarse, finer = (fine_reference(sc, None, dt=0.2 / n) for n in (1000, 4000))
    plain = api.simulate(sc.with_master(algorithm="newton").with_changes("test", dt=0.2 / 1000), reference=False,
                         certificates=False)
    assert plain.summary["error_order"] == 1
    assert true_error(plain, finer)["true_error"] > 1e-3
    assert true_error(coarse, finer)["true_error"] < 1e-2 * true_error(plain, finer)["true_error"]
    wave = fine_reference(scenario("two_oscillators", 0.2), None, dt=1e-3)
    assert wave.summary["error_order"] == 2 and not isinstance(wave, Extrapolated)
    only_c = api.simulate(with_a_signal(0.05).with_master(algorithm="newton"), reference=False, certificates=False)
    assert only_c.summary["error_order"] == 2            # the signal drives C alone, no port's input


def test_dr_starts_from_the_waves_extrapolated_over_the_varying_step():
    """start: auto is the extrapolated start in the tolerance mode: fewer inner iterations than the
    previous step's waves, the same steps and about the same true error."""
    sc = scenario("two_oscillators", 0.5, tolerance=1e-3)
    auto, previous = (api.simulate(sc.with_master(start=start), reference=False, certificates=False)
                      for start in ("auto", "previous"))
    assert auto.summary["start"] == "extrapolated"
    assert auto.summary["accepted_steps"] == previous.summary["accepted_steps"]
    assert auto.steps["iterations"].sum() < 0.7 * previous.steps["iterations"].sum()
    assert np.allclose(auto.trajectory["q1"], previous.trajectory["q1"], atol=1e-3 * 0.4)


def test_doubling_estimates_by_two_half_steps():
    sc = scenario("foreign_pair", 0.3, algorithm="gauss-seidel", tolerance=1e-3)
    one = api.simulate(sc, reference=False, certificates=False).summary
    two = api.simulate(sc.with_master(estimate="doubling"), reference=False, certificates=False).summary
    per_step = two["fmu_calls"]["doStep"] / (two["accepted_steps"] + two["rejected_steps"])
    assert per_step == pytest.approx(3 * 2, rel=0.01)           # one step of h and two of h/2, two FMUs
    assert one["fmu_calls"]["doStep"] / (one["accepted_steps"] + one["rejected_steps"]) == 2


def test_an_fmu_that_keeps_its_step_is_refused(tmp_path):
    raw = (CONFIGS / "foreign_pair.yaml").read_text().replace("fmu: ForeignMass", "fmu: FixedStepMass")
    (tmp_path / "s.yaml").write_text(raw)
    sc = load_scenario(tmp_path / "s.yaml").with_master(algorithm="explicit", tolerance=1e-3)
    with pytest.raises(ConfigError, match="subsystem A's FMU cannot change its communication step size"):
        api.simulate(sc, reference=False, certificates=False)
    api.simulate(sc.with_master(tolerance=None).with_changes("test", T=0.01), reference=False, certificates=False)


def test_the_command_line_writes_the_variable_grid_and_true_error(tmp_path):
    out = tmp_path / "out"
    done = subprocess.run([*CLI, "run", str(CONFIGS / "foreign_pair.yaml"), "--T", "0.1", "--master", "gauss-seidel",
                           "--tolerance", "1e-3", "--reference", "fine", "--no-certificates", "--out", str(out)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    assert done.stderr.count("run: 0.1 s simulated in ") == 1, done.stderr        # once, at the end
    s = json.loads((out / "summary.json").read_text())
    assert s["accepted_steps"] > 0 and s["rejected_steps"] >= 0 and 0 < s["true_error"] < 1e-1
    header = (out / "steps.csv").read_text().splitlines()[0].split(",")
    assert {"dt", "error_estimate", "rejected", "inner_eps"} <= set(header)
    bad = subprocess.run([*CLI, "run", str(CONFIGS / "foreign_pair.yaml"), "--T", "0.2", "--tolerance", "-1",
                          "--out", str(tmp_path / "bad")], capture_output=True, text=True)
    assert bad.returncode == 2
    capped = subprocess.run([*CLI, "run", str(CONFIGS / "foreign_pair.yaml"), "--T", "0.01", "--tolerance", "1e-2",
                             "--fmu-tolerance", "1e-7", "--set", "subsystems.A.tolerance=1e-4", "--no-certificates",
                             "--quiet", "--out", str(tmp_path / "capped")], capture_output=True, text=True)
    assert capped.returncode == 0, capped.stderr
    assert json.loads((tmp_path / "capped" / "summary.json").read_text())["fmu_tolerance"] == {"A": 1e-7}
    bad = subprocess.run([*CLI, "run", str(CONFIGS / "foreign_pair.yaml"), "--T", "0.01", "--fmu-tolerance", "tight",
                          "--out", str(tmp_path / "bad")], capture_output=True, text=True)
    assert bad.returncode == 2 and "master.fmu_tolerance: must be auto, null or a number > 0" in bad.stderr


def test_equal_error_calls_follow_each_fixed_series():
    from wavecosim.sweeps.tolerances import best_fixed, calls_for
    series = [(100, 1e-2), (400, 2.5e-3), (1600, 6.25e-4)]          # first order: error ~ 1 / calls
    assert calls_for(series, 2e-2) == (100.0, False)
    assert calls_for(series, 5e-3) == (pytest.approx(200.0), False)
    assert calls_for(series, 6.25e-5) == (pytest.approx(16000.0), True)
    unstable = [(1600, 6.4e4), (6400, 4.77)]                         # far from converged: extrapolated at order 2
    assert calls_for(unstable, 4.77e-2) == (pytest.approx(64000.0), True)
    rows = [{"mode": "fixed", "master": m, "K": "", "doStep": c * f, "true_error": e}
            for m, f in (("explicit", 1), ("newton", 3)) for c, e in series]
    assert best_fixed(rows, 5e-3)[0::2] == (pytest.approx(200.0), "explicit")



def test_the_fixed_grid_sets_its_fmus_up_as_the_tightest_tolerance_run():
    """No fixed run is held back by its FMUs' own error where the tolerance mode's are not."""
    from wavecosim.masters.adaptive import FMU_SHARE
    from wavecosim.sweeps.tolerances import plan
    runs = plan(scenario("foreign_pair", 0.1), (1e-2, 1e-4), refine=(1,))
    assert {sc.master.fmu_tolerance for mode, sc in runs if mode == "fixed"} == {FMU_SHARE * 1e-4}
    assert {sc.master.fmu_tolerance for mode, sc in runs if mode != "fixed"} == {"auto"}

@pytest.mark.slow
def test_compare_tolerances_writes_the_table_and_the_figure(tmp_path):
    out = tmp_path / "cmp"
    done = subprocess.run([*CLI, "compare", str(CONFIGS / "foreign_pair.yaml"), "--T", "0.05", "--tolerances",
                           "1e-2", "--masters", "gauss-seidel", "--quiet", "--out", str(out)],
                          capture_output=True, text=True)
    assert done.returncode == 0, done.stderr
    rows = json.loads((out / "tolerances.json").read_text())
    assert {r["mode"] for r in rows} == {"tolerance", "doubling", "fixed"}
    assert all(0 < r["true_error"] < 1 for r in rows)
    assert (out / "tolerances.png").stat().st_size > 0 and (out / "tolerances.csv").exists()


def test_the_rows_give_each_runs_ledger_and_its_tolerance():
    """Each row of compare --tolerances gives the run's max_ledger beside its own ledger_tolerance
    (the figures the docs' ledger block reads); dr's stay within it."""
    from wavecosim.sweeps.tolerances import measure, plan
    sc = scenario("two_oscillators", 0.2)
    reference = fine_reference(sc, None, dt=sc.dt / 10)
    rows = [measure(mode, run, reference) for mode, run in plan(sc, [1e-2], masters=["dr"], refine=())]
    assert [r["mode"] for r in rows] == ["tolerance", "doubling"]
    assert all(0 < r["ledger_tolerance"] and r["max_ledger"] <= r["ledger_tolerance"] for r in rows)


def test_the_api_takes_a_tolerance_as_the_file_does(capsys):
    """simulate(tolerance=...) is master.tolerance: the same steps, to the bit, as the key set in the
    scenario; with reference="fine" the summary gives the true error; its progress is the share of
    the time span, each tenth once; a tolerance <= 0 is one line."""
    given = api.simulate("two_oscillators", T=0.2, tolerance=1e-3, reference="fine", certificates=False,
                         progress=True)
    shown = capsys.readouterr().err.splitlines()
    assert [line for line in shown if "%" in line] == [f"  {p} % of the time span" for p in range(10, 101, 10)]
    keyed = api.simulate(api.load("two_oscillators", T=0.2, changes={"master.tolerance": 1e-3}), reference=False,
                         certificates=False)
    assert given.summary["tolerance"] == 1e-3 and given.summary["accepted_steps"] == keyed.summary["accepted_steps"]
    assert given.trajectory.tobytes() == keyed.trajectory.tobytes()
    assert 1e-4 < given.summary["true_error"] < 1e-2
    with pytest.raises(ConfigError, match="tolerance: must be > 0"):
        api.load("two_oscillators", tolerance=0)
