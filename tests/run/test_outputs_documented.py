"""Every column a run writes and every key of its summary.json and metadata.json is documented
(docs/outputs.md is generated from these descriptions), with a unit in metadata.json; and every
description is of something some run writes. The runs below reach every runtime concern: the
energy ledger and the monolithic guard, fixed and tuned γ, the certificates, FMUs without H,
deadlines, the DR options, signals, every master."""
import copy
import csv
import json

import pytest

import wavecosim as wc
from paths import CONFIGS, THIRD_PARTY
from wavecosim.run import glossary
from wavecosim.run.observers import Observer, described_as
from wavecosim.run.runner import OBSERVERS, STEP_DESCRIBED
from wavecosim.scenario.config import parse_scenario

T = 0.05
SIGNALS = {
    "name": "signals", "dt": 0.01, "T": T, "gamma": 0.4,
    "subsystems": {
        "A": {"fmu": "DuffingSide", "start": {"q1": 0.4, "d": -0.4}},
        "B": {"fmu": "Oscillator", "port": {"wave_in": "a_left", "wave_out": "b_left", "effort": "e_left",
                                            "flow": "f_left", "physical_in": "F_left", "input": "effort"}},
        "S": {"fmu": "LinearSide"},
    },
    "couplings": [{"type": "equal_effort_opposite_flow", "ports": ["A", "B"]}],
    "sources": {"push": {"csv": "push.csv"}},
    "signals": [{"from": "push.force", "to": "B.a_right"}, {"from": "A.q1", "to": "S.F", "factor": 2.0}],
    "master": {"K": 3},
}
SIGNAL_ONLY = {"name": "pair", "dt": 0.01, "T": T,
               "subsystems": {"A": {"fmu": "LinearSide", "start": {"q2": 0.1}}, "B": {"fmu": "LinearSide"}},
               "signals": [{"from": "A.q2", "to": "B.F"}, {"from": "B.q2", "to": "A.F"}]}


def runs(folder):
    """(name, scenario, simulate's options) of every run: together they write every documented figure."""
    table1 = wc.load(K=8, T=0.3)
    (folder / "push.csv").write_text("time,force\n0.0,0.0\n0.02,1.0\n")
    yield "table1", table1, {}
    yield "monolithic guard", table1.with_master(energy_guard="monolithic"), {}
    yield "deadline, relaxation auto", wc.load(K=100, T=T).with_master(deadline_us=30.0, relaxation="auto"), {}
    yield "anderson", wc.load(K=3, T=T).with_master(anderson=2, anderson_memory=True, warm_start=True), {}
    yield "auto-retune", wc.load(CONFIGS / "two_oscillators_stiff.yaml", gamma="auto-retune", K=3, T=T), {}
    yield "without H", wc.load(CONFIGS / "foreign_pair.yaml", K=3, T=T), {}
    yield "without error columns", wc.load(K=3, T=T).with_changes(error=[]), {}
    yield "signals", parse_scenario(copy.deepcopy(SIGNALS), "signals.yaml", folder), {}
    yield "signals only", parse_scenario(copy.deepcopy(SIGNAL_ONLY), "pair.yaml", folder), {}
    yield "tolerance", wc.load(T=T).with_master(tolerance=1e-2), {"reference": "fine"}
    for master in ("explicit", "gauss-seidel", "jacobi-iter", "gauss-seidel-iter", "aitken", "iqn-ils", "newton"):
        yield master, wc.load(master=master, K=2, T=T), {"reference": master != "explicit"}


@pytest.fixture(scope="module")
def written(tmp_path_factory):
    """{run name: {file kind: (CSV header or JSON object)}}, the lockstep references' files included."""
    folder = tmp_path_factory.mktemp("documented")
    out = {}
    for k, (name, scenario, options) in enumerate(runs(folder)):
        wc.simulate(scenario, out_dir=folder / str(k), warn=lambda message: None, **options)
        for suffix, label in (("", name), ("_monolithic", f"{name}, its reference")):
            if (folder / str(k) / f"summary{suffix}.json").exists():
                out[label] = {kind: _header(folder / str(k) / f"{kind}{suffix}.csv") for kind in ("trajectory", "steps")}
                out[label].update({kind: json.loads((folder / str(k) / f"{kind}{suffix}.json").read_text())
                                   for kind in ("summary", "metadata")})
    return out


def _header(path):
    with open(path, newline="") as f:
        return next(csv.reader(f))


def step_descriptions():
    return [STEP_DESCRIBED] + [cls.described for cls in OBSERVERS]


def test_every_observer_is_listed_with_its_descriptions():
    def subclasses(cls):
        return {s for c in cls.__subclasses__() for s in (c, *subclasses(c))}
    shipped = {c for c in subclasses(Observer) if c.__module__.startswith("wavecosim.")}    # not a test's own
    assert shipped <= set(OBSERVERS)


def test_every_column_and_key_written_is_documented_with_its_unit(written):
    for name, files in written.items():
        for column in files["steps"]:
            assert any(described_as(d, column) for d in step_descriptions()), (name, column)
        assert set(files["summary"]) <= set(glossary.SUMMARY), (name, set(files["summary"]) - set(glossary.SUMMARY))
        assert set(files["metadata"]) == set(glossary.METADATA), name
        units = files["metadata"]["units"]
        assert list(units["trajectory"]) == files["trajectory"] and list(units["steps"]) == files["steps"], name


def test_every_description_is_of_something_written(written):
    columns = {c for files in written.values() for c in files["steps"]}
    for d in step_descriptions():
        for pattern in d:
            assert any(described_as({pattern: d[pattern]}, c) for c in columns), pattern
    keys = {k for files in written.values() for k in files["summary"]}
    assert set(glossary.SUMMARY) <= keys, set(glossary.SUMMARY) - keys


def test_units_come_from_the_model_descriptions_and_the_descriptions(written):
    units = written["table1"]["metadata"]["units"]
    assert units["trajectory"] == {"time": "s", "q1": "m", "v1": "m/s", "d": "m", "q2": "m", "v2": "m/s",
                                   "bA": "sqrt(J)", "bB": "sqrt(J)"}
    steps = units["steps"]
    assert steps["gamma_A"] == "N/(m/s)" and steps["error"] == "m" and steps["H_total"] == "J"
    assert steps["inner_residual"] == "sqrt(J)" and steps["reason"] == "text"
    assert written["jacobi-iter"]["metadata"]["units"]["steps"]["inner_residual"] == ""   # port variables of any unit


@pytest.mark.skipif(not (THIRD_PARTY / "reference_fmus").is_dir(), reason="the third-party FMUs are not here")
@pytest.mark.parametrize("version", ["fmi2", "fmi3"])
def test_a_unit_given_by_the_declared_type_is_the_columns_unit(version, tmp_path):
    # the Reference FMU BouncingBall declares h and v by type (Position: m, Velocity: m/s), without a unit of their own
    wc.simulate(THIRD_PARTY / "reference_fmus" / version / "BouncingBall.fmu", T=0.1, out_dir=tmp_path,
                warn=lambda message: None)
    units = json.loads((tmp_path / "metadata.json").read_text())["units"]["trajectory"]
    assert units["BouncingBall.h"] == "m" and units["BouncingBall.v"] == "m/s"
