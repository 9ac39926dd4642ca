"""Signal connections and sources on FMUs built here: a CSV table and another FMU's output drive
inputs that are not port variables, sampled at the start of each macro-step and held over it
(to = factor * from + offset). The Oscillator's right channel is left out of the port, so its
incident wave a_right is a free input (a force source behind the impedance gamma); a LinearSide
without a port, stepped once per macro-step, takes A's position as its force."""
import copy
import math

import numpy as np
import pytest

import wavecosim as wc
from scenes import SIGNAL_SCENE
from wavecosim.cli import main
from wavecosim.scenario.config import parse_scenario
from wavecosim.errors import ConfigError
from wavecosim.run.runner import run

DT = 0.01
STEP_AT = 0.05            # the table steps from 0 to 1 here: macro-step 5 is the first to hold 1

BASE = {
    **SIGNAL_SCENE, "dt": DT,
    "sources": {"push": {"csv": "push.csv"}},
    "signals": [{"from": "push.force", "to": "B.a_right"},
                {"from": "A.q1", "to": "S.F", "factor": 2.0, "offset": 0.5}],
    "master": {"algorithm": "dr", "K": 8},
    "outputs": {"q1": "A.q1", "q": "B.q", "held": "B.a_right", "F_S": "S.F", "q_S": "S.q2"},
    "error": ["q1", "q"],
}


@pytest.fixture
def folder(tmp_path):
    (tmp_path / "push.csv").write_text(f"time,force\n0.0,0.0\n{STEP_AT},1.0\n1.0,1.0\n")
    return tmp_path


def scenario(folder, change=None):
    raw = copy.deepcopy(BASE)
    if change:
        change(raw)
    return parse_scenario(raw, "signals.yaml", folder)


def quiet(message):
    """Set-up notes are not under test here."""


def test_a_step_in_the_table_is_held_from_its_own_macro_step(folder):
    """Row t_{n+1} shows the input held over step n: the table's value at t_n. The step at 0.05 s is
    held from macro-step 5 on, so it first shows in the row at 0.06 s, and B's motion leaves the
    motion without the source exactly there."""
    with_push = run(scenario(folder), warn=quiet)
    without = run(scenario(folder, lambda r: r["signals"].pop(0)), warn=quiet)
    t, held = with_push.trajectory["time"], with_push.trajectory["held"]
    first = int(np.argmax(held > 0.5))
    assert t[first] == pytest.approx(STEP_AT + DT) and np.all(held[:first] == 0.0)
    moved = np.flatnonzero(with_push.trajectory["q"] != without.trajectory["q"])
    assert t[moved[0]] == pytest.approx(STEP_AT + DT)


def test_factor_and_offset_scale_the_value_sampled_at_the_start_of_the_step(folder):
    """S.F held over step n is 2 q1(t_n) + 0.5, to the last bit; the signal-only LinearSide moves."""
    traj = run(scenario(folder), warn=quiet).trajectory
    assert np.array_equal(traj["F_S"][1:], 2.0 * traj["q1"][:-1] + 0.5)
    assert abs(traj["q_S"][-1]) > 1e-3


def test_linear_interpolation_between_table_rows(folder):
    (folder / "ramp.csv").write_text("time,force\n0.0,0.0\n1.0,10.0\n")

    def ramp(raw):
        raw["sources"] = {"push": {"csv": "ramp.csv", "interpolation": "linear"}}
    traj = run(scenario(folder, ramp), warn=quiet).trajectory
    assert np.allclose(traj["held"][1:], 10.0 * traj["time"][:-1], rtol=0, atol=1e-12)


def test_fast_path_equals_the_python_reference_with_signals(folder):
    """The kernel holds the signals itself in its blocks of steps (kernel/c/signals.c); every number
    equals the Python reference's."""
    fast = run(scenario(folder), reference="lockstep", warn=quiet)
    slow = run(scenario(folder, lambda r: r["master"].update(fast=False)), reference="lockstep", warn=quiet)
    assert fast.summary["fast_path"] and not slow.summary["fast_path"]
    assert fast.summary["fast_note"] == "C kernel" and fast.summary["block_steps"] > 0
    for name in ("trajectory", "steps"):
        a, b = getattr(fast, name), getattr(slow, name)
        for field in a.dtype.names:
            assert np.array_equal(a[field], b[field], equal_nan=field != "reason"), field
    assert fast.summary["max_error"] < 1e-2
    assert fast.summary["signal_driven_subsystems"] == ["B", "S"] and "not a passivity" in fast.summary["signal_note"]


