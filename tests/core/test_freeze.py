"""An FMU that stops advancing when doStep gets noSetFMUStatePriorToCurrentPoint = false: the quirk
probe (core/quirks.py) finds it over several steps and gives it true, and where the scenario forces
false the freeze watch (run/observers/freeze_watch.py) marks the run suspect. The FMU is StrictMass
with freeze_without_flag 2: every doStep with false after its first returns to the start point, as
a real CVODE-based FMU does (outputs constant from the second step, status OK), paired with
ForeignSpring; the mass starts moving, so the spring's force, the mass's input, changes."""
import copy
import json

import numpy as np
import pytest
import yaml

import wavecosim as wc
from paths import CONFIGS
from wavecosim.masters import MASTERS
from wavecosim.run.observers.freeze_watch import FROZEN_STEPS
from wavecosim.run.runner import run
from wavecosim.scenario.config import parse_scenario

PAIR = yaml.safe_load((CONFIGS / "foreign_pair.yaml").read_text())
PAIR["subsystems"]["A"].update(fmu="StrictMass", start={"v": 0.5})
PAIR["T"] = 0.05
NOTE = "StrictMass.fmu does not advance when doStep gets noSetFMUStatePriorToCurrentPoint = false"


def pair(master, freeze=2, quirks=None, fast=True):
    raw = copy.deepcopy(PAIR)
    raw["master"] = {"algorithm": master, "K": 3, "fast": fast}
    raw["subsystems"]["A"]["integers"] = {"freeze_without_flag": freeze}
    if quirks is not None:
        raw["subsystems"]["A"]["quirks"] = quirks
    return parse_scenario(raw, "pair.yaml")


def simulate(scenario, out_dir=None, notes=None):
    return run(scenario, out_dir, warn=(notes.append if notes is not None else lambda m: None), file_suffix=False)


@pytest.mark.parametrize("master", list(MASTERS))
def test_every_master_advances_the_freezing_fmu_and_says_why(master):
    """The probe gives StrictMass true (it returns to its start point with false, which two steps
    cannot tell from a step that moves): every master's run equals its run with the plain StrictMass
    bit for bit, finishes, and summary.json carries the flag, its reason and the note."""
    notes = []
    frozen, plain = simulate(pair(master), notes=notes), simulate(pair(master, freeze=0))
    assert frozen.status == "finished" and frozen.outputs.tobytes() == plain.outputs.tobytes()
    v = frozen.column("v")
    assert len(set(v[2:].tolist())) > 40                                  # it advances
    rolls_back = MASTERS[master].needs_rollback
    assert frozen.summary["quirks"]["A"] == {"no_set_fmu_state_prior": True,
                                             "chosen_by": "probe" if rolls_back else "no rollback"}
    assert [n for n in frozen.summary["notes"] if NOTE in n] == [n for n in notes if NOTE in n]
    assert len([n for n in notes if NOTE in n]) == 1
    assert frozen.summary["freeze_watch"] == {"steps": FROZEN_STEPS, "suspect": {}}
    if rolls_back:
        assert plain.summary["quirks"]["A"] == {"no_set_fmu_state_prior": False, "chosen_by": "probe"}


def test_the_rollback_masters_stay_near_the_explicit_run():
    """With true, every master that rolls back advances as the explicit master does (the same
    trajectory to the explicit master's one-step lag at dt = 1 ms: a few % of its range; frozen: all of it)."""
    explicit = simulate(pair("explicit")).column("v")
    for master in (m for m, cls in MASTERS.items() if cls.needs_rollback):
        v = simulate(pair(master)).column("v")
        assert np.max(np.abs(v - explicit)) < 0.05 * np.ptp(explicit), master


@pytest.mark.parametrize("master,fast", [("dr", True), ("dr", False), ("jacobi-iter", True),
                                         ("jacobi-iter", False), ("gauss-seidel-iter", True), ("aitken", True),
                                         ("iqn-ils", True), ("newton", True)])
def test_forced_false_the_freeze_watch_marks_the_run_suspect(tmp_path, master, fast):
    """quirks.no_set_fmu_state_prior: false on the freezing FMU: v stays at its start value from the
    second step on while the spring's force changes; the watch warns once, summary.json says
    `suspect` with the frozen subsystem and its stretch, the same on the C route and the Python one."""
    notes = []
    result = simulate(pair(master, quirks={"no_set_fmu_state_prior": False}, fast=fast), tmp_path, notes)
    v, F = result.column("v"), result.column("F")
    assert np.all(v[2:] == v[0]) and len(set(F[2:].tolist())) > 40
    summary = json.loads((tmp_path / "summary.json").read_text())
    assert summary["status"] == "suspect" and summary["message"].startswith("frozen: A (")
    assert summary["freeze_watch"]["suspect"] == {"A": {"from_step": 2, "from_t": 0.002, "steps": 48}}
    assert summary["quirks"]["A"] == {"no_set_fmu_state_prior": False, "chosen_by": "quirks key"}
    assert len([n for n in notes if n.startswith("subsystem A: its outputs stayed the same")]) == 1


