"""The interface energy ledger (master.energy_guard: ledger) on the real FMUs, through runner.run.

It keeps L^n = sum_k I^k (the energy the interface supplied) at or below roundoff, so the stored
energy of a source-free scene never rises above H(0), while a driven scene may rise with its source
and a converging DR run is left untouched."""
import copy
import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
import yaml

from paths import ROOT
from wavecosim.scenario.config import parse_scenario
from wavecosim.errors import ConfigError
from wavecosim.masters import ledger as energy_ledger
from wavecosim.masters.ledger import ANCHORED, BLENDED, ITERATED, KEPT, PROJECTED, ZERO
from wavecosim.kernel import drkernel as fast_path
from wavecosim.run import live, runner
from wavecosim.run.runner import run

ROUNDOFF = 1e-12
STAR = ROOT / "configs" / "star.yaml"
TABLE_I = ROOT / "configs" / "two_oscillators.yaml"


CHAIN = ROOT / "configs" / "chain.yaml"


def scenario(path, guard, K, T=None, algorithm="dr", parameters=None, master=None, **top):
    """A scenario file with master settings, T and top-level keys replaced (parameters: {(sub, name): value});
    one thread unless the master settings say otherwise."""
    raw = yaml.safe_load(Path(path).read_text())
    raw.setdefault("master", {}).update(algorithm=algorithm, K=K, energy_guard=guard, **(master or {}))
    raw["master"].setdefault("threads", "1")          # no thread plan on trial: its steps are made alone
    raw.update(top, **({"T": T} if T else {}))
    for (sub, name), value in (parameters or {}).items():
        raw["subsystems"][sub].setdefault("parameters", {})[name] = value
    return parse_scenario(copy.deepcopy(raw), f"{Path(path).name} {guard} K={K}", Path(path).parent)


def column(result, name):
    return result.steps_table.array()[:, result.steps_table.columns.index(name)]


def test_star_at_K1_stays_below_its_start_energy_with_the_ledger():
    """Unguarded, K = 1 pumps the star to 3.1e6 H(0) over 20 s; the ledger holds it below H(0)."""
    result = run(scenario(STAR, "ledger", 1, T=20.0), certificates=False)
    H = np.asarray(result.energy)
    assert H.max() <= H[0] * (1 + ROUNDOFF)
    assert result.summary["energy_guard_steps"] > 0 and result.summary["energy_guard_extra_doSteps"] > 0


def test_every_redo_moves_its_inputs_and_the_ledger_never_exceeds_roundoff():
    """The paper's start at K = 1 on the star: the ledger projects the steps that would supply energy.
    Fails when the projection is a no-op (t = 0): the ledger then exceeds its tolerance at once."""
    result = run(scenario(STAR, "ledger", 1, T=5.0, master={"start": "paper"}), certificates=False)
    scale, ledger = column(result, "scale"), column(result, "ledger")
    acted = column(result, "ledger_action") > 0
    assert acted.sum() == result.summary["energy_guard_steps"] > 0
    assert result.summary["energy_guard_actions"]["projected"] == acted.sum()
    assert np.all(scale[acted] < 1.0) and np.all(scale[~acted] == 1.0)
    assert ledger.max() <= 1e3 * ROUNDOFF * result.energy[0]     # tol: RTOL times the wave traffic
    assert np.array_equal(column(result, "interface_energy"), column(result, "interface_supply"))
    assert result.summary["max_ledger"] == ledger.max()


def test_a_driven_scene_may_rise_with_its_source_and_the_ledger_stays_out_of_the_way():
    """Table I with c2 = -3 (negative damping, a source inside B) at K = 20: the monolithic guard
    redoes most steps (H rises above H(0), as the source makes it), the ledger none."""
    driven = {("B", "c2"): -3.0}
    off = run(scenario(TABLE_I, "off", 20, T=5.0, parameters=driven), reference="lockstep", certificates=False)
    mono = run(scenario(TABLE_I, "monolithic", 20, T=5.0, parameters=driven), certificates=False)
    ledger = run(scenario(TABLE_I, "ledger", 20, T=5.0, parameters=driven, master={"start": "paper"}),
                 reference="lockstep", certificates=False)
    assert max(off.energy) > 1.5 * off.energy[0]
    assert mono.summary["energy_guard_steps"] > 400
    assert ledger.summary["energy_guard_steps"] == 0 and ledger.summary["energy_guard_extra_doSteps"] == 0
    assert np.array_equal(ledger.outputs, off.outputs)
    assert np.array_equal(ledger.error, off.error)


