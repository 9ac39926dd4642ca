"""The measured table of docs/masters.md, "A system of signals only": OMSimulator's dual-mass
oscillator (two OpenModelica FMUs wired by signals, no state save: ../shared/third_party), T = 1,
the explicit master in the tolerance mode at 1e-2 to 1e-4 (step control without rejection) and at
fixed steps, every run against one fine reference (the explicit master, Richardson-extrapolated)
with the FMUs set up as the tightest run sets up its own:

    .venv/bin/python scripts/signals_table.py [OUT]           # rows into OUT/signals.json, the table into the page
    .venv/bin/python scripts/signals_table.py OUT --again     # the table again from the rows in OUT

The page holds it between `<!-- measured: signals-tolerance -->` and `<!-- end of measured -->`.
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "master"))

import compatibility  # noqa: E402
import measured  # noqa: E402
from wavecosim.sweeps import tolerances  # noqa: E402

TOLERANCES = (1e-2, 1e-3, 1e-4)
FIXED = (1e-3, 1e-4, 1e-5)
THIRD_PARTY = ROOT.parent / "shared" / "third_party"
PAGE = ROOT / "docs" / "masters.md"


def measure(out):
    """The tolerance mode's rows, then the fixed steps'."""
    path = compatibility.dual_mass_ssd(THIRD_PARTY, out)
    sc, _ = compatibility.load(path, outputs={"x1": "system1.x1", "x2": "system2.x2"}, T=1.0, dt=1e-3)
    fixed = tolerances.fixed_fmus(sc, TOLERANCES)
    reference = tolerances.fine(fixed)
    rows = [tolerances.measure("tolerance", sc.with_master(tolerance=tol), reference) for tol in TOLERANCES]
    rows += [tolerances.measure("fixed", fixed.with_changes("the table", dt=dt), reference) for dt in FIXED]
    return rows


def table(rows):
    """One line per run."""
    out = ["| run | true error | doSteps | accepted steps | wall (s) |", "|---|---|---|---|---|"]
    for r in rows:
        run = f"tolerance {r['tolerance']:.0e}" if r["mode"] == "tolerance" else f"fixed dt = {r['dt']:g}"
        out.append(f"| {run} | {r['true_error']:.2e} | {r['doStep']:_} | {r['accepted_steps']:_} | "
                   f"{r['wall_time_s']:.2f} |".replace("_", " "))
    return "\n".join(out) + "\n"


def main(out, again=False):
    if not again and not (THIRD_PARTY / "dual_mass_oscillator").exists():
        sys.exit("the dual-mass oscillator (../shared/third_party/dual_mass_oscillator) is absent")
    out.mkdir(parents=True, exist_ok=True)
    measured.write(PAGE, "signals-tolerance", table(measured.rows(out / "signals.json", lambda: measure(out), again)))


if __name__ == "__main__":
    main(*measured.arguments(ROOT / "out" / "signals"))
