"""The measured table of docs/masters.md, "libcosim's ECCO beside the tolerance mode": on the foreign
pair (T = 2), the tolerance mode (gauss-seidel, dr) at 1e-2 and 1e-3 and libcosim's ECCO at 1e-2 to
1e-6, every run against one fine reference (wavecosim.sweeps.tolerances, sweeps/ecco.py), with the
fixed grid of explicit and gauss-seidel beneath it. Needs libcosimpy (the `peers` extra):

    .venv/bin/python scripts/ecco_table.py [OUT]            # rows into OUT/ecco.json, the table into the page
    .venv/bin/python scripts/ecco_table.py OUT --again      # the table again from the rows in OUT

The page holds it between `<!-- measured: ecco -->` and `<!-- end of measured -->`.
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "master"))

import measured  # noqa: E402
from wavecosim.scenario.config import load_scenario  # noqa: E402
from wavecosim.sweeps import tolerances  # noqa: E402
from wavecosim.sweeps.ecco import peer_rows  # noqa: E402

MODE_TOLERANCES, ECCO_TOLERANCES = (1e-2, 1e-3), (1e-2, 1e-3, 1e-4, 1e-5, 1e-6)
MASTERS = ("gauss-seidel", "dr")
PAGE = ROOT / "docs" / "masters.md"


def measure():
    """Every row: the tolerance mode, step doubling and the fixed grid, then ECCO."""
    sc = load_scenario(ROOT / "configs" / "foreign_pair.yaml").with_changes("the ECCO table", T=2.0)
    reference = tolerances.fine(sc)
    rows = [tolerances.measure(mode, s, reference) for mode, s in tolerances.plan(sc, MODE_TOLERANCES, MASTERS)]
    return rows + peer_rows(sc, ECCO_TOLERANCES, reference, ("ecco",), note=print)


def cells(rows, mode, master, tol):
    """'true error | doSteps | wall' of the row, or dashes."""
    r = next((r for r in rows if r["mode"] == mode and r["master"] == master and r["tolerance"] == tol), None)
    return f"{r['true_error']:.2e} | {r['doStep']} | {r['wall_time_s']:.2f}" if r else "– | – | –"


def table(rows):
    """The page's block: the table and the fixed grid's line."""
    head = ["| tolerance | ECCO: true error | doSteps | wall (s) | tolerance mode, `gauss-seidel`: true error | "
            "doSteps | wall (s) | tolerance mode, `dr`: true error | doSteps | wall (s) |",
            "|---|---|---|---|---|---|---|---|---|---|"]
    body = [f"| {tol:.0e} | {cells(rows, 'ecco', 'libcosim', tol)} | {cells(rows, 'tolerance', MASTERS[0], tol)} | "
            f"{cells(rows, 'tolerance', MASTERS[1], tol)} |" for tol in ECCO_TOLERANCES]
    fixed = {m: [r for r in rows if r["mode"] == "fixed" and r["master"] == m] for m in ("explicit", "gauss-seidel")}
    line = "; ".join(f"`{m}` " + ", ".join(f"{r['true_error']:.2e} with {r['doStep']} doSteps (dt = {r['dt']:g})"
                                            for r in runs) for m, runs in fixed.items())
    return "\n".join(head + body) + f"\n\nFixed steps of the same grid: {line}.\n"


def main(out, again=False):
    measured.write(PAGE, "ecco", table(measured.rows(out / "ecco.json", measure, again)))


if __name__ == "__main__":
    main(*measured.arguments(ROOT / "out" / "ecco"))
