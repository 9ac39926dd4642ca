"""Every master's kernel route gives its Python reference's numbers, to the last bit.

For each master with a kernel route (ROUTED), `master.fast: true` (the C kernel) runs against
`master.fast: false` (the Python reference) on the scenes that exercise what the route does: wave
ports (Table I), the stiff scene, several channels per port (chain), a physical port through the
wave adapter (foreign_pair; the classical masters over its signed physical ports), an FMI 3 FMU and Dymola FMUs whose queries stall (when the third-party
FMUs are present), the certificates inside the blocks, the energy ledger acting, a deadline, two
threads, a change of gamma, and failures. Compared step by step (every StepLog field, the committed
waves or outputs, the inner loop's trace, FMU calls, an undo and recommit), through the Route
(run_steps: blocks, the H cap, undo after a block) and through the runner in its blocks
(trajectories, steps tables, FMU calls, the summary's figures). A route a master gives is a
`Route`; the masters without a kernel route give none.
"""
import contextlib
import copy
import dataclasses
import json
import math

import numpy as np
import pytest

from paths import CONFIGS, THIRD_PARTY
from wavecosim.core import ports
from wavecosim.core.gamma import rescatter
from wavecosim.core.readings import Sampler
from wavecosim.core.scene import build_scene
from wavecosim.errors import ConfigError, FmuError, NumericalError, RunFailed
from wavecosim.masters import MASTERS
from wavecosim.masters.base import Route
from wavecosim.run.runner import run
from wavecosim.scenario.config import load_scenario

ROUTED = ("dr", "explicit", "gauss-seidel", "jacobi-iter", "gauss-seidel-iter", "newton", "aitken", "iqn-ils")
BLOCKS = ("dr", "explicit", "gauss-seidel", "jacobi-iter", "gauss-seidel-iter")     # their route makes blocks
THIRD_PARTY_SCENES = ("fmi3_damper", "dcmotor_shaft")
STEPS = 30                          # macro-steps of the step-by-step comparisons
# summary entries that say which route ran or how long it took (all others must agree)
ROUTE_KEYS = ("block_steps", "fast_path", "fast_note", "threads", "thread_note", "real_time_factor",
              "step_time_us", "guarded_step_time_us", "deadline_bound")


def bits(x):
    return np.asarray(x, dtype=float).tobytes()


@pytest.fixture(scope="module")
def scenario(built_fmus):
    """scenario(name, T=None, **master): a shipped scenario file with T and master settings replaced
    (read once per module; skipped when it needs the absent third-party FMUs)."""
    loaded = {}

    def shipped(name, T=None, **master):
        if name not in loaded:
            if name in THIRD_PARTY_SCENES and not THIRD_PARTY.exists():
                pytest.skip("needs the third-party FMUs (../shared/third_party)")
            loaded[name] = load_scenario(CONFIGS / f"{name}.yaml")
        sc = copy.deepcopy(loaded[name])
        return dataclasses.replace(sc, T=T or sc.T).with_master(**master)
    return shipped


@contextlib.contextmanager
def both_routes(sc):
    """The scenario's master on its Python reference and on its kernel route, each over a scene of
    its own; all closed afterwards."""
    cls = MASTERS[sc.master.algorithm]
    masters, scenes = [], []
    try:
        for fast in ("false", "true"):
            scenes.append(build_scene(sc, wave=cls.wave, needs_rollback=cls.needs_rollback))
            masters.append(cls(scenes[-1], dataclasses.replace(sc.master, fast=fast)))
        yield masters, scenes
    finally:
        for m in masters:
            m.close()
        for s in scenes:
            s.close()


def committed(m):
    """What a master carries from one macro-step to the next: b^n (wave) or y^n (and the inputs of
    the last commit when it rolls back)."""
    if m.wave:
        return bits(m.b)
    return bits(m.y) + (bits(m.u) if hasattr(m, "u") else b"")


def same_logs(a, b, where, fields=("residual", "a_hat", "u0", "uK")):
    assert (a.iterations, a.reason) == (b.iterations, b.reason), where
    for field in fields:
        x, y = getattr(a, field), getattr(b, field)
        assert (x is None) == (y is None) and bits(x) == bits(y), f"{where}: {field}"


