"""The paper's experiment: the monolithic reference and one DR run per budget K, with errors."""
from pathlib import Path

from .observers.recorder import write_json
from .runner import reference_scenario, run

SWEEP_FIELDS = ("K", "max_error", "rms_error", "final_error", "max_passivity_pos", "max_augmented_pos",
                "min_fne_margin", "wall_time_s")


def reference_run(scenario, out_dir=None, progress=None):
    """The monolithic discrete-time trajectory: interface Newton at every macro-step."""
    return run(reference_scenario(scenario), out_dir=out_dir, label="monolithic", progress=progress,
               certificates=False)


def sweep(scenario, Ks, out_dir, progress=None, certificates=True, reference=None, on_run=None):
    """Run DR for every K in Ks against the monolithic reference; writes DIR/summary.json."""
    out_dir = Path(out_dir) if out_dir is not None else None
    reference = reference or reference_run(scenario, out_dir, progress and progress("monolithic"))
    runs, results = [], []
    for K in Ks:
        sc = scenario.with_master(algorithm="dr", K=K)
        result = run(sc, out_dir=out_dir, label=f"K{K}", progress=progress and progress(f"K = {K}"),
                     certificates=certificates, reference=reference)
        entry = {k: result.summary.get(k) for k in SWEEP_FIELDS}
        entry.update({k: v for k, v in result.summary.items() if k not in entry})
        runs.append(entry)
        results.append(result)
        if out_dir is not None:
            write_json(out_dir / "summary.json", {"scenario": scenario.name, "source": scenario.source,
                                                  "reference": reference.summary, "runs": runs})
        if on_run:
            on_run(entry)
    return reference, results, runs


__all__ = ["sweep", "reference_run", "SWEEP_FIELDS"]
