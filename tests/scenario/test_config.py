"""Bad input loses nothing and says what is wrong: every malformed scenario below, run through the
real CLI (`wavecosim.cli.main`, and a few through the installed `wavecosim` executable), ends with
exit code 2 and exactly one stderr line `error: ...` naming the file and the key (or the option),
with no traceback. FMU archives are extracted safely into temporary folders that are removed, and
YAML is read without Python tags."""
import copy
import os
import subprocess
import tempfile
import zipfile
from pathlib import Path

import pytest
import yaml

from paths import CLI, ROOT
from wavecosim.cli import main


BASE = {
    "name": "bad_input_base",
    "dt": 0.01,
    "T": 0.05,
    "gamma": 0.4,
    "subsystems": {
        "A": {"fmu": "DuffingSide", "parameters": {"k12": 120.0}, "start": {"q1": 0.4, "d": -0.4},
              "port": {"wave_in": "a", "wave_out": "b", "effort": "e", "flow": "f"}},
        "B": {"fmu": "LinearSide", "parameters": {"m2": 4.0}},
    },
    "couplings": [{"type": "equal_effort_opposite_flow", "ports": ["A", "B"]}],
    "master": {"algorithm": "dr", "K": 5},
    "outputs": {"q1": "A.q1", "q2": "B.q2"},
    "error": ["q1", "q2"],
}


def cli(args, capsys):
    """Run `wavecosim ARGS` in-process through wavecosim.cli.main; (exit code, stdout, stderr)."""
    with pytest.raises(SystemExit) as info:
        main([str(a) for a in args])
    out, err = capsys.readouterr()
    return info.value.code, out, err


def assert_one_line_error(code, err, *needles):
    assert code == 2, f"exit code {code}, stderr: {err!r}"
    assert "Traceback" not in err
    lines = err.strip().splitlines()
    assert len(lines) == 1, f"expected one line, got {lines!r}"
    assert lines[0].startswith("error: ")
    for needle in needles:
        assert needle in lines[0], f"{needle!r} not in {lines[0]!r}"
    return lines[0]


def mutate(change):
    raw = copy.deepcopy(BASE)
    change(raw)
    return raw


def _set(path, value):
    def change(raw):
        *parents, last = path
        node = raw
        for p in parents:
            node = node[p]
        node[last] = value
    return change


def _drop(path):
    def change(raw):
        *parents, last = path
        node = raw
        for p in parents:
            node = node[p]
        del node[last]
    return change


def _couplings(value):
    return _set(["couplings"], value)


EQ = {"type": "equal_effort_opposite_flow", "ports": ["A", "B"]}

