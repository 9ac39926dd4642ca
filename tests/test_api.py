"""wavecosim's Python API: the same numbers as the CLI, arrays other tools take, nothing written
unless asked, and errors as the project's exception classes."""
import json
import os

import matplotlib
import numpy as np
import pytest

import wavecosim as wc
from wavecosim.cli import main

matplotlib.use("Agg")


def test_simulate_gives_the_cli_numbers_bit_for_bit(tmp_path):
    with pytest.raises(SystemExit) as info:
        main(["run", "--K", "20", "--T", "1", "--out", str(tmp_path), "--quiet"])
    assert info.value.code == 0
    on_disk = json.loads((tmp_path / "summary.json").read_text())
    r = wc.simulate(K=20, T=1)
    for key in ("max_error", "rms_error", "final_error", "max_passivity_pos", "max_augmented_pos", "H_final"):
        assert r.summary[key] == on_disk[key], key
    assert r.trajectory["time"].tolist() == [k / 100 for k in range(101)]


def test_results_are_arrays_fmpy_and_pandas_take(tmp_path):
    r = wc.simulate(K=3, T=0.5, reference=False, certificates=False)
    assert r.trajectory.dtype.names[0] == "time" and r.steps.dtype.names[0] == "time"
    assert r.reference is None and "max_error" not in r.summary
    from fmpy.util import read_csv, write_csv
    write_csv(str(tmp_path / "t.csv"), r.trajectory)
    back = read_csv(str(tmp_path / "t.csv"))
    assert back.dtype.names == r.trajectory.dtype.names and np.allclose(back["q1"], r.trajectory["q1"], rtol=1e-12)
    assert np.array_equal(r.energy[1:], r.steps["H_total"])


def test_nothing_is_written_without_out_dir(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)
    wc.simulate(K=1, T=0.2)
    wc.sweep(Ks=[0, 1], T=0.2, certificates=False)
    assert os.listdir(tmp_path) == []


def test_sweep_and_compare_return_tables():
    table = wc.sweep(Ks=[0, 20], T=0.5, certificates=False)
    arr = table.array(["K", "max_error"])
    assert arr["K"].tolist() == [0.0, 20.0] and arr["max_error"][1] < arr["max_error"][0]
    cmp = wc.compare(masters=["explicit", "dr"], Ks=[5], T=0.2, certificates=False)
    assert [(r["master"], r["K"]) for r in cmp.rows] == [("explicit", "-"), ("dr", 5)]


def test_errors_are_the_projects_classes():
    with pytest.raises(wc.ConfigError, match="K: must be >= 0"):
        wc.load(K=-1).master
    with pytest.raises(wc.ConfigError, match="gamma: must be > 0"):
        wc.simulate(gamma=-1.0)
    with pytest.raises(wc.ConfigError, match="master: must be one of"):
        wc.simulate(master="jacobi")
    sc = wc.load()
    raw_fail = wc.with_overrides(sc, T=0.5)
    import dataclasses
    sub = dataclasses.replace(raw_fail.subsystems[0], integers={"newton_max_iter": 4},
                              start={**raw_fail.subsystems[0].start, "q1": 2.0, "d": -2.0})
    failing = dataclasses.replace(raw_fail, subsystems=[sub, raw_fail.subsystems[1]])
    with pytest.raises(wc.RunFailed) as info:
        wc.simulate(failing, reference=False)
    assert info.value.exit_code == 3 and isinstance(info.value.error, wc.FmuError)
    assert info.value.result.summary["steps"] == 18 and len(info.value.result.trajectory) == 19