def test_a_master_that_never_rolls_back_passes_true_and_finishes():
    """The explicit master passes true whatever the key says: the FMU advances, the run finishes."""
    result = simulate(pair("explicit", quirks={"no_set_fmu_state_prior": False}))
    assert result.status == "finished" and result.summary["freeze_watch"]["suspect"] == {}


def test_links_at_rest_far_from_a_pulse_are_not_suspect(tmp_path):
    """A chain of 200 wave-port links under DR, the first one struck: links the pulse has not reached
    keep their outputs while links elsewhere move; their own inputs (the coupled channels) do not
    change, so the run finishes without a word."""
    text = (CONFIGS / "chain_512.yaml").read_text().replace("511", "199").replace("510", "198")
    (tmp_path / "chain.yaml").write_text(text)
    result = run(wc.load(tmp_path / "chain.yaml", T=0.25), None, certificates=False, warn=lambda m: None)
    assert result.status == "finished" and result.summary["freeze_watch"]["suspect"] == {}


class Values:
    """A Reading: H, E, F of one step as lists."""

    def __init__(self, H, E, F):
        self.H, self.E, self.F = H, E, F


class Layout:
    """The blocks' log and readings as prepare_block reads them: H, E and F of A and B at log rows 0 .. 5."""
    observed_at = 0

    @staticmethod
    def rows(key):
        return {"H": [0, 1], "E": [2, 3], "F": [4, 5]}[key]


class Log:
    """A kernel log of every step (values x steps, one row per value) as Pass.steps reads it."""

    def __init__(self, values):
        self.values = np.ascontiguousarray(values.T)
        self.address, self.ld = self.values.ctypes.data, self.values.shape[1]


def state(watch):
    """What a watch carries from one step to the next, where it holds it (its C arrays after a block),
    the values before as bits (NaN among them)."""
    from wavecosim.run.observers.freeze_watch import STATE
    held = [(watch.c[name][:len(getattr(watch, name))] if watch.in_c else list(getattr(watch, name))) for name in STATE]
    return [np.array(held[0]).tobytes(), *held[1:]]


def held_stretches(watch, rng, steps):
    """H, E and F of A and B over the steps (steps x 6): all moving, with stretches of held outputs
    of every length around FROZEN_STEPS (the inputs held too in some of their steps) and NaNs."""
    values = rng.random((steps, 6))
    values[rng.random(steps) < 0.01, 2] = np.nan              # a NaN differs from every value, itself too
    for out, inp in zip(watch.outs, watch.ins):
        j = 0
        while j < steps:
            start, length = j + int(rng.integers(1, 30)), int(rng.integers(5, 45))
            for k in range(start + 1, min(start + length, steps)):
                values[k, out] = values[k - 1, out]
                if rng.random() < 0.2:
                    values[k, inp] = values[k - 1, inp]
            j = start + length
    return values


def test_the_watch_in_blocks_equals_the_watch_step_by_step():
    """Stretches of equal outputs (some with changing inputs, of every length around FROZEN_STEPS)
    given step by step, and in blocks of uneven sizes to the C pass (kernel/c/blocks.c) with steps
    made one by one among them: the same subsystems found and warned of, with the same stretches, the
    same state after every block."""
    from wavecosim.core.scene import build_scene
    from wavecosim.run.observers.freeze_watch import FreezeWatch
    scene = build_scene(pair("explicit"), wave=False, needs_rollback=False)
    try:
        rng = np.random.default_rng(7)
        said = {"one": [], "blocks": []}
        one, blocks = (FreezeWatch(scene, said[key].append) for key in said)
        steps = 3000
        values = held_stretches(one, rng, steps)
        reading = [Values(list(v[:2]), list(v[2:4]), list(v[4:])) for v in values]
        first = Values([0.0, 0.0], [0.0, 0.0], [0.0, 0.0])
        one.start(first)
        blocks.start(first)
        blocks.prepare_block(Layout, Layout)
        log, n = Log(values), 0
        for j, size in enumerate(rng.integers(1, 90, size=200)):
            size = min(int(size), steps - n)
            if not size:
                break
            for k in range(n, n + size):
                one.after_step(k, 0.0, None, reading[k], None)
            if j % 3 == 2:                                        # steps made one by one between blocks
                for k in range(n, n + size):
                    blocks.after_step(k, 0.0, None, reading[k], None)
            else:
                blocks.before_passes()
                blocks.block_pass().steps(0, log, n, size)
                blocks.after_passes()
            assert state(one) == state(blocks) and said["one"] == said["blocks"], n
            n += size
        assert len(one.found) == 2 and n == steps and one.found == blocks.found
        assert said["one"] == said["blocks"] and len(said["one"]) == 2
    finally:
        scene.close()
