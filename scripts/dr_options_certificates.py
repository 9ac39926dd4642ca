"""The certificates under each DR option (docs/masters.md, "Options"): a table, about a minute.

    .venv/bin/python scripts/dr_options_certificates.py [OPTION,OPTION K,K,K]

(the second form: only those options of DR_OPTIONS, at those budgets on both scenes)

Runs DR on Table I and the stiff scene with certificates on (8 sampled FNE pairs and Theorem 1's
augmented residual per step, the Condition 1 watch) for a few budgets, plain and with each named
option (wavecosim.sweeps.comparison.DR_OPTIONS), and prints max error, the largest positive augmented
residual (Theorem 1: <= 0 up to roundoff), the smallest FNE margin, the steps the ledger guard
redid and max H/H(0).
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from wavecosim.sweeps.budget import reference_run  # noqa: E402
from wavecosim.sweeps.comparison import DR_OPTIONS  # noqa: E402
from wavecosim.scenario.config import load_scenario  # noqa: E402
from wavecosim.run.runner import run  # noqa: E402

SCENES = {"table1": ("two_oscillators.yaml", (3, 8, 20)), "stiff": ("two_oscillators_stiff.yaml", (4, 8, 20))}


def row(name, option, K, s):
    return (f"| {name} | {option or 'plain'} | {K} | {s['max_error']:.2e} | {s.get('max_augmented_pos', float('nan')):.1e} "
            f"| {s.get('min_fne_margin', float('nan')):.2e} | {s['energy_guard_steps']} | {s['H_growth']:.6g} |")


def main(names=None, budgets=None):
    options = {"": (None, {}, None), **DR_OPTIONS} if names is None else {n: DR_OPTIONS[n] for n in names}
    print("| scene | option | K | max error | max augmented⁺ (Thm. 1) | min FNE margin | ledger steps | max H/H(0) |")
    print("|---|---|---|---|---|---|---|---|")
    for name, (config, Ks) in SCENES.items():
        base = load_scenario(ROOT / "configs" / config)
        if name == "stiff":
            base = base.with_changes(gamma="auto")        # gamma = 0.4 barely contracts there (docs/gamma.md)
        reference = reference_run(base)
        for option, (gamma, changes, _) in options.items():
            sc = base if gamma is None else base.with_changes(gamma=gamma)
            for K in Ks if budgets is None else budgets:
                result = run(sc.with_master(K=K, **changes), reference=reference, warn=lambda m: None)
                print(row(name, option, K, result.summary), flush=True)


if __name__ == "__main__":
    main(sys.argv[1].split(",") if len(sys.argv) > 1 else None,
         [int(k) for k in sys.argv[2].split(",")] if len(sys.argv) > 2 else None)
