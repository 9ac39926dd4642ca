"""`master.threads: auto | N`: the subsystems of DR and of the Jacobi family on up to N threads.

Claims: the files a run writes are the same bytes on 1, 2, 4 and 8 threads, on an 8-subsystem scene
(the chain of 8 links; the 8 heavy chains) and on Table I, for DR, explicit, jacobi-iter, aitken and
iqn-ils (their passes in C, their update in Python, as the Python reference to the last bit), and the
kernel really ran that many threads; the plan is longest-processing-time first, re-balanced when the
costs drift; auto keeps a thread only while its measured round pays, and gives threads back when
the costs fall; N is capped by the CPUs ($WAVECOSIM_CPUS) and the subsystems.
"""
import dataclasses

import pytest

from paths import CONFIGS
from wavecosim.core.scene import build_scene
from wavecosim.errors import ConfigError
from wavecosim.kernel.drkernel import Kernel, thread_plan
from wavecosim.masters.threads import TRIAL_STEPS, ThreadPlanner, makespan
from wavecosim.run.runner import run
from wavecosim.scenario.config import load_scenario

THREADS = ("1", "2", "4", "8")


def written(scenario, out):
    """The bytes of the files a run writes (trajectory and per-step log), and its summary."""
    result = run(scenario, out, certificates=False, file_suffix=False)
    assert result.status == "finished"
    return {name: (out / name).read_bytes() for name in ("trajectory.csv", "steps.csv")}, result.summary


def same_bytes_on_every_thread_count(scenario, tmp_path, expected_threads):
    files = {}
    for threads in THREADS:
        files[threads], summary = written(scenario.with_master(fast="true", threads=threads), tmp_path / threads)
        assert summary["fast_path"] is True
        assert summary["threads"] == expected_threads(int(threads)), summary["thread_note"]
    for threads in THREADS[1:]:
        assert files[threads] == files["1"], f"{threads} threads changed the bytes"


@pytest.fixture
def eight_cpus(monkeypatch):
    """Plans of up to 8 threads on this machine, whatever its cores (they then share them)."""
    monkeypatch.setenv("WAVECOSIM_CPUS", "8")


JACOBI_FAMILY = ["dr", "explicit", "jacobi-iter", "aitken", "iqn-ils"]


@pytest.mark.parametrize("algorithm", JACOBI_FAMILY)
def test_chain_of_eight_same_bytes_on_1_2_4_8_threads(built_fmus, eight_cpus, tmp_path, algorithm):
    scenario = dataclasses.replace(load_scenario(CONFIGS / "chain.yaml"), T=0.3)
    scenario = scenario.with_master(algorithm=algorithm, K=6, energy_guard="off")
    same_bytes_on_every_thread_count(scenario, tmp_path, lambda n: n)


@pytest.mark.parametrize("algorithm", JACOBI_FAMILY)
def test_table_i_same_bytes_on_1_2_4_8_threads(built_fmus, eight_cpus, tmp_path, algorithm):
    scenario = dataclasses.replace(load_scenario(), T=1.0).with_master(algorithm=algorithm, K=8)
    same_bytes_on_every_thread_count(scenario, tmp_path, lambda n: min(n, 2))     # two subsystems


def test_heavy_chains_same_bytes_on_1_2_4_8_threads(built_fmus, eight_cpus, tmp_path):
    if "HeavyChain" not in built_fmus:
        pytest.skip("the HeavyChain FMU is not available")
    scenario = dataclasses.replace(load_scenario(CONFIGS / "heavy_chain_8.yaml"), T=0.03)
    same_bytes_on_every_thread_count(scenario, tmp_path, lambda n: n)


@pytest.mark.parametrize("algorithm", ["aitken", "iqn-ils"])
def test_accelerated_masters_passes_in_c_same_bytes_as_python(built_fmus, eight_cpus, tmp_path, algorithm):
    """aitken and iqn-ils: their passes in C on 4 threads, their update in Python; the files, the FMU
    calls and the per-step log as the Python reference's."""
    scenario = dataclasses.replace(load_scenario(CONFIGS / "chain.yaml"), T=0.3).with_master(algorithm=algorithm, K=6)
    python, py_summary = written(scenario.with_master(fast="false"), tmp_path / "python")
    kernel, summary = written(scenario.with_master(fast="true", threads="4"), tmp_path / "kernel")
    assert not py_summary["fast_path"] and summary["fast_path"] and summary["threads"] == 4
    assert summary["fast_note"] == "C kernel passes, the update in Python"
    assert kernel == python and summary["fmu_calls"] == py_summary["fmu_calls"]


def test_threads_capped_by_cpus(built_fmus, monkeypatch, tmp_path):
    monkeypatch.setenv("WAVECOSIM_CPUS", "3")
    scenario = dataclasses.replace(load_scenario(CONFIGS / "chain.yaml"), T=0.05).with_master(threads="8")
    _, summary = written(scenario, tmp_path)
    assert summary["threads"] == 3 and "capped at 3: 3 CPUs, 8 subsystems" in summary["thread_note"]


def test_gauss_seidel_stays_serial(built_fmus, eight_cpus, tmp_path):
    scenario = dataclasses.replace(load_scenario(), T=0.1).with_master(algorithm="gauss-seidel-iter", threads="4")
    _, summary = written(scenario, tmp_path)
    assert summary["threads"] == 1 and "predecessors' new outputs" in summary["thread_note"]


