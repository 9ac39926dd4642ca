"""The measured table of docs/masters.md, "Choosing a tolerance": for each scene (`master.options:
auto`: gamma, relaxation and DR's Anderson window chosen from the scene), the tolerance mode (dr and
gauss-seidel, predictor estimate) and step doubling at each tolerance beside a grid of fixed (dt, K),
every run's true error against one fine reference (wavecosim.sweeps.tolerances):

    .venv/bin/python scripts/tolerance_table.py [OUT]           # rows into OUT/<scene>/, the table into the page
    .venv/bin/python scripts/tolerance_table.py OUT --again     # the table again from the rows in OUT
    .venv/bin/python scripts/tolerance_table.py OUT --scenes=chain,dcmotor     # only these scenes

Per tolerance-mode run the table gives its true error over the tolerance, its FMU doSteps and wall
time, the doSteps the cheapest fixed (master, K) needs for the same true error (its runs' log-log
line; ~: extrapolated past its most accurate run) and those of step doubling at the same tolerance. The page holds
it between `<!-- measured: tolerances -->` and `<!-- end of measured -->`.
"""
import json
import re
import sys
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
sys.path.insert(0, str(ROOT / "master"))

from wavecosim.scenario.config import load_scenario  # noqa: E402
from wavecosim.sweeps.tolerances import best_fixed, compare_tolerances  # noqa: E402

TOLERANCES = (1e-2, 1e-3, 1e-4)
SCENES = (("two_oscillators", 2.0), ("two_oscillators_stiff", 2.0), ("chain", 1.0), ("foreign_pair", 0.5),
          ("dcmotor", 0.05))                     # (config, T): shortened where the Python route takes long
REFINE = {"dcmotor": (1, 4, 16, 64, 256, 1024)}  # the fixed grid down to the tolerance mode's errors at 1e-4
PAGE = ROOT / "docs" / "masters.md"
BLOCK = re.compile(r"(<!-- measured: tolerances -->\n).*?(<!-- end of measured -->)", re.S)
LEDGER = re.compile(r"(<!-- measured: tolerance-ledger -->\n).*?(<!-- end of measured -->)", re.S)


def scene_rows(name, T, out, again):
    """The scene's rows: measured now, or read back from an earlier measurement (again)."""
    folder = out / name
    if again:
        return json.loads((folder / "tolerances.json").read_text())
    sc = load_scenario(ROOT / "configs" / f"{name}.yaml").with_changes("the table", T=T).with_master(options="auto")
    folder.mkdir(parents=True, exist_ok=True)
    return compare_tolerances(sc, TOLERANCES, folder, **({"refine": REFINE[name]} if name in REFINE else {}))


def lines(name, T, rows):
    """The table's rows of one scene."""
    out = []
    for r in rows:
        if r["mode"] != "tolerance" or r["true_error"] != r["true_error"]:
            continue
        best = best_fixed(rows, r["true_error"])
        twin = next((d for d in rows if d["mode"] == "doubling" and d["tolerance"] == r["tolerance"]
                     and d["master"] == r["master"]), None)
        fixed = (f"{'~' if best[1] else ''}{best[0]:.0f} ({best[2]}); {r['doStep'] / best[0]:.2f}" if best else "–")
        doubling = f"{twin['doStep']}; {r['doStep'] / twin['doStep']:.2f}" if twin else "–"
        out.append(f"| {name} (T = {T:g}) | {r['master']} | {r['tolerance']:.0e} | {r['true_error']:.2e} | "
                   f"{r['true_error'] / r['tolerance']:.2f} | {r['doStep']} | {r['wall_time_s']:.2f} | {fixed} | "
                   f"{doubling} |")
    return out


def ledger_lines(name, rows):
    """The energy ledger of the scene's `dr` runs: the largest max_ledger of the tolerance mode and
    of step doubling over the tolerances, and the largest share of its own ledger_tolerance any of
    them reached (where the rows record it)."""
    dr = [r for r in rows if r["mode"] in ("tolerance", "doubling") and r["master"] == "dr" and r["max_ledger"] != ""]

    def largest(mode):
        values = [r["max_ledger"] for r in dr if r["mode"] == mode]
        return f"{max(values):.1e}" if values else "–"
    shares = [r["max_ledger"] / r["ledger_tolerance"] for r in dr if r.get("ledger_tolerance", "") != ""]
    share = f"{max(shares):.2f}" if len(shares) == len(dr) and dr else "–"
    return [f"| {name} | {largest('tolerance')} | {largest('doubling')} | {share} |"]


def main(out, again=False, only=None):
    head = ["| scene | master | tolerance | true error | / tolerance | doSteps | wall (s) | best fixed at that error: "
            "doSteps (master); ratio | doubling: doSteps; ratio |", "|---|---|---|---|---|---|---|---|---|"]
    body, ledger = [], []
    for name, T in SCENES:
        if only and name not in only:
            continue
        if (name == "dcmotor" and not (ROOT.parent / "shared" / "third_party").exists()) or \
                (again and not (out / name / "tolerances.json").exists()):
            continue
        rows = scene_rows(name, T, out, again)
        body += lines(name, T, rows)
        ledger += ledger_lines(name, rows)
        print("\n".join(body[-len(TOLERANCES) * 2:]), flush=True)
    ledger_head = ["| scene | max_ledger, tolerance mode | max_ledger, step doubling | largest max_ledger / "
                   "ledger_tolerance |",
                   "|---|---|---|---|"]
    text = BLOCK.sub(lambda m: m.group(1) + "\n".join(head + body) + "\n" + m.group(2), PAGE.read_text())
    PAGE.write_text(LEDGER.sub(lambda m: m.group(1) + "\n".join(ledger_head + ledger) + "\n" + m.group(2), text))


if __name__ == "__main__":
    given = [a for a in sys.argv[1:] if not a.startswith("--")]
    only = next((a.split("=", 1)[1].split(",") for a in sys.argv if a.startswith("--scenes=")), None)
    main(Path(given[0]) if given else ROOT / "out" / "tolerances", "--again" in sys.argv, only)
