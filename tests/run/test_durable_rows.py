"""A supervised run's rows are durable as they are committed: a child that dies with no chance to
write them (the FaultySide test FMU calls _exit(3), or closes every file descriptor of its process and
segfaults, at step 2500 of 3000) keeps every step it committed, the kernel call in progress included.
Each: the exit code, one line, the rows bit for bit those of the same run without the fault (the
steps' columns that a block's Python observers fill after the block left empty in the rows of the
block in progress), and nothing left in the temporary folder. A durable run writes the same files
as one in the command's own process."""
import json
import os
import signal
import subprocess
import time

import pytest
import yaml

from paths import CLI

STEP = 2500


def wavecosim(folder, raw, *options, env=None):
    """`wavecosim run` of the scenario `raw` into folder/out, with a temporary folder of its own:
    (process, out folder, temporary folder)."""
    folder.mkdir(exist_ok=True)
    (folder / "scenario.yaml").write_text(yaml.safe_dump(raw, sort_keys=False))
    temp = folder / "temp"
    temp.mkdir(exist_ok=True)
    proc = subprocess.run([*CLI, "run", "scenario.yaml", "--out", "out", "--quiet", *options], cwd=folder,
                          env={**os.environ, "TMPDIR": str(temp), **(env or {})}, capture_output=True, text=True,
                          timeout=120)
    return proc, folder / "out", temp


def rows(path):
    return path.read_bytes().split(b"\r\n")[1:-1]


def one_line(proc, code):
    lines = [ln for ln in proc.stderr.strip().splitlines() if not ln.startswith("wavecosim: building")]
    assert proc.returncode == code and len(lines) == 1 and "Traceback" not in proc.stderr, proc.stderr
    return lines[0]


@pytest.fixture(scope="module")
def uninterrupted(tmp_path_factory, faulty_scenario):
    """The same runs without the fault, with and without the reference: {options: out folder}."""
    out = {}
    for options in [(), ("--no-reference",)]:
        proc, out[options], _ = wavecosim(tmp_path_factory.mktemp("whole"), faulty_scenario(), *options)
        assert proc.returncode == 0, proc.stderr
    return out


def kept(out, whole, suffix="", late=()):
    """The steps summary.json says are kept, each row on disk that of the uninterrupted run (the
    columns `late` empty or the same)."""
    steps = json.loads((out / f"summary{suffix}.json").read_text())["steps"]
    assert rows(out / f"trajectory{suffix}.csv") == rows(whole / f"trajectory{suffix}.csv")[:steps + 1]
    header = (out / f"steps{suffix}.csv").read_bytes().split(b"\r\n")[0].split(b",")
    got, want = rows(out / f"steps{suffix}.csv"), rows(whole / f"steps{suffix}.csv")[:steps]
    assert len(got) == len(want)
    for a, b in zip(got, want):
        for name, x, y in zip(header, a.split(b","), b.split(b",")):
            assert x == y or (name.decode() in late and x == b""), (name, x, y)
    return steps


@pytest.mark.parametrize("step", [STEP, 50], ids=["in-a-block-filled-again", "in-the-first-block"])
def test_an_exit_no_handler_sees_keeps_the_kernel_call_in_progress(step, tmp_path, faulty_scenario, uninterrupted):
    """_exit(3) inside a kernel call of 1024 steps: the rows its C pass counted, up to the step before."""
    proc, out, temp = wavecosim(tmp_path, faulty_scenario(18, step), "--no-reference")
    assert one_line(proc, 5) == f"error: the FMU ended the process with exit(3); {step} steps kept"
    late = ("interface_energy", "ledger", "scale", "ledger_action", "ledger_rounds", "gamma_A", "gamma_B",
            "fne_watch", "fne_A", "fne_B", "augmented")
    assert kept(out, uninterrupted[("--no-reference",)], late=late) == step
    assert list(temp.iterdir()) == []


def test_an_fmu_that_closes_every_descriptor_keeps_every_committed_row(tmp_path, faulty_scenario, uninterrupted):
    """Every descriptor closed (the output files, the rescue's pipe, the output to the parent), then
    SIGSEGV: the child cannot write; its parent writes the rows both runs committed (the reference,
    which runs ahead and faults at STEP, step by step; the run itself in blocks behind it)."""
    proc, out, temp = wavecosim(tmp_path, faulty_scenario(19, STEP))
    line = one_line(proc, 5)
    steps = kept(out, uninterrupted[()])
    assert line == f"error: subsystem B: the FMU crashed (SIGSEGV: segmentation fault) in fmi2DoStep; {steps} steps kept"
    assert kept(out, uninterrupted[()], "_monolithic") == STEP and 1024 <= steps <= STEP
    assert list(temp.iterdir()) == []


def test_a_durable_run_writes_what_an_unsupervised_one_writes(tmp_path, faulty_scenario, uninterrupted):
    """The kernel's passes after every step (counting the rows) give the bits of its passes over
    many steps at once."""
    proc, out, _ = wavecosim(tmp_path, faulty_scenario(), "--no-reference", env={"WAVECOSIM_IN_PROCESS": "1"})
    assert proc.returncode == 0, proc.stderr
    whole = uninterrupted[("--no-reference",)]
    for name in ("trajectory.csv", "steps.csv"):
        assert (out / name).read_bytes() == (whole / name).read_bytes()


@pytest.mark.slow
def test_the_texts_of_string_outputs_are_kept_too(tmp_path):
    """A process killed outright while its String output's texts go on (SignalSource's label): the rows
    its parent writes from the shared memory give them as the run writes them."""
    raw = {"name": "typed", "dt": 0.05, "T": 1000.0, "outputs": {"label": "src.label", "count": "src.count"},
           "subsystems": {"src": {"fmu": "SignalSource", "integers": {"period": 3}}}}
    whole, _, _ = wavecosim(tmp_path / "whole", raw)
    assert whole.returncode == 0, whole.stderr
    (tmp_path / "killed").mkdir()
    (tmp_path / "killed" / "scenario.yaml").write_text(yaml.safe_dump({**raw, "T": 5000.0}, sort_keys=False))
    proc = subprocess.Popen([*CLI, "run", "scenario.yaml", "--out", "out", "--quiet"], cwd=tmp_path / "killed",
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    trajectory = tmp_path / "killed" / "out" / "trajectory.csv"
    while not (trajectory.exists() and trajectory.stat().st_size > 1000) and proc.poll() is None:
        time.sleep(0.05)
    time.sleep(0.2)                                    # rows committed since the last hand-over to the writer
    os.kill(int(open(f"/proc/{proc.pid}/task/{proc.pid}/children").read().split()[0]), signal.SIGKILL)
    _, err = proc.communicate(timeout=60)
    assert proc.returncode == 5 and err.startswith("error: the run crashed (SIGKILL)"), err
    got = rows(trajectory)
    assert 1024 < len(got) <= 20_001 and got == rows(tmp_path / "whole" / "out" / "trajectory.csv")[:len(got)]
    assert {row.split(b",", 1)[1].rsplit(b",", 1)[0] for row in got} == {b'"low"', b'"high, ""on"""'}
