"""Multi-rate (subsystems.X.substeps): a subsystem makes N doSteps of dt / N per macro-step, its
coupling inputs held, on every master; its FMU calls, its energy and the refusals."""
import json
import subprocess

import numpy as np
import pytest
from fmpy import extract, read_model_description
from fmpy.fmi2 import FMU2Slave

from paths import CLI, CONFIGS
from wavecosim import api
from wavecosim.core.gamma import rescatter
from wavecosim.core.scene import build_scene
from wavecosim.fmi.builtin import builtin_fmus
from wavecosim.masters import MASTERS
from wavecosim.scenario.config import load_scenario, parse_scenario

FAST = {"subsystems.A.parameters.k1": 20000.0}          # mass 1 on a stiff spring: A is the fast side


def scene(name, T, changes=None, **master):
    return api.load(CONFIGS / f"{name}.yaml", T=T, changes=changes).with_master(**master)


def alone(name, parameters, inputs, dt, n):
    """The FMU `name` alone under fmpy, one RK4 step per doStep: per macro-step its input F set from `inputs`, n doSteps of dt / n,
    then its output v read; the outputs, one per macro-step."""
    path = builtin_fmus()[name]
    md = read_model_description(path)
    vr = {v.name: v.valueReference for v in md.modelVariables}
    fmu = FMU2Slave(guid=md.guid, unzipDirectory=extract(path), modelIdentifier=md.coSimulation.modelIdentifier,
                    instanceName="alone")
    fmu.instantiate()
    try:
        fmu.setupExperiment(startTime=0.0)
        fmu.setReal([vr[k] for k in parameters], list(parameters.values()))
        fmu.setInteger([vr["substeps"]], [1])                # one RK4 step per doStep
        fmu.enterInitializationMode()
        fmu.exitInitializationMode()
        out, h = [], dt / n
        for step, u in enumerate(inputs):
            t = 0.0 + step * dt
            fmu.setReal([vr["F"]], [u])
            for k in range(n):
                fmu.doStep(t + k * h, h)
            out.append(fmu.getReal([vr["v"]])[0])
        return np.array(out)
    finally:
        fmu.terminate()
        fmu.freeInstance()


def test_substeps_are_the_fmu_stepped_n_times_finer_with_its_input_held(tmp_path):
    raw = (CONFIGS / "foreign_pair.yaml").read_text().replace("    start: {v: 0.0}\n",
                                                               "    start: {v: 0.0}\n    substeps: 4\n")
    raw = raw.replace("parameters: {m: 1.0, c: 0.0}", "parameters: {m: 1.0, c: 200.0}\n    integers: {substeps: 1}")
    (tmp_path / "s.yaml").write_text(raw.replace("  F: B.F\n", "  F: B.F\n  u: A.F\n"))
    sc = load_scenario(tmp_path / "s.yaml").with_changes("test", T=0.05).with_master(algorithm="explicit")
    r = api.simulate(sc, reference=False, certificates=False)
    held = r.column("u")[1:]                      # the input A held over each macro-step
    assert np.ptp(held) > 0
    v = alone("ForeignMass", {"m": 1.0, "c": 200.0}, held, sc.dt, 4)
    assert np.array_equal(r.column("v")[1:], v)
    assert not np.allclose(alone("ForeignMass", {"m": 1.0, "c": 200.0}, held, sc.dt, 1), v, rtol=1e-9, atol=0)


@pytest.mark.parametrize("master", MASTERS)
def test_every_master_counts_n_do_steps_per_macro_step(master):
    runs = [api.simulate(scene("two_oscillators", 0.05, {**FAST, "subsystems.A.substeps": n}, algorithm=master, K=3),
                         reference=False, certificates=False).summary for n in (1, 4)]
    one, four = (s["fmu_calls_by_subsystem"] for s in runs)
    assert four["A"]["doStep"] == 4 * four["B"]["doStep"] and one["A"]["doStep"] == one["B"]["doStep"]
    if master in ("explicit", "gauss-seidel"):
        assert four["A"]["doStep"] == 4 * one["A"]["doStep"] == 4 * 5
    assert runs[1]["fast_path"] == runs[0]["fast_path"]          # substeps keep the route the master has


def test_dr_with_substeps_keeps_the_ledger_and_gains_no_energy():
    changes = {**FAST, "subsystems.A.substeps": 4}
    for K in (3, 50):
        s = api.simulate(scene("two_oscillators", 1.0, changes, K=K), reference=False).summary
        assert s["max_ledger"] <= s["ledger_tolerance"]
        assert s["max_passivity_pos"] <= 1e-12 * 1656          # Condition 2 of the macro-step to roundoff of H
        assert s["H_growth"] <= 1.0 + 1e-12
        assert s["fmu_calls_by_subsystem"]["A"]["doStep"] == 4 * s["fmu_calls_by_subsystem"]["B"]["doStep"]


def test_substeps_bring_the_fast_side_closer_to_the_true_solution():
    errors = [api.simulate(scene("two_oscillators", 1.0, {**FAST, "subsystems.A.substeps": n}, K=50),
                           reference="fine", certificates=False).summary["true_error"] for n in (1, 4)]
    assert errors[1] < 0.5 * errors[0]


def run_cli(tmp_path, *sets, config="two_oscillators.yaml"):
    return subprocess.run([*CLI, "run", str(CONFIGS / config), "--T", "0.02", "--quiet", "--no-certificates",
                           "--no-reference", "--out", str(tmp_path / "out"),
                           *[a for s in sets for a in ("--set", s)]], capture_output=True, text=True)


