"""The C formatter against Python's repr, on many random bit patterns (every exponent) and
tests/kernel/test_csvtext.py's edge classes: `python scripts/csvfmt_check.py [MILLIONS]` (default
10) with wavecosim importable; prints the counts checked and any mismatch, exits 1 on one."""
import sys
from pathlib import Path

import numpy as np

from wavecosim.kernel import csvfmt

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests" / "kernel"))
from test_csvtext import edge_doubles, odd_doubles  # noqa: E402  (the test's edge classes)


def chunks(millions):
    """10^6 random bit patterns at a time, then the edge classes."""
    rng = np.random.default_rng(2026)
    for _ in range(millions):
        yield "random bit patterns", rng.integers(0, 2 ** 64, 10 ** 6, dtype=np.uint64).view(np.float64)
    yield "edge classes", np.concatenate([edge_doubles(rng, 250_000), odd_doubles(rng, 0)])


def main(millions):
    counts, bad = {}, []
    for kind, values in chunks(millions):
        bad += [(v, text) for v, text in zip(values.tolist(), csvfmt.c_reprs(values)) if text != repr(v)][:10]
        counts[kind] = counts.get(kind, 0) + len(values)
        print(f"{kind}: {counts[kind]} checked, {len(bad)} mismatches", flush=True)
    for v, text in bad:
        print(f"mismatch: repr {v!r}, C {text}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1]) if len(sys.argv) > 1 else 10))
