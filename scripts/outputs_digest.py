"""A digest of what the shipped scenes compute: one line per scene and master, the SHA-256 of the
trajectory's bytes and of the summary's figures. Two runs that print the same lines computed the
same bits. The CPU check runs it under each BLAS kernel the CPU has (OPENBLAS_CORETYPE) and compares.

    python scripts/outputs_digest.py [--T 0.2] [SCENE ...]
"""
import argparse
import hashlib
import json
import sys
from pathlib import Path

import numpy as np

import wavecosim as wc

ROOT = Path(__file__).resolve().parent.parent
SCENES = ["two_oscillators", "two_oscillators_stiff", "chain", "star", "planar", "rlc_motor", "foreign_pair",
          "fmi3_damper", "dcmotor", "dcmotor_shaft"]
MASTERS = [("dr", {"K": 20}), ("dr", {"K": 5, "gamma": "auto"}), ("explicit", {}), ("gauss-seidel", {}),
           ("iqn-ils", {"K": 10}), ("aitken", {"K": 10}), ("newton", {})]
FIGURES = ("max_error", "rms_error", "gamma", "gammas", "max_ledger", "fmu_calls")


def digest(config, T, master, options):
    """SHA-256 of one run's trajectory and figures (hex, 16 digits)."""
    r = wc.simulate(str(config), T=T, master=master, warn=lambda _m: None, **options)
    h = hashlib.sha256()
    for name in r.trajectory.dtype.names:
        h.update(np.ascontiguousarray(r.trajectory[name]).tobytes())
    h.update(json.dumps({k: r.summary.get(k) for k in FIGURES}, sort_keys=True, default=repr).encode())
    return h.hexdigest()[:16]


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--T", type=float, default=0.2)
    ap.add_argument("scenes", nargs="*", default=SCENES)
    args = ap.parse_args(argv)
    for scene in args.scenes:
        config = ROOT / "configs" / f"{scene}.yaml"
        if "third_party" in config.read_text() and not (ROOT.parent / "shared" / "third_party").exists():
            continue
        for master, options in MASTERS:
            try:
                line = digest(config, args.T, master, options)
            except wc.WavecosimError as e:
                line = f"refused: {type(e).__name__}"
            print(f"{scene} {master} {json.dumps(options, sort_keys=True)} {line}", flush=True)


if __name__ == "__main__":
    sys.exit(main())
