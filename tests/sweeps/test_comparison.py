"""`compare`: every master over its budgets against the monolithic reference, on the real FMUs."""
import dataclasses
import json

import pytest

from paths import ROOT
from wavecosim.cli import main
from wavecosim.sweeps.comparison import BUDGETS, compare
from wavecosim.scenario.config import load_scenario

TABLE_I = ROOT / "configs" / "two_oscillators.yaml"
STIFF = ROOT / "configs" / "two_oscillators_stiff.yaml"
PNG = b"\x89PNG\r\n\x1a\n"


def scenario(path, T):
    return dataclasses.replace(load_scenario(path), T=T)


@pytest.fixture(scope="module")
def table1(tmp_path_factory):
    out = tmp_path_factory.mktemp("compare")
    return out, compare(scenario(TABLE_I, 2.0), out, certificates=False)


def test_every_master_and_budget_is_a_row_and_on_disk(table1):
    out, (_, results, rows) = table1
    expected = [(m, "-" if K is None else K) for m, Ks in BUDGETS.items() for K in Ks]
    assert [(r["master"], r["K"]) for r in rows] == expected
    saved = json.loads((out / "compare.json").read_text())
    assert [(r["master"], r["K"]) for r in saved["runs"]] == expected
    assert all(r["finite"] == "yes" and r["diverged"] == "no" for r in rows)
    for r in rows:
        assert r["doStep"] > 0 and r["wall_time_s"] > 0 and r["real_time_factor"] > 0


def test_error_falls_with_budget_for_every_converging_master(table1):
    _, (_, _, rows) = table1
    paper = (0, 3, 8, 20, 35, 50)      # DR's error is not monotone between these at small K (K = 5: 0.016, 6: 0.032)
    for master in ("jacobi-iter", "gauss-seidel-iter", "dr"):
        errors = [r["max_error"] for r in rows if r["master"] == master and (master != "dr" or r["K"] in paper)]
        floor = 1e-13                                  # roundoff: two converged runs may tie there
        assert all(b < a or b < floor for a, b in zip(errors, errors[1:])), (master, errors)
        assert errors[-1] < 1e-10, (master, errors)
    newton = next(r for r in rows if r["master"] == "newton")
    assert newton["max_error"] == 0.0                  # the reference is the newton master


def test_a_diverging_master_is_reported_not_raised(tmp_path):
    # T = 20 s: the explicit master's outputs pass the growth bound (1e12 times their initial scale);
    # jacobi-iter diverges too with no energy guard, and passes it later (the ledger would hold it:
    # test_energy_ledger.py)
    stiff = scenario(STIFF, 20.0).with_master(energy_guard="off")
    ref, results, rows = compare(stiff, tmp_path, masters=["explicit", "jacobi-iter", "dr"],
                                 Ks=[1, 3], certificates=False)
    by = {(r["master"], r["K"]): r for r in rows}
    explicit = by[("explicit", "-")]
    assert explicit["finite"] == "no" and explicit["diverged"] == "yes" and explicit["status"] == "failed"
    assert explicit["message"] and explicit["steps"] < 2000
    jacobi = by[("jacobi-iter", 1)]
    assert jacobi["finite"] == "no" and jacobi["diverged"] == "yes" and "has grown past" in jacobi["message"]
    assert explicit["steps"] < jacobi["steps"] < 2000
    for K in (1, 3):
        assert by[("dr", K)]["diverged"] == "no" and by[("dr", K)]["H_growth"] <= 1.0 + 1e-12
    saved = json.loads((tmp_path / "compare.json").read_text())
    assert len(saved["runs"]) == 5


def test_cli_compare_prints_the_table_and_draws_the_figures(tmp_path, capsys):
    with pytest.raises(SystemExit) as exc:
        main(["compare", str(TABLE_I), "--T", "1", "--masters", "explicit,jacobi-iter,dr", "--Ks", "2,20",
              "--out", str(tmp_path), "--plots", "--quiet", "--no-certificates"])
    assert exc.value.code == 0
    printed = capsys.readouterr().out
    assert "max_error" in printed and "wall_time_s" in printed and "jacobi-iter" in printed
    assert len(json.loads((tmp_path / "compare.json").read_text())["runs"]) == 5
    for name in ("pareto.png", "energy_by_master.png"):
        assert (tmp_path / name).read_bytes()[:8] == PNG