# (id, change to BASE, fragments the one error line must contain)
CASES = [
    ("missing-subsystems", _drop(["subsystems"]), ["subsystems: missing required key"]),
    ("couplings-mapping", _couplings({"type": "dirac"}), ["couplings: must be a list of couplings"]),
    ("dr-without-couplings", _drop(["couplings"]),
     ["master.algorithm: dr couples power bonds, and this system has none (no couplings); it runs with explicit"]),
    ("missing-fmu", _drop(["subsystems", "A", "fmu"]), ["subsystems.A.fmu: missing required key"]),
    ("unknown-top-key", _set(["dtt"], 0.01), ["dtt: unknown key"]),
    ("unknown-subsystem-key", _set(["subsystems", "A", "params"], {}), ["subsystems.A.params: unknown key"]),
    ("unknown-master-key", _set(["master", "KK"], 3), ["master.KK: unknown key"]),
    ("unknown-port-key", _set(["subsystems", "A", "port", "wave"], "a"), ["subsystems.A.port.wave: unknown key"]),
    ("dt-string", _set(["dt"], "fast"), ["dt: must be a number"]),
    ("dt-zero", _set(["dt"], 0), ["dt: must be > 0"]),
    ("dt-negative", _set(["dt"], -0.01), ["dt: must be > 0"]),
    ("T-zero", _set(["T"], 0.0), ["T: must be > 0"]),
    ("T-negative", _set(["T"], -1.0), ["T: must be > 0"]),
    ("T-not-whole-steps", _set(["T"], 0.015), ["T: must be a whole number of steps"]),
    ("T-shorter-than-dt", _set(["T"], 0.001), ["T: must be at least one step"]),
    ("gamma-zero", _set(["gamma"], 0), ["gamma: must be > 0"]),
    ("gamma-negative", _set(["gamma"], -0.4), ["gamma: must be > 0"]),
    ("gamma-nan", _set(["gamma"], float("nan")), ["gamma: must be finite"]),
    ("gamma-unknown-mode", _set(["gamma"], "automatic"), ["gamma: must be one of auto, auto-retune, fast-unsafe"]),
    ("gamma-list", _set(["gamma"], [0.4]), ["gamma: must be a number"]),
    ("subsystem-gamma-zero", _set(["subsystems", "B", "gamma"], 0.0), ["subsystems.B.gamma: must be > 0"]),
    ("K-negative", _set(["master", "K"], -1), ["master.K: must be >= 0"]),
    ("K-real", _set(["master", "K"], 2.5), ["master.K: must be an integer"]),
    ("K-bool", _set(["master", "K"], True), ["master.K: must be an integer"]),
    ("eps-zero", _set(["master", "eps"], 0.0), ["master.eps: must be > 0"]),
    ("algorithm-unknown", _set(["master", "algorithm"], "magic"), ["master.algorithm: must be one of"]),
    ("subsystems-empty", _set(["subsystems"], {}), ["subsystems: must name at least one subsystem"]),
    ("subsystems-list", _set(["subsystems"], ["A", "B"]), ["subsystems: must be a mapping"]),
    ("parameter-string", _set(["subsystems", "A", "parameters", "k12"], "stiff"),
     ["subsystems.A.parameters.k12: A: k12 is a Real variable of DuffingSide.fmu; got 'stiff'"]),
    ("parameter-inf", _set(["subsystems", "A", "parameters", "k12"], float("inf")),
     ["subsystems.A.parameters.k12: must be finite"]),
    ("integer-real", _set(["subsystems", "A", "integers"], {"newton_max_iter": 2.5}),
     ["subsystems.A.integers.newton_max_iter: must be an integer"]),
    ("port-dimensions", _set(["subsystems", "A", "port", "wave_out"], ["b", "e"]),
     ["subsystems.A.port.wave_out: has 2 entries but wave_in has 1 channels"]),
    ("coupling-not-lossless", _couplings([{"type": "dirac", "ports": ["A", "B"], "E": [[1, 0], [0, 1]],
                                           "F": [[1, 0], [0, 1]]}]), ["couplings[0]: not lossless"]),
    ("coupling-not-full-rank", _couplings([{"type": "dirac", "ports": ["A", "B"], "E": [[1, -1], [0, 0]],
                                            "F": [[0, 0], [0, 0]]}]), ["couplings[0]: [E F] is not of full rank"]),
    ("coupling-matrix-size", _couplings([{"type": "dirac", "ports": ["A", "B"], "E": [[1, -1, 0]] * 3,
                                          "F": [[0, 0, 0]] * 3}]), ["couplings[0]: E and F must be 2x2"]),
    ("coupling-type", _couplings([{"type": "spring", "ports": ["A", "B"]}]), ["couplings[0].type: must be one of"]),
    ("coupling-unknown-subsystem", _couplings([{"type": "equal_effort_opposite_flow", "ports": ["A", "C"]}]),
     ["couplings[0].ports: 'C' names no subsystem"]),
    ("coupling-channel-range", _couplings([{"type": "equal_effort_opposite_flow", "ports": ["A[1]", "B"]}]),
     ["couplings[0]: A[1] names channel 1 but A has 1 channel(s)"]),
    ("coupling-channel-twice", _couplings([EQ, {"type": "free_end", "ports": ["A"]}]),
     ["couplings[1].ports: channel A[0] is already connected by couplings[0]"]),
    ("coupling-channel-unconnected", lambda raw: (raw["subsystems"]["B"].update(port={}),
                                                  _couplings([{"type": "free_end", "ports": ["A"]}])(raw)),
     ["couplings: port channel(s) B[0] are not connected by any coupling"]),
    ("transformer-without-ratio", _couplings([{"type": "transformer", "ports": ["A", "B"]}]),
     ["couplings[0].ratio: missing required key for a transformer"]),
    ("couplings-empty", lambda raw: (raw.update(couplings=[]), raw["master"].update(algorithm="explicit")),
     ["couplings: port channel(s) A[0] are not connected by any coupling"]),
    ("fmu-builtin-unknown", _set(["subsystems", "A", "fmu"], "NoSuchModel"),
     ["subsystems.A.fmu: no built-in FMU named 'NoSuchModel'"]),
    ("fmu-path-missing", _set(["subsystems", "A", "fmu"], "nowhere/Missing.fmu"),
     ["subsystems.A.fmu: FMU file not found", "Missing.fmu"]),
    ("port-variable-missing", _set(["subsystems", "A", "port", "wave_in"], "alpha"),
     ["subsystems.A.port.wave_in: the FMU DuffingSide.fmu has no variable 'alpha'"]),
    ("energy-variable-missing", _set(["subsystems", "A", "port", "energy"], "E_total"),
     ["subsystems.A.port.energy: the FMU DuffingSide.fmu has no variable 'E_total'"]),
    ("parameter-name-missing", _set(["subsystems", "A", "parameters", "k99"], 1.0),
     ["subsystems.A.parameters.k99:", "has no variable 'k99'"]),
    ("start-name-missing", _set(["subsystems", "B", "start"], {"q9": 1.0}),
     ["subsystems.B.start.q9:", "has no variable 'q9'"]),
    ("integer-name-missing", _set(["subsystems", "A", "integers"], {"max_iter": 3}),
     ["subsystems.A.integers.max_iter:", "has no variable 'max_iter'"]),
    ("output-variable-missing", _set(["outputs", "q1"], "A.q9"), ["outputs.q1: subsystem A has no variable 'q9'"]),
    ("output-reference", _set(["outputs", "q1"], "q1"), ["outputs.q1: must be SUBSYSTEM.variable"]),
    ("error-column", _set(["error"], ["q3"]), ["error: must list output columns"]),
    ("certificates-augmented", _set(["certificates"], {"augmented": "yes"}),
     ["certificates.augmented: must be true or false"]),
    ("certificates-every-zero", _set(["certificates"], {"every": 0}),
     ["certificates.every (an integer >= 1 or auto): must be >= 1, got 0"]),
    ("certificates-every-word", _set(["certificates"], {"every": "often"}),
     ["certificates.every (an integer >= 1 or auto): must be an integer, got 'often'"]),
    ("fne-watch", _set(["fne_watch"], 1), ["fne_watch: must be true or false"]),
]


