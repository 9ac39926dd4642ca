"""The scripts in examples/ run as a user runs them (headless) and print what they promise."""
import os
import re
import subprocess
import sys

from paths import CLI, ROOT, THIRD_PARTY
from wavecosim import examples



def run_example(name, *args, cwd=None):
    proc = subprocess.run([sys.executable, str(ROOT / "examples" / name), *map(str, args)], capture_output=True,
                          text=True, cwd=cwd, env={"MPLBACKEND": "Agg", "PATH": "/usr/bin:/bin"}, timeout=300)
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_sweep_example_draws_error_against_budget_and_calls(tmp_path):
    out = run_example("sweep_budget.py", tmp_path / "fig.png", cwd=tmp_path)
    lines = [ln for ln in out.splitlines() if ln.startswith("K =")]
    errors = [float(ln.split("max error ")[1].split(",")[0]) for ln in lines]
    assert len(lines) == 7 and errors[-1] < 1e-9 < errors[0]
    assert (tmp_path / "fig.png").stat().st_size > 10_000


def test_own_fmu_example_reads_the_result_as_arrays(tmp_path):
    out = run_example("own_fmu.py", cwd=tmp_path)
    assert out.startswith("101 rows, fields ('time', 'q1', 'q2')")


def python_elsewhere(code, cwd):
    """stdout of `python -c code` run in `cwd` (no scenario file there), with the tests' environment."""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=cwd, timeout=120,
                          env={**os.environ, "MPLBACKEND": "Agg"})
    assert proc.returncode == 0, proc.stderr
    return proc.stdout


def test_a_built_in_example_runs_by_name_from_any_folder(tmp_path, built_fmus):
    out = python_elsewhere("import wavecosim as wc\n"
                           "r = wc.simulate('two_oscillators', T=0.1)\n"
                           "s = wc.simulate('two_oscillators.ssd', T=0.1)\n"
                           "print(r.summary['steps'], r.summary['scenario'], s.summary['max_error'] == "
                           "r.summary['max_error'])", tmp_path)
    assert out.split() == ["10", "two_oscillators", "True"]
    assert list(tmp_path.iterdir()) == []
    run = subprocess.run(CLI + ["validate", "two_oscillators_stiff"], capture_output=True, text=True, cwd=tmp_path,
                         timeout=120)
    assert run.returncode == 0 and "two_oscillators_stiff.yaml: OK (2 subsystems, 2 channels" in run.stdout


def test_the_examples_list_says_what_each_is_and_what_it_needs_when_it_cannot_run():
    out = subprocess.run(CLI + ["examples"], capture_output=True, text=True, timeout=60, check=True).stdout
    runnable, _, lacking = out.partition("\nnot runnable here:\n")
    rows = {ln.split()[0]: ln.split(None, 1)[1] for ln in runnable.splitlines()}
    assert rows["two_oscillators"] == "Linear-Duffing coupled oscillators, paper Table I"
    assert rows["two_oscillators.ssd"] == "Linear-Duffing coupled oscillators, paper Table I"
    assert all(rows.values()) and "dcmotor_ports" not in rows
    assert ("dcmotor_ports          The shaft's power ports and the run's settings for OMSimulator's dcmotor SSD "
            "(an overlay, --ports)\n                       needs an SSP system: it is a --ports overlay") in lacking
    assert ("dcmotor" in rows) == THIRD_PARTY.is_dir()


def test_an_example_whose_fmu_file_is_absent_names_it(tmp_path, monkeypatch):
    (tmp_path / "lonely.yaml").write_text("# A mass alone\nname: lonely\nsubsystems:\n"
                                          "  A: {fmu: ../elsewhere/Mass.fmu}\n  B: {fmu: LinearSide}\n")
    monkeypatch.setattr(examples, "CONFIGS", tmp_path)
    assert examples.describe("lonely") == {"name": "lonely", "description": "A mass alone",
                                           "needs": "Mass.fmu in ../elsewhere (FMUs not installed with the "
                                                    "package)"}
    (tmp_path.parent / "elsewhere").mkdir()
    (tmp_path.parent / "elsewhere" / "Mass.fmu").write_bytes(b"PK")
    assert examples.describe("lonely")["needs"] == ""


def test_the_readmes_python_block_runs_from_an_empty_folder(tmp_path, built_fmus):
    block = re.search(r"```python\n(.*?)```", (ROOT / "README.md").read_text(encoding="utf-8"), re.S).group(1)
    python_elsewhere(block, tmp_path)
    assert list(tmp_path.iterdir()) == []