def same_block_logs(a, b, where):
    """A row of a block's log against the reference's StepLog (blocks log no iterates u^0, u^K)."""
    same_logs(a, b, where, ("residual", "a_hat") if b.a_hat is not None else ("residual",))


def same_state(ref, fast, scenes, where):
    assert committed(ref) == committed(fast), f"{where}: the committed waves or outputs differ"
    assert [s.calls for s in scenes[0].subsystems] == [s.calls for s in scenes[1].subsystems], f"{where}: FMU calls"
    adapters = [[s.map.info() for s in scene.subsystems if s.adapter] for scene in scenes]
    assert adapters[0] == adapters[1], f"{where}: wave adapter figures"


def the_route(master):
    """master.route(), checked against the declared contract."""
    route = master.route()
    assert route is None or isinstance(route, Route)
    return route


def test_every_master_is_routed_or_declares_no_route(scenario):
    """A master not in ROUTED gives no route and runs its Python reference; a routed one runs the
    kernel with fast: auto (newton makes no blocks: one kernel call per step; aitken and iqn-ils neither:
    their passes in C, their update in Python), the reference with false."""
    sc = scenario("two_oscillators_stiff", K=3)
    for name, cls in MASTERS.items():
        scene = build_scene(sc, wave=cls.wave, needs_rollback=cls.needs_rollback)
        try:
            for fast in ("auto", "false"):
                master = cls(scene, dataclasses.replace(sc.master, algorithm=name, fast=fast))
                route, info = the_route(master), master.run_info()
                master.close()
                kernel = name in ROUTED and fast == "auto"
                assert info.get("fast_path", False) is kernel, (name, fast, info.get("fast_note"))
                assert (route is not None) == (kernel and name in BLOCKS), (name, fast)
        finally:
            scene.close()


# (master, scene, T, master settings) of the step-by-step comparisons
STEPPED = {
    "dr-table1-K0": ("dr", "two_oscillators", dict(K=0)),
    "dr-table1-K8": ("dr", "two_oscillators", dict(K=8)),
    "dr-table1-tolerance": ("dr", "two_oscillators", dict(K=50, eps=1e-9)),
    "dr-stiff-options": ("dr", "two_oscillators_stiff", dict(K=3, anderson=2, start="extrapolated", relaxation=0.9)),
    "dr-adapter": ("dr", "foreign_pair", dict(K=5)),
    "dr-fmi3": ("dr", "fmi3_damper", dict(K=5)),
    "newton-table1": ("newton", "two_oscillators", {}),
    "newton-stiff": ("newton", "two_oscillators_stiff", {}),
    "newton-adapter": ("newton", "foreign_pair", {}),
    "newton-fmi3": ("newton", "fmi3_damper", {}),
    "explicit-stiff": ("explicit", "two_oscillators_stiff", {}),
    "explicit-physical": ("explicit", "foreign_pair", {}),
    "gauss-seidel-stiff": ("gauss-seidel", "two_oscillators_stiff", {}),
    "jacobi-iter-physical": ("jacobi-iter", "foreign_pair", dict(K=3)),
    "jacobi-iter-stiff": ("jacobi-iter", "two_oscillators_stiff", dict(K=3)),
    "gauss-seidel-iter-chain": ("gauss-seidel-iter", "chain", dict(K=10, eps=1e-9)),
    "aitken-stiff": ("aitken", "two_oscillators_stiff", dict(K=3)),
    "iqn-ils-chain": ("iqn-ils", "chain", dict(K=6)),
}


def retune(masters, scenes):
    """Halve every subsystem's gamma between macro-steps (as auto-retune does) on both routes."""
    for m, scene in zip(masters, scenes):
        gammas = {s.name: 0.5 * s.gamma for s in scene.subsystems}
        b = rescatter(scene, gammas)
        scene.set_gammas(gammas)
        m.retune(b)


