"""wavecosim/csvtext.py (fmus/kernel/csvfmt.c): every double written exactly as repr writes it, and a
table's file byte for byte the same through C as through the Python formatters."""
import numpy as np
import pytest

from wavecosim import csvtext
from wavecosim.observers import recorder
from wavecosim.observers.recorder import Labels, Table, ints

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


def test_special_values_read_as_repr():
    assert [csvtext.c_repr(v) for v in SPECIAL] == [repr(v) for v in SPECIAL]


def test_random_bit_patterns_read_as_repr():
    values = odd_doubles(np.random.default_rng(11), 200_000)
    mismatches = [repr(v) for v in values.tolist() if csvtext.c_repr(v) != repr(v)]
    assert mismatches == []


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
