"""Regenerate the README figures, docs/figures/*.png, from the real FMUs (about a minute).

    .venv/bin/python scripts/make_figures.py

Runs the same code as `wavecosim sweep --plots` (the paper's Figs. 4-6 on Table I) and
`wavecosim compare --plots` (every master and budget, on Table I and on the stiff scene); the data
of each run stays under out/figures/, only the PNGs are copied into docs/figures/.
"""
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from wavecosim.comparison import compare  # noqa: E402
from wavecosim.config import load_scenario  # noqa: E402
from wavecosim.plots import compare_plots, sweep_plots  # noqa: E402
from wavecosim.budget_sweep import sweep  # noqa: E402

DATA, FIGURES = ROOT / "out" / "figures", ROOT / "docs" / "figures"


def publish(paths, prefix):
    for p in paths:
        target = FIGURES / f"{prefix}_{p.name}"
        shutil.copyfile(p, target)
        print(f"wrote {target.relative_to(ROOT)}")


def main():
    FIGURES.mkdir(parents=True, exist_ok=True)
    table1 = load_scenario(ROOT / "configs" / "two_oscillators.yaml")
    stiff = load_scenario(ROOT / "configs" / "two_oscillators_stiff.yaml")
    reference, results, _ = sweep(table1, [0, 3, 8, 20, 35, 50], DATA / "sweep")
    publish(sweep_plots(results, reference, DATA / "sweep"), "table1")
    for name, sc in (("table1", table1), ("stiff", stiff)):
        reference, results, rows = compare(sc, DATA / f"compare_{name}")
        publish(compare_plots(rows, results, reference, DATA / f"compare_{name}"), name)


if __name__ == "__main__":
    main()
