"""Energy guards side by side (docs/energy.md): ledger, monolithic and off on every shipped scene and
on the runs where a small budget pumps energy in; prints a Markdown table.

    .venv/bin/python scripts/ledger_table.py [--quick]

Per run: max H/H(0); max (H - W)/H(0), W the work of the sources inside the FMUs (the running sum of
the positive Condition 2 residuals: dH_i beyond what port i took in); max error against the
monolithic reference (lockstep); steps the guard acted on; its extra doStep calls; master wall time.
"""
import argparse
import sys
from pathlib import Path

import numpy as np
import yaml

from wavecosim.scenario.config import parse_scenario
from wavecosim.run.runner import run

ROOT = Path(__file__).resolve().parent.parent

GUARDS = ("ledger", "monolithic", "off")
DRIVEN = {("B", "c2"): -3.0}
STIFF_K12 = {("A", "k12"): 1.2e6}


def runs(quick):
    """(label, file, master settings, T, parameters, top-level keys) of every row group."""
    shipped = [(f"{p.stem} (own K, T)", p, {}, None, {}, {}) for p in sorted((ROOT / "configs").glob("*.yaml"))]
    extra = [("star K=1, 20 s", ROOT / "configs/star.yaml", {"K": 1}, 20.0, {}, {}),
             ("chain K=1, 20 s", ROOT / "configs/chain.yaml", {"K": 1}, 20.0, {}, {}),
             ("Table I K=8", ROOT / "configs/two_oscillators.yaml", {"K": 8}, None, {}, {}),
             ("Table I k12=1.2e6, gamma=100, K=1", ROOT / "configs/two_oscillators.yaml", {"K": 1}, None,
              STIFF_K12, {"gamma": 100.0}),
             ("driven (Table I, c2=-3) K=8", ROOT / "configs/two_oscillators.yaml", {"K": 8}, None, DRIVEN, {}),
             ("driven (Table I, c2=-3) K=20", ROOT / "configs/two_oscillators.yaml", {"K": 20}, None, DRIVEN, {}),
             ("stiff, jacobi-iter K=1", ROOT / "configs/two_oscillators_stiff.yaml",
              {"algorithm": "jacobi-iter", "K": 1}, None, {}, {})]
    picked = extra if quick else shipped + extra
    return [r for r in picked if "heavy" not in r[0] or not quick]


def scenario(path, master, T, parameters, top, guard):
    raw = yaml.safe_load(Path(path).read_text())
    raw.setdefault("master", {}).update(master, energy_guard=guard)
    raw.update(top, **({"T": T} if T else {}))
    for (sub, name), value in parameters.items():
        raw["subsystems"][sub].setdefault("parameters", {})[name] = value
    return parse_scenario(raw, str(path), Path(path).parent)


def figures(result):
    """The row's numbers from one run (with its lockstep reference)."""
    s = result.summary
    H = np.asarray(result.energy)
    positive = np.clip(result.per_subsystem("r_"), 0.0, None).sum(axis=1)
    W = np.concatenate([[0.0], np.cumsum(positive)])
    error = result.error
    return {"H": H.max() / H[0], "H-W": (H - W).max() / H[0],
            "error": float(np.nanmax(error)) if error is not None else float("nan"),
            "acted": s.get("energy_guard_steps", 0), "extra": s.get("energy_guard_extra_doSteps", "-"),
            "wall": s["wall_time_s"], "status": s["status"]}


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--quick", action="store_true", help="only the runs where the guards matter (no shipped scenes)")
    args = ap.parse_args(argv)
    print("| run | guard | max H/H(0) | max (H−W)/H(0) | max error | steps acted | extra doSteps | wall (s) |")
    print("|---|---|---|---|---|---|---|---|")
    for label, path, master, T, parameters, top in runs(args.quick):
        for guard in GUARDS:
            sc = scenario(path, master, T, parameters, top, guard)
            try:
                f = figures(run(sc, reference="lockstep", certificates=False, warn=lambda m: None))
            except Exception as exc:                  # a diverging unguarded run is a row, not a stop
                print(f"| {label} | {guard} | failed: {str(exc).splitlines()[0][:80]} | | | | | |")
                continue
            print(f"| {label} | {guard} | {f['H']:.4g} | {f['H-W']:.4g} | {f['error']:.3g} | {f['acted']} | "
                  f"{f['extra']} | {f['wall']:.3f} |", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())
