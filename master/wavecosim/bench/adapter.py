"""`wavecosim bench`, the wave adapter rows: what a frozen-map evaluation of a subsystem with a
physical port costs on the Python route (wavecosim/core/ports.py::WaveAdapter, `master.fast: false`)
and on the C route (kernel/c/adapter.c under the DR kernel), on configs/foreign_pair.yaml and,
when the third-party FMUs are present, configs/dcmotor_shaft.yaml.

Each route is a whole run as `wavecosim run --no-reference` makes it (certificates off); µs per
query is the master time over the frozen-map evaluations of all its adapters, so it includes the
query's share of the DR update; doSteps per evaluation is the adapters' own count (equal on both
routes, as are the numbers: the bench checks the trajectories to the last bit).
"""
from ..examples import path as example, third_party
from ..scenario.config import load_scenario
from ..run.runner import run

SCENES = (("foreign_pair", None), ("dcmotor_shaft", "dcmotor"))       # (example, third-party folder it needs)
ROUTES = {"python": "false", "c": "true"}


def route_run(scenario, fast):
    """One run on a route: (figures, trajectory bytes)."""
    result = run(scenario.with_master(fast=fast, threads="1"), certificates=False, warn=lambda msg: None)
    s = result.summary
    adapters = s["wave_adapter"].values()
    evaluations = sum(a["map_evaluations"] for a in adapters)
    doSteps = sum(a["doSteps"] for a in adapters)
    return {"us_per_query": 1e6 * s["wall_time_s"] / evaluations, "doSteps_per_evaluation": doSteps / evaluations,
            "map_evaluations": evaluations, "master_s": s["wall_time_s"]}, result.trajectory.tobytes()


def scene_rows(scenario, repeats, progress):
    """Both routes on one scene, each the best of `repeats` runs taken in turn."""
    best, trajectories = {}, {}
    for i in range(repeats):
        for route, fast in ROUTES.items():
            progress(f"  wave adapter: {scenario.name}, {route} route ({i + 1}/{repeats})")
            figures, trajectories[route] = route_run(scenario, fast)
            if route not in best or figures["us_per_query"] < best[route]["us_per_query"]:
                best[route] = figures
    return {**best, "python_over_c": best["python"]["us_per_query"] / best["c"]["us_per_query"],
            "bit_identical": trajectories["python"] == trajectories["c"], "K": scenario.master.K,
            "steps": scenario.n_steps}


def adapter_bench(quick, repeats, progress=print):
    """{scene: rows} for every adapter scene whose FMUs are here (quick: the first 0.2 s)."""
    out = {}
    for name, needs in SCENES:
        if needs is not None and (third_party() is None or not (third_party() / needs).exists()):
            progress(f"  wave adapter: {name} skipped (the third-party folder {needs} is absent)")
            continue
        scenario = load_scenario(example(name))
        if quick and scenario.T > 0.2:
            scenario = scenario.with_changes(T=0.2)
        out[scenario.name] = scene_rows(scenario, repeats, progress)
    return out


def report_lines(rows):
    """The printed rows."""
    lines = [f"{'wave adapter (DR)':<34}{'µs/query':>10}{'doSteps/evaluation':>20}"]
    for name, r in rows.items():
        for route in ROUTES:
            lines.append(f"{name + ', ' + route + ' route':<34}{r[route]['us_per_query']:>10.2f}"
                         f"{r[route]['doSteps_per_evaluation']:>20.3f}")
        lines.append(f"  K = {r['K']}, {r['steps']} steps: python / c = {r['python_over_c']:.1f}, "
                     f"bit-identical: {r['bit_identical']}")
    return lines