def test_each_master_writes_into_a_folder_of_its_own(tmp_path):
    compare(scenario(TABLE_I, 0.1), tmp_path, masters=["explicit", "dr"], Ks=[2, 5], certificates=False,
            options=["relaxed"])
    assert sorted(p.name for p in tmp_path.iterdir()) == ["compare.json", "dr", "dr-relaxed", "explicit", "monolithic"]
    kinds = ("trajectory", "steps", "summary", "metadata")
    for folder, labels in (("explicit", ["explicit"]), ("dr", ["dr_K2", "dr_K5"]),
                           ("dr-relaxed", ["dr-relaxed_K2", "dr-relaxed_K5"]), ("monolithic", ["monolithic"])):
        expected = sorted(f"{kind}_{label}.{'csv' if kind in kinds[:2] else 'json'}" for kind in kinds for label in labels)
        assert sorted(p.name for p in (tmp_path / folder).iterdir()) == expected


@pytest.mark.parametrize("args, words", [(["--masters", "explicit,leapfrog"], "unknown master 'leapfrog'"),
                                         (["--K", "3", "--Ks", "1,2"], "not both")])
def test_cli_compare_rejects_bad_options_in_one_line(tmp_path, capsys, args, words):
    with pytest.raises(SystemExit) as exc:
        main(["compare", str(TABLE_I), "--out", str(tmp_path), "--quiet", *args])
    assert exc.value.code == 2
    err = capsys.readouterr().err.strip()
    assert words in err and len(err.splitlines()) == 1


def test_energy_safe_is_the_interface_ledger_and_H_within_roundoff(tmp_path):
    """IQN-ILS at K = 2 on the stiff scene ends at 2.5 H(0): H below 1000 H(0) passes as not diverged,
    yet the interface supplied net energy, so it is not energy-safe and `cheapest` skips it (it is kept
    in cheapest_any_energy). DR with its ledger is safe."""
    from wavecosim.sweeps.comparison import cheapest
    ref, results, rows = compare(scenario(STIFF, 10.0), tmp_path, masters=["iqn-ils", "dr"], Ks=[2],
                                 certificates=False)
    iqn, dr = rows
    assert iqn["diverged"] == "no" and 1.5 < iqn["H_growth"] < 1e3
    assert iqn["energy_safe"] == "no" and iqn["ledger_max"] > 1e3 * iqn["energy_allowance"]
    assert dr["energy_safe"] == "yes" and dr["ledger_max"] <= dr["energy_allowance"] and dr["H_growth"] <= 1.0
    loose = {**iqn, "max_error": 0.5 * dr["max_error"]}                  # were it accurate, still not picked
    assert "iqn-ils" not in cheapest([loose, dr], (dr["max_error"],))[f"{dr['max_error']:g}"]
    assert "iqn-ils" in cheapest([loose, dr], (dr["max_error"],), safe=False)[f"{dr['max_error']:g}"]
    saved = json.loads((tmp_path / "compare.json").read_text())
    assert set(saved) >= {"cheapest", "cheapest_any_energy"}


def test_critical_path_counts_a_sequential_masters_calls_whole():
    from wavecosim.sweeps.comparison import compare_row
    import wavecosim as wc
    sc = scenario(ROOT / "configs" / "chain.yaml", 0.2)
    gs, jac = (compare_row(wc.simulate(sc, master=m, K=2, certificates=False), 2, subsystems=8)
               for m in ("gauss-seidel-iter", "jacobi-iter"))
    assert gs["critical_path_doSteps"] == gs["doSteps_per_step"] == 24.0
    assert jac["critical_path_doSteps"] == jac["doSteps_per_step"] / 8 == 3.0
