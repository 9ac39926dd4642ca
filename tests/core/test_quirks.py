"""Real FMUs' quirks, found at set-up (core/quirks.py), and every master and option run against
StrictMass (models/strict_mass), which aborts the process on any misuse of an instance or a state
handle. The quirks are StrictMass's own switches: freeze_without_flag (stays put when doStep gets
noSetFMUStatePriorToCurrentPoint = false, as a third-party CVODE pair does), shared_state (not
reentrant), restore_error (an approximate restore); ForeignSpring with k = d = 0 has a port whose
output does not respond to its input."""
import copy
import json
import re
import subprocess
import sys

import numpy as np
import pytest
import yaml

from paths import CLI, CONFIGS
from wavecosim.errors import ConfigError
from wavecosim.fmi.fmu import Fmu
from wavecosim.run.runner import run
from wavecosim.scenario.config import parse_scenario

PAIR = yaml.safe_load((CONFIGS / "foreign_pair.yaml").read_text())
PAIR["subsystems"]["A"]["fmu"] = "StrictMass"


def pair(T=0.02, **changes):
    """The foreign pair with StrictMass as the mass; changes: {"A.integers": {...}, "master": {...}, ...}."""
    raw = copy.deepcopy(PAIR)
    raw["T"] = T
    for key, value in changes.items():
        node = raw
        for part in key.split(".")[:-1]:
            node = node["subsystems"][part] if part in raw["subsystems"] else node[part]
        last = key.split(".")[-1]
        if isinstance(value, dict) and isinstance(node.get(last), dict):
            node[last].update(value)
        else:
            node[last] = value
    return raw


def simulate(raw, reference=None, notes=None):
    return run(parse_scenario(raw, "pair.yaml"), None, reference=reference,
               warn=notes.append if notes is not None else lambda message: None)


# Every master, route and option over the strict pair, each from its own copy of the scenario:
# a child process that must end with every run finished (an abort kills it).
VARIANTS = {
    "dr": {}, "dr python": {"master": {"fast": "false"}}, "no sign (orientation probe)": {"A.port.sign": None},
    "auto-retune": {"gamma": "auto-retune"}, "fastest": {"gamma": "fastest"},
    "relaxation auto": {"master": {"relaxation": "auto"}}, "anderson": {"master": {"anderson": 2}},
    "warm start": {"master": {"warm_start": True}}, "two threads": {"master": {"threads": "2"}},
    "deadline": {"master": {"deadline_us": 40.0}}, "fixed gamma": {"gamma": 0.5},
    "certificates every step": {"certificates": {"fne_pairs": 2, "every": 1}},
    "ledger redoes (dr)": {"gamma": "fast-unsafe", "master": {"K": 3}, "B.parameters": {"d": 0.0}},
    "ledger redoes (dr python)": {"gamma": "fast-unsafe", "master": {"K": 3, "fast": "false"},
                                  "B.parameters": {"d": 0.0}},
    "ledger redoes over a longer run (dr)": {"T": 0.2, "gamma": "fast-unsafe", "master": {"K": 3},
                                             "B.parameters": {"d": 0.0}},
    "ledger redoes under a deadline (dr)": {"gamma": "fast-unsafe", "master": {"K": 3, "deadline_us": 1.0},
                                            "B.parameters": {"d": 0.0}},
    "options auto": {"master": {"options": "auto"}}, "paper start": {"master": {"start": "paper"}},
    "monolithic guard": {"master": {"energy_guard": "monolithic"}},
    **{f"{m}{route}": {"master": {"algorithm": m, **({"fast": "false"} if route else {})}}
       for m in ("explicit", "gauss-seidel", "jacobi-iter", "gauss-seidel-iter", "aitken", "iqn-ils", "newton")
       for route in ("", " python")},
    "ledger redoes (jacobi-iter)": {"master": {"algorithm": "jacobi-iter", "K": 0, "energy_guard": "ledger"},
                                    "B.parameters": {"d": 0.0}},
    "ledger redoes (jacobi-iter python)": {"master": {"algorithm": "jacobi-iter", "K": 0, "energy_guard": "ledger",
                                                      "fast": "false"}, "B.parameters": {"d": 0.0}},
}
DRIVER = """
import json, sys
sys.path.insert(0, {tests!r})
from core.test_quirks import VARIANTS, pair, simulate
for name, changes in VARIANTS.items():
    raw = pair(**changes)
    if "A.port.sign" in changes:
        raw["subsystems"]["A"]["port"].pop("sign")
    result = simulate(raw, reference="lockstep")
    print(json.dumps([name, result.status, result.summary["steps"], result.summary.get("energy_guard_steps", 0),
                      result.summary.get("energy_guard_actions", {{}})]), flush=True)
"""