def test_thread_plan_is_longest_first():
    plan, load = thread_plan([300.0, 1.0, 280.0], 2)
    assert plan[0] != plan[2] and sorted(load) == [281.0, 300.0]
    plan, load = thread_plan([5.0, 3.0, 3.0, 2.0, 2.0, 2.0, 1.0, 1.0], 3)
    assert sorted(load) == [6.0, 6.0, 7.0] and makespan([5.0, 3.0, 3.0, 2.0, 2.0, 2.0, 1.0, 1.0], plan, 3) == 7.0


@pytest.fixture
def kernel(built_fmus, eight_cpus):
    """The C kernel over the eight heavy chains (its threads are real; no step is made)."""
    if "HeavyChain" not in built_fmus:
        pytest.skip("the HeavyChain FMU is not available")
    scene = build_scene(load_scenario(CONFIGS / "heavy_chain_8.yaml"))
    coupling = scene.wave_map()
    k = Kernel(scene.kernel_scene(), coupling.P_sparse, coupling.J_L_sparse)
    yield k
    k.close()
    scene.close()


def trial(planner, round_s):
    """The macro-steps of one trial, each with this round."""
    assert planner.on_trial
    for _ in range(TRIAL_STEPS):
        planner.tried(round_s)


def test_auto_adds_threads_while_they_pay(kernel):
    planner = ThreadPlanner(kernel, "auto", 8)
    planner.measured([300.0] * 8, 2400e-6)                       # serial: 8 x 300 µs a round
    assert planner.trial[0] == 2 and kernel.thread_plan() == planner.trial[1]
    trial(planner, 1300e-6)                                      # pays: kept, 3 threads go on trial
    assert planner.threads == 2 and planner.trial[0] == 3
    trial(planner, 1000e-6)                                      # 3 of 4 predicted a round: pays
    assert planner.threads == 3 and planner.trial[0] == 4        # 5..7 threads would not shorten the round
    trial(planner, 950e-6)                                       # 5% faster, 33% predicted: back to 3
    assert planner.threads == 3 and not planner.on_trial
    assert kernel.threads == 3 and kernel.thread_plan() == planner.plan
    assert planner.note.startswith("3 threads: 4 threads were not faster here")


def test_auto_stays_serial_when_a_thread_would_not_pay(kernel):
    planner = ThreadPlanner(kernel, "auto", 8)
    planner.measured([30.0] * 8, 240e-6)
    assert not planner.on_trial and planner.threads == 1 and kernel.threads == 1
    assert planner.note.startswith("serial: a second thread would take over 120 µs per round")


def test_auto_stays_serial_on_a_round_too_short_to_share(kernel):
    """A round under 2 PARALLEL_MIN_US cannot give a second thread its share, whatever the costs: the
    planner tries no plan and reads the costs only when asked; a longer round is planned as usual."""
    planner = ThreadPlanner(kernel, "auto", 8)
    assert planner.begin() == (True, True)
    planner.end(True, 250e-6)
    assert not planner.on_trial and planner.threads == 1 and kernel.threads == 1
    assert planner.note == "serial: a round takes 250 µs, a second thread pays from 300 µs"
    assert planner.costs == [0.0] * 8                            # no evaluation was timed: read as zeros
    planner.measured([300.0] * 8, 2400e-6)
    assert planner.trial[0] == 2


def test_auto_gives_threads_back_when_the_costs_fall(kernel):
    planner = ThreadPlanner(kernel, "auto", 8)
    planner.measured([400.0] * 8, 3200e-6)
    trial(planner, 1700e-6)
    assert planner.threads == 2
    planner.trial = None                                         # (the 3-thread trial not made)
    planner.measured([50.0] * 8, 400e-6)                         # 200 µs a thread: 2 still pay
    assert planner.threads == 2
    planner.measured([30.0] * 8, 240e-6)                         # 120 µs a thread: they do not
    assert planner.threads == 1 and kernel.threads == 1 and planner.note.startswith("serial (auto, fewer")


def test_plan_rebalanced_when_the_costs_drift(kernel):
    planner = ThreadPlanner(kernel, "4", 8)
    planner.measured([300.0] * 8, 2400e-6)
    assert planner.threads == 4 and kernel.threads == 4
    assert makespan([300.0] * 8, kernel.thread_plan(), 4) == 600.0
    drifted = [300.0] * 8
    drifted[planner.plan.index(1)] = drifted[planner.plan.index(2)] = 900.0     # thread 1 and 2 each got heavier
    drifted[len(planner.plan) - 1 - planner.plan[::-1].index(1)] = 900.0        # thread 1 twice
    before = makespan(drifted, planner.plan, 4)
    planner.measured(drifted, 1e-3)
    assert kernel.threads == 4 and kernel.thread_plan() == planner.plan
    assert makespan(drifted, planner.plan, 4) == max(thread_plan(drifted, 4)[1]) < before
    assert "re-balanced" in planner.note


def with_threads(tmp_path, value):
    """Table I's file with `master.threads: value`."""
    text = (CONFIGS / "two_oscillators.yaml").read_text()
    path = tmp_path / "threads.yaml"
    path.write_text(text.replace("  algorithm: dr", f"  algorithm: dr\n  threads: {value}"))
    return path


@pytest.mark.parametrize("value", ["0", "-1", "x", "true", "1.5"])
def test_bad_threads_is_a_config_error(tmp_path, value):
    with pytest.raises(ConfigError, match="master.threads: must be auto or a number of threads >= 1"):
        load_scenario(with_threads(tmp_path, value))


def test_threads_setting_read(tmp_path):
    assert load_scenario(with_threads(tmp_path, 4)).master.threads == "4"
    assert load_scenario(with_threads(tmp_path, "auto")).master.threads == "auto"
