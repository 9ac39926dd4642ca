"""What a run records when the scenario names no columns: every output and every input a signal
drives, of every subsystem, named <subsystem>.<variable> in the scenario's and each FMU's order;
glob patterns (`outputs:` as a list, `--outputs`) narrow them; named columns stay as they are."""
import subprocess

import pytest
import yaml

from paths import CLI, CONFIGS
import wavecosim as wc
from wavecosim.errors import ConfigError
from wavecosim.run.recorder import header
from wavecosim.run.runner import run
from wavecosim.scenario.config import parse_scenario

PAIR = {"subsystems": {"sink": {"fmu": "SignalSink"}, "src": {"fmu": "SignalSource"}},
        "signals": [{"from": "src.y", "to": "sink.u"}, {"from": "src.flag", "to": "sink.on"}], "T": 0.1}
SRC = ["src.y", "src.count", "src.flag", "src.label"]
SINK = ["sink.u", "sink.integral", "sink.scaled", "sink.shifted", "sink.length", "sink.on", "sink.off", "sink.echo"]


def columns(**top):
    return run(parse_scenario({**PAIR, **top}, "pair.yaml")).columns


def test_every_output_and_driven_input_in_the_files_order():
    """The sink comes first as the file lists it; its driven inputs u and on, not n or text."""
    assert columns() == SINK + SRC


def test_patterns_narrow_the_columns_and_name_other_variables():
    assert columns(outputs=["src.*"]) == SRC
    assert columns(outputs=["*.y", "sink.o*"]) == ["sink.on", "sink.off", "src.y"]
    assert columns(outputs=["src.y", "sink.gain"]) == ["src.y", "sink.gain"]        # a parameter, named exactly
    result = wc.simulate(parse_scenario(PAIR, "pair.yaml"), outputs=["sink.integral"])
    assert result.columns == ["sink.integral"]


def test_named_columns_stay_as_the_file_names_them():
    assert columns(outputs={"y": "src.y", "n": "src.count"}) == ["y", "n"]
    named = parse_scenario({**PAIR, "outputs": {"y": "src.y", "n": "src.count"}}, "pair.yaml")
    assert wc.simulate(named, outputs=["n"]).columns == ["n"]              # by column name
    assert wc.simulate(named, outputs=["src.y"]).columns == ["y"]          # by variable


BAD = [
    ("pattern-matches-nothing", dict(outputs=["nope.*"]),
     "pair.yaml: outputs: 'nope.*' matches no output and names no variable (columns are named like sink.u)"),
    ("column-time", dict(outputs={"time": "src.y"}), "pair.yaml: outputs.time: a column name cannot be `time`"),
    ("column-comma", dict(outputs={"a,b": "src.y"}), "outputs.a,b: a column name cannot be `time` or hold a comma"),
    ("column-quote", dict(outputs={'a"b': "src.y"}), "or hold a comma, quote or line break"),
    ("pattern-not-text", dict(outputs=[3]), "pair.yaml: outputs: must be a list of patterns like [A.*, B.y], got [3]"),
    ("error-not-a-column", dict(error=["src.nope"]), "pair.yaml: error: 'src.nope' is not an output column"),
]


@pytest.mark.parametrize("case, top, needle", BAD, ids=[b[0] for b in BAD])
def test_bad_columns_are_one_line_errors(case, top, needle):
    with pytest.raises(ConfigError) as info:
        columns(**top)
    assert needle in str(info.value) and "\n" not in str(info.value)


def test_the_command_line_narrows_with_repeated_outputs(tmp_path):
    path = tmp_path / "pair.yaml"
    path.write_text(yaml.safe_dump(PAIR))
    proc = subprocess.run([*CLI, "run", str(path), "--outputs", "src.count", "--outputs", "sink.o*", "--quiet",
                           "--out", str(tmp_path / "o")], capture_output=True, text=True, timeout=120)
    assert proc.returncode == 0, proc.stderr
    assert (tmp_path / "o" / "trajectory.csv").read_text().splitlines()[0] == "time,sink.on,sink.off,src.count"


def test_a_shipped_scene_keeps_its_columns():
    sc = wc.load(CONFIGS / "two_oscillators.yaml", T=0.02)
    assert run(sc, certificates=False).columns == list(sc.outputs)


def test_a_column_name_with_a_comma_is_quoted_in_the_header():
    """Variables named like x[1,2] (structured names) keep their name, quoted as CSV quotes text."""
    assert header(["time", "A.x[1,2]", 'A.say"hi"', "A.y"]) == 'time,"A.x[1,2]","A.say""hi""",A.y'
