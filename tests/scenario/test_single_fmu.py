"""One FMU alone (`wavecosim run X.fmu`), on FMUs built here: the times from its DefaultExperiment,
its inputs at their start values or from a CSV file in the FMI cross-check format, every value
equal to a plain fmpy loop with fmpy's Input; clear one-line refusals."""
import subprocess
import zipfile

import fmpy

import numpy as np
import pytest

from conftest import fmpy_loop, input_signals, same_bits
from paths import CLI, THIRD_PARTY
import wavecosim as wc

INPUT = ('"time", "u", "n", "on"\n'          # quoted names, spaces after the commas
         '0, 0, 1, false\n0.5, 1, 2, false\n0.5, 4, 3, true\n'    # an event at 0.5 s: the time given twice
         '0.75, -2, 5, TRUE\n2, 0, 7, false\n')


def cli(*args, timeout=120):
    proc = subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True, timeout=timeout)
    return proc.returncode, proc.stdout, proc.stderr


def test_an_fmu_with_an_input_file_equals_a_plain_fmpy_loop(built_fmus, tmp_path):
    path = built_fmus["SignalSink"]
    (tmp_path / "in.csv").write_text(INPUT)
    code, _, err = cli("run", path, "--input", tmp_path / "in.csv", "--dt", "0.1", "--quiet", "--out", tmp_path / "o")
    assert code == 0 and "text of SignalSink.fmu; they keep their start values" in err, err
    sc = wc.load(path, input=tmp_path / "in.csv", dt=0.1, warn=lambda m: None)
    assert (sc.start_time, sc.T, sc.master.algorithm, sc.gamma) == (0.0, 2.0, "explicit", None)
    result = wc.simulate(sc)
    names = ["u", "integral", "scaled", "n", "shifted", "length", "on", "off", "echo"]
    expected = fmpy_loop(path, 0.1, 20, names, signals=input_signals(tmp_path / "in.csv"), unzipdir=str(tmp_path / "s"))
    assert same_bits(result, "SignalSink", expected)
    n, on = result.trajectory["SignalSink.n"], result.trajectory["SignalSink.on"]
    assert (n[5], on[5], n[6], on[6]) == (1, 0, 3, 1)         # held over the step at 0.5 s: after the event
    assert (tmp_path / "o" / "trajectory.csv").read_text().splitlines()[0] == \
        "time,SignalSink.u,SignalSink.integral,SignalSink.scaled,SignalSink.n,SignalSink.shifted,SignalSink.length," \
        "SignalSink.on,SignalSink.off,SignalSink.echo"


def test_an_fmu_alone_keeps_its_inputs_at_their_start_values(built_fmus):
    result = wc.simulate(built_fmus["SignalSource"])
    assert result.summary["steps"] == 40 and result.reference is None
    assert np.array_equal(result.trajectory["SignalSource.count"], np.arange(41))


def test_a_column_that_names_no_input_is_refused_naming_the_closest(built_fmus, tmp_path):
    (tmp_path / "in.csv").write_text("time,u,txt\n0,1,a\n1,1,b\n")
    code, _, err = cli("run", built_fmus["SignalSink"], "--input", tmp_path / "in.csv", "--dt", "0.5", "--quiet",
                       "--out", tmp_path / "o")
    assert code == 2 and err.splitlines() == ["error: --input: in.csv: column 'txt' names no input of SignalSink.fmu "
                                              "(did you mean text?)"], err
    assert not (tmp_path / "o").exists()


def test_a_library_not_named_after_the_model_identifier_says_so(built_fmus, tmp_path):
    renamed = tmp_path / "Renamed.fmu"
    with zipfile.ZipFile(built_fmus["SignalSource"]) as src, zipfile.ZipFile(renamed, "w") as dst:
        for item in src.infolist():
            dst.writestr(item.filename.replace("SignalSource.so", "signal_source.so"), src.read(item))
    code, out, err = cli("run", renamed, "--quiet", "--out", tmp_path / "o")
    assert code == 2 and len(err.strip().splitlines()) == 1, err
    assert "Renamed.fmu: binaries/linux64 holds signal_source.so, but the modelIdentifier 'SignalSource' asks " \
           "for SignalSource.so: the library must be named after the modelIdentifier" in err


BAD = [
    (["run", "{sink}", "--dt", "0.3"], "T: must be a whole number of steps dt = 0.3, got 2.0 (the DefaultExperiment "
                                       "stopTime of SignalSink)"),
    (["run", "{config}", "--input", "{csv}"], "input: only for an FMU (.fmu)"),
    (["run", "{sink}", "--dt", "0.1", "--outputs", "SignalSink.nothing*"], "outputs: 'SignalSink.nothing*' matches no"),
]


