"""Hostile input is refused in one line with exit code 2, before anything is read whole or run: numbers
that are not finite or do not fit a C int, nesting too deep, files that are special, loop or are too
big, sweeps too large, a scheduler address that is not one. Each case is a real command line."""
import os
import subprocess

import pytest

from paths import CLI, CONFIGS

SCENARIO = CONFIGS / "two_oscillators.yaml"
FAST = ["--T", "0.01", "--no-reference", "--quiet", "--out", "out"]


def scenario_with(folder, old, new, name):
    """The paper's scenario file with one text replaced, written into folder."""
    text = SCENARIO.read_text()
    assert old in text
    (folder / name).write_text(text.replace(old, new))
    return name


def nested(folder):
    (folder / "nested.yaml").write_text("a: " + "[" * 5000 + "]" * 5000 + "\n")
    return ["validate", "nested.yaml"]


def aliased(folder):
    """Anchors each nesting the one before 60 levels down: shallow as written, 2400 levels deep."""
    lines = ["a0: &a0 " + "[" * 60 + "1" + "]" * 60]
    lines += [f"a{i}: &a{i} " + "[" * 60 + f"*a{i - 1}" + "]" * 60 for i in range(1, 40)]
    (folder / "aliased.yaml").write_text("\n".join(lines) + "\n")
    return ["validate", "aliased.yaml"]


def huge_table(folder):
    """A 1 GB time table as a sparse file: nothing of it is written, and nothing read."""
    with open(folder / "big.csv", "wb") as f:
        f.truncate(1 << 30)
    (folder / "big.yaml").write_text(SCENARIO.read_text() + "sources:\n  table: {csv: big.csv}\n")
    return ["validate", "big.yaml"]


def fifo(folder):
    os.mkfifo(folder / "pipe.fmu")
    return ["validate", scenario_with(folder, "fmu: DuffingSide", "fmu: pipe.fmu", "fifo.yaml")]


def loop(folder):
    os.symlink("loop.fmu", folder / "loop.fmu")
    return ["run", "loop.fmu", *FAST]


CASES = {
    "K-overflow": lambda f: ["run", str(SCENARIO), "--K", "99999999999999999999", *FAST],
    "interval-overflow": lambda f: ["run", str(SCENARIO), "--output-interval", "99999999999999999999", *FAST],
    "eps-inf": lambda f: ["run", str(SCENARIO), "--eps", "inf", *FAST],
    "timeout-nan": lambda f: ["run", str(SCENARIO), "--step-timeout", "nan", *FAST],
    "nested-yaml": nested,
    "aliased-yaml": aliased,
    "negative-seed": lambda f: ["validate", scenario_with(f, "fne_seed: 1", "fne_seed: -1", "seed.yaml")],
    "K-in-file": lambda f: ["validate", scenario_with(f, "K: 50", "K: 99999999999999999999", "big_k.yaml")],
    "sweep-missing-file": lambda f: ["sweep", "missing.yaml", "--set", "master.K=1,2", "--out", "out"],
    "scheduler-garbage": lambda f: ["sweep", str(SCENARIO), "--set", "master.K=1", "--scheduler", "garbage"],
    "huge-table": huge_table,
    "Ks-overflow": lambda f: ["compare", str(SCENARIO), "--Ks", "0,99999999999999999999", "--out", "out"],
    "huge-range": lambda f: ["sweep", str(SCENARIO), "--set", "master.K=0..1000000", "--out", "out"],
    "huge-linspace": lambda f: ["sweep", str(SCENARIO), "--set", "master.eps=linspace(0.1,1,100000000)"],
    "huge-grid": lambda f: ["sweep", str(SCENARIO), "--set", "master.K=0..999", "--set", "master.anderson=0..999"],
    "symlink-loop": loop,
    "device": lambda f: ["validate", scenario_with(f, "fmu: DuffingSide", "fmu: /dev/zero", "zero.yaml")],
    "fifo": fifo,
}


@pytest.mark.parametrize("case", list(CASES))
def test_hostile_input_is_refused_in_one_line(case, tmp_path, built_fmus):
    args = CASES[case](tmp_path)
    done = subprocess.run(CLI + args, cwd=tmp_path, capture_output=True, text=True, timeout=60)
    lines = done.stderr.strip().splitlines()
    assert done.returncode == 2, done.stderr[-2000:]
    assert len(lines) == 1 and lines[0].startswith("error: ") and "Traceback" not in done.stderr, done.stderr
    assert not (tmp_path / "out" / "summary.json").exists()


@pytest.mark.slow
def test_an_unreachable_scheduler_is_one_line_after_the_stated_timeout(tmp_path, built_fmus):
    args = ["sweep", str(SCENARIO), "--set", "master.K=1", "--T", "0.01", "--scheduler", "tcp://127.0.0.1:1", "--quiet"]
    done = subprocess.run(CLI + args, cwd=tmp_path, capture_output=True, text=True, timeout=60)
    assert done.returncode == 2 and "Traceback" not in done.stderr, done.stderr[-2000:]
    assert done.stderr.strip() == ("error: --scheduler tcp://127.0.0.1:1: no Dask scheduler answered within 10 s "
                                   "(OSError)")


def test_the_api_takes_numpy_numbers(built_fmus):
    import numpy as np

    import wavecosim as wc
    result = wc.simulate(None, K=np.int64(5), eps=np.float64(1e-9), T=np.float64(0.02), reference=False)
    assert result.summary["K"] == 5 and type(result.summary["K"]) is int and result.summary["steps"] == 2
    with pytest.raises(wc.ConfigError, match="K: must be <= 2147483647"):
        wc.simulate(None, K=np.int64(2 ** 40))
    table = wc.sweep(None, np.array([0, 3]), T=0.02, certificates=False)
    assert [type(r["K"]) for r in table.rows] == [int, int] and [r["K"] for r in table.rows] == [0, 3]
