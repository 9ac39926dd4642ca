"""The measured table of docs/masters.md, "The FMUs' own tolerance": the dcmotor (T = 0.05,
gauss-seidel, `options: auto`) in the tolerance mode with its FMUs set up at their own 1e-5
(`fmu_tolerance: null`) and as the tolerance mode sets them up (`auto`), every run against one fine
reference with its FMUs at 1e-7. Needs ../shared/third_party:

    .venv/bin/python scripts/fmu_tolerance_table.py [OUT]           # rows into OUT/fmu_tolerance.json, the table into the page
    .venv/bin/python scripts/fmu_tolerance_table.py OUT --again     # the table again from the rows in OUT

The page holds it between `<!-- measured: fmu-tolerance -->` and `<!-- end of measured -->`.
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "master"))

import measured  # noqa: E402
from wavecosim.scenario.config import load_scenario  # noqa: E402
from wavecosim.sweeps import tolerances  # noqa: E402

TOLERANCES = (1e-3, 1e-4)
SETTINGS = (None, "auto")                     # fmu_tolerance: the FMUs' own, then the tolerance mode's
PAGE = ROOT / "docs" / "masters.md"


def measure():
    """One row per (tolerance, fmu_tolerance)."""
    sc = load_scenario(ROOT / "configs" / "dcmotor.yaml").with_changes("the table", T=0.05).with_master(
        algorithm="gauss-seidel", options="auto")
    reference = tolerances.fine(tolerances.fixed_fmus(sc, TOLERANCES))
    rows = []
    for tol in TOLERANCES:
        for setting in SETTINGS:
            run = sc.with_master(tolerance=tol, fmu_tolerance=setting)
            rows.append({**tolerances.measure("tolerance", run, reference), "fmu_tolerance": setting or "null"})
            print(rows[-1], flush=True)
    return rows


def table(rows):
    """The page's block: per tolerance, both set-ups side by side."""
    def cells(tol, setting):
        r = next(r for r in rows if r["tolerance"] == tol and r["fmu_tolerance"] == setting)
        return f"{r['true_error']:.2e} | {r['doStep']:_} | {r['wall_time_s']:.2f}".replace("_", " ")

    out = ["| tolerance | FMUs at their own 10⁻⁵: true error | doSteps | wall (s) | FMUs at 10⁻³ × tolerance "
           "(`auto`): true error | doSteps | wall (s) |", "|---|---|---|---|---|---|---|"]
    out += [f"| {tol:.0e} | {cells(tol, 'null')} | {cells(tol, 'auto')} |" for tol in TOLERANCES]
    return "\n".join(out) + "\n"


def main(out, again=False):
    if not again and not (ROOT.parent / "shared" / "third_party" / "dcmotor").exists():
        sys.exit("the dcmotor's FMUs (../shared/third_party/dcmotor) are absent")
    measured.write(PAGE, "fmu-tolerance", table(measured.rows(out / "fmu_tolerance.json", measure, again)))


if __name__ == "__main__":
    main(*measured.arguments(ROOT / "out" / "tolerances"))
