"""`wavecosim info FILE`: an FMU's variables, default experiment and capabilities; a system's components,
connections, power ports and couplings; one line and the error's exit code for a file that is none of these."""
import json
import subprocess

import pytest

from paths import CLI, CONFIGS, THIRD_PARTY

needs_third_party = pytest.mark.skipif(not THIRD_PARTY.is_dir(), reason=f"{THIRD_PARTY} is absent")


def info(*args, code=0):
    proc = subprocess.run(CLI + ["info", *map(str, args)], capture_output=True, text=True, timeout=120)
    assert proc.returncode == code, proc.stderr
    return proc


def described(*args):
    return json.loads(info(*args, "--json").stdout)


def by_name(variables):
    return {v["name"]: v for v in variables}


def test_a_built_in_fmu_lists_its_variables_with_causality_type_unit_and_start(built_fmus):
    d = described(built_fmus["LinearSide"])
    assert d["kind"] == "FMU" and d["fmi_version"] == "2.0" and d["model_name"] == "LinearSide"
    q2, F = by_name(d["variables"])["q2"], by_name(d["variables"])["F"]
    assert (q2["causality"], q2["type"], q2["unit"]) == ("output", "Real", "m")
    assert (F["causality"], F["unit"]) == ("input", "N")
    assert d["capabilities"]["canGetAndSetFMUstate"] is True
    lines = info(built_fmus["LinearSide"]).stdout.splitlines()
    assert lines[0].endswith("FMI 2.0 model LinearSide, by wavecosim fmus/layer; CoSimulation")
    assert "  canGetAndSetFMUstate: yes" in lines
    assert any(ln.split()[:4] == ["input", "continuous", "Real", "F"] for ln in lines)


def test_the_ssd_example_shows_its_components_ports_and_the_coupling_it_pairs():
    d = described(CONFIGS / "two_oscillators.ssd")
    assert d["kind"] == "system" and [c["name"] for c in d["components"]] == ["A", "B"]
    assert [c["fmu"] for c in d["components"]] == ["DuffingSide", "LinearSide"]
    assert d["couplings"] == [{"type": "equal_effort_opposite_flow", "ports": ["A", "B"]}]
    assert d["ports"]["B"]["physical_in"] == "F" and d["experiment"]["dt"] == 0.01
    text = info(CONFIGS / "two_oscillators.ssd").stdout
    assert "couplings (1):\n  equal_effort_opposite_flow: A, B\n" in text


def test_a_scenario_file_shows_its_system():
    d = described(CONFIGS / "foreign_pair.yaml")
    assert [(c["name"], c["fmu"], c["inputs"], c["outputs"]) for c in d["components"]] == [
        ("A", "ForeignMass", 1, 2), ("B", "ForeignSpring", 1, 2)]
    assert d["ports"]["B"]["sign"] == [-1.0] and d["connections"] == [] and d["two_way"] == []
    by_name_only = described("foreign_pair")                  # an example by its name, from any folder
    assert by_name_only.pop("path").endswith("foreign_pair.yaml") and d.pop("path").endswith("foreign_pair.yaml")
    assert by_name_only == d


@pytest.mark.parametrize("name, content, code, message", [
    ("broken.fmu", "not a zip", 3, "is not an FMU (not a zip archive)"),
    ("notes.txt", "hello", 2, "not an FMU (.fmu), an SSP system (.ssd, .ssp, folder) or a scenario file (.yaml)"),
    ("overlay.yaml", "ports: {A: {physical_in: F}}\n", 2, "a ports overlay of an SSP system, not a scenario"),
])
def test_a_file_that_is_none_of_these_is_one_line_and_its_exit_code(tmp_path, name, content, code, message):
    (tmp_path / name).write_text(content)
    err = info(tmp_path / name, code=code).stderr.strip().splitlines()
    assert len(err) == 1 and err[0].startswith("error: ") and message in err[0]


@needs_third_party
def test_a_third_party_fmu_shows_its_default_experiment_and_capabilities():
    d = described(THIRD_PARTY / "reference_fmus" / "fmi2" / "VanDerPol.fmu")
    assert d["default_experiment"] == {"startTime": 0, "stopTime": 20, "stepSize": 0.01}
    assert by_name(d["variables"])["mu"] == {"name": "mu", "causality": "parameter", "variability": "fixed",
                                             "type": "Real", "unit": "", "start": "1", "description": ""}
    pair = described(THIRD_PARTY / "dual_mass_oscillator" / "DualMassOscillator.System1.fmu")
    assert pair["capabilities"]["canGetAndSetFMUstate"] is False


@needs_third_party
def test_a_third_party_ssd_shows_where_an_overlay_could_pair_ports_and_what_it_pairs_with_one():
    ssd = THIRD_PARTY / "dcmotor" / "SystemStructure.ssd"
    d = described(ssd)
    assert sorted(c["name"] for c in d["components"]) == ["edrive_mass", "emachine_model", "stimuli_model"]
    assert d["ports"] == {} and d["couplings"] == []
    assert {"from": "emachine_model.M", "to": "edrive_mass.M_A", "factor": 1.0, "offset": 0.0} in d["connections"]
    assert [w["components"] for w in d["two_way"]] == [["edrive_mass", "emachine_model"]]
    with_ports = described(ssd, "--ports", CONFIGS / "dcmotor_ports.yaml")
    assert with_ports["couplings"] == [{"type": "equal_effort_opposite_flow",
                                        "ports": ["emachine_model", "edrive_mass"]}]
    assert set(with_ports["ports"]) == {"emachine_model", "edrive_mass"}
