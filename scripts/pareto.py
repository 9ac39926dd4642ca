"""The Pareto figures and the targets table of the docs (a few minutes; `make figures`):

    .venv/bin/python scripts/pareto.py

Runs `compare` (every master over its default grid, and DR with every named option,
wavecosim.sweeps.comparison.DR_OPTIONS; certificates off) on Table I and on the stiff scene, copies
pareto.png and energy_by_master.png into docs/figures/<scene>_*.png, and prints, per scene and
target max error, the cheapest budget of the best DR option with Theorem 1's certificate, of the
best DR option of all (Anderson included: energy-safe through the ledger guard only), and of the
best classical master (Newton apart: it is the reference), and of the best classical master on the
C kernel route (IQN-ILS and Aitken are Python loops), with doSteps per macro-step, wall time and
the route each ran on (C kernel or Python loop). The data stays under out/figures/;

    .venv/bin/python scripts/pareto.py --table

prints the table again from it, without running anything.
"""
import json
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from wavecosim.sweeps.comparison import CERTIFIED, DR_OPTIONS, TARGETS, compare, group_name  # noqa: E402
from wavecosim.scenario.config import load_scenario  # noqa: E402
from wavecosim.plots import compare_plots  # noqa: E402

DATA, FIGURES = ROOT / "out" / "figures", ROOT / "docs" / "figures"
SCENES = {"table1": "two_oscillators.yaml", "stiff": "two_oscillators_stiff.yaml"}
CLASSICAL = ("explicit", "gauss-seidel", "jacobi-iter", "gauss-seidel-iter", "aitken", "iqn-ils")


def route(row):
    return "C kernel" if row.get("fast_path") else "Python"


def best(rows, target, keep):
    """The row with the fewest doSteps per macro-step (then the least wall time) reaching `target`,
    not diverged, among the rows `keep` accepts; None if none does."""
    ok = [r for r in rows if keep(r) and r["diverged"] == "no" and r["max_error"] <= target]
    return min(ok, key=lambda r: (r["doSteps_per_step"], r["wall_time_s"]), default=None)


def cell(row):
    if row is None:
        return "not reached"
    return (f"{group_name(row)} K = {row['K']}: {row['doSteps_per_step']:.3g} doSteps/step, "
            f"{row['max_error']:.1e}, {row['wall_time_s']:.3f} s ({route(row)}), H/H(0) {row['H_growth']:.4g}")


def targets_table(name, rows):
    lines = []
    kinds = (("DR, Theorem 1 certified", lambda r: r["master"] == "dr" and r["option"] in CERTIFIED),
             ("DR, any option (ledger guard)", lambda r: r["master"] == "dr"),
             ("classical (incl. IQN-ILS)", lambda r: r["master"] in CLASSICAL),
             ("classical on the C kernel", lambda r: r["master"] in CLASSICAL and r.get("fast_path")))
    for target in TARGETS:
        cells = [cell(best(rows, target, keep)) for _, keep in kinds]
        lines.append(f"| {name} | {target:g} | " + " | ".join(cells) + " |")
    return lines


def main(table_only=False):
    FIGURES.mkdir(parents=True, exist_ok=True)
    table = ["| scene | max error | " + " | ".join(("best DR, Theorem 1 certified", "best DR, any option",
                                                     "best classical (incl. IQN-ILS)",
                                                     "best classical on the C kernel")) + " |",
             "|---|---|---|---|---|---|"]
    for name, config in SCENES.items():
        out = DATA / f"pareto_{name}"
        if table_only:
            table += targets_table(name, json.loads((out / "compare.json").read_text())["runs"])
            continue
        reference, results, rows = compare(load_scenario(ROOT / "configs" / config), out, certificates=False,
                                           options=list(DR_OPTIONS))
        for p in compare_plots(rows, results, reference, out):
            target = FIGURES / f"{name}_{p.name}"
            shutil.copyfile(p, target)
            print(f"wrote {target.relative_to(ROOT)}")
        table += targets_table(name, rows)
    print("\n".join(table))


if __name__ == "__main__":
    main(table_only="--table" in sys.argv[1:])