@pytest.mark.parametrize("K", [0, 20, 50])
def test_table_i_runs_that_keep_the_ledger_by_themselves_are_untouched(K):
    off = run(scenario(TABLE_I, "off", K, T=5.0), reference="lockstep", certificates=False)
    ledger = run(scenario(TABLE_I, "ledger", K, T=5.0, master={"start": "paper"}), reference="lockstep",
                 certificates=False)
    assert ledger.summary["energy_guard_steps"] == 0
    assert np.array_equal(ledger.error, off.error)
    if K == 0:
        assert ledger.summary["max_ledger"] <= 0.0     # it telescopes: L^n = -|b^{n+1}|^2 / 2


def test_a_rolling_back_physical_master_is_held_by_the_ledger():
    """jacobi-iter at K = 1 on the stiff scene reaches 4e36 H(0) unguarded; the ledger, scaling its
    commit inputs towards zero power, keeps H <= H(0)."""
    stiff = ROOT / "configs" / "two_oscillators_stiff.yaml"
    off = run(scenario(stiff, "off", 1, T=2.0, algorithm="jacobi-iter"), certificates=False)
    ledger = run(scenario(stiff, "ledger", 1, T=2.0, algorithm="jacobi-iter"), certificates=False)
    assert max(off.energy) > 1e3 * off.energy[0]
    H = np.asarray(ledger.energy)
    assert H.max() <= H[0] * (1 + ROUNDOFF) and ledger.summary["energy_guard_steps"] > 0


def test_with_no_time_left_a_redo_commits_a_query_or_zero():
    """Under a deadline too short for any fitted correction, a redo commits the input of a query whose
    supply fits (one round) or, when none does or it misses, zero inputs; H stays below H(0); the
    realised step times are reported."""
    result = run(scenario(CHAIN, "ledger", 1000, master={"deadline_us": 1e-3}), certificates=False)
    s = result.summary
    action, rounds = column(result, "ledger_action"), column(result, "ledger_rounds")
    acted = action > 0
    assert s["energy_guard_steps"] > 0 and set(action[acted]) <= {ZERO, ANCHORED} and ANCHORED in action
    assert np.all(column(result, "scale")[acted] == 0.0) and np.all(rounds[action == ANCHORED] == 1)
    assert s["energy_guard_extra_doSteps"] == 8 * rounds.sum()
    assert max(result.energy) <= result.energy[0] * (1 + ROUNDOFF)
    assert s["guarded_step_time_us"]["count"] == s["energy_guard_steps"]


def test_the_fitted_scale_is_the_largest_root_of_the_quadratic_supply():
    q = (lambda s: 3.0 * s * s + 2.0 * s - 1.0)                 # q(s) = 1 at s = (sqrt(28) - 2) / 6
    assert energy_ledger.largest_root(q(0.0), q(0.5), q(1.0), 1.0) == pytest.approx((28 ** 0.5 - 2) / 6)
    assert energy_ledger.largest_root(-1.0, -0.5, 1.0, 0.0) == pytest.approx(0.5 ** 0.5)    # 2 s^2 - 1
    assert energy_ledger.largest_root(-1.0, 0.0, 1.0, 0.5) == pytest.approx(0.75)           # linear


@pytest.mark.parametrize("value, expected", [(True, "monolithic"), (False, "off"), ("ledger", "ledger"),
                                             ("monolithic", "monolithic"), ("off", "off")])
def test_energy_guard_values_and_old_booleans(value, expected):
    assert scenario(TABLE_I, value, 1).master.energy_guard == expected


def test_a_bad_energy_guard_is_one_line_naming_the_key():
    with pytest.raises(ConfigError, match=r"master\.energy_guard: must be one of ledger, monolithic, off, got 'on-ish'"):
        scenario(TABLE_I, "on-ish", 1)