@pytest.mark.parametrize("master", ["explicit", "gauss-seidel", "jacobi-iter", "newton"])
def test_every_master_holds_the_signals(folder, master):
    """Physical masters run B in physical mode, where its right force input is F_right."""
    def physical(raw):
        raw["master"] = {"algorithm": master, "K": 3}
        if master != "newton":
            raw["signals"][0]["to"] = "B.F_right"
            raw["outputs"]["held"] = "B.F_right"
    traj = run(scenario(folder, physical), warn=quiet).trajectory
    assert traj["held"][int(round((STEP_AT + DT) / DT))] == 1.0
    assert np.array_equal(traj["F_S"][1:], 2.0 * traj["q1"][:-1] + 0.5)


def _table(text):
    def change(raw):
        raw["sources"] = {"push": {"csv": "bad.csv"}}
        raw["_table"] = text
    return change


BAD = [
    ("unknown-subsystem", lambda r: r["signals"][1].update({"from": "Z.q1"}),
     "signals[1].from: 'Z.q1' names no subsystem or source (have: A, B, S, push)"),
    ("unknown-target", lambda r: r["signals"][1].update({"to": "push.force"}),
     "signals[1].to: 'push.force' names no subsystem (have: A, B, S)"),
    ("unknown-column", lambda r: r["signals"][0].update({"from": "push.torque"}),
     "signals[0].from: source push has no column 'torque' (have: force)"),
    ("no-dot", lambda r: r["signals"][0].update({"from": "push"}),
     "signals[0].from: must be SUBSYSTEM.variable or SOURCE.column, got 'push'"),
    ("factor-nan", lambda r: r["signals"][1].update({"factor": math.nan}), "signals[1].factor: must be finite"),
    ("factor-text", lambda r: r["signals"][1].update({"factor": "two"}), "signals[1].factor: must be a number"),
    ("unknown-key", lambda r: r["signals"][1].update({"gain": 2}), "signals[1].gain: unknown key"),
    ("port-variable", lambda r: r["signals"][1].update({"to": "B.a_left"}),
     "signals[1].to: B.a_left is a port variable of B, so a signal cannot drive it"),
    ("start-value", lambda r: r["subsystems"]["S"].update({"start": {"F": 1.0}}),
     "signals[1].to: S.F is driven by a signal, so it cannot also have a start value (subsystems.S.start.F)"),
    ("driven-twice", lambda r: r["signals"].append({"from": "A.q1", "to": "S.F"}),
     "signals[2].to: S.F is already driven by signals[1]"),
    ("interpolation", lambda r: r["sources"]["push"].update({"interpolation": "cubic"}),
     "sources.push.interpolation: must be one of hold, linear, got 'cubic'"),
    ("source-named-as-subsystem", lambda r: r.update({"sources": {"A": {"csv": "push.csv"}}}),
     "sources.A: is also the name of a subsystem"),
    ("csv-missing", lambda r: r["sources"]["push"].update({"csv": "nowhere.csv"}), "sources.push.csv: cannot read"),
    ("csv-no-time", _table("t,force\n0,1\n"), "sources.push.csv: bad.csv: the first column of the header must be `time`"),
    ("csv-times-decreasing", _table("time,force\n0,1\n0.5,2\n0.5,3\n0.4,3\n"),
     "sources.push.csv: bad.csv: times must not decrease, line 5 has 0.4 after 0.5"),
    ("csv-boolean-time", _table("time,force\n0,1\ntrue,2\n"), "bad.csv: line 3: the time must be a number"),
    ("csv-mixed-column", _table("time,force\n0,1\n1,true\n"), "bad.csv: column force mixes true/false and numbers"),
    ("csv-not-numbers", _table("time,force\n0,abc\n"), "sources.push.csv: bad.csv: line 2 is not all numbers"),
]


