"""Errors wherever there is a reference: a run whose scenario names no `error` columns is measured
over every recorded Real output, each column's largest |Δy| divided by its range in the reference;
`error` columns still override."""
import csv
import json
import subprocess

import numpy as np
import pytest

import wavecosim as wc
from paths import CLI, CONFIGS, THIRD_PARTY
from wavecosim.run.observers.errors import column_scales

DCMOTOR = THIRD_PARTY / "dcmotor" / "SystemStructure.ssd"


def _table(path):
    with open(path, newline="") as f:
        rows = list(csv.reader(f))
    return {name: np.array([float(r[j]) for r in rows[1:]]) for j, name in enumerate(rows[0])}


def expected_errors(ours, ref):
    """{column: max |Δy| / the column's range in the reference} from two trajectories."""
    out = {}
    for name in ours:
        if name == "time":
            continue
        d, y = np.abs(ours[name] - ref[name]), ref[name]
        scale = column_scales(np.array([y.min()]), np.array([y.max()]), np.array([np.abs(y).max()]))[0]
        out[name] = float(d.max() / scale)
    return out


def test_a_column_is_scaled_by_its_range_or_its_size_when_constant():
    scales = column_scales(np.array([-2.0, 5.0, 5.0, 0.0]), np.array([3.0, 5.0, 5.0 + 1e-14, 0.0]),
                           np.array([3.0, 5.0, 5.0 + 1e-14, 0.0]))
    assert scales.tolist() == [5.0, 5.0, 5.0 + 1e-14, 1.0]


def test_a_run_without_error_columns_has_every_real_outputs_error(tmp_path):
    scenario = wc.load(CONFIGS / "two_oscillators.yaml", T=0.2, K=3).with_changes(error=[])
    result = wc.simulate(scenario, out_dir=tmp_path, warn=lambda m: None)
    s = json.loads((tmp_path / "summary.json").read_text())
    expected = expected_errors(_table(tmp_path / "trajectory.csv"), _table(tmp_path / "trajectory_monolithic.csv"))
    assert set(s["errors"]) == set(expected) == set(result.trajectory.dtype.names[1:])
    for name, value in expected.items():
        assert s["errors"][name] == pytest.approx(value, rel=1e-6, abs=1e-300), name
    assert s["max_error"] == max(s["errors"].values()) > 1e-6          # K = 3: far from the reference
    assert "error" not in result.steps_table.columns


def test_error_columns_still_override_the_figures(tmp_path):
    result = wc.simulate(wc.load(CONFIGS / "two_oscillators.yaml", T=0.2, K=3), warn=lambda m: None)
    s = result.summary
    assert s["max_error"] == float(np.nanmax(result.steps["error"])) != max(s["errors"].values())
    assert set(s["errors"]) == set(result.trajectory.dtype.names[1:])


def test_dr_on_the_in_repo_ssd_writes_max_error_and_every_columns_error(tmp_path):
    out = tmp_path / "out"
    done = subprocess.run([*CLI, "run", str(CONFIGS / "two_oscillators.ssd"), "--master", "dr", "--K", "3",
                           "--T", "0.2", "--out", str(out)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    s = json.loads((out / "summary.json").read_text())
    expected = expected_errors(_table(out / "trajectory.csv"), _table(out / "trajectory_monolithic.csv"))
    assert set(s["errors"]) == set(expected) == {"q1", "v1", "d", "q2", "v2", "bA", "bB"}
    for name, value in expected.items():
        assert s["errors"][name] == pytest.approx(value, rel=1e-6, abs=1e-300), name
    assert s["max_error"] > 0


@pytest.mark.skipif(not DCMOTOR.exists(), reason="the third-party dcmotor is not here")
def test_dr_on_an_ssd_with_power_bonds_writes_its_errors(tmp_path):
    ports = tmp_path / "ports.yaml"            # the shipped overlay without its `error` columns
    ports.write_text("".join(line for line in (CONFIGS / "dcmotor_ports.yaml").read_text().splitlines(True)
                             if not line.startswith("error:")))
    out = tmp_path / "out"
    done = subprocess.run([*CLI, "run", str(DCMOTOR), "--ports", str(ports), "--master", "dr", "--T", "0.03",
                           "--out", str(out)], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    s = json.loads((out / "summary.json").read_text())
    expected = expected_errors(_table(out / "trajectory.csv"), _table(out / "trajectory_monolithic.csv"))
    assert set(s["errors"]) == {"w", "M", "I", "U"} == set(expected)
    for name, value in expected.items():
        assert s["errors"][name] == pytest.approx(value, rel=1e-6, abs=1e-300), name
    assert 0 < s["max_error"] == max(s["errors"].values()) < 1e-3


@pytest.mark.slow
@pytest.mark.skipif(not DCMOTOR.exists(), reason="the third-party dcmotor is not here")
def test_sweep_and_compare_report_the_same_errors_on_an_ssd(tmp_path):
    ports = tmp_path / "ports.yaml"
    ports.write_text("".join(line for line in (CONFIGS / "dcmotor_ports.yaml").read_text().splitlines(True)
                             if not line.startswith("error:")))
    common = [str(DCMOTOR), "--ports", str(ports), "--T", "0.01", "--quiet"]
    for command, ks in (("sweep", "--K"), ("compare", "--Ks")):
        done = subprocess.run([*CLI, command, *common, ks, "2", "--out", str(tmp_path / command),
                               *(["--masters", "dr"] if command == "compare" else [])],
                              capture_output=True, text=True, timeout=120)
        assert done.returncode == 0, done.stderr
    swept = json.loads((tmp_path / "sweep" / "summary.json").read_text())["runs"][0]
    compared = json.loads((tmp_path / "compare" / "compare.json").read_text())["runs"][0]
    assert swept["errors"] == compared["errors"] and set(swept["errors"]) == {"w", "M", "I", "U"}
    assert swept["max_error"] == compared["max_error"] == max(swept["errors"].values()) > 0