def test_steps_csv_and_summary_carry_the_ledger(tmp_path):
    run(scenario(STAR, "ledger", 1, T=2.0, master={"start": "paper"}), out_dir=tmp_path, certificates=False)
    with open(tmp_path / "steps_dr_K1.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert {"interface_energy", "ledger", "scale", "ledger_action", "ledger_rounds"} <= set(rows[0])
    actions = {r["ledger_action"] for r in rows}
    assert "kept" in actions and actions <= set(energy_ledger.ACTIONS) and len(actions) > 1
    assert all(r["reason"] == "energy-guard" for r in rows if r["ledger_action"] != "kept")
    assert all((float(r["ledger_rounds"]) > 0) == (r["ledger_action"] != "kept") for r in rows)
    summary = json.loads((tmp_path / "summary_dr_K1.json").read_text())
    assert summary["energy_guard_steps"] == sum(r["ledger_action"] != "kept" for r in rows)
    assert summary["energy_guard_actions"] == {a: sum(r["ledger_action"] == a for r in rows) for a in energy_ledger.ACTIONS}
    assert summary["max_ledger"] == max(float(r["ledger"]) for r in rows)
    assert summary["energy_guard_extra_doSteps"] > 0


def test_redone_steps_are_bit_identical_on_the_fast_path_and_the_reference():
    """The kernel's redo (drkernel.c, in blocks) gives the Python reference's numbers."""
    base = scenario(STAR, "ledger", 1, T=2.0, master={"start": "paper"})
    ref = run(base.with_master(fast="false"), certificates=False)
    fast = run(base.with_master(fast="true"), certificates=False)
    assert fast.summary["fast_path"] and not ref.summary["fast_path"]
    assert ref.summary["energy_guard_steps"] == fast.summary["energy_guard_steps"] > 0
    assert np.array_equal(ref.outputs, fast.outputs)
    assert np.array_equal(column(ref, "scale"), column(fast, "scale"))


def test_default_guard_is_the_ledger_for_dr_and_off_for_the_classical_masters():
    """DR runs under the ledger unless told otherwise; the classical masters run as other tools run
    them (off), and `energy_guard: ledger` guards them too."""
    import wavecosim as wc
    sc = wc.load(T=0.2)
    assert wc.simulate(sc, K=8, reference=False, certificates=False).summary["energy_guard"] == "ledger"
    assert wc.simulate(sc, master="jacobi-iter", K=1, reference=False).summary["energy_guard"] == "off"
    assert wc.simulate(sc, master="explicit", reference=False).summary["energy_guard"] == "n/a"
    guarded = sc.with_master(algorithm="jacobi-iter", K=1, energy_guard="ledger")
    assert wc.simulate(guarded, reference=False).summary["energy_guard"] == "ledger"


def same_run(ref, fast, blocks=True):
    """Kernel and Python reference runs agree byte for byte: rows, outputs, FMU calls, ledger figures."""
    assert fast.summary["fast_path"] and not ref.summary["fast_path"]
    assert fast.summary["block_steps"] == (fast.summary["steps"] if blocks else 0)   # blocks: the kernel made all
    assert ref.steps_table.array().tobytes() == fast.steps_table.array().tobytes()
    assert ref.outputs.tobytes() == fast.outputs.tobytes()
    keys = ("fmu_calls", "energy_guard_steps", "energy_guard_extra_doSteps", "energy_guard_actions", "max_ledger",
            "ledger_final")
    assert [ref.summary[k] for k in keys] == [fast.summary[k] for k in keys]


REDO_SCENES = {     # scenes whose redos take these actions (besides kept)
    "projected, blended": (CHAIN, 6, {}, {}, {PROJECTED, BLENDED}),
    "iterated, projected": (STAR, 20, {"eps": 1e-2, "start": "paper"}, {}, {ITERATED}),
    "projected, stiff": (STAR, 4, {}, {("A", "knl"): 8e7}, {PROJECTED}),
}


@pytest.mark.parametrize("blocks", [True, False])
@pytest.mark.parametrize("scene", REDO_SCENES)
def test_the_kernels_redo_is_the_reference_in_every_action(monkeypatch, blocks, scene):
    """Redone steps (continued iterations, projections, blends towards a query) made by the kernel
    in blocks or step by step (one dr_run_steps call per step), byte for byte the Python reference's."""
    if not blocks:
        monkeypatch.setattr(live, "BLOCK_STEPS", 1)
    path, K, master, parameters, actions = REDO_SCENES[scene]
    base = scenario(path, "ledger", K, T=5.0 if path == STAR else None, parameters=parameters, master=master)
    ref, fast = (run(base.with_master(fast=f), certificates=False) for f in ("false", "true"))
    same_run(ref, fast, blocks)
    assert actions <= set(column(fast, "ledger_action"))
    assert max(fast.energy) <= fast.energy[0] * (1 + ROUNDOFF)


def test_step_by_step_with_certificates_under_a_deadline_is_block_mode_bit_for_bit(monkeypatch):
    """Step by step (blocks of one step; certificates on, which the blocks compute too) the kernel makes
    each step and its guard in one call (never macro_step + redo from Python), and rows, outputs, FMU
    calls and ledger figures equal the blocks' (no certificates), bit for bit, in every action. The
    10 s deadline is never reached, so only the step times may differ."""
    calls = {"macro_step": 0, "redo": 0}
    for name in calls:
        def counted(self, *args, _name=name, _real=getattr(fast_path.Kernel, name)):
            calls[_name] += 1
            return _real(self, *args)
        monkeypatch.setattr(fast_path.Kernel, name, counted)
    base = scenario(CHAIN, "ledger", 6).with_master(deadline_us=1e7)
    blocks = run(base, certificates=False)
    with monkeypatch.context() as m:
        m.setattr(live, "BLOCK_STEPS", 1)
        steps = run(base, certificates=True)
    assert blocks.summary["block_steps"] == blocks.summary["steps"] and steps.summary["block_steps"] == 0
    assert calls == {"macro_step": 0, "redo": 0}
    shared = blocks.steps_table.columns
    assert set(shared) < set(steps.steps_table.columns)           # the certificates add their own columns
    picked = steps.steps_table.array()[:, [steps.steps_table.columns.index(c) for c in shared]]
    assert blocks.steps_table.array().tobytes() == picked.tobytes()
    assert blocks.outputs.tobytes() == steps.outputs.tobytes()
    keys = ("fmu_calls", "energy_guard_steps", "energy_guard_extra_doSteps", "energy_guard_actions", "max_ledger",
            "ledger_final")
    assert [blocks.summary[k] for k in keys] == [steps.summary[k] for k in keys]
    assert set(column(steps, "ledger_action")) == {KEPT, PROJECTED, BLENDED}
    for s in (blocks.summary, steps.summary):
        assert s["step_time_us"]["count"] == s["steps"] and s["deadline_bound"]["deadline_us"] == 1e7


def test_past_the_deadline_the_kernel_commits_a_query_or_zero_at_once_and_keeps_the_ledger():
    """A deadline already passed when the guard looks (1 ns): the inner loop makes one iteration,
    every redo commits a query's input or zero inputs, the ledger stays at roundoff and H below H(0),
    in the kernel as in the Python reference, byte for byte; the bound is reported."""
    base = scenario(CHAIN, "ledger", 1000).with_master(deadline_us=1e-3)
    ref, fast = (run(base.with_master(fast=f), certificates=False) for f in ("false", "true"))
    same_run(ref, fast)
    s, acted = fast.summary, column(fast, "ledger_action") > 0
    assert s["energy_guard_steps"] > 0 and np.all(column(fast, "scale")[acted] == 0.0)
    assert np.all(column(fast, "iterations") == 1)
    assert s["energy_guard_actions"]["anchored"] > 0 and s["energy_guard_actions"]["zero"] > 0
    assert s["energy_guard_extra_doSteps"] == 8 * column(fast, "ledger_rounds").sum()
    assert column(fast, "ledger").max() <= 1e3 * ROUNDOFF * fast.energy[0]
    assert max(fast.energy) <= fast.energy[0] * (1 + ROUNDOFF)
    bound = s["deadline_bound"]
    assert bound["deadline_us"] == 1e-3 and bound["bound_us"] == bound["deadline_us"] + bound["round_us"] > 0
    assert s["step_time_us"]["count"] == s["steps"] and 0.0 <= bound["within"] <= 1.0


def test_step_time_spread_and_bound_by_nearest_rank():
    times = [(1e-6 * t, t >= 30, 1e-6, math.nan) for t in range(1, 101)]          # 1 .. 100 µs
    assert energy_ledger.spread([t for t, _, _, _ in times]) == pytest.approx(
        {"median": 50.0, "p99": 99.0, "max": 100.0, "count": 100})
    bound = energy_ledger.deadline_bound(times, 40.0)
    assert bound["bound_us"] == pytest.approx(41.0) and bound["within"] == 0.41
    assert bound["guarded_within"] == pytest.approx(12 / 71) and bound["on_cpu_within"] is None


def redo_once(fast, K, fraction, eps=None, steps=20, path=TABLE_I):
    """A scene with the paper's start, `steps` macro-steps at budget K, then the ledger's redo of the
    last one with an allowance `fraction` |I| below its supply I: (the redo's result, b^{n+1}, FMU calls)."""
    import dataclasses
    from wavecosim.core.scene import build_scene
    from wavecosim.masters.dr_fast import FastDRMaster
    sc = scenario(path, "ledger", K, master={"start": "paper"})
    scene = build_scene(sc)
    master = FastDRMaster(scene, dataclasses.replace(sc.master, fast=fast, eps=eps))
    try:
        for n in range(steps):
            log = master.make_step(n, n * sc.dt)             # the master's own steps, its ledger left out
        inputs, outputs = master._committed_inputs(log), master._committed_outputs
        supplied = master._supply(inputs, outputs)[0]
        done = energy_ledger.EnergyLedger(master)._redo(log, inputs, outputs, supplied, supplied - fraction * abs(supplied))
        return done, list(master.b), [dict(s.calls) for s in master.subsystems], master.kernel is not None
    finally:
        master.close()
        scene.close()


STAGES = {     # (scene, K, steps, allowance below the supply by fraction |I|, eps): the redo's action
    "projected": (TABLE_I, 8, 20, 1e-6, None),
    "blended": (CHAIN, 6, 20, 1.0, None),
    "anchored": (TABLE_I, 3, 20, 0.5, None),
    "scaled": (CHAIN, 3, 20, 1.0, None),
    "zero": (TABLE_I, 1, 20, 0.1, None),
    "iterated": (TABLE_I, 8, 20, 1e-6, 0.5),
}


@pytest.mark.parametrize("action", STAGES)
def test_each_stage_of_the_redo_is_the_same_in_the_kernel_and_the_reference(action):
    """One redo per stage, forced by the allowance it is given: the kernel's (dr_ledger_redo) gives the
    Python reference's action, scale, supply, rounds, committed inputs, b^{n+1} and FMU calls, bit for
    bit; the blend and the scaling land strictly inside their segments."""
    path, K, steps, fraction, eps = STAGES[action]
    ref, fast = (redo_once(f, K, fraction, eps, steps, path) for f in ("false", "true"))
    assert fast[3] and not ref[3]
    assert energy_ledger.ACTIONS[ref[0][3]] == action
    if action in ("blended", "scaled"):
        assert 0.0 < ref[0][0] < 1.0
    assert repr(ref[0][:5]) == repr(fast[0][:5]) and repr(list(ref[0][5])) == repr(list(fast[0][5]))
    assert repr(ref[1]) == repr(fast[1]) and ref[2] == fast[2]


def test_the_projection_lands_on_the_allowance_of_an_affine_map():
    """Two subsystems, one channel each, S(a) = rho a + c (slopes in [0, 1]): the secant to the last
    query is the slope, so the supply of the projected input is the target to roundoff, and the move is
    against the supply's gradient a - rho S(a)."""
    rho, c = [0.3, 0.8], [0.5, -0.2]
    S = (lambda a: [r * x + ci for r, x, ci in zip(rho, a, c)])
    supply = (lambda a: 0.5 * (sum(x * x for x in a) - sum(y * y for y in S(a))))
    a, u = [1.0, 2.0], [0.7, 1.1]
    target = supply(a) - 0.3
    moved = energy_ledger.projected([(0, 1), (1, 1)], a, S(a), (u, S(u)), supply(a), target)
    assert supply(moved) == pytest.approx(target, rel=1e-12, abs=1e-12)
    gradient = [x - r * y for x, r, y in zip(a, rho, S(a))]
    step = [x - m for x, m in zip(a, moved)]
    assert step[0] * gradient[1] == pytest.approx(step[1] * gradient[0]) and step[0] * gradient[0] > 0
    assert energy_ledger.projected([(0, 1), (1, 1)], a, S(a), (u, S(u)), supply(a), -1e9) is None