def write_yaml(path, raw):
    path.write_text(yaml.safe_dump(raw, sort_keys=False))
    return path


@pytest.mark.parametrize("case_id, change, needles", CASES, ids=[c[0] for c in CASES])
def test_malformed_scenario(case_id, change, needles, tmp_path, capsys):
    bad = write_yaml(tmp_path / f"{case_id}.yaml", mutate(change))
    out_dir = tmp_path / "out"
    code, _, err = cli(["run", bad, "--out", out_dir, "--quiet"], capsys)
    assert_one_line_error(code, err, str(bad), *needles)
    assert not (out_dir / "summary.json").exists()


def test_the_base_scenario_is_valid(tmp_path, capsys):
    """The cases above fail because of their one change: unchanged, the scenario runs (exit 0)."""
    good = write_yaml(tmp_path / "good.yaml", copy.deepcopy(BASE))
    with pytest.raises(SystemExit) as info:
        main(["run", str(good), "--out", str(tmp_path / "out"), "--quiet"])
    assert info.value.code == 0
    assert (tmp_path / "out" / "summary.json").exists()


TEXT_CASES = [
    ("not-yaml", "dt: [0.01, 0.02\n", ["not valid YAML (line"]),
    ("empty-file", "", ["must be a mapping, got NoneType"]),
    ("top-level-list", "- dt: 0.01\n", ["must be a mapping, got list"]),
    ("duplicate-key", "dt: 0.01\nT: 1.0\ndt: 0.1\n", ["not valid YAML (line 3: duplicate key 'dt' (first on line 1))"]),
]


