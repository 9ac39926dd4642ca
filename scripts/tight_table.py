"""The measured table of docs/masters.md, "Tighter tolerances": the recommended master of each scene
(as scripts/tolerance_table.py measures them) in the tolerance mode at 1e-5 and 1e-6, against one fine
reference each (its FMUs set up as the tightest run sets up its own), beside the best fixed run of
the tolerance table's grid at the same true error (mostly extrapolated: "~"). Needs that table's
rows (scripts/tolerance_table.py OUT) first:

    .venv/bin/python scripts/tight_table.py [OUT]            # rows into OUT/tight.json, the table into the page
    .venv/bin/python scripts/tight_table.py OUT --again      # the table again from the rows in OUT

The page holds it between `<!-- measured: tight -->` and `<!-- end of measured -->`.
"""
import json
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "master"))

import measured  # noqa: E402
from tolerance_table import SCENES  # noqa: E402
from wavecosim.scenario.config import load_scenario  # noqa: E402
from wavecosim.sweeps import tolerances  # noqa: E402

RECOMMENDED = {"two_oscillators": "dr", "two_oscillators_stiff": "dr", "chain": "dr", "foreign_pair": "gauss-seidel",
               "dcmotor": "gauss-seidel"}
TIGHT = {"two_oscillators": (1e-5, 1e-6), "two_oscillators_stiff": (1e-5, 1e-6), "chain": (1e-5, 1e-6),
         "foreign_pair": (1e-5,), "dcmotor": (1e-5,)}     # a first-order master at 1e-6 would run for hours
PAGE = ROOT / "docs" / "masters.md"


def measure(out):
    """Each scene's tolerance-mode rows at its tight tolerances."""
    rows = []
    for name, T in SCENES:
        if name == "dcmotor" and not (ROOT.parent / "shared" / "third_party").exists():
            continue
        sc = load_scenario(ROOT / "configs" / f"{name}.yaml").with_changes("the table", T=T).with_master(options="auto")
        reference = tolerances.fine(tolerances.fixed_fmus(sc, TIGHT[name]))
        for tol in TIGHT[name]:
            run = sc.with_master(algorithm=RECOMMENDED[name], tolerance=tol, estimate="auto")
            rows.append({"scene": name, "T": T, **tolerances.measure("tolerance", run, reference)})
            print(rows[-1], flush=True)
    return rows


def table(rows, out):
    """The page's block: one line per row, its best fixed run read from the tolerance table's grid."""
    head = ["| scene | master | tolerance | true error | / tolerance | doSteps | wall (s) | best fixed at that error: "
            "doSteps (master); ratio |", "|---|---|---|---|---|---|---|---|"]
    body = []
    for r in rows:
        grid = json.loads((out / r["scene"] / "tolerances.json").read_text())
        best = tolerances.best_fixed(grid, r["true_error"])
        fixed = f"{'~' if best[1] else ''}{best[0]:.0f} ({best[2]}); {r['doStep'] / best[0]:.2f}" if best else "–"
        body.append(f"| {r['scene']} (T = {r['T']:g}) | {r['master']} | {r['tolerance']:.0e} | {r['true_error']:.2e} | "
                    f"{r['true_error'] / r['tolerance']:.2f} | {r['doStep']} | {r['wall_time_s']:.2f} | {fixed} |")
    return "\n".join(head + body) + "\n"


def main(out, again=False):
    measured.write(PAGE, "tight", table(measured.rows(out / "tight.json", lambda: measure(out), again), out))


if __name__ == "__main__":
    main(*measured.arguments(ROOT / "out" / "tolerances"))
