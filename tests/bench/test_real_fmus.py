"""The real_fmus rows of `wavecosim bench`: the floor is the run's own FMU calls made again.

Claims: the floor's recorder (kernel/c/floor.c) records every FMU call the kernel makes in a run
(explicit on the foreign pair: per step and subsystem setReal, doStep, getReal and the observed
read; the signal pair: the signals' reads and writes and the doSteps of subsystems stepped alone);
made again on fresh instances, those calls leave the FMUs exactly where the run left them (the last
trajectory row, bit for bit), so the floor makes the same calls with the same arguments; a row
reports the whole run, the floor and their ratio.
"""
import dataclasses

import numpy as np
import pytest

from paths import CONFIGS
from wavecosim.bench.real_fmus import _floor, _recorded, _rows, signal_pair
from wavecosim.fmi.fmu import interposed
from wavecosim.kernel.floor import FloorRecorder
from wavecosim.run.runner import open_parts, run
from wavecosim.scenario.config import load_scenario


def quiet(message):
    """Set-up notes are not under test here."""


def replayed_outputs(sc, recorder):
    """The recorded calls made again on fresh instances; the recorded outputs read after them."""
    scene, master, _ = open_parts(sc, quiet)
    try:
        master.close()
        everyone = {s.name: s for s in scene.subsystems + scene.signal_only}
        recorder.replay({name: (s.fmu.component, s.fmu.function_pointer) for name, s in everyone.items()})
        return [float(everyone[ref.split(".")[0]].fmu.get_real([everyone[ref.split(".")[0]].fmu.vr(
            ref.split(".", 1)[1])])[0]) for ref in sc.outputs.values()]
    finally:
        scene.close()


@pytest.mark.parametrize("config, master, calls_per_step", [("foreign_pair", "explicit", 8),
                                                            ("foreign_pair", "dr", None),
                                                            ("signal_pair", "explicit", 8)])
def test_the_floor_makes_the_runs_fmu_calls_again(config, master, calls_per_step, built_fmus):
    loaded = signal_pair() if config == "signal_pair" else load_scenario(CONFIGS / f"{config}.yaml")
    sc = dataclasses.replace(loaded, T=0.05).with_master(algorithm=master, K=3)
    recorder = _recorded(sc)
    try:
        result = run(sc, certificates=False, warn=quiet)
        assert result.summary["fast_path"] and result.summary["block_steps"] == sc.n_steps
        if calls_per_step is not None:
            assert recorder.calls == calls_per_step * sc.n_steps
        assert np.array_equal(replayed_outputs(sc, recorder), result.outputs[-1])
        assert _floor(sc, recorder) > 0.0
    finally:
        recorder.close()


def test_without_the_hook_nothing_is_recorded(built_fmus):
    recorder = FloorRecorder()
    try:
        with interposed(None):
            recorder.start()
            run(dataclasses.replace(load_scenario(CONFIGS / "foreign_pair.yaml"), T=0.01).with_master(algorithm="explicit"),
                certificates=False, warn=quiet)
            recorder.stop()
        assert recorder.calls == 0
    finally:
        recorder.close()


def test_rows_name_every_system_and_master(built_fmus):
    systems = [("foreign_pair", load_scenario(CONFIGS / "foreign_pair.yaml"), None, None),
               ("signal_pair", signal_pair(), None, None),
               ("absent", None, None, "not here")]
    rows = _rows(systems, steps=10)
    assert [(r["name"], r["master"]) for r in rows] == [("foreign_pair", "explicit"), ("foreign_pair", "gauss-seidel"),
                                                         ("foreign_pair", "dr"), ("signal_pair", "explicit"),
                                                         ("absent", None)]
    assert all(r["scenario"].n_steps == 10 for r in rows if "scenario" in r) and rows[-1]["skipped"] == "not here"
