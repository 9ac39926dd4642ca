"""`--plots` on every kind of run: each figure is drawn where its data exists and is a real PNG, and
a figure or columns left out are named in one `plots:` line on stderr."""
import os
import re
import subprocess

import pytest

from paths import CLI, CONFIGS, THIRD_PARTY

PNG = b"\x89PNG\r\n\x1a\n"
ENV = {"MPLBACKEND": "Agg", "WAVECOSIM_IN_PROCESS": "1"}        # in this process: one interpreter less per run
FIGURES = {"run": ("trajectories.png", "energy.png", "error.png"),
           "sweep": ("fig4_trajectories.png", "fig5_certificates.png", "fig6_error.png", "energy_by_K.png"),
           "compare": ("pareto.png", "energy_by_master.png")}


def plots(args, out, command="run"):
    """Run `command ... --plots` into `out`; (stdout + stderr, {figure: what became of it})."""
    proc = subprocess.run(CLI + [command, *map(str, args), "--plots", "--quiet", "--out", str(out)],
                          capture_output=True, text=True, timeout=300, env={**os.environ, **ENV})
    assert proc.returncode == 0, proc.stderr[-2000:]
    fate = {}
    for name in FIGURES[command]:
        wrote, left = f"wrote {out / name}" in proc.stdout, re.search(rf"^plots: {re.escape(name)}: (.*)$",
                                                                     proc.stderr, re.M)
        if wrote:
            assert (out / name).read_bytes()[:8] == PNG and (out / name).stat().st_size > 5000
        assert wrote or left, f"{name}: neither drawn nor said why\n{proc.stderr}"
        fate[name] = ("drawn" if wrote else "") + (f"; {left.group(1)}" if left else "")
        assert wrote or not (out / name).exists()
    return proc.stdout + proc.stderr, fate


@pytest.mark.slow
def test_a_scene_with_energy_and_a_reference_draws_all_three_and_names_the_columns_left_out(tmp_path, built_fmus):
    _, fate = plots(["--T", "0.2", "--master", "explicit"], tmp_path)
    assert fate["energy.png"] == fate["error.png"] == "drawn"
    assert fate["trajectories.png"] == ("drawn; 2 of 7 columns drawn; left out: v1, d, v2, bA, bB (--plot PATTERN "
                                        "draws others; trajectory.csv has them all)")


def test_fmus_without_stored_energy_leave_out_the_energy_figure_and_say_why(tmp_path, built_fmus):
    _, fate = plots([CONFIGS / "foreign_pair.yaml", "--T", "0.05"], tmp_path)
    assert fate["trajectories.png"].startswith("drawn; 2 of 3 columns drawn; left out: F (")
    assert fate["error.png"] == "drawn"
    assert fate["energy.png"].startswith("; not drawn: the total stored energy H needs every subsystem's")


def test_without_error_columns_the_trajectories_are_the_power_ports(tmp_path, built_fmus):
    text = (CONFIGS / "foreign_pair.yaml").read_text().split("\noutputs:")[0]
    (tmp_path / "pair.yaml").write_text(text)
    _, fate = plots([tmp_path / "pair.yaml", "--T", "0.05"], tmp_path / "out")
    assert fate["trajectories.png"].startswith("drawn; 2 of 4 columns drawn; left out: A.x, B.x (")
    assert fate["error.png"] == "; not drawn: the scenario names no error columns (`error:`)"


def test_one_fmu_alone_draws_its_outputs_only(tmp_path, built_fmus):
    _, fate = plots([built_fmus["LinearSide"], "--T", "0.05", "--dt", "0.01"], tmp_path)
    assert fate["trajectories.png"] == "drawn"
    assert fate["error.png"] == "; not drawn: no monolithic reference ran (no power ports, or --no-reference)"
    assert "not drawn" in fate["energy.png"]


def test_the_legend_names_the_master_and_its_budget_only_where_it_iterates(built_fmus):
    import wavecosim as wc
    from wavecosim.plots import run_label
    labels = [run_label(wc.simulate(master=m, K=7, T=0.02, reference=False, certificates=False))
              for m in ("explicit", "gauss-seidel", "jacobi-iter", "dr")]
    assert labels == ["explicit", "gauss-seidel", "jacobi-iter, K = 7", "dr, K = 7"]


