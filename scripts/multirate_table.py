"""The measured table of docs/masters.md, "Multi-rate": Table I's pair with A on a stiff spring
(k1 = 20000: A at 50 rad/s, B at 3.5 rad/s), T = 2, at macro-steps and substeps of A (or B), under
dr (K = 50), newton, gauss-seidel and explicit; true error over q1 and q2 against the monolithic
reference at dt = 1e-4 without substeps (run/fine.py), doSteps over both FMUs:

    .venv/bin/python scripts/multirate_table.py [OUT]           # rows into OUT/multirate.json, the table into the page
    .venv/bin/python scripts/multirate_table.py OUT --again     # the table again from the rows in OUT

The page holds it between `<!-- measured: multirate -->` and `<!-- end of measured -->`; beside it,
in `<!-- measured: multirate-tolerance -->`, DR (`options: auto`) in the tolerance mode at fixed
substeps of A, against the reference at dt = 1e-5 (OUT/multirate_tolerance.json).
"""
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "master"))

import measured  # noqa: E402
from wavecosim import api  # noqa: E402
from wavecosim.run.fine import fine_reference, true_error  # noqa: E402
from wavecosim.scenario.config import load_scenario  # noqa: E402

CASES = ((0.01, 1, 1), (0.01, 2, 1), (0.01, 4, 1), (0.01, 8, 1), (0.01, 1, 4), (0.005, 1, 1), (0.0025, 1, 1),
         (0.00125, 1, 1))                          # (dt, substeps of A, substeps of B)
MASTERS = (("dr", {"K": 50}), ("newton", {}), ("gauss-seidel", {}), ("explicit", {}))
UNDER_TOLERANCE = ((1e-2, 1), (1e-2, 2), (1e-2, 4), (1e-3, 1), (1e-3, 2))     # (tolerance, substeps of A)
PAGE = ROOT / "docs" / "masters.md"


def scene(dt=0.01, a=1, b=1):
    """Table I's pair on A's stiff spring at macro-step dt with these substeps of A and B."""
    changes = (("T", 2.0), ("dt", dt), ("subsystems.A.parameters.k1", 20000.0), ("subsystems.A.substeps", a),
               ("subsystems.B.substeps", b))
    return load_scenario(ROOT / "configs" / "two_oscillators.yaml", changes=changes)


def measure():
    """One row per (case, master): true error and doSteps."""
    reference = fine_reference(scene(), None, dt=1e-4)
    rows = []
    for dt, a, b in CASES:
        sc = scene(dt, a, b)
        for master, extra in MASTERS:
            result = api.simulate(sc.with_master(algorithm=master, **extra), reference=False, certificates=False)
            rows.append({"dt": dt, "A": a, "B": b, "master": master, "doStep": result.summary["fmu_calls"]["doStep"],
                         "true_error": true_error(result, reference)["true_error"]})
            print(rows[-1], flush=True)
    return rows


def measure_tolerance():
    """One row per (tolerance, substeps of A): DR in the tolerance mode, its steps, doSteps and true error."""
    reference = fine_reference(scene(), None, dt=1e-5)
    rows = []
    for tol, a in UNDER_TOLERANCE:
        run = scene(a=a).with_master(algorithm="dr", tolerance=tol, options="auto")
        result = api.simulate(run, reference=False, certificates=False)
        rows.append({"tolerance": tol, "A": a, "steps": result.summary["accepted_steps"],
                     "doStep": result.summary["fmu_calls"]["doStep"],
                     "true_error": true_error(result, reference)["true_error"]})
        print(rows[-1], flush=True)
    return rows


def table_tolerance(rows):
    """The block of the tolerance mode at fixed substeps."""
    out = ["| tolerance | substeps of A | accepted steps | doSteps | true error |", "|---|---|---|---|---|"]
    out += [f"| {r['tolerance']:.0e} | {r['A']} | {r['steps']:_} | {r['doStep']:_} | {r['true_error']:.2e} |"
            .replace("_", " ") for r in rows]
    return "\n".join(out) + "\n"


def table(rows):
    """The page's block."""
    def get(dt, a, b, master):
        return next(r for r in rows if (r["dt"], r["A"], r["B"], r["master"]) == (dt, a, b, master))

    out = ["| macro-step Δt | substeps of A | true error (dr, newton) | doSteps dr | doSteps newton | "
           "gauss-seidel true error / doSteps | explicit true error / doSteps |", "|---|---|---|---|---|---|---|"]
    for dt, a, b in CASES:
        dr, nw, gs, ex = (get(dt, a, b, m) for m, _ in MASTERS)
        same = abs(dr["true_error"] - nw["true_error"]) <= 0.005 * nw["true_error"]
        err = f"{dr['true_error']:.3f}" if same else f"{dr['true_error']:.3f}, {nw['true_error']:.3f}"
        sub = f"{a}" + (f" (B: {b})" if b != 1 else "")
        out.append(f"| {dt:g} | {sub} | {err} | {dr['doStep']:_} | {nw['doStep']:_} | "
                   f"{gs['true_error']:.3f} / {gs['doStep']:_} | {ex['true_error']:.3f} / {ex['doStep']:_} |"
                   .replace("_", " "))
    return "\n".join(out) + "\n"


def main(out, again=False):
    measured.write(PAGE, "multirate", table(measured.rows(out / "multirate.json", measure, again)))
    measured.write(PAGE, "multirate-tolerance",
                   table_tolerance(measured.rows(out / "multirate_tolerance.json", measure_tolerance, again)))


if __name__ == "__main__":
    main(*measured.arguments(ROOT / "out" / "multirate"))