@pytest.mark.parametrize("case", STEPPED)
def test_step_by_step(scenario, case):
    """Every StepLog, the committed waves or outputs and the FMU calls after each step, the DR trace;
    wave masters change gamma half way; then an undo of the last step and its recommit."""
    name, scene, settings = STEPPED[case]
    sc = scenario(scene, algorithm=name, **settings)
    with both_routes(sc) as ((ref, fast), scenes):
        assert fast.run_info()["fast_path"] and not ref.run_info()["fast_path"]
        traced = [m.enable_trace(True) for m in (ref, fast)]
        for n in range(STEPS):
            if n == STEPS // 2 and ref.wave:
                retune((ref, fast), scenes)
            a, b = ref.step(n, n * sc.dt), fast.step(n, n * sc.dt)
            same_logs(a, b, f"step {n}")
            same_state(ref, fast, scenes, f"step {n}")
            if traced == [True, True]:
                assert [bits(p) for q in ref.trace for p in q] == [bits(p) for q in fast.trace for p in q]
        if ref.guardable:
            inputs = ref._committed_inputs(a)
            for m in (ref, fast):
                m._undo_step()
                m._recommit(inputs)
            same_state(ref, fast, scenes, "undo and recommit")


@pytest.mark.parametrize("name, scene, settings", [
    ("dr", "two_oscillators", dict(K=8, energy_guard="off")),
    ("dr", "two_oscillators", dict(K=8, threads="1", energy_guard="off")),
    ("dr", "two_oscillators", dict(K=3, start="previous", energy_guard="off")),     # a^{n-1} after the undo
    ("explicit", "two_oscillators_stiff", {}),
    ("gauss-seidel", "two_oscillators", {}), ("jacobi-iter", "two_oscillators_stiff", dict(K=3)),
    ("gauss-seidel-iter", "two_oscillators_stiff", dict(K=10, eps=1e-12))])
def test_the_route_makes_the_steps_of_the_reference(scenario, name, scene, settings):
    """Route.run_steps in blocks of 7 (the last one short) logs the reference's steps and reads what
    its Sampler reads; with an H cap below H it stops after one step, and undo_step after a block
    goes back as after step()."""
    sc = scenario(scene, algorithm=name, **settings)
    with both_routes(sc) as ((ref, fast), scenes):
        route = the_route(fast)
        assert route is not None and ref.route() is None
        samplers = [Sampler(s, sc.outputs) for s in scenes]
        route.observe(samplers[1].observed)
        readings = []

        def ref_step(n):
            """The reference's step n and the run's reading after it (the kernel reads it in the block)."""
            step = ref.step(n, n * sc.dt)
            readings.append(samplers[0].read())
            return step
        n = 0
        while n < STEPS:
            done, log, error = route.run_steps(n, min(7, STEPS - n))
            assert error is None and done == min(7, STEPS - n) and not log.stopped
            for j in range(done):
                same_block_logs(ref_step(n + j), route.step_log(log, j), f"step {n + j}")
            assert plain_ledger(log), f"the ledger's rows of the block from step {n}"
            n += done
            same_state(ref, fast, scenes, f"block ending at step {n - 1}")
        observed = samplers[1].block(log.observed).outputs[-1]
        assert bits(readings[-1].outputs) == bits(observed)
        done, log, error = route.run_steps(n, 10, H_cap=0.0)
        assert (done, error, log.stopped) == (1, None, True)
        same_block_logs(ref_step(n), route.step_log(log, 0), "capped step")
        if ref.guardable:
            for m in (ref, fast):
                m._undo_step()
            same_state(ref, fast, scenes, "undo after a block")
            same_block_logs(ref_step(n), route.step_log(route.run_steps(n, 1)[1], 0), "step after the undo")
            same_state(ref, fast, scenes, "step after the undo")


def plain_ledger(log):
    """Every step of a block made without the ledger or a deadline logs the ledger's defaults: nothing
    supplied, booked or timed, scale 1, kept, no redo round."""
    led = log.ledger
    return (all(np.isnan(led[k]).all() for k in ("supplied", "ledger", "traffic", "step_s", "cpu_s"))
            and (led["scale"] == 1.0).all() and (led["action"] == 0).all() and (led["rounds"] == 0).all()
            and np.array_equal(led["round_s"], np.full(len(log), led["round_s"][0]), equal_nan=True))