def test_every_master_and_option_runs_the_strict_fmu_without_abort(tmp_path):
    """All of VARIANTS in one child process with the lockstep reference: no abort (the strict FMU
    saw no NULL, freed or foreign state, no doStep off its time, no call out of the state machine),
    every run finished, and the energy ledger acted (undo, redo) where it is meant to, through each of
    its redo stages the pair reaches (the kernel's and Python's)."""
    tests = str(CONFIGS.parent / "tests")
    proc = subprocess.run([sys.executable, "-c", DRIVER.format(tests=tests)], capture_output=True, text=True,
                          timeout=900)
    assert proc.returncode == 0, proc.stderr[-2000:]
    done = {name: rest for name, *rest in map(json.loads, proc.stdout.splitlines())}
    assert set(done) == set(VARIANTS)
    assert all(status == "finished" and steps == round(VARIANTS[name].get("T", 0.02) / PAIR["dt"])
               for name, (status, steps, _, _) in done.items()), done
    assert all(done[name][2] > 0 for name in done if name.startswith("ledger redoes")), done
    stages = {action for name, (_, _, _, actions) in done.items() for action, count in actions.items()
              if name.startswith("ledger redoes") and count and action != "kept"}
    assert stages >= {"projected", "blended", "anchored", "scaled"}, done


def plain_loop(path, steps, flag, values_a, values_b):
    """The reference for a run without iteration: an fmpy loop, doStep(t_n, dt) with the other's
    output of the last step (0 before the first, as the physical masters start), with the given
    noSetFMUStatePriorToCurrentPoint."""
    a, b = Fmu(path["StrictMass"], "A", values_a), Fmu(path["ForeignSpring"], "B", values_b)
    try:
        rows, dt, F, v = [], PAIR["dt"], 0.0, 0.0
        for n in range(steps):
            a.set_real([a.vr("F")], [F])
            b.set_real([b.vr("v")], [v])
            a.slave.doStep(n * dt, dt, noSetFMUStatePriorToCurrentPoint=flag)
            b.slave.doStep(n * dt, dt, noSetFMUStatePriorToCurrentPoint=flag)
            (x, F), v = b.get_real([b.vr("x"), b.vr("F")]), a.get_real([a.vr("v")])[0]
            rows.append([x, v, F])
        return np.array(rows)
    finally:
        a.close()
        b.close()


FREEZE = {"A.integers": {"freeze_without_flag": 1}}


def values(raw, name):
    sub = raw["subsystems"][name]
    return {**sub.get("parameters", {}), **sub.get("start", {}), **sub.get("integers", {})}


@pytest.mark.parametrize("master", ["explicit", "jacobi-iter"])
def test_an_fmu_frozen_without_the_flag_runs_as_an_fmpy_loop_with_it(built_fmus, master):
    """StrictMass with freeze_without_flag: the probe finds it frozen with false and moving with
    true, warns in one line, records it in metadata, and the run equals an fmpy loop passing true to
    the last bit (the explicit master, and jacobi-iter converged with K = 0's commit: same exchange)."""
    raw = pair(T=0.05, master={"algorithm": master, "K": 0}, **FREEZE)
    notes = []
    result = simulate(raw, notes=notes)
    loop = plain_loop(built_fmus, 50, True, values(raw, "A"), values(raw, "B"))
    assert result.outputs[1:].tobytes() == loop.tobytes()
    frozen = plain_loop(built_fmus, 50, False, values(raw, "A"), values(raw, "B"))
    assert np.all(frozen[1:, 1] == frozen[0, 1])                     # v stuck after the first step
    warned = [n for n in notes if "noSetFMUStatePriorToCurrentPoint = false" in n]
    assert len(warned) == 1 and "subsystems.A: StrictMass.fmu does not advance" in warned[0]


def test_dr_on_the_frozen_fmu_equals_dr_on_the_plain_one():
    """DR (kernel route, gamma auto's probe, the lockstep reference): the freezing FMU gets true and
    gives the plain StrictMass's trajectory bit for bit; metadata.json says why."""
    frozen, plain = simulate(pair(**FREEZE), reference="lockstep"), simulate(pair(), reference="lockstep")
    assert frozen.outputs.tobytes() == plain.outputs.tobytes()
    assert frozen.reference.outputs.tobytes() == plain.reference.outputs.tobytes()


