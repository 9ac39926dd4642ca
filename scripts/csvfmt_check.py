"""The C formatter's fast route against its exact reference route and against Python's repr, on many
random bit patterns (every exponent) and tests/test_csvtext.py's edge classes. Run from the repo root:
PYTHONPATH=$PWD python scripts/csvfmt_check.py [MILLIONS] (default 10); prints the counts checked and
any mismatch, exits 1 on one."""
import sys

import numpy as np

from wavecosim.kernel import csvfmt as csvtext
from tests.test_csvtext import edge_doubles, odd_doubles


def chunks(millions):
    """10^6 random bit patterns at a time, then the edge classes."""
    rng = np.random.default_rng(2026)
    for _ in range(millions):
        yield "random bit patterns", rng.integers(0, 2 ** 64, 10 ** 6, dtype=np.uint64).view(np.float64)
    yield "edge classes", np.concatenate([edge_doubles(rng, 250_000), odd_doubles(rng, 0)])


def main(millions):
    counts, bad = {}, []
    for kind, values in chunks(millions):
        fast, exact = csvtext.c_reprs(values), csvtext.c_reprs(values, exact=True)
        bad += [(v, f, e) for v, f, e in zip(values.tolist(), fast, exact) if not f == e == repr(v)][:10]
        counts[kind] = counts.get(kind, 0) + len(values)
        print(f"{kind}: {counts[kind]} checked, {len(bad)} mismatches", flush=True)
    for v, f, e in bad:
        print(f"mismatch: repr {v!r}, fast {f}, exact {e}")
    return 1 if bad else 0


if __name__ == "__main__":
    sys.exit(main(int(sys.argv[1]) if len(sys.argv) > 1 else 10))