@pytest.mark.parametrize("case_id, text, needles", TEXT_CASES, ids=[c[0] for c in TEXT_CASES])
def test_malformed_yaml_text(case_id, text, needles, tmp_path, capsys):
    bad = tmp_path / f"{case_id}.yaml"
    bad.write_text(text)
    code, _, err = cli(["run", bad, "--out", tmp_path / "out", "--quiet"], capsys)
    assert_one_line_error(code, err, str(bad), *needles)


def test_scenario_file_missing(tmp_path, capsys):
    code, _, err = cli(["run", tmp_path / "absent.yaml", "--quiet"], capsys)
    assert_one_line_error(code, err, "absent.yaml: scenario file not found")


def test_python_tags_are_rejected(tmp_path, capsys):
    """A `!!python/object` tag is an error, and the code it names is never run."""
    marker = tmp_path / "PWNED"
    bad = tmp_path / "tag.yaml"
    bad.write_text(f'dt: !!python/object/apply:os.system ["touch {marker}"]\nT: 1.0\n')
    code, _, err = cli(["run", bad, "--quiet"], capsys)
    assert_one_line_error(code, err, str(bad), "not valid YAML (line 1: could not determine a constructor",
                          "python/object/apply:os.system")
    assert not marker.exists()


@pytest.mark.parametrize("args, needles", [
    (["--K", "-1"], ["Invalid value for '--K'"]),
    (["--gamma", "-1"], ["--gamma: must be > 0"]),
    (["--gamma", "fast"], ["--gamma: must be a number > 0 or auto"]),
    (["--dt", "0"], ["Invalid value for '--dt'"]),
    (["--T", "0.015", "--dt", "0.01"], ["--T/--dt: T must be a whole number of steps dt = 0.01, got 0.015"]),
    (["--master", "magic"], ["Invalid value for '--master'"]),
    (["--no-such-option"], ["No such option '--no-such-option'"]),
], ids=["K", "gamma-negative", "gamma-word", "dt", "T-dt", "master", "option"])
def test_bad_command_line_options(args, needles, tmp_path, capsys):
    good = write_yaml(tmp_path / "good.yaml", copy.deepcopy(BASE))
    code, _, err = cli(["run", good, "--out", tmp_path / "out", "--quiet", *args], capsys)
    assert_one_line_error(code, err, *needles)


# ---- FMU archives: not an FMU, no state save/restore, escaping members, temporary folders ----

def _fmu_case(tmp_path, fmu_file):
    raw = copy.deepcopy(BASE)
    raw["subsystems"]["A"]["fmu"] = fmu_file.name
    return write_yaml(tmp_path / "scenario.yaml", raw)


def test_fmu_that_is_not_a_zip(tmp_path, capsys):
    fake = tmp_path / "Fake.fmu"
    fake.write_text("this is not an archive\n")
    code, _, err = cli(["run", _fmu_case(tmp_path, fake), "--quiet"], capsys)
    assert_one_line_error(code, err, "subsystems.A.fmu:", "Fake.fmu is not an FMU (not a zip archive)")


def test_zip_without_model_description(tmp_path, capsys):
    fake = tmp_path / "Empty.fmu"
    with zipfile.ZipFile(fake, "w") as z:
        z.writestr("readme.txt", "no model description here")
    code, _, err = cli(["run", _fmu_case(tmp_path, fake), "--quiet"], capsys)
    assert_one_line_error(code, err, "subsystems.A.fmu:", "Empty.fmu is not an FMU (no modelDescription.xml)")


def _rewritten_copy(src, dst, rewrite=None, extra=None):
    """A copy of a built FMU with its modelDescription.xml rewritten and extra members added."""
    with zipfile.ZipFile(src) as zin, zipfile.ZipFile(dst, "w") as zout:
        for item in zin.infolist():
            data = zin.read(item.filename)
            if item.filename == "modelDescription.xml" and rewrite:
                data = rewrite(data.decode()).encode()
            zout.writestr(item, data)
        for name, data in (extra or {}).items():
            zout.writestr(name, data)
    return dst


