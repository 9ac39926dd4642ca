"""Cost of a generated step against the hand-written one: ns per fmi2DoStep from a small C driver
(scripts/step_cost.c) on each (generated, hand-written) pair, in both port modes; with
--instructions, machine instructions per doStep counted by valgrind (steady on a loaded machine).

    .venv/bin/python scripts/ph_step_cost.py [--steps N] [--instructions]
"""
import argparse
import re
import subprocess
import tempfile
import zipfile
from pathlib import Path

from fmpy import read_model_description

from wavecosim.fmi import build

ROOT = Path(__file__).resolve().parent.parent
PAIRS = [("LinearSidePH", "LinearSide"), ("ChainLinkPH", "ChainLink"), ("RLCCircuitPH", "RLCCircuit"),
         ("DuffingSidePH", "DuffingSide")]
EXTRA = ["Pendulum", "PendulumCart"]


def load_build():
    return build


def compile_driver(build, tmp):
    exe = tmp / "step_cost"
    subprocess.run(["gcc", "-O2", "-std=c99", "-I", str(build.fmi_headers()), str(ROOT / "scripts" / "step_cost.c"),
                    "-o", str(exe), "-ldl", "-lm"], check=True)
    return exe


def cost_per_step(exe, fmu, tmp, mode, steps, instructions):
    """Runs the driver on one FMU; inputs are the wave inputs (mode 0) or the physical ones (1).
    Returns ns per doStep, or instructions per doStep under valgrind (7 runs of `steps` each)."""
    md = read_model_description(str(fmu))
    ident = md.coSimulation.modelIdentifier
    lib = tmp / f"{ident}.so"
    with zipfile.ZipFile(fmu) as z:
        lib.write_bytes(z.read(f"binaries/linux64/{ident}.so"))
    by_name = {v.name: v for v in md.modelVariables}
    inputs = [v.valueReference for v in md.modelVariables
              if v.causality == "input" and (v.name.startswith("a") and v.unit is None) == (mode == 0)]
    args = [str(exe), str(lib), md.guid, str(by_name["port_mode"].valueReference), str(mode), str(steps),
            *map(str, inputs)]
    if not instructions:
        return float(subprocess.run(args, check=True, capture_output=True, text=True).stdout)
    out = subprocess.run(["valgrind", "--tool=callgrind", f"--callgrind-out-file={tmp / 'cg.out'}",
                          "--toggle-collect=fmi2DoStep", *args], check=True, capture_output=True, text=True)
    return float(re.search(r"refs:\s+([\d,]+)", out.stderr).group(1).replace(",", "")) / (7 * steps)


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--steps", type=int, default=200000)
    parser.add_argument("--instructions", action="store_true")
    args = parser.parse_args()
    steps = min(args.steps, 2000) if args.instructions else args.steps
    unit = "instructions" if args.instructions else "ns"
    build = load_build()
    fmus = build.build_all(log=lambda *_: None)
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        exe = compile_driver(build, tmp)
        print(f"| FMU | mode | {unit} per doStep | hand-written | ratio |\n|---|---|---|---|---|")
        for gen, hand in PAIRS + [(x, None) for x in EXTRA]:
            for mode, label in ((0, "wave"), (1, "physical")):
                g = cost_per_step(exe, fmus[gen], tmp, mode, steps, args.instructions)
                if hand is None:
                    print(f"| {gen} | {label} | {g:.0f} | – | – |")
                    continue
                w = cost_per_step(exe, fmus[hand], tmp, mode, steps, args.instructions)
                print(f"| {gen} | {label} | {g:.0f} | {w:.0f} | {g / w:.2f} |")


if __name__ == "__main__":
    main()
