"""The DR tables of docs/masters.md and docs/energy.md, measured and written into the pages.

    .venv/bin/python scripts/dr_tables.py table1            # Table I: the paper (guard off) beside the default
    .venv/bin/python scripts/dr_tables.py pairs             # dcmotor and fmi3_damper, K = 0..10 (third-party FMUs)
    .venv/bin/python scripts/dr_tables.py targets [--scenes chain,star,dcmotor@0.1] [--options all] [--out out/targets]

Each command replaces the text between `<!-- table:NAME -->` and `<!-- /table:NAME -->` in the pages
(NAME: table1, pairs, targets) and prints it. `targets` runs `wavecosim compare` per scene into
OUT/SCENE (reusing a compare.json already there; SCENE@T shortens the scene to T seconds) and sets,
per target max error, the best classical master that evaluates its subsystems side by side (any
energy) against the best energy-safe DR run.
"""
import argparse
import json
import re
import sys
from pathlib import Path

import wavecosim as wc
from wavecosim.sweeps.comparison import TARGETS, compare, parse_options

ROOT = Path(__file__).resolve().parent.parent
PAGES = (ROOT / "docs" / "masters.md", ROOT / "docs" / "energy.md")
PARALLEL = ("jacobi-iter", "aitken", "iqn-ils")          # classical masters evaluating side by side
MASTERS = ("gauss-seidel-iter", *PARALLEL, "dr")
TABLE_I_KS = (0, 3, 8, 20, 35, 50)
PAIRS = ("dcmotor.yaml", "fmi3_damper.yaml")


def quiet(message):
    """Sign-probe notes and the like are not part of the tables."""


def fmt(x, digits=3):
    return "–" if x is None or x != x else f"{x:.{digits}e}"


def write(name, text):
    """Put `text` between the markers of table NAME in the pages that have them; print it."""
    pattern = re.compile(rf"(<!-- table:{name} -->\n).*?(<!-- /table:{name} -->)", re.S)
    for page in PAGES:
        if page.exists() and pattern.search(page.read_text()):
            page.write_text(pattern.sub(lambda m: m.group(1) + text + m.group(2), page.read_text()))
    print(text)


def actions(summary):
    acts = {k: v for k, v in summary.get("energy_guard_actions", {}).items() if v and k != "kept"}
    return ", ".join(f"{k} {v}" for k, v in acts.items()) or "none"


def table1():
    """Table I at the paper's budgets: energy_guard off (Algorithm 1 as printed) and the default."""
    sc = wc.load()
    paper = {r["K"]: r for r in wc.sweep(sc.with_master(energy_guard="off"), Ks=TABLE_I_KS, certificates=False).rows}
    default = {r["K"]: r for r in wc.sweep(sc, Ks=TABLE_I_KS, certificates=False).rows}
    lines = ["| K | guard off: max / rms / final error | default (ledger, start previous): max / rms / final error "
             "| ledger actions | max ledger ≤ tolerance |", "|---|---|---|---|---|"]
    for K in TABLE_I_KS:
        p, d = paper[K], default[K]
        lines.append(f"| {K} | {fmt(p['max_error'])} / {fmt(p['rms_error'])} / {fmt(p['final_error'])} | "
                     f"{fmt(d['max_error'])} / {fmt(d['rms_error'])} / {fmt(d['final_error'])} | {actions(d)} | "
                     f"{fmt(d['max_ledger'], 1)} ≤ {fmt(d['ledger_tolerance'], 1)} |")
    return "\n".join(lines) + "\n"


def pairs():
    """Both real pairs at K = 0..10: guard off against the default, the ratio, what the ledger did."""
    lines = []
    for config in PAIRS:
        sc = wc.load(ROOT / "configs" / config)
        lines += [f"`configs/{config}`:", "",
                  "| K | guard off | default | default / off | ledger actions | doSteps per step (default) |",
                  "|---|---|---|---|---|---|"]
        for K in range(11):
            off, on = (wc.simulate(sc.with_master(K=K, energy_guard=g), certificates=False, warn=quiet).summary
                       for g in ("off", "ledger"))
            lines.append(f"| {K} | {fmt(off['max_error'])} | {fmt(on['max_error'])} | "
                         f"{on['max_error'] / off['max_error']:.2f} | {actions(on)} | "
                         f"{on['fmu_calls']['doStep'] / on['steps']:.2f} |")
        lines.append("")
    return "\n".join(lines)


def best(group, names):
    """(name, row) of the fewest doSteps per macro-step among `names` in one target's cheapest map."""
    found = [(n, r) for n, r in group.items() if n in names]
    return min(found, key=lambda nr: nr[1]["doSteps_per_step"], default=(None, None))


def target_rows(scene, data):
    """The targets table's rows of one scene from its compare.json."""
    safe, anyway = data["cheapest"], data["cheapest_any_energy"]
    lines = []
    for target in (f"{t:g}" for t in TARGETS):
        cls, c = best(anyway.get(target, {}), PARALLEL)
        dr, d = best(safe.get(target, {}), [n for n in safe.get(target, {}) if n.split(":")[0] == "dr"])
        gs = anyway.get(target, {}).get("gauss-seidel-iter")
        ratio = f"{d['doSteps_per_step'] / c['doSteps_per_step']:.2f}" if c and d else "–"
        critical = (f"{d['critical_path_doSteps']:.2f} / {gs['critical_path_doSteps']:.2f}" if d and gs else "–")
        show = (lambda n, r: f"{n} K = {r['K']}: {r['doSteps_per_step']:.2f} ({r['max_error']:.1e})" if r else "none")
        lines.append(f"| {scene} | {target} | {show(cls, c)} | {show(dr, d)} | {ratio} | {critical} |")
    return lines


def targets(scenes, options, out, Ks=None):
    lines = ["| scene | max error ≤ | best parallel classical (any energy): doSteps/step | best energy-safe DR: "
             "doSteps/step | DR / classical | critical path, DR / gauss-seidel-iter |", "|---|---|---|---|---|---|"]
    for scene in scenes:
        name, _, T = scene.partition("@")
        folder = Path(out) / scene
        if not (folder / "compare.json").exists():
            sc = wc.load(ROOT / "configs" / f"{name}.yaml", **({"T": float(T)} if T else {}))
            compare(sc, folder, list(MASTERS), Ks, certificates=False, options=parse_options(options))
        label = f"{name} (T = {T} s)" if T else name
        lines += target_rows(label, json.loads((folder / "compare.json").read_text()))
    return "\n".join(lines) + "\n"


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("table", choices=("table1", "pairs", "targets"))
    parser.add_argument("--scenes", default="chain")
    parser.add_argument("--options", default="all")
    parser.add_argument("--out", default=str(ROOT / "out" / "targets"))
    args = parser.parse_args(argv)
    if args.table == "table1":
        write("table1", table1())
    elif args.table == "pairs":
        write("pairs", pairs())
    else:
        write("targets", targets([s.strip() for s in args.scenes.split(",") if s.strip()], args.options, args.out))


if __name__ == "__main__":
    sys.exit(main())
