"""Regenerate the Table I sweep figures of the docs, docs/figures/table1_*.png, from the real FMUs
(`make figures` runs this and the other figure scripts).

    .venv/bin/python scripts/make_figures.py

Runs the same code as `wavecosim sweep --plots` (the paper's Figs. 4-6 on Table I); the data of
each run stays under out/figures/, only the PNGs are copied into docs/figures/. The comparison of
masters (Pareto and energy figures, Table I and the stiff scene) comes from scripts/pareto.py.
"""
import shutil
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT))

from wavecosim.scenario.config import load_scenario  # noqa: E402
from wavecosim.plots import sweep_plots  # noqa: E402
from wavecosim.sweeps.budget import sweep  # noqa: E402

DATA, FIGURES = ROOT / "out" / "figures", ROOT / "docs" / "figures"


def publish(paths, prefix):
    for p in paths:
        target = FIGURES / f"{prefix}_{p.name}"
        shutil.copyfile(p, target)
        print(f"wrote {target.relative_to(ROOT)}")


def main():
    FIGURES.mkdir(parents=True, exist_ok=True)
    table1 = load_scenario(ROOT / "configs" / "two_oscillators.yaml")
    reference, results, _ = sweep(table1, [0, 3, 8, 20, 35, 50], DATA / "sweep")
    publish(sweep_plots(results, reference, DATA / "sweep"), "table1")


if __name__ == "__main__":
    main()
