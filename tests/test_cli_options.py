"""Options of `run` and `sweep` through the real command line: --out naming a file (exit 7 as the
table says), `run --set KEY=VALUE`, and `sweep --ports` for an SSP system with an overlay."""
import json
import subprocess

from paths import CLI, CONFIGS

SSD = CONFIGS / "two_oscillators.ssd"


def cli(*args, cwd=None):
    proc = subprocess.run([*CLI, *map(str, args)], capture_output=True, text=True, timeout=120, cwd=cwd)
    return proc.returncode, proc.stdout, proc.stderr


def test_out_naming_a_file_is_an_output_error(tmp_path):
    (tmp_path / "taken").write_text("a file\n")
    code, _, err = cli("run", "--T", "0.05", "--quiet", "--out", tmp_path / "taken")
    assert code == 7 and err.splitlines() == [f"error: {tmp_path / 'taken'}: is a file, not a folder; choose another "
                                              f"--out"], err


def test_run_set_gives_a_key_one_value(tmp_path, built_fmus):
    code, out, err = cli("run", "--T", "0.05", "--quiet", "--no-reference", "--set", "master.K=7",
                         "--set", "subsystems.A.parameters.k1=2.5", "--out", tmp_path / "o")
    assert code == 0 and "dr K=7" in out, err
    scenario = json.loads((tmp_path / "o" / "metadata.json").read_text())["scenario"]
    assert scenario["master"]["K"] == 7 and scenario["subsystems"][0]["parameters"]["k1"] == 2.5


def test_run_set_refuses_a_list_and_an_unknown_key(tmp_path):
    code, _, err = cli("run", "--T", "0.05", "--quiet", "--set", "master.K=7,8", "--out", tmp_path / "o")
    assert code == 2 and err.splitlines() == ["error: --set master.K: a run takes one value (a sweep takes lists and "
                                              "distributions)"], err
    code, _, err = cli("run", "--T", "0.05", "--quiet", "--set", "master.Kx=7", "--out", tmp_path / "o")
    assert code == 2 and len(err.splitlines()) == 1 and "master.Kx: unknown key" in err, err


def test_sweep_takes_an_ssp_system_with_its_ports_overlay(tmp_path, built_fmus):
    """The overlay's dt and T reach every run, of a general sweep and of the sweep over K."""
    (tmp_path / "ports.yaml").write_text("dt: 0.005\nT: 0.05\n")
    code, _, err = cli("sweep", SSD, "--ports", tmp_path / "ports.yaml", "--set", "master.K=0,3", "--workers", "1",
                       "--quiet", "--out", tmp_path / "general")
    assert code == 0, err
    runs = json.loads((tmp_path / "general" / "runs.json").read_text())["runs"]
    assert [(r["master.K"], r["dt"], r["steps"]) for r in runs] == [(0, 0.005, 10), (3, 0.005, 10)]
    code, _, err = cli("sweep", SSD, "--ports", tmp_path / "ports.yaml", "--K", "3", "--quiet", "--out", tmp_path / "K")
    assert code == 0, err
    runs = json.loads((tmp_path / "K" / "summary.json").read_text())["runs"]
    assert [(r["K"], r["dt"], r["steps"]) for r in runs] == [(3, 0.005, 10)]
