"""Inputs that would wrap, overflow, run forever or exhaust memory are one-line ConfigErrors (exit 2),
found before anything is opened or allocated."""
import copy
import subprocess
import time

import pytest
import yaml

from paths import CLI
from wavecosim.api import simulate
from wavecosim.errors import ConfigError
from wavecosim.scenario.config import DEFAULT_CONFIG, load_raw, parse_scenario

BASE = yaml.safe_load(DEFAULT_CONFIG.read_text())


def scenario_file(tmp_path, change):
    raw = copy.deepcopy(BASE)
    change(raw)
    path = tmp_path / "s.yaml"
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


@pytest.mark.parametrize("change, message", [
    (lambda r: r["subsystems"]["A"].update(integers={"newton_max_iter": 10 ** 12}),
     "subsystems.A.integers.newton_max_iter: must be <= 2147483647, got 1000000000000"),
    (lambda r: r.update(dt=5e-324), "T: dt = 5e-324 is too small for T = 10.0 (inf steps; at most 1e+15)"),
    (lambda r: r.update(couplings=[{"type": "dirac", "ports": ["A", "B"], "E": [[1.0, 0.0], [0.0]],
                                    "F": [[0.0, 1.0], [1.0, 0.0]]}]),
     "couplings[0].E[1]: has 1 entries, row 0 has 2: a matrix has rows of one length"),
    (lambda r: r.update(step_timeout=0), "step_timeout: must be > 0, got 0.0"),
])
def test_a_bad_number_is_one_line(tmp_path, change, message):
    path = scenario_file(tmp_path, change)
    with pytest.raises(ConfigError) as info:
        parse_scenario(load_raw(path), str(path), path.parent)
    assert str(info.value) == f"{path}: {message}"


def test_a_huge_value_is_quoted_in_a_few_hundred_characters(tmp_path):
    path = scenario_file(tmp_path, lambda r: r["master"].update(K="k" * 1_000_000))
    with pytest.raises(ConfigError) as info:
        parse_scenario(load_raw(path), str(path), path.parent)
    text = str(info.value)
    assert len(text) < len(str(path)) + 500 and text.startswith(f"{path}: master.K: must be an integer, got 'kkk")
    assert "characters left out" in text and "\n" not in text


def test_a_billion_laughs_yaml_is_refused_before_it_is_expanded(tmp_path):
    lines = ["a0: &a0 [x, x, x, x, x, x, x, x, x, x]"]
    lines += [f"a{i}: &a{i} [{', '.join([f'*a{i - 1}'] * 10)}]" for i in range(1, 10)]
    path = tmp_path / "laughs.yaml"
    path.write_text("\n".join(lines + ["dt: *a9"]) + "\n")
    started = time.perf_counter()
    proc = subprocess.run([*CLI, "validate", str(path)], capture_output=True, text=True, timeout=60)
    assert proc.returncode == 2 and proc.stderr.strip() == (
        f"error: {path}: its anchors and aliases expand to more than 1,000,000 values (refused before expanding it)")
    assert time.perf_counter() - started < 30


@pytest.mark.parametrize("options, message", [
    (["--dt", "nan"], "error: Invalid value for '--dt': 'nan' is not a finite number"),
    (["--T", "inf"], "error: Invalid value for '--T': 'inf' is not a finite number"),
    (["--T", "1e7"], "macro-steps, over the limit of 100,000,000 (pass --force, or max_steps=None in Python, "
                     "to run it anyway)")])
def test_bad_or_huge_runs_from_the_command_line(tmp_path, options, message):
    proc = subprocess.run([*CLI, "run", *options, "--out", str(tmp_path / "out"), "--quiet"], capture_output=True,
                          text=True, timeout=60)
    assert proc.returncode == 2 and proc.stderr.strip().endswith(message), proc.stderr
    assert not (tmp_path / "out").exists()


def test_the_step_limit_is_checked_before_anything_is_opened(monkeypatch):
    import wavecosim.run.parts as parts
    monkeypatch.setattr(parts, "build_scene", lambda *a, **k: pytest.fail("a scene was built"))
    with pytest.raises(ConfigError, match="1,000,000,000 macro-steps, over the limit of 100,000,000"):
        simulate(T=1e7)