@pytest.mark.parametrize("value", ["0", "1.5", "two"])
def test_a_bad_substeps_is_refused_in_one_line(tmp_path, value):
    done = run_cli(tmp_path, f"subsystems.A.substeps={value}")
    assert done.returncode == 2
    assert "subsystems.A.substeps" in done.stderr and len(done.stderr.strip().splitlines()) == 1


def test_an_fmu_that_keeps_its_step_takes_substeps_only_at_that_step(tmp_path):
    raw = (CONFIGS / "foreign_pair.yaml").read_text().replace("fmu: ForeignMass", "fmu: FixedStepMass")
    (tmp_path / "fixed.yaml").write_text(raw)
    config = str(tmp_path / "fixed.yaml")
    done = run_cli(tmp_path, "subsystems.A.substeps=2", "master.algorithm=explicit", config=config)
    assert done.returncode == 2, done.stderr
    assert "subsystems.A.substeps: 2 makes doSteps of 0.0005 s, but FixedStepMass.fmu keeps its step 0.01 s" \
        in done.stderr and len(done.stderr.strip().splitlines()) == 1
    sc = api.load(config, T=0.02, dt=0.02, changes={"subsystems.A.substeps": 2}).with_master(algorithm="explicit")
    assert api.simulate(sc, reference=False).summary["fmu_calls_by_subsystem"]["A"]["doStep"] == 2


def test_the_kernel_route_insists_in_one_line_where_it_cannot(tmp_path):
    done = run_cli(tmp_path, "subsystems.B.substeps=2", "master.fast=true", config="foreign_pair.yaml")
    assert done.returncode == 2
    assert "master.fast: true, but subsystem B makes 2 substeps per macro-step with a wave adapter" in done.stderr


# (master, scene, T, master settings, substeps) run on both routes
ROUTES = {
    "dr-ledger-acting": ("dr", "two_oscillators_stiff", 0.3, dict(K=1, energy_guard="ledger"), {"A": 3}),
    "dr-two-threads": ("dr", "two_oscillators", 0.2, dict(K=5, threads="2"), {"A": 4, "B": 2}),
    "newton": ("newton", "two_oscillators", 0.2, {}, {"A": 4}),
    "explicit-signed-port": ("explicit", "foreign_pair", 0.05, {}, {"B": 3}),
    "jacobi-iter-ledger": ("jacobi-iter", "two_oscillators_stiff", 0.3, dict(K=1, energy_guard="ledger"), {"A": 3}),
    "aitken": ("aitken", "two_oscillators", 0.2, dict(K=3), {"B": 2}),
}


@pytest.mark.parametrize("case", ROUTES)
def test_the_kernel_route_makes_the_substeps_of_the_reference(case):
    name, config, T, settings, substeps = ROUTES[case]
    changes = {f"subsystems.{k}.substeps": n for k, n in substeps.items()}
    runs = [api.simulate(scene(config, T, changes, algorithm=name, fast=fast, **settings),
                         reference=name != "explicit") for fast in ("false", "true")]
    ref, fast = runs
    assert fast.summary["fast_path"] and not ref.summary["fast_path"]
    for table in ("trajectory", "steps"):
        a, b = getattr(ref, table), getattr(fast, table)
        assert a.dtype == b.dtype and a.tobytes() == b.tobytes(), table
    for key in ("fmu_calls_by_subsystem", "max_passivity_pos", "max_ledger", "energy_guard_extra_doSteps"):
        assert json.dumps(ref.summary.get(key)) == json.dumps(fast.summary.get(key)), key
    if settings.get("energy_guard") == "ledger":
        assert fast.summary["energy_guard_steps"] > 0


def test_a_subsystem_joined_by_signals_only_makes_its_substeps():
    pair = {"name": "pair", "dt": 0.01, "T": 0.1, "outputs": {"qA": "A.q2"},
            "subsystems": {"A": {"fmu": "LinearSide", "parameters": {"m2": 1.0, "k2": 10.0}, "start": {"q2": 0.1}},
                           "B": {"fmu": "LinearSide", "parameters": {"m2": 2.0, "k2": 5.0}}},
            "signals": [{"from": "A.q2", "to": "B.F"}, {"from": "B.q2", "to": "A.F"}]}
    runs = [api.simulate(parse_scenario({**pair, "subsystems": {**pair["subsystems"], "A": {
        **pair["subsystems"]["A"], "substeps": n}}}, "pair.yaml"), reference=False) for n in (1, 3)]
    calls = runs[1].summary["fmu_calls_by_subsystem"]
    assert calls["A"]["doStep"] == 3 * calls["B"]["doStep"] == 3 * 10
    assert not np.array_equal(runs[0].column("qA"), runs[1].column("qA"))


def test_the_stage_of_a_multi_rate_wave_port_is_the_macro_steps():
    built = build_scene(scene("two_oscillators", 0.1, {**FAST, "subsystems.A.substeps": 4}))
    try:
        a = built.subsystems[0]
        a.freeze(0, 0.0)
        b = a.advance([0.3])
        assert rescatter(built, built.gammas)[0] == pytest.approx(b[0], rel=1e-12)
        assert a.stage() != list(a.read(list(a.port.effort) + list(a.port.flow)))
    finally:
        built.close()
