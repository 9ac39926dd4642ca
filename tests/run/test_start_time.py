"""Start time, tolerance, step size and stop time from the FMUs' DefaultExperiment (Timer, built here:
start 20 s, stop 22 s, step 0.25 s, tolerance 1e-5) unless the file or the command line gives them;
the grid is t_n = t_0 + n dt everywhere: the recorded times, the doStep calls of the Python masters
and of the C kernel, and its blocks of steps."""
import math

import numpy as np
import pytest
from fmpy.fmi2 import fmi2LastSuccessfulTime

import wavecosim as wc
from wavecosim.errors import ConfigError
from wavecosim.run.runner import LiveRun, run
from wavecosim.scenario.config import parse_scenario

TIMER = {"name": "timer", "subsystems": {"clock": {"fmu": "Timer"}}}


def timer(**top):
    return parse_scenario({**TIMER, **top}, "timer.yaml")


def test_the_default_experiment_sets_start_step_stop_and_tolerance():
    sc = timer()
    assert (sc.start_time, sc.dt, sc.T, sc.n_steps) == (20.0, 0.25, 22.0, 8)
    traj = run(sc).trajectory
    assert np.array_equal(traj["time"], 20.0 + 0.25 * np.arange(9))
    assert np.array_equal(traj["clock.clock"], traj["time"]) and set(traj["clock.start"]) == {20.0}
    assert set(traj["clock.tolerance"]) == {1e-5}
    assert np.array_equal(traj["clock.steps"], np.arange(9))


def test_the_file_and_the_command_line_override_the_default_experiment(tmp_path):
    sc = parse_scenario({**TIMER, "start_time": 1.0, "dt": 0.5, "T": 3.0,
                         "subsystems": {"clock": {"fmu": "Timer", "tolerance": 1e-8}}}, "timer.yaml")
    traj = run(sc).trajectory
    assert np.array_equal(traj["time"], [1.0, 1.5, 2.0, 2.5, 3.0]) and np.array_equal(traj["clock.clock"], traj["time"])
    assert set(traj["clock.tolerance"]) == {1e-8}
    result = wc.simulate(timer(), start_time=-1.0, dt=0.5, T=0.0)
    assert np.array_equal(result.trajectory["time"], [-1.0, -0.5, 0.0])
    assert result.trajectory["clock.start"][0] == -1.0


BAD = [
    ("stop-before-start", dict(T=19.0), "timer.yaml: T: the stop time must be after the start time 20, got 19"),
    ("not-whole-steps", dict(dt=0.3), "timer.yaml: T: must be a whole number of steps dt = 0.3 after the start time "
                                      "20, got 22.0 (the DefaultExperiment stopTime of clock)"),
]


@pytest.mark.parametrize("case, top, needle", BAD, ids=[b[0] for b in BAD])
def test_times_that_do_not_fit_are_refused_naming_where_they_came_from(case, top, needle):
    with pytest.raises(ConfigError) as info:
        timer(**top)
    assert needle in str(info.value)


def test_start_times_that_differ_and_a_missing_step_size_are_refused_in_one_line():
    two = {"subsystems": {"clock": {"fmu": "Timer"}, "src": {"fmu": "SignalSource"}}}
    with pytest.raises(ConfigError, match=r"^mix.yaml: start_time: not given, and the FMUs' DefaultExperiment start "
                                          r"times differ \(clock: 20, src: 0\); give start_time or --start-time$"):
        parse_scenario(two, "mix.yaml")
    assert parse_scenario({**two, "start_time": 0.0}, "mix.yaml").dt == 0.05        # the smaller stepSize
    with pytest.raises(ConfigError, match=r"^sink.yaml: dt: not given, and no FMU gives a DefaultExperiment "
                                          r"stepSize; give dt: or --dt$"):
        parse_scenario({"subsystems": {"sink": {"fmu": "SignalSink"}}}, "sink.yaml")


def _last_successful_time(live):
    return [s.fmu.slave.getRealStatus(fmi2LastSuccessfulTime) for s in live.scene.subsystems]


@pytest.mark.parametrize("master, fast", [("dr", "true"), ("dr", "false"), ("explicit", "true"), ("explicit", "false")])
def test_masters_and_the_kernel_step_from_the_start_time(master, fast):
    """Table I shifted to t_0 = 5: the same numbers (its FMUs do not read the time), every time
    5 + t, and the FMUs' last doStep ended at 5 + T (fmi2LastSuccessfulTime), in blocks of steps
    (kernel) and step by step (Python)."""
    base = wc.load(None, T=0.2, master=master).with_master(fast=fast)
    shifted = base.with_changes(start_time=5.0, T=5.2)
    a, b = run(base, certificates=False), run(shifted, certificates=False)
    assert np.array_equal(b.trajectory["time"], 5.0 + a.trajectory["time"])
    for name in a.columns:
        assert np.array_equal(a.trajectory[name], b.trajectory[name]), name
    assert b.summary["block_steps"] == a.summary["block_steps"] and (fast == "false") == (a.summary["block_steps"] == 0)
    live = LiveRun(shifted, certificates=False)
    try:
        live.start()
        n = 0
        while n < live.n_steps:
            n += live.advance(n, live.block_size(n))
        assert all(math.isclose(t, 5.2, rel_tol=1e-12) for t in _last_successful_time(live))
    finally:
        live.finish("finished", "")