def test_the_quirks_key_overrides_the_probe(tmp_path):
    """quirks.no_set_fmu_state_prior: false keeps the standard's flag: the freezing FMU then freezes
    (v constant after the first step), as every master did before the probe; metadata.json says so."""
    raw = pair(T=0.05, **FREEZE, **{"A.quirks": {"no_set_fmu_state_prior": False}})
    result = run(parse_scenario(raw, "pair.yaml"), tmp_path, warn=lambda m: None, file_suffix=False)
    v = result.column("v")
    assert np.all(v[2:] == v[1]) and v[1] != v[0]
    quirks = json.loads((tmp_path / "metadata.json").read_text())["quirks"]
    assert quirks["A"]["no_set_fmu_state_prior"] is False and quirks["A"]["chosen_by"] == "quirks key"
    assert quirks["A"]["found"]["frozen_without_flag"] is True
    assert quirks["B"]["chosen_by"] == "probe" and quirks["B"]["found"]["reentrant"] is True


def two_pairs(shared):
    """Two mass-spring pairs in one scene, both masses StrictMass with shared_state."""
    raw = pair()
    subs = raw["subsystems"]
    subs["A"]["integers"] = {"shared_state": shared}
    subs["C"], subs["D"] = copy.deepcopy(subs["A"]), copy.deepcopy(subs["B"])
    subs["D"]["start"] = {"x": -0.2}
    raw["couplings"].append({"type": "equal_effort_opposite_flow", "ports": ["C", "D"]})
    raw["outputs"].update(xD="D.x", vC="C.v")
    return raw


def test_a_non_reentrant_fmu_gets_its_own_copy_of_the_binary():
    """shared_state 1 (one block of variables per copy of the binary): the probe's second instance
    disturbs the first, so C opens from its own copy; the run (and its lockstep reference) equals
    the same scene without the quirk to the last bit."""
    notes = []
    shared = simulate(two_pairs(1), reference="lockstep", notes=notes)
    plain = simulate(two_pairs(0), reference="lockstep")
    assert shared.outputs.tobytes() == plain.outputs.tobytes()
    assert shared.reference.outputs.tobytes() == plain.reference.outputs.tobytes()
    assert any("StrictMass.fmu is not reentrant" in n and "own copy of the binary" in n for n in notes)


def test_an_fmu_that_cannot_run_twice_in_a_process_is_refused_in_one_line(tmp_path):
    """shared_state 2 (one block for the whole process): even a copy of the binary disturbs, so a
    second instance is refused (exit 2), in the scene or for the lockstep reference; alone, it runs."""
    path = tmp_path / "two.yaml"
    path.write_text(yaml.safe_dump(two_pairs(2)))
    proc = subprocess.run([*CLI, "run", str(path), "--quiet", "--out", str(tmp_path / "o")], capture_output=True,
                          text=True, timeout=300)
    assert proc.returncode == 2
    line = proc.stderr.strip().splitlines()[-1]
    assert line.startswith(f"error: {path}: subsystems.C.fmu: StrictMass.fmu cannot run twice in one process")
    one = pair(**{"A.integers": {"shared_state": 2}})
    with pytest.raises(ConfigError, match="cannot run twice in one process.*--no-reference"):
        simulate(one, reference="lockstep")
    assert simulate(one).status == "finished"


def test_an_approximate_restore_is_measured_and_reported():
    """restore_error 1e-6 (moving, v = 0.3, so the error shows): the probe measures the outputs two
    steps after fmi2SetFMUstate about that far off and says so once; the exact StrictMass says nothing."""
    notes, exact = [], []
    simulate(pair(**{"A.parameters": {"restore_error": 1e-6}, "A.start": {"v": 0.3}}), notes=notes)
    simulate(pair(**{"A.start": {"v": 0.3}}), notes=exact)
    approx = [n for n in notes if "restores its state only to" in n]
    assert len(approx) == 1 and "subsystems.A: StrictMass.fmu restores its state only to" in approx[0]
    assert float(approx[0].split("only to ")[1].split()[0]) == pytest.approx(1e-6, rel=0.5)
    assert not any("restores its state" in n for n in exact)


def test_a_port_that_does_not_respond_is_reported():
    """ForeignSpring with k = d = 0 outputs F = 0 whatever its input: the coupling cannot move it."""
    notes = []
    simulate(pair(master={"algorithm": "explicit"}, **{"B.parameters": {"k": 0.0, "d": 0.0}}), notes=notes)
    assert any("port outputs of ForeignSpring.fmu do not move when its inputs do" in n for n in notes)


@pytest.mark.parametrize("quirks, message", [
    ({"flag": True}, "subsystems.A.quirks.flag: unknown key (allowed: no_set_fmu_state_prior, reentrant, probe)"),
    ({"reentrant": "yes"}, "subsystems.A.quirks.reentrant: must be true or false, got 'yes'"),
])
def test_quirks_keys_are_checked(quirks, message):
    with pytest.raises(ConfigError, match=re.escape(message)):
        parse_scenario(pair(**{"A.quirks": quirks}), "pair.yaml")
