"""The measured tables of docs/parallel.md, made from measurements, never copied by hand.

  python scripts/parallel_tables.py round-trip rt.json
      µs per round trip of every engine that carries a run to worker processes (shared memory,
      Dask actors; Ray actors when `ray` is importable), with 1, 2 and 8 workers each holding one
      subsystem of configs/chain.yaml, side by side in one run, with the load average.
  python scripts/parallel_tables.py write bench.json rt.json [docs/parallel.md]
      replaces the tables between the `<!-- name -->` and `<!-- /name -->` markers of the page:
      `parallel_threads` from `wavecosim bench --json` (or `--only parallel_threads`), `round_trip`
      from the file above.
"""
import json
import os
import re
import sys
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
WORKERS = (1, 2, 8)
ROUNDS = 300


def _dask_client(workers):
    from distributed import Client, LocalCluster
    cluster = LocalCluster(n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=None)
    client = Client(cluster)
    client.close = lambda close=client.close: (close(), cluster.close())     # the cluster with the client
    return client


def _ray_round_trip(scenario, workers):
    """µs per round of `workers` Ray actors, each hosting one subsystem, answering ping."""
    import ray
    from wavecosim.run.distributed import SubsystemHost, groups_of
    ray.init(num_cpus=max(workers), include_dashboard=False, log_to_driver=False, ignore_reinit_error=True)
    Host = ray.remote(SubsystemHost)
    out = {}
    try:
        for w in workers:
            actors = [Host.remote(scenario, names) for names in groups_of(scenario, w)]
            ray.get([a.ping.remote() for a in actors])
            started = time.perf_counter()
            for _ in range(ROUNDS):
                ray.get([a.ping.remote() for a in actors])
            out[w] = 1e6 * (time.perf_counter() - started) / ROUNDS
            ray.get([a.close.remote() for a in actors])
    finally:
        ray.shutdown()
    return out


def round_trip(path):
    from wavecosim.run.distributed import round_trips
    from wavecosim.scenario.config import load_scenario
    scenario = load_scenario(ROOT / "configs" / "chain.yaml").with_master(energy_guard="off")
    load = [os.getloadavg()[0]]
    engines = {"shm": round_trips(scenario, "shm", WORKERS, rounds=ROUNDS),
               "dask": round_trips(scenario, "dask", WORKERS, _dask_client, rounds=ROUNDS)}
    try:
        engines["ray"] = _ray_round_trip(scenario, WORKERS)
    except ImportError:
        pass
    load.append(os.getloadavg()[0])
    data = {"scene": scenario.name, "cpus": os.cpu_count(), "rounds": ROUNDS, "load_average_1min": load,
            "us_per_round_trip": {e: {str(w): v for w, v in rows.items()} for e, rows in engines.items()}}
    Path(path).write_text(json.dumps(data, indent=1))
    print(json.dumps(data, indent=1))


def threads_table(bench):
    p = bench["parallel_threads"]
    lines = [f"Eight heavy chains (`configs/heavy_chain_8.yaml`), DR K = {p['K']}, "
             f"{min(p['us_per_eval']):.0f}-{max(p['us_per_eval']):.0f} µs per evaluation, {p['cpus']} CPUs, "
             f"load average {p['load_average_1min'][0]:.2f} before and {p['load_average_1min'][1]:.2f} after; "
             f"best of {p['repeats']} runs of {p['steps']} macro-steps; the floor of any plan (the costliest "
             f"subsystem per round) is {p['floor_us_per_step']:.0f} µs per macro-step.", "",
             "| threads | used | µs per macro-step | speedup | target | ideal of the plan (µs) |",
             "|---|---|---|---|---|---|"]
    for r in p["rows"]:
        lines.append(f"| {r['threads']} | {r['threads_used']} | {r['us_per_step']:.0f} | {r['speedup']:.2f} | "
                     f"{r['target_speedup']:.2f} | {r['ideal_us_per_step']:.0f} |")
    return lines


def round_trip_table(rt):
    engines = rt["us_per_round_trip"]
    workers = list(next(iter(engines.values())))
    lines = [f"µs per round trip (every worker answers one call, no FMU work), {rt['cpus']} CPUs, load average "
             f"{rt['load_average_1min'][0]:.2f} before and {rt['load_average_1min'][1]:.2f} after, "
             f"{rt['rounds']} rounds each, side by side in one run.", "",
             "| engine | " + " | ".join(f"{w} worker{'s' if w != '1' else ''}" for w in workers) + " |",
             "|---|" + "---|" * len(workers)]
    for engine, rows in engines.items():
        lines.append(f"| {engine} | " + " | ".join(f"{rows[w]:.0f}" for w in workers) + " |")
    return lines


def write(bench_path, rt_path, page=ROOT / "docs" / "parallel.md"):
    text = Path(page).read_text()
    tables = {"parallel_threads": threads_table(json.loads(Path(bench_path).read_text())),
              "round_trip": round_trip_table(json.loads(Path(rt_path).read_text()))}
    for name, lines in tables.items():
        pattern = re.compile(rf"(<!-- {name} -->\n).*?(<!-- /{name} -->)", re.S)
        if not pattern.search(text):
            raise SystemExit(f"{page}: no <!-- {name} --> ... <!-- /{name} --> markers")
        text = pattern.sub(lambda m: m.group(1) + "\n".join(lines) + "\n" + m.group(2), text)
    Path(page).write_text(text)
    print(f"wrote {page}")


if __name__ == "__main__":
    if len(sys.argv) >= 3 and sys.argv[1] == "round-trip":
        round_trip(sys.argv[2])
    elif len(sys.argv) in (4, 5) and sys.argv[1] == "write":
        write(*sys.argv[2:])
    else:
        raise SystemExit(__doc__)
