"""wavecosim/kernel/csvfmt.py (kernel/c/csvfmt.c): every double written exactly as repr writes it, and a
table's file byte for byte the same through C as through the Python formatters."""
import numpy as np
import pytest

from wavecosim.kernel import csvfmt as csvtext
from wavecosim.run import recorder
from wavecosim.run.recorder import Labels, Table, ints

pytestmark = pytest.mark.skipif(csvtext.library() is None, reason="the C formatter could not be built")

SPECIAL = [0.0, -0.0, float("nan"), -float("nan"), float("inf"), -float("inf"), 0.1, 0.3, 1e-05, 0.0001, 123.0,
           1e16, 1e15, 9999999999999998.0, 1e22, 1e23, 5e-324, 2.2250738585072014e-308, 2.225073858507201e-308,
           1.7976931348623157e308, 2.0 ** 59, 2.0 ** 60, 2.0 ** 63, 9007199254740993.0, 0.30000000000000004]


def odd_doubles(rng, n):
    """n random bit patterns (every exponent, subnormals, nan and inf among them), powers of 2 and 10 and
    their neighbours, integers, and the kind of values a run writes."""
    bits = rng.integers(0, 2 ** 64, n, dtype=np.uint64, endpoint=False).view(np.float64)
    twos = 2.0 ** np.arange(-1074, 1024)
    tens = np.array([float(f"1e{k}") for k in range(-323, 309)])
    return np.concatenate([bits, twos, np.nextafter(twos, 0.0), np.nextafter(twos, np.inf), tens,
                           np.nextafter(tens, 0.0), np.nextafter(tens, np.inf),
                           rng.integers(-2 ** 53, 2 ** 53, 20_000).astype(float), np.arange(20_000) / 100.0,
                           rng.standard_normal(20_000) * 1e-13, rng.standard_normal(20_000) * 1e200])


def edge_doubles(rng, n):
    """Where a shortest-digits routine goes wrong: subnormals, the ends of the range, integers up to 2^53
    and beyond, dyadic fractions k / 2^j (finite decimals: exact ties and trailing zeros), short digit
    strings times powers of ten, and the neighbours of all of them."""
    subnormal = rng.integers(1, 2 ** 52, n, dtype=np.uint64).view(np.float64)
    ends = np.array([5e-324, 1e-323, 2.2250738585072014e-308, 2.225073858507201e-308, 1.7976931348623157e308,
                     1.7976931348623155e308, 2.0 ** 53, 2.0 ** 53 + 2, 2.0 ** 64, 2.0 ** 54 - 2])
    big_ints = rng.integers(0, 2 ** 63, n, dtype=np.int64).astype(float) * 2.0 ** rng.integers(0, 40, n)
    dyadic = rng.integers(1, 2 ** 30, n) / 2.0 ** rng.integers(1, 70, n)
    short = rng.integers(1, 10 ** 6, n).astype(float) * 10.0 ** rng.integers(-30, 30, n)
    decimals = np.array([float(f"{m}e{x}") for m, x in zip(rng.integers(1, 10 ** 15, n // 4).tolist(),
                                                             rng.integers(-320, 300, n // 4).tolist())])
    values = np.concatenate([subnormal, ends, big_ints, dyadic, short, decimals, fives(rng, n)])
    with np.errstate(over="ignore"):                   # the largest double's upper neighbour is inf
        return np.concatenate([values, np.nextafter(values, 0.0), np.nextafter(values, np.inf), -values])


def fives(rng, n):
    """Significands that are multiples of 5^j (j = 1 .. 22) times 2^-195 .. 2^84, where the table's 10^-k
    is exact or v 10^-k may be an integer (a rounded-up table entry must not make it look otherwise)."""
    p = 5 ** rng.integers(1, 23, n)
    low, high = -(-2 ** 52 // p), (2 ** 53 - 1) // p
    m = (low + (rng.random(n) * (high - low + 1)).astype(np.int64)) * p
    exponent = rng.integers(880, 1160, n)
    return ((exponent << 52) | (m - 2 ** 52)).astype(np.uint64).view(np.float64)


def test_random_bit_patterns_and_edge_cases_read_as_repr():
    """The one check of the formatter: its text is repr's, on the special values, random bit patterns
    of every exponent and the edge classes (scripts/csvfmt_check.py runs it over many millions)."""
    rng = np.random.default_rng(11)
    values = np.concatenate([SPECIAL, odd_doubles(rng, 200_000), edge_doubles(rng, 20_000)])
    assert [(v, t) for v, t in zip(values.tolist(), csvtext.c_reprs(values)) if t != repr(v)] == []


def rows_of_every_kind(n, rng):
    return np.column_stack([np.arange(n) / 100.0, rng.integers(0, 50, n), rng.standard_normal(n) * 1e-13,
                            rng.integers(0, 3, n), odd_doubles(rng, n)[:n]])


def test_table_file_is_the_same_through_c_and_python(tmp_path, monkeypatch):
    monkeypatch.setattr(recorder, "BLOCK", 64)
    rows = rows_of_every_kind(300, np.random.default_rng(3))
    files = []
    for name, writer in (("c.csv", csvtext.block_writer), ("py.csv", lambda block, kinds: None)):
        monkeypatch.setattr(recorder, "block_writer", writer)
        table = Table(["time", "n", "x", "why", "y"], tmp_path / name,
                      formats={"n": ints, "why": Labels(["budget", "tolerance", "deadline"])})
        table.append_block(rows)
        table.close()
        files.append((tmp_path / name).read_bytes())
    assert files[0] == files[1] and files[0].count(b"\r\n") == 301
