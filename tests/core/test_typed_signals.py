"""Signals of every type on FMUs built here: SignalSource's Real, Integer, Boolean and String outputs
drive SignalSink's inputs of the same types (a signal-only pair, no power bond), and every value
recorded equals a plain fmpy loop over the two FMUs, to the last bit; Integer and Boolean columns
are written as integers, Strings as quoted text a CSV reader takes back."""
import csv

import numpy as np
import pytest
from fmpy import extract, instantiate_fmu, read_model_description

from paths import CLI
from wavecosim.errors import ConfigError, NumericalError, RunFailed
from wavecosim.run.runner import run
from wavecosim.scenario.config import parse_scenario

PAIR = {
    "name": "typed",
    "subsystems": {"src": {"fmu": "SignalSource", "parameters": {"frequency": 0.5}, "integers": {"period": 3}},
                   "sink": {"fmu": "SignalSink", "parameters": {"gain": 3.0}}},
    "signals": [{"from": "src.y", "to": "sink.u", "factor": 2.0, "offset": 0.25},
                {"from": "src.count", "to": "sink.n"},
                {"from": "src.flag", "to": "sink.on"},
                {"from": "src.label", "to": "sink.text"}],
}
DT, STEPS = 0.05, 40          # SignalSource's DefaultExperiment: stepSize 0.05, stopTime 2


def pair(change=None):
    raw = {**PAIR, "signals": [dict(s) for s in PAIR["signals"]]}
    if change:
        change(raw)
    return parse_scenario(raw, "typed.yaml")


def plain_loop(built_fmus, tmp_path):
    """The two FMUs stepped by fmpy: the sink's inputs set from the source in initialization mode,
    then at each t_n every source output read, every sink input set (u = 2 y + 0.25), one doStep each; {src.x / sink.x: values at every grid point}."""
    fmus, md, vr = {}, {}, {}
    for name, ident in (("src", "SignalSource"), ("sink", "SignalSink")):
        md[name] = read_model_description(str(built_fmus[ident]))
        vr[name] = {v.name: v.valueReference for v in md[name].modelVariables}
        fmus[name] = instantiate_fmu(extract(str(built_fmus[ident]), unzipdir=str(tmp_path / name)), md[name])
        fmus[name].setupExperiment(startTime=0.0)
    fmus["src"].setReal([vr["src"]["frequency"]], [0.5])
    fmus["src"].setInteger([vr["src"]["period"]], [3])
    fmus["sink"].setReal([vr["sink"]["gain"]], [3.0])
    for fmu in fmus.values():
        fmu.enterInitializationMode()
    src, sink = fmus["src"], fmus["sink"]

    def hold():
        y, count = src.getReal([vr["src"]["y"]])[0], src.getInteger([vr["src"]["count"]])[0]
        flag, label = src.getBoolean([vr["src"]["flag"]])[0], src.getString([vr["src"]["label"]])[0].decode()
        sink.setReal([vr["sink"]["u"]], [2.0 * y + 0.25])
        sink.setInteger([vr["sink"]["n"]], [count])
        sink.setBoolean([vr["sink"]["on"]], [flag])
        sink.setString([vr["sink"]["text"]], [label])

    hold()                                    # in initialization mode, as the master settles the start
    for fmu in fmus.values():
        fmu.exitInitializationMode()
    rows = {}

    def record():
        for name, fmu in fmus.items():
            for v in md[name].modelVariables:
                if v.causality in ("output", "input"):
                    get = {"Real": fmu.getReal, "Integer": fmu.getInteger, "Boolean": fmu.getBoolean,
                           "String": fmu.getString}[v.type]
                    value = get([v.valueReference])[0]
                    rows.setdefault(f"{name}.{v.name}", []).append(value.decode() if isinstance(value, bytes)
                                                                     else float(value))
    hold()
    record()
    for n in range(STEPS):
        hold()
        for fmu in fmus.values():
            fmu.doStep(n * DT, DT)
        record()
    return rows