@pytest.mark.parametrize("case, change, needle", BAD, ids=[b[0] for b in BAD])
def test_bad_signals_and_sources_are_one_line_errors(folder, case, change, needle):
    raw = copy.deepcopy(BASE)
    change(raw)
    if "_table" in raw:
        (folder / "bad.csv").write_text(raw.pop("_table"))
    with pytest.raises(ConfigError) as info:
        parse_scenario(raw, "signals.yaml", folder)
    assert str(info.value).startswith("signals.yaml: ") and needle in str(info.value)
    assert "\n" not in str(info.value)


SCENE_BAD = [
    ("unknown-variable", lambda r: r["signals"][1].update({"from": "A.nope"}),
     "signals[1].from: the FMU DuffingSide.fmu of A has no variable 'nope'"),
    ("not-an-input", lambda r: r["signals"][1].update({"to": "S.q2"}),
     "signals[1].to: S.q2 is not an input of LinearSide.fmu (causality output)"),
    ("default-port-input", lambda r: (r["subsystems"]["A"].pop("port"), r["signals"][0].update({"to": "A.u"})),
     "signals[0].to: A.u is a port variable of A, so a signal cannot drive it"),
]


@pytest.mark.parametrize("case, change, needle", SCENE_BAD, ids=[b[0] for b in SCENE_BAD])
def test_signals_the_fmus_refuse_exit_2(folder, case, change, needle, capsys):
    """Variables are checked when the FMUs are opened: the CLI's validate ends with exit 2, one line."""
    raw = copy.deepcopy(BASE)
    change(raw)
    import yaml
    path = folder / "bad.yaml"
    path.write_text(yaml.safe_dump(raw))
    with pytest.raises(SystemExit) as info:
        main(["validate", str(path)])
    err = capsys.readouterr().err.strip().splitlines()
    assert info.value.code == 2 and len(err) == 1 and needle in err[0], err


def test_a_subsystem_without_port_and_without_signals_keeps_the_default_wave_port(folder):
    """Old files omit `port:` for our FMUs: only a subsystem that a signal names and no coupling
    names is signal-only."""
    sc = scenario(folder, lambda r: r["subsystems"]["B"].pop("port"))
    assert [s.name for s in sc.subsystems] == ["A", "B"] and [s.name for s in sc.signal_subsystems] == ["S"]
    assert sc.subsystems[1].port["wave_in"] == ["a"]


def test_the_api_runs_a_scene_with_signals(folder):
    result = wc.simulate(scenario(folder), K=20, warn=quiet)
    assert result.summary["status"] == "finished" and result.summary["signals"] == 2


def test_a_non_finite_signal_stops_the_run_naming_the_signal(folder):
    """A held value that overflows (2 x 1e308 from the table at 0.05 s) stops the run with a
    NumericalError (exit 4) naming the signal, the step and the time; the steps before it are kept."""
    (folder / "huge.csv").write_text(f"time,force\n0.0,0.0\n{STEP_AT},1e308\n")

    def huge(raw):
        raw["sources"] = {"push": {"csv": "huge.csv"}}
        raw["signals"][0]["factor"] = 2.0
    with pytest.raises(wc.RunFailed) as info:
        run(scenario(folder, huge), warn=quiet)
    assert "signals[0]: push.force gave inf at step 5 (t = 0.05)" in str(info.value)
    assert info.value.exit_code == 4 and info.value.result.summary["steps"] == 5


def test_metadata_names_a_time_table_by_its_file_and_checksum(folder):
    """metadata.json records each source table by its path, SHA-256, rows and columns, not its values
    (a large --input file would be copied whole into it)."""
    import hashlib
    import json
    sc = scenario(folder)
    wc.simulate(sc, out_dir=folder / "out", reference=False, warn=quiet)
    (table,) = json.loads((folder / "out" / "metadata.json").read_text())["scenario"]["sources"]
    source = sc.sources[0]
    assert table == {"name": source.name, "csv": source.csv, "interpolation": source.interpolation,
                     "sha256": hashlib.sha256(open(source.csv, "rb").read()).hexdigest(),
                     "rows": len(source.times), "columns": list(source.columns)}
