"""FMUs nobody here wrote, each run alone (`wavecosim run X.fmu`): every recorded value equals a
plain fmpy loop (doStep(t_n, dt), inputs applied by fmpy's Input before it, the DefaultExperiment's
start time and tolerance set up as fmpy sets them up), to the last bit. Dymola's FMI 2 and FMI 3
IO and pendulum (FMIZoo), and the Modelica Association's Reference FMUs in both versions.
Skipped when ../shared/third_party is absent (a fresh clone)."""
import numpy as np
import pytest

from conftest import fmpy_loop, input_signals, same_bits
from paths import CLI, THIRD_PARTY
import wavecosim as wc

pytestmark = pytest.mark.skipif(not THIRD_PARTY.exists(), reason="the third-party FMUs (../shared/third_party) are absent")
ZOO, REFERENCE = THIRD_PARTY / "fmizoo", THIRD_PARTY / "reference_fmus"


def quiet(message):
    """Set-up notes (the FMI 3 files' schema warning) are checked in their own test."""


def run_alone(path, **options):
    return wc.simulate(path, warn=quiet, **options)


def test_fmi2_io_from_the_command_line_equals_a_plain_fmpy_loop(tmp_path):
    """The issue's own run: y_real, y_integer and y_boolean of IO.fmu, --dt 0.01 --T 1."""
    import subprocess
    out = tmp_path / "out"
    proc = subprocess.run([*CLI, "run", str(ZOO / "fmi2" / "IO.fmu"), "--dt", "0.01", "--T", "1", "--quiet",
                           "--out", str(out)], capture_output=True, text=True, timeout=300)
    assert proc.returncode == 0, proc.stderr
    import csv
    with open(out / "trajectory.csv", newline="") as f:
        rows = list(csv.reader(f))
    header, data = rows[0], rows[1:]
    assert header == ["time", "IO.y_real", "IO.y_boolean", "IO.y_integer"] and len(data) == 101
    expected = fmpy_loop(ZOO / "fmi2" / "IO.fmu", 0.01, 100, ["y_real", "y_integer", "y_boolean"],
                         unzipdir=str(tmp_path / "io"))
    for name in ("y_real", "y_integer", "y_boolean"):
        column = [float(r[header.index(f"IO.{name}")]) for r in data]
        assert column == expected[name], name
    assert all(r[header.index("IO.y_integer")].lstrip("-").isdigit() for r in data)     # integers as integers


INPUT = ('"time","u_real","u_integer","u_boolean"\n0,0,0,false\n0.25,1.5,2,false\n0.25,-1,3,true\n'
         '0.6,2,5,true\n1,4,7,false\n')


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
def test_io_with_an_input_file_equals_fmpys_input(version, tmp_path):
    """The FMI cross-check input format: quoted headers, true/false, an event at 0.25 s (the time
    given twice); u_real interpolated, the discrete inputs held, as fmpy's Input applies them."""
    (tmp_path / "in.csv").write_text(INPUT)
    result = wc.simulate(wc.load(ZOO / version / "IO.fmu", input=tmp_path / "in.csv", dt=0.05, warn=quiet), warn=quiet)
    names = ["u_real", "y_real", "u_integer", "y_integer", "u_boolean", "y_boolean"]
    expected = fmpy_loop(ZOO / version / "IO.fmu", 0.05, 20, names, signals=input_signals(tmp_path / "in.csv"),
                         unzipdir=str(tmp_path / "io"))
    assert same_bits(result, "IO", expected)
    assert result.trajectory["IO.u_boolean"][6] == 1.0 and result.trajectory["IO.y_integer"][-1] > 3


def test_the_fmi3_pendulum_equals_a_plain_fmpy_loop(tmp_path):
    """Dymola's FMI 3 pendulum (events from friction), driven by an external force from a file."""
    (tmp_path / "force.csv").write_text("time,extForce\n0,0\n0.3,5\n0.7,-5\n1,0\n")
    path = ZOO / "fmi3" / "SpringFrictionPendulumExtForce1D.fmu"
    result = wc.simulate(wc.load(path, input=tmp_path / "force.csv", dt=0.01, T=1.0, warn=quiet), warn=quiet)
    names = ["extForce", "v", "a", "accSensor.a"]
    expected = fmpy_loop(path, 0.01, 100, names, signals=input_signals(tmp_path / "force.csv"),
                         unzipdir=str(tmp_path / "p"))
    assert same_bits(result, "SpringFrictionPendulumExtForce1D", expected)
    assert np.ptp(result.trajectory["SpringFrictionPendulumExtForce1D.v"]) > 0.1


