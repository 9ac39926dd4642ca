"""The scripts in examples/ run as a user runs them (headless) and print what they promise."""
import subprocess
import sys
from paths import ROOT



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
