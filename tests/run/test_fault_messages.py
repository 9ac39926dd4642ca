"""Errors named for what failed, with the subsystem that caused it: an FMU's message formatted with its
printf arguments, a NaN an FMU gave named as a NaN from that FMU (not a singular matrix or the other
subsystem's refused input), a broken restore named as one. FaultySide (models/faulty_side) faults 15-17."""
import json

import pytest
import yaml

from wavecosim.cli import main


def run_cli(tmp_path, raw, capsys, *extra):
    scenario = tmp_path / "scenario.yaml"
    scenario.write_text(yaml.safe_dump(raw, sort_keys=False))
    with pytest.raises(SystemExit) as info:
        main(["run", str(scenario), "--out", str(tmp_path / "out"), "--quiet", "--no-reference", *extra])
    _, err = capsys.readouterr()
    lines = [line for line in err.strip().splitlines() if not line.startswith("warning: ")]
    assert len(lines) == 1 and "Traceback" not in err, err
    return info.value.code, lines[0]


def steps_kept(tmp_path):
    return json.loads((tmp_path / "out" / "summary.json").read_text())["steps"]


def test_an_fmu_message_is_formatted_with_its_printf_arguments(tmp_path, capsys, faulty_scenario):
    """FaultySide logs "fmi2DoStep failed: %s at t = %g" with its arguments, as the FMI logger's contract
    has it: the line shows the text, not the format."""
    code, line = run_cli(tmp_path, faulty_scenario(15, 3, T=0.1), capsys)
    assert code == 3
    assert line == ("error: subsystem B: fmi2DoStep returned Error at step 3 (t = 0.03): fmi2DoStep failed: "
                    "the spring broke at t = 0.03")
    assert steps_kept(tmp_path) == 3


@pytest.mark.parametrize("master", ["newton", "dr", "jacobi-iter"])
def test_a_nan_is_named_for_the_fmu_that_gave_it(master, tmp_path, capsys, faulty_scenario):
    """B's FMU returns NaN outputs with status OK at step 3: the NaN reaches the interface Newton (a
    non-finite residual) or A (which refuses it as an input); the line names B as its maker, exit 4."""
    code, line = run_cli(tmp_path, faulty_scenario(16, 3, T=0.1), capsys, "--master", master)
    assert code == 4, line
    assert line.startswith("error: ") and "subsystem B" in line and "non-finite" in line
    assert "singular" not in line and not line.startswith("error: subsystem A")
    assert steps_kept(tmp_path) == 3


def test_a_broken_restore_is_named_as_one(tmp_path, capsys, faulty_scenario):
    """B's restore is off by a little from the start (fault 17): the set-up probe measures it, and the
    interface solve that cannot converge says why."""
    code, line = run_cli(tmp_path, faulty_scenario(17, 0, T=0.1), capsys, "--master", "newton")
    assert code == 4
    assert line.startswith("error: subsystem B: its FMU does not restore its state (fmi2SetFMUstate off by ")
    assert "did not converge" in line


@pytest.mark.parametrize("fast", ["true", "false"], ids=["kernel", "python"])
def test_a_restore_that_breaks_during_the_run_is_named_as_one(fast, tmp_path, capsys, faulty_scenario):
    """B's restore holds at the set-up probe and breaks from step 5 on (fault 17): the step made twice
    from the saved state tells why the interface Newton cannot converge, on either route."""
    code, line = run_cli(tmp_path, faulty_scenario(17, 5, T=0.1), capsys, "--master", "newton",
                         "--set", f"master.fast={fast}")
    assert code == 4, line
    assert line.startswith("error: subsystem B: its FMU does not restore its state (the same step made twice "
                           "from its saved state gave outputs "), line