def test_a_plain_block_after_a_timed_one_logs_the_ledger_defaults_again(scenario):
    """The kernel writes the ledger's plain rows once per log and skips them while they hold: a call
    timed by a deadline that logs inside them (after the columns of an earlier call) writes its
    times there, so the next plain call over those columns writes the defaults again; so does a plain
    call over more columns than the last plain rows written, or with another round time."""
    sc = scenario("two_oscillators", algorithm="dr", K=3, energy_guard="off")        # the kernel keeps no ledger
    with both_routes(sc) as ((_, fast), scenes):
        fast.route().observe(Sampler(scenes[1], sc.outputs).observed, 12)
        kernel = fast.kernel
        assert plain_ledger(kernel.run_steps(0, 12)[1])
        kernel.io.deadline_s = 1.0                      # clocked, never reached
        done, log, _ = kernel.run_steps(12, 4, at=3)    # columns 3 .. 6
        assert done == 4 and not np.isnan(log.ledger["step_s"]).any()
        kernel.io.deadline_s = 0.0
        done, log, _ = kernel.run_steps(16, 12)
        assert done == 12 and plain_ledger(log)
        kernel.io.deadline_s = 1.0
        kernel.run_steps(28, 12)                         # every column timed
        kernel.io.deadline_s = 0.0
        assert plain_ledger(kernel.run_steps(40, 4, at=3)[1])      # plain in columns 3 .. 6 alone
        done, log, _ = kernel.run_steps(44, 12)
        assert done == 12 and plain_ledger(log)
        kernel.io.round_s = 0.25                         # a plain row logs the round time as it stands
        done, log, _ = kernel.run_steps(56, 12)
        assert done == 12 and plain_ledger(log) and (log.ledger["round_s"] == 0.25).all()


def same_run(ref, fast, skip=()):
    """The runs agree byte for byte: status, trajectory, steps table, and every summary figure but
    those naming the route or its timing (and `skip`)."""
    assert not ref.summary["fast_path"] and fast.summary["fast_path"], fast.summary["fast_note"]
    assert (ref.status, ref.message) == (fast.status, fast.message)
    assert ref.trajectory_table.array().tobytes() == fast.trajectory_table.array().tobytes(), "trajectories differ"
    assert ref.steps_table.columns == fast.steps_table.columns
    for j, column in enumerate(ref.steps_table.columns):
        assert bits(ref.steps_table.array()[:, j]) == bits(fast.steps_table.array()[:, j]), f"steps column {column}"

    def figures(result):
        return json.dumps({k: v for k, v in result.summary.items()
                           if k not in ROUTE_KEYS + tuple(skip) and not k.endswith("_s")}, sort_keys=True)
    assert figures(ref) == figures(fast)


def run_both(sc, **options):
    """The run on the Python reference and on the kernel route."""
    return [run(sc.with_master(fast=fast), warn=lambda note: None, **options) for fast in ("false", "true")]