def test_a_schema_invalid_model_description_loads_with_one_warning():
    """Dymola 2023x writes `order` on FMI 3 annotations, which the schema forbids: one warning."""
    notes = []
    result = wc.simulate(ZOO / "fmi3" / "IO.fmu", dt=0.1, warn=notes.append)
    assert result.summary["status"] == "finished"
    schema = [n for n in notes if "schema" in n]
    assert len(schema) == 1 and "IO.fmu: modelDescription.xml does not conform to the FMI 3.0 schema" in schema[0]
    assert "attribute 'order'" in schema[0] and "\n" not in schema[0]


REFERENCE_RUNS = [  # (FMU, dt, stop time (None: the DefaultExperiment's), recorded variables)
    ("BouncingBall", 0.01, None, ["h", "v"]),
    ("Dahlquist", 0.1, None, ["x"]),
    ("Stair", 0.2, None, ["counter"]),         # it ends the simulation after the step to t = 9
    ("VanDerPol", 0.01, None, ["x0", "x1"]),
]


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
@pytest.mark.parametrize("name, dt, T, names", REFERENCE_RUNS, ids=[r[0] for r in REFERENCE_RUNS])
def test_reference_fmus_equal_plain_fmpy_loops(version, name, dt, T, names, tmp_path):
    """Each Reference FMU alone, its DefaultExperiment's step size and stop time (no option given)."""
    path = REFERENCE / version / f"{name}.fmu"
    result = run_alone(path, T=T)
    sc = wc.load(path, T=T, warn=quiet)
    assert sc.dt == dt and result.summary["steps"] == (45 if name == "Stair" else sc.n_steps)
    expected = fmpy_loop(path, dt, sc.n_steps, names, unzipdir=str(tmp_path / name))
    assert same_bits(result, name, expected)
    if name == "Stair":               # as fmpy's simulate: the run ends, finished, after the step the FMU ended
        assert result.summary["status"] == "finished" and result.summary["steps"] == 45
        assert result.summary["message"] == "subsystem Stair ended the simulation after the step to t = 9"


FEEDTHROUGH = {"fmi2": ["Float64_continuous_input", "Float64_discrete_input", "Int32_input", "Boolean_input"],
               "fmi3": ["Float64_continuous_input", "Float64_discrete_input", "Float32_continuous_input",
                        "Int8_input", "UInt8_input", "Int16_input", "UInt16_input", "Int32_input", "UInt32_input",
                        "Int64_input", "UInt64_input", "Boolean_input"]}


@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
def test_feedthrough_of_every_type_equals_a_plain_fmpy_loop(version, tmp_path):
    """Every input type of Feedthrough from one file, every output recorded: numbers as numbers,
    the String and Binary outputs as quoted text."""
    inputs = FEEDTHROUGH[version]
    rows = [[0.0] + [0] * len(inputs), [0.5] + [3] * len(inputs), [0.5] + [7] * len(inputs),
            [1.0] + [9] * len(inputs)]
    text = ",".join(["time", *inputs]) + "\n" + "".join(
        ",".join(str(v if not n.startswith("Boolean") else ("true" if v > 4 else "false")) for n, v in
                 zip(["time", *inputs], r)) + "\n" for r in rows)
    (tmp_path / "in.csv").write_text(text)
    path = REFERENCE / version / "Feedthrough.fmu"
    result = wc.simulate(wc.load(path, input=tmp_path / "in.csv", dt=0.1, T=1.0, warn=quiet), warn=quiet)
    outputs = [n.replace("input", "output") for n in inputs] + ["String_output", "Enumeration_output"]
    expected = fmpy_loop(path, 0.1, 10, inputs + outputs, signals=input_signals(tmp_path / "in.csv"),
                         unzipdir=str(tmp_path / "f"))
    assert same_bits(result, "Feedthrough", expected)
    assert result.trajectory["Feedthrough.Int32_output"][-1] == 7 and result.trajectory["Feedthrough.Boolean_output"][-1] == 1
    assert set(result.trajectory["Feedthrough.String_output"]) == {"Set me!"}