@pytest.mark.slow
def test_plot_patterns_pick_the_columns_and_a_pattern_matching_none_is_refused(tmp_path, built_fmus):
    _, fate = plots(["--T", "0.05", "--plot", "v*", "--plot", "d"], tmp_path / "a")
    assert fate["trajectories.png"].startswith("drawn; 3 of 7 columns drawn; left out: q1, q2, bA, bB (")
    proc = subprocess.run(CLI + ["run", "--T", "0.05", "--plot", "x*", "--quiet", "--out", str(tmp_path / "b")],
                          capture_output=True, text=True, timeout=120)
    assert proc.returncode == 2 and proc.stderr.strip().splitlines()[-1] == (
        "error: --plot: x* matches no column (have: q1, v1, d, q2, v2, bA, bB)")
    assert (tmp_path / "b" / "trajectory.csv").exists()
    general = subprocess.run(CLI + ["sweep", "--set", "master.K=1,2", "--plot", "q*", "--out", str(tmp_path / "c")],
                             capture_output=True, text=True, timeout=120)
    assert general.returncode == 2 and general.stderr.strip() == (
        "error: --plot: a sweep with --set draws its --plot-y figures, not trajectories")


@pytest.mark.slow
def test_a_sweep_of_fmus_without_energy_draws_the_figures_it_has(tmp_path, built_fmus):
    _, fate = plots([CONFIGS / "foreign_pair.yaml", "--T", "0.05", "--Ks", "0,3"], tmp_path, "sweep")
    assert fate["fig4_trajectories.png"].startswith("drawn") and fate["fig6_error.png"] == "drawn"
    assert "not drawn" in fate["fig5_certificates.png"] and "not drawn" in fate["energy_by_K.png"]


@pytest.mark.slow
def test_a_comparison_of_fmus_without_energy_draws_the_error_against_cost(tmp_path, built_fmus):
    _, fate = plots([CONFIGS / "foreign_pair.yaml", "--T", "0.05", "--masters", "explicit,dr", "--Ks", "1,3"],
                    tmp_path, "compare")
    assert fate["pareto.png"].startswith("drawn; the energy growth panel not drawn: the total stored energy H")
    assert fate["energy_by_master.png"].startswith("; not drawn: the total stored energy H needs every subsystem's")


def third_party_systems():
    """Every system of the third-party corpus that a short run can make: single FMUs, SSP systems (with
    the dcmotor overlay too) and the example scenes made of their FMUs."""
    if not THIRD_PARTY.is_dir():
        return [pytest.param(None, marks=pytest.mark.skip(reason=f"{THIRD_PARTY} is absent"))]
    fmus = sorted(p for p in THIRD_PARTY.rglob("*.fmu") if "resources" not in p.parts and p.stem != "Clocks")
    systems = [[p, "--dt", "0.01", "--start-time", "0"] for p in fmus]       # Clocks: no co-simulation interface
    systems += [[p] for p in sorted(THIRD_PARTY.rglob("SystemStructure.ssd"))]
    systems += [[THIRD_PARTY / "dcmotor" / "SystemStructure.ssd", "--ports", CONFIGS / "dcmotor_ports.yaml"]]
    systems += [[CONFIGS / f"{name}.yaml"] for name in ("dcmotor", "dcmotor_shaft", "fmi3_damper")]
    return [pytest.param(s, id=f"{s[0].parent.name}/{s[0].name}{' --ports' if '--ports' in s else ''}")
            for s in systems]


QUICK_SCENES = ["two_oscillators.ssd", "two_oscillators_stiff.yaml", "chain.yaml", "pendulum_cart.yaml", "planar.yaml",
                "rlc_motor.yaml", "star.yaml"]


@pytest.mark.slow
@pytest.mark.parametrize("scene", QUICK_SCENES)
def test_every_quick_in_repo_scene_draws_all_three(scene, tmp_path, built_fmus):
    _, fate = plots([CONFIGS / scene, "--T", "0.05"], tmp_path)
    assert all(f.startswith("drawn") for f in fate.values()), fate


@pytest.mark.slow
@pytest.mark.parametrize("system", third_party_systems())
def test_every_third_party_system_plots(system, tmp_path, built_fmus):
    _, fate = plots([*system, "--T", "0.05"], tmp_path)
    assert fate["trajectories.png"].startswith("drawn") or "no column" in fate["trajectories.png"]
    assert "not drawn" in fate["energy.png"]                   # no third-party FMU reports its stored energy
    if not any(str(a).endswith(".yaml") for a in system):
        assert "not drawn" in fate["error.png"]                  # no power port without an overlay


@pytest.mark.slow
@pytest.mark.skipif(not THIRD_PARTY.is_dir(), reason=f"{THIRD_PARTY} is absent")
def test_a_sweep_of_an_ssd_with_ports_plots(tmp_path, built_fmus):
    _, fate = plots([THIRD_PARTY / "dcmotor" / "SystemStructure.ssd", "--ports", CONFIGS / "dcmotor_ports.yaml",
                     "--Ks", "0,5", "--T", "0.02"], tmp_path, "sweep")
    assert fate["fig4_trajectories.png"].startswith("drawn; 2 of 4 columns drawn; left out: I, U (")
    assert fate["fig6_error.png"] == "drawn" and "not drawn" in fate["energy_by_K.png"]
