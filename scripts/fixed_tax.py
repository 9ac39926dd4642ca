"""The fixed tax of a short run: a 10-step run of configs/foreign_pair.yaml (the CLI, files written,
the lockstep reference, certificates: every default) against `python -c "import wavecosim"`, each
in a fresh process, in rounds (best of each), with the gamma choice in the build cache (warm) and
without it (cold: a copy of the cache without its gamma folder). The children use and write Python's
bytecode caches, as a package installed by pip has them (PYTHONDONTWRITEBYTECODE is dropped: without
the caches every import compiles its modules again). Prints one JSON object.

    python scripts/fixed_tax.py [--rounds 5]
"""
import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent


ENV = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}


def seconds(cmd, env=None):
    started = time.perf_counter()
    subprocess.run(cmd, check=True, env=env or ENV, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)
    return time.perf_counter() - started


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--rounds", type=int, default=5)
    args = parser.parse_args()
    from wavecosim.kernel.build import cache_dir
    out = tempfile.mkdtemp(prefix="wavecosim-tax-")
    run = [sys.executable, "-m", "wavecosim", "run", str(ROOT / "configs" / "foreign_pair.yaml"), "--T", "0.01",
           "--quiet", "--out", out]
    best = {"import_s": float("inf"), "run_warm_s": float("inf"), "run_cold_s": float("inf")}
    subprocess.run(run, check=True, env=ENV, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL)   # builds, warm cache
    for _ in range(args.rounds):
        best["import_s"] = min(best["import_s"], seconds([sys.executable, "-c", "import wavecosim"]))
        best["run_warm_s"] = min(best["run_warm_s"], seconds(run))
        cold = tempfile.mkdtemp(prefix="wavecosim-cache-")
        shutil.copytree(cache_dir(), cold, dirs_exist_ok=True, ignore=shutil.ignore_patterns("gamma"))
        best["run_cold_s"] = min(best["run_cold_s"], seconds(run, {**ENV, "WAVECOSIM_CACHE": cold}))
        shutil.rmtree(cold, ignore_errors=True)
    summary = json.loads((Path(out) / "summary.json").read_text())
    best.update(warm_over_import_s=best["run_warm_s"] - best["import_s"],
                cold_over_import_s=best["run_cold_s"] - best["import_s"],
                set_up_s=summary["total_time_s"] - summary["loop_time_s"], rounds=args.rounds,
                load_average_1min=os.getloadavg()[0])
    shutil.rmtree(out, ignore_errors=True)
    print(json.dumps(best, indent=1))


if __name__ == "__main__":
    main()
