"""The measured table of docs/masters.md, "Tighter tolerances": the recommended master of each scene
(as scripts/tolerance_table.py measures them) in the tolerance mode at 1e-5 and 1e-6, against one fine
reference each (its FMUs set up as the tightest run sets up its own), beside the best fixed run of
the tolerance table's grid at the same true error (mostly extrapolated: "~"); dt_min is lowered to
dt/10 000 where the default binds a first-order master. Needs that table's
rows (scripts/tolerance_table.py OUT) first:

    .venv/bin/python scripts/tight_table.py [OUT]            # rows into OUT/tight.json, the table into the page
    .venv/bin/python scripts/tight_table.py OUT --again      # the table again from the rows in OUT
    .venv/bin/python scripts/tight_table.py OUT --scenes=dcmotor    # only these scenes, the others' rows kept

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
TIGHT = (1e-5, 1e-6)
DT_MIN = {("foreign_pair", 1e-6): 1e-4, ("dcmotor", 1e-6): 1e-4}   # dt_min / dt where the default, 1e-3, binds
PAGE = ROOT / "docs" / "masters.md"


def measure(out, only=None, kept=()):
    """Each scene's tolerance-mode rows at the tight tolerances (only: these scenes; the rows of
    the others are `kept`)."""
    rows = [r for r in kept if only and r["scene"] not in only]
    for name, T in SCENES:
        if (only and name not in only) or (name == "dcmotor" and not (ROOT.parent / "shared" / "third_party").exists()):
            continue
        sc = load_scenario(ROOT / "configs" / f"{name}.yaml").with_changes("the table", T=T).with_master(options="auto")
        reference = tolerances.fine(tolerances.fixed_fmus(sc, TIGHT))
        for tol in TIGHT:
            run = sc.with_master(algorithm=RECOMMENDED[name], tolerance=tol, estimate="auto",
                                 dt_min=sc.dt * DT_MIN.get((name, tol), 1e-3))
            rows.append({"scene": name, "T": T, **tolerances.measure("tolerance", run, reference),
                         "dt_min": run.master.dt_min})
            print(rows[-1], flush=True)
    order = [name for name, T in SCENES]
    return sorted(rows, key=lambda r: (order.index(r["scene"]), -r["tolerance"]))


def table(rows, out):
    """The page's block: one line per row, its best fixed run read from the tolerance table's grid."""
    head = ["| scene | master | tolerance | dt_min | true error | / tolerance | doSteps | wall (s) | best fixed at that "
            "error: doSteps (master); ratio |", "|---|---|---|---|---|---|---|---|---|"]
    body = []
    for r in rows:
        grid = json.loads((out / r["scene"] / "tolerances.json").read_text())
        best = tolerances.best_fixed(grid, r["true_error"])
        fixed = f"{'~' if best[1] else ''}{best[0]:.0f} ({best[2]}); {r['doStep'] / best[0]:.2f}" if best else "–"
        body.append(f"| {r['scene']} (T = {r['T']:g}) | {r['master']} | {r['tolerance']:.0e} | {r['dt_min']:.0e} | "
                    f"{r['true_error']:.2e} | {r['true_error'] / r['tolerance']:.2f} | {r['doStep']} | "
                    f"{r['wall_time_s']:.2f} | {fixed} |")
    return "\n".join(head + body) + "\n"


def main(out, again=False, only=None):
    kept = json.loads((out / "tight.json").read_text()) if only and (out / "tight.json").exists() else ()
    measured.write(PAGE, "tight", table(measured.rows(out / "tight.json", lambda: measure(out, only, kept), again), out))


if __name__ == "__main__":
    only = next((a.split("=", 1)[1].split(",") for a in sys.argv if a.startswith("--scenes=")), None)
    main(*measured.arguments(ROOT / "out" / "tolerances"), only)