def test_fmu_without_state_save_restore(built_fmus, tmp_path, capsys):
    """An FMU declaring canGetAndSetFMUstate=false cannot be frozen and rolled back by DR."""
    def no_state(xml):
        assert 'canGetAndSetFMUstate="true"' in xml
        return xml.replace('canGetAndSetFMUstate="true"', 'canGetAndSetFMUstate="false"')
    fmu = _rewritten_copy(built_fmus["DuffingSide"], tmp_path / "NoState.fmu", no_state)
    code, _, err = cli(["run", _fmu_case(tmp_path, fmu), "--quiet"], capsys)
    assert_one_line_error(code, err, "subsystems.A.fmu: NoState.fmu cannot get and set its state")


def test_fmu_with_escaping_member_is_refused(built_fmus, tmp_path, capsys, monkeypatch):
    """A '../evil' member is refused before anything is extracted, and the folder is removed."""
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    fmu = _rewritten_copy(built_fmus["DuffingSide"], tmp_path / "Evil.fmu",
                          extra={"../evil": "escaped", "binaries/../../evil2": "escaped"})
    code, _, err = cli(["run", _fmu_case(tmp_path, fmu), "--quiet"], capsys)
    assert_one_line_error(code, err, "subsystems.A.fmu:", "archive member '../evil' escapes the extraction folder")
    assert not (tmp_path / "evil").exists() and not (scratch / "evil").exists()
    assert not (tmp_path / "evil2").exists()
    assert list(scratch.iterdir()) == []


def test_extraction_folders_are_removed_after_a_run(tmp_path, monkeypatch):
    """Every FMU is unpacked into its own temporary folder, and a finished run leaves none behind."""
    from wavecosim.scenario.config import parse_scenario
    from wavecosim.run.runner import run
    scratch = tmp_path / "tmp"
    scratch.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(scratch))
    seen = set()
    real_mkdtemp = tempfile.mkdtemp

    def spy(*args, **kwargs):
        path = real_mkdtemp(*args, **kwargs)
        seen.add(Path(path))
        return path
    monkeypatch.setattr(tempfile, "mkdtemp", spy)
    run(parse_scenario(copy.deepcopy(BASE), "base", ROOT / "configs"), certificates=False)
    assert len(seen) >= 2 and all(p.parent == scratch for p in seen)
    assert list(scratch.iterdir()) == []


# ---- through the installed executable: exit code and stderr of the real process ----

@pytest.mark.parametrize("case_id", ["dt-zero", "coupling-not-lossless", "fmu-path-missing", "parameter-name-missing"])
def test_executable(case_id, tmp_path):
    change, needles = next((c[1], c[2]) for c in CASES if c[0] == case_id)
    bad = write_yaml(tmp_path / f"{case_id}.yaml", mutate(change))
    env = dict(os.environ, TMPDIR=str(tmp_path))
    proc = subprocess.run([*CLI, "run", str(bad), "--out", str(tmp_path / "out"), "--quiet"],
                          capture_output=True, text=True, env=env, timeout=120)
    assert_one_line_error(proc.returncode, proc.stderr, str(bad), *needles)
    assert proc.stdout == ""
    assert not list(tmp_path.glob("wavecosim-fmu-*"))


def test_gamma_is_auto_where_there_is_a_power_bond_and_none_without():
    from wavecosim.scenario.config import parse_scenario
    raw = mutate(_drop(["gamma"]))
    assert parse_scenario(raw, "base").gamma == "auto"
    alone = {"dt": 0.01, "T": 0.05, "subsystems": {"B": {"fmu": "LinearSide"}}}
    sc = parse_scenario(alone, "alone")
    assert sc.gamma is None and sc.master.algorithm == "explicit" and sc.subsystems == []


def test_a_scenario_is_read_as_utf8_whatever_locale_an_fmu_set(tmp_path):
    """Dymola and OpenModelica FMUs call setlocale(LC_ALL, "C") in the process that loads them; a
    scenario file with a non-ASCII character still reads, as UTF-8."""
    import locale
    from wavecosim.scenario.config import load_scenario
    text = (ROOT / "configs" / "two_oscillators.yaml").read_text(encoding="utf-8")
    path = tmp_path / "s.yaml"
    path.write_text("# stiffness in N·m, Ω\n" + text, encoding="utf-8")
    before = locale.setlocale(locale.LC_CTYPE)
    try:
        locale.setlocale(locale.LC_CTYPE, "C")
        assert load_scenario(path).name
    finally:
        locale.setlocale(locale.LC_CTYPE, before)
