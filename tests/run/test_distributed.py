"""One DR run with its subsystems in worker processes (wavecosim/run/distributed.py).

Claims: the recorded outputs and times are the in-process run's to the last bit (energy guard off,
no certificates) on Table I and on the 8-subsystem chain, with one worker per subsystem or groups of
them, through shared memory and through Dask actors on a real local cluster; the round trip is
measured; what the prototype does not carry over is refused in one line; a worker that cannot open
its FMU says so.
"""
import dataclasses

import pytest

from paths import CONFIGS
from wavecosim.errors import ConfigError
from wavecosim.run.distributed import groups_of, run_distributed
from wavecosim.run.runner import run
from wavecosim.scenario.config import load_scenario


def in_process(scenario):
    result = run(scenario, certificates=False)
    return result.t, result.outputs, result.steps["iterations"]


def same_bits(scenario, got):
    t, outputs, iterations = in_process(scenario)
    assert got.t.tobytes() == t.tobytes()
    assert got.outputs.tobytes() == outputs.tobytes(), "the worker processes changed the numbers"
    assert got.iterations.tolist() == iterations.astype(int).tolist()
    assert got.round_trip_us > 0


def table_i(T=0.3):
    return dataclasses.replace(load_scenario(), T=T).with_master(energy_guard="off")


def test_table_i_in_two_processes_same_bits(built_fmus):
    scenario = table_i()
    got = run_distributed(scenario)
    assert (got.engine, got.workers) == ("shm", 2)
    same_bits(scenario, got)


def test_chain_of_eight_in_worker_processes_same_bits(built_fmus):
    scenario = dataclasses.replace(load_scenario(CONFIGS / "chain.yaml"), T=0.1).with_master(K=8, energy_guard="off")
    same_bits(scenario, run_distributed(scenario, workers=3))           # groups of 3, 3 and 2 subsystems


@pytest.mark.slow
def test_heavy_chains_one_process_each_same_bits(built_fmus):
    if "HeavyChain" not in built_fmus:
        pytest.skip("the HeavyChain FMU is not available")
    scenario = dataclasses.replace(load_scenario(CONFIGS / "heavy_chain_8.yaml"), T=0.02).with_master(energy_guard="off")
    got = run_distributed(scenario)
    assert got.workers == 8
    same_bits(scenario, got)


@pytest.mark.slow
def test_table_i_on_dask_actors_same_bits(built_fmus):
    distributed = pytest.importorskip("distributed")
    scenario = table_i(T=0.1)
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True, dashboard_address=None) as cluster, \
            distributed.Client(cluster) as client:
        got = run_distributed(scenario, engine="dask", client=client)
    assert got.engine == "dask"
    same_bits(scenario, got)


def test_groups_are_consecutive_and_cover_every_subsystem():
    scenario = load_scenario(CONFIGS / "chain.yaml")
    assert groups_of(scenario, 3) == [["L0", "L1"], ["L2", "L3", "L4"], ["L5", "L6", "L7"]]
    assert groups_of(scenario, None) == [[f"L{i}"] for i in range(8)]
    assert groups_of(scenario, 50) == groups_of(scenario, 8)


@pytest.mark.parametrize("change, message", [
    ({"algorithm": "jacobi-iter"}, "worker processes run dr only"),
    ({"relaxation": 1.5}, "Algorithm 1 as the paper gives it"),
])
def test_what_is_not_carried_over_is_refused(change, message):
    with pytest.raises(ConfigError, match=message):
        run_distributed(table_i().with_master(**change))


def test_substeps_are_refused():
    scenario = table_i()
    scenario.subsystems[0].substeps = 2
    with pytest.raises(ConfigError, match="subsystems.A.substeps: worker processes make one doStep per macro-step"):
        run_distributed(scenario)


def test_a_worker_that_cannot_open_its_fmu_says_so(built_fmus):
    scenario = table_i()
    scenario.subsystems[1].parameters["no_such_parameter"] = 1.0
    with pytest.raises(ConfigError, match="a worker could not open its subsystems: .*no_such_parameter"):
        run_distributed(scenario)
