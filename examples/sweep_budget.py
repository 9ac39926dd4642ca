"""Load the paper's Table I scene, sweep the inner budget K, and plot the error against K and
against FMU calls (doSteps per macro-step): the speed-accuracy trade of the DR master.

    python examples/sweep_budget.py [OUT.png]
"""
import sys
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402

import wavecosim as wc  # noqa: E402


def main(out="sweep_budget.png"):
    table_i = Path(__file__).resolve().parent.parent / "configs" / "two_oscillators.yaml"
    scenario = wc.load(table_i, T=2.0)                                # a shorter horizon than the paper's
    table = wc.sweep(scenario, Ks=[0, 2, 5, 10, 20, 35, 50], certificates=False)
    runs = table.array(["K", "max_error", "steps"])
    calls = [r["fmu_calls"]["doStep"] / r["steps"] for r in table.rows]
    fig, (a, b) = plt.subplots(1, 2, figsize=(10, 3.8))
    a.semilogy(runs["K"], runs["max_error"], "o-")
    a.set(xlabel="inner budget K", ylabel="max error against the monolithic run")
    b.loglog(calls, runs["max_error"], "o-")
    b.set(xlabel="doSteps per macro-step", ylabel="max error")
    for ax in (a, b):
        ax.grid(alpha=0.3, which="both")
    fig.tight_layout()
    fig.savefig(out, dpi=110)
    for row, c in zip(table.rows, calls):
        print(f"K = {row['K']:>2}: max error {row['max_error']:.3e}, {c:.0f} doSteps per macro-step")
    return table


if __name__ == "__main__":
    main(*sys.argv[1:])