# (master, scene, T, master settings, run options, what the kernel's run must show)
RUNS = {
    "dr-table1-K0": ("dr", "two_oscillators", 1.0, dict(K=0), {}, "blocks"),
    "dr-table1-certificates": ("dr", "two_oscillators", 0.5, dict(K=8), dict(certificates=True), "blocks"),
    "dr-table1-tolerance": ("dr", "two_oscillators", 1.0, dict(K=50, eps=1e-9), {}, "blocks"),
    "dr-stiff-two-threads": ("dr", "two_oscillators_stiff", 0.5, dict(K=3, threads="2"), {}, "threads"),
    "dr-chain-two-threads": ("dr", "chain", 0.3, dict(K=8, threads="2"), {}, "threads"),
    "dr-star-ledger": ("dr", "star", 1.0, dict(K=1, energy_guard="ledger", start="paper"), {}, "guard"),
    "dr-star-deadline": ("dr", "star", 1.0, dict(K=1000, deadline_us=1e-3), {}, "deadline"),
    "dr-adapter": ("dr", "foreign_pair", 0.05, dict(K=5), {}, "adapter"),
    "dr-adapter-two-threads": ("dr", "foreign_pair", 0.05, dict(K=5, threads="2"), {}, "threads"),
    "dr-fmi3": ("dr", "fmi3_damper", 0.3, dict(K=5), {}, "adapter"),
    "dr-stalled-queries": ("dr", "dcmotor_shaft", 0.05, {}, {}, "stalled"),
    "newton-table1": ("newton", "two_oscillators", 0.5, {}, {}, ""),
    "newton-stiff": ("newton", "two_oscillators_stiff", 0.5, {}, {}, ""),
    "newton-chain": ("newton", "chain", 0.2, {}, {}, ""),
    "newton-adapter": ("newton", "foreign_pair", 0.05, {}, {}, "adapter"),
    "newton-fmi3": ("newton", "fmi3_damper", 0.1, {}, {}, "adapter"),
    "explicit-stiff": ("explicit", "two_oscillators_stiff", 1.0, {}, dict(output_interval=7), "blocks"),
    "explicit-physical": ("explicit", "foreign_pair", 0.3, {}, {}, "blocks"),
    "gauss-seidel-iter-physical": ("gauss-seidel-iter", "foreign_pair", 0.3, dict(K=3, eps=1e-12), {}, "blocks"),
    "gauss-seidel-chain": ("gauss-seidel", "chain", 0.5, {}, {}, "blocks"),
    "jacobi-iter-table1-K0": ("jacobi-iter", "two_oscillators", 0.5, dict(K=0, energy_guard="off"), {}, "blocks"),
    "jacobi-iter-stiff": ("jacobi-iter", "two_oscillators_stiff", 1.0, dict(K=3), {}, "blocks"),
    "jacobi-iter-stiff-ledger": ("jacobi-iter", "two_oscillators_stiff", 1.0, dict(K=1, energy_guard="ledger"), {},
                                 "guard"),
    "jacobi-iter-deadline": ("jacobi-iter", "chain", 0.3, dict(K=1000, deadline_us=1e-3), {}, "deadline"),
    "gauss-seidel-iter-chain": ("gauss-seidel-iter", "chain", 0.5, dict(K=10, eps=1e-9), {}, "blocks"),
    "aitken-stiff": ("aitken", "two_oscillators_stiff", 0.5, dict(K=3), {}, ""),
    "iqn-ils-chain-two-threads": ("iqn-ils", "chain", 0.3, dict(K=6, threads="2"), {}, "threads"),
}


@pytest.mark.parametrize("case", RUNS)
def test_whole_runs(scenario, case):
    name, scene, T, settings, options, shows = RUNS[case]
    if shows in ("blocks", "guard", "deadline"):        # no thread plan on trial: its step is made alone
        settings = {"threads": "1", **settings}
    ref, fast = run_both(scenario(scene, T, algorithm=name, **settings), **options)
    same_run(ref, fast)
    s = fast.summary
    assert ref.summary["block_steps"] == 0
    if shows in ("blocks", "guard", "deadline") and name in BLOCKS:
        by_step = name != "dr" and s["energy_guard"] == "ledger"        # the classical masters' ledger
        assert s["block_steps"] == (0 if by_step else s["steps"])
    if shows == "guard":
        assert s["energy_guard_steps"] > 0
    if shows == "deadline":
        assert set(fast.steps["iterations"]) == {1} and "deadline" in set(fast.steps["reason"])
    if shows == "threads":
        assert s["threads"] == 2
    if shows == "adapter":
        assert s["wave_adapter"]
    if shows == "stalled":
        assert s["wave_adapter"]["machine"]["stalled_queries"] > 0


def failing(sc, **options):
    """The error of the run on each route (RunFailed): equal messages and exit codes; the first."""
    errors = []
    for fast in ("false", "true"):
        with pytest.raises(RunFailed) as info:
            run(sc.with_master(fast=fast), certificates=False, warn=lambda note: None, **options)
        errors.append(info.value)
    assert [(str(e), e.exit_code) for e in errors[:1]] == [(str(e), e.exit_code) for e in errors[1:]]
    # the kernel books no FMU call of the step that failed (the reference counts the calls it made)
    same_run(errors[0].result, errors[1].result, skip=("fmu_calls", "fmu_calls_by_subsystem"))
    return errors[1]


@pytest.mark.parametrize("name, threads, newton_max_iter, q1, step",
                         [(m, "1", 1, 3.0, 0) for m in ROUTED] + [("dr", "2", 1, 3.0, 0), ("dr", "2", 4, 2.0, 18)])