@pytest.mark.parametrize("args, needle", BAD, ids=["not-whole", "input-without-fmu", "outputs-match-nothing"])
def test_refusals_are_one_line_with_exit_2(args, needle, built_fmus, tmp_path):
    from paths import CONFIGS
    (tmp_path / "in.csv").write_text("time,u\n0,1\n")
    values = {"sink": built_fmus["SignalSink"], "config": CONFIGS / "two_oscillators.yaml", "csv": tmp_path / "in.csv"}
    code, out, err = cli(*[a.format(**values) for a in args], "--quiet", "--out", tmp_path / "o")
    lines = err.strip().splitlines()
    assert code == 2 and len(lines) == 1 and needle in lines[0], err


def test_an_fmu_without_a_step_size_runs_with_fmpys_default_said_first(built_fmus, tmp_path):
    """SignalSink gives a stopTime of 2 s and no stepSize: fmpy's simulate takes 0.004 s (500 steps)."""
    code, out, err = cli("run", built_fmus["SignalSink"], "--quiet", "--out", tmp_path / "o")
    assert code == 0, err
    assert err.splitlines()[0] == "warning: SignalSink.fmu: dt = 0.004 (fmpy's default for a run of 2 s: 500 steps; " \
                                  "--dt chooses another)", err
    assert "dt=0.004 (fmpy's default)" in out and "T=2.0" in out and len((tmp_path / "o" / "trajectory.csv").read_text().splitlines()) == 502


@pytest.mark.parametrize("kind", ["text", "truncated"])
def test_a_file_that_is_not_an_fmu_says_so_before_anything_else(kind, built_fmus, tmp_path):
    bad = tmp_path / "Bad.fmu"
    if kind == "text":
        bad.write_text("a text file, not an archive\n")
    else:
        bad.write_bytes(built_fmus["SignalSink"].read_bytes()[:2000])
    code, out, err = cli("run", bad, "--quiet", "--out", tmp_path / "o")
    assert code == 3 and err.splitlines() == [f"error: {bad}: not an FMU: not a zip archive (or a truncated one)"], err


BOUNCING = THIRD_PARTY / "fmizoo" / "fmi2" / "BouncingBall1D.fmu"


@pytest.mark.skipif(not BOUNCING.exists(), reason="the third-party FMUs (../shared/third_party) are absent")
def test_an_fmu_without_outputs_records_what_fmpy_records(tmp_path):
    """BouncingBall1D (Dymola) has no outputs: fmpy's simulate records its continuous states."""
    code, _, err = cli("run", BOUNCING, "--quiet", "--out", tmp_path / "o")
    assert code == 0 and "BouncingBall1D: the FMU has no outputs; recording mass_s, mass_v as fmpy does" in err, err
    ours = np.genfromtxt(tmp_path / "o" / "trajectory.csv", delimiter=",", names=True, deletechars="")
    theirs = fmpy.simulate_fmu(str(BOUNCING))
    assert ours.dtype.names == ("time", *(f"BouncingBall1D.{n}" for n in theirs.dtype.names[1:])) == \
        ("time", "BouncingBall1D.mass_s", "BouncingBall1D.mass_v")
    for name in theirs.dtype.names:
        column = name if name == "time" else f"BouncingBall1D.{name}"
        assert np.allclose(ours[column], theirs[name], rtol=1e-9, atol=1e-12)


def test_an_fmu_without_a_default_experiment_runs_a_second_as_fmpy_does(built_fmus, tmp_path):
    bare = tmp_path / "Bare.fmu"
    with zipfile.ZipFile(built_fmus["SignalSink"]) as src, zipfile.ZipFile(bare, "w") as dst:
        for item in src.infolist():
            data = src.read(item)
            if item.filename == "modelDescription.xml":
                data = data.replace(b'<DefaultExperiment startTime="0" stopTime="2"/>', b"")
            dst.writestr(item, data)
    code, out, err = cli("run", bare, "--quiet", "--out", tmp_path / "o")
    assert code == 0 and "dt=0.002 (fmpy's default)" in out and "T=1.0 (fmpy's default)" in out, err
    assert err.splitlines()[:2] == [
        "warning: Bare.fmu: T = 1 (fmpy's default: the start time + 1 s; --T chooses another)",
        "warning: Bare.fmu: dt = 0.002 (fmpy's default for a run of 1 s: 500 steps; --dt chooses another)"], err