def test_every_type_through_a_signal_only_pair_equals_a_plain_fmpy_loop(built_fmus, tmp_path):
    result = run(pair(), tmp_path / "out", file_suffix=False, formats=("csv", "mat"))
    expected = plain_loop(built_fmus, tmp_path)
    traj = result.trajectory
    assert list(traj.dtype.names[1:]) == list(expected)          # every output and connected input
    for column, values in expected.items():
        if traj[column].dtype.kind == "U":
            assert list(traj[column]) == values, column
        else:
            assert np.array_equal(traj[column], np.array(values)), column
    assert set(traj["sink.echo"]) == {"", "low", 'high, "on"'} and traj["sink.off"].max() == 1.0
    with open(tmp_path / "out" / "trajectory.csv", newline="") as f:
        rows = list(csv.reader(f))
    header = rows[0]
    written = {h: [r[j] for r in rows[1:]] for j, h in enumerate(header)}
    assert written["sink.shifted"][:3] == ["10", "10", "11"] and set(written["src.flag"]) == {"0", "1"}
    assert written["src.label"] == list(traj["src.label"])          # the csv module reads the text back
    assert 'high, ""on""' in (tmp_path / "out" / "trajectory.csv").read_text()
    from scipy.io import loadmat
    mat = loadmat(str(tmp_path / "out" / "trajectory.mat"))
    assert [str(v[0]) for v in mat["src_label"].ravel()] == list(traj["src.label"])     # texts as a cell array


def test_integer_and_boolean_outputs_pass_validate_and_run(tmp_path):
    """A scene naming Integer and Boolean outputs as columns: validate and run both succeed."""
    import subprocess
    import yaml
    raw = {**PAIR, "outputs": {"count": "src.count", "flag": "src.flag", "off": "sink.off"}, "T": 0.2}
    path = tmp_path / "typed.yaml"
    path.write_text(yaml.safe_dump(raw))
    for command in (["validate", str(path)], ["run", str(path), "--quiet", "--out", str(tmp_path / "o")]):
        proc = subprocess.run([*CLI, *command], capture_output=True, text=True, timeout=120)
        assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "o" / "trajectory.csv").read_text().splitlines()[:3] == \
        ["time,count,flag,off", "0.0,0,0,1", "0.05,1,0,1"]


BAD = [
    ("real-to-integer", lambda r: r["signals"][1].update({"from": "src.y"}),
     "typed.yaml: signals[1]: src.y gives real values, which cannot drive sink.n, a Integer input"),
    ("factor-on-integer", lambda r: r["signals"][1].update({"factor": 2.0}),
     "typed.yaml: signals[1]: a factor or offset scales Real inputs only; sink.n is a Integer input"),
    ("string-to-boolean", lambda r: r["signals"][2].update({"from": "src.label"}),
     "signals[2]: src.label gives string values, which cannot drive sink.on, a Boolean input"),
]


@pytest.mark.parametrize("case, change, needle", BAD, ids=[b[0] for b in BAD])
def test_a_signal_its_input_cannot_take_is_refused_when_the_fmus_open(case, change, needle):
    with pytest.raises(ConfigError) as info:
        run(pair(change))
    assert needle in str(info.value) and "\n" not in str(info.value)


def test_an_integer_outside_its_inputs_range_stops_the_run(tmp_path):
    """An Integer table column driving an Integer input: 3e9 does not fit 32 bits (NumericalError)."""
    (tmp_path / "n.csv").write_text("time,n\n0,1\n0.1,3000000000\n")

    def table(raw):
        raw["sources"] = {"tab": {"csv": str(tmp_path / "n.csv")}}
        raw["signals"][1] = {"from": "tab.n", "to": "sink.n"}
    with pytest.raises(RunFailed) as info:
        run(pair(table))
    assert isinstance(info.value.__cause__, NumericalError)
    assert "signals[1]: tab.n gave 3000000000, outside the range -2147483648..2147483647 of the Integer input " \
           "sink.n at step 2 (t = 0.1)" in str(info.value)
    assert info.value.result.summary["steps"] == 2