def test_an_fmu_error_is_the_references(scenario, name, threads, newton_max_iter, q1, step):
    """A doStep that fails (the Duffing side's Newton held to a few iterations) names subsystem, call,
    step and time."""
    sc = scenario("two_oscillators", 1.0, algorithm=name, K=3, threads=threads)
    sc.subsystems[0].integers["newton_max_iter"] = newton_max_iter
    sc.subsystems[0].start["q1"] = q1
    error = failing(sc)
    assert isinstance(error.error, FmuError) and error.exit_code == 3
    assert str(error).startswith(f"subsystem A: fmi2DoStep returned Error at step {step} ")


@pytest.mark.parametrize("bound, why", [(1e12, "has grown past 1e+12"), (math.inf, "fmi2DoStep returned Error")])
def test_a_run_that_blows_up_fails_alike_in_blocks(scenario, bound, why):
    """Explicit coupling pumps the stiff scene up until its outputs pass the growth bound (without
    one: until an FMU fails): the same failure at the same step, the same rows before it (output
    interval 7) and the same FMU calls, the kernel's in blocks that stop at the bound too."""
    sc = dataclasses.replace(scenario("two_oscillators_stiff", 20.0, algorithm="explicit"), growth_bound=bound)
    error = failing(sc, output_interval=7)
    assert why in str(error) and error.result.summary["block_steps"] > 0
    if bound < math.inf:                   # the kernel stops where the reference does: the same FMU calls
        with pytest.raises(RunFailed) as reference:
            run(sc.with_master(fast="false"), certificates=False, warn=lambda note: None, output_interval=7)
        assert reference.value.result.summary["fmu_calls"] == error.result.summary["fmu_calls"]


def test_a_newton_that_does_not_converge_is_the_references(scenario):
    """Gamma 0.4 on a stiff coupling with a heavy mass: the interface Newton gives up, alike."""
    sc = scenario("two_oscillators", 10.0, algorithm="newton").with_changes(gamma=0.4, dt=0.1)
    sc.subsystems[0].parameters["k12"] = 1.2e5
    sc.subsystems[1].parameters["m2"] = 400.0
    error = failing(sc)
    assert isinstance(error.error, NumericalError) and error.exit_code == 4
    assert str(error).startswith("interface Newton at step ") and "did not converge" in str(error)


def test_an_unsolved_adapter_query_is_the_references(scenario, monkeypatch):
    monkeypatch.setattr(ports, "TOL", 0.0)
    monkeypatch.setattr(ports, "ACCEPT", 0.0)
    error = failing(scenario("foreign_pair", 0.2).with_changes(gamma=1.0))
    assert isinstance(error.error, NumericalError)
    assert str(error).startswith("subsystem A: wave adapter at step 0 (t = 0): no convergence in 30 Newton iterations")


def test_an_fmu_error_inside_an_adapter_query_is_the_references(scenario):
    """A spring so stiff that one doStep overflows its force: named as the FMU's own call."""
    sc = scenario("foreign_pair", 0.2, K=5).with_changes(gamma=1.0)
    sc.subsystems[1].parameters["k"] = 1e300
    error = failing(sc)
    assert str(error).startswith("subsystem B: fmi2DoStep returned Error at step 0 (t = 0)")


@pytest.mark.parametrize("name", ["dr", "jacobi-iter", "newton"])
def test_fast_true_where_the_kernel_cannot_run_is_a_config_error(scenario, name):
    """master.fast: true insists on the kernel: one line naming the subsystem; auto falls back."""
    sc = scenario("two_oscillators", algorithm=name)
    cls = MASTERS[name]
    scene = build_scene(sc, wave=cls.wave)
    try:
        scene.subsystems[1].fmu.can_save_state = False
        with pytest.raises(ConfigError) as info:
            cls(scene, dataclasses.replace(sc.master, fast="true"))
        message = str(info.value)
        assert "\n" not in message and "master.fast: true, but subsystem B cannot get and set" in message
        fallback = cls(scene, dataclasses.replace(sc.master, fast="auto"))
        assert not fallback.run_info()["fast_path"] and "subsystem B" in fallback.run_info()["fast_note"]
        assert fallback.route() is None
        fallback.close()
    finally:
        scene.close()
