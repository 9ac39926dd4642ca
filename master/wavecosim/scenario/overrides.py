"""`--set KEY=VALUES`: sweep axes over any key of a scenario file, as plain data.

KEY is a path into the YAML mapping: dotted names, `[i]` for a list entry
(`master.K`, `subsystems.A.parameters.k12`, `couplings[0].ratio`). VALUES is one of:

| VALUES | gives |
|---|---|
| `0,3,8` | a list of values (each read as an integer, a number, true/false/null or text) |
| `0..63`, `0..3,8` | whole numbers from a to b inclusive (may be mixed into a list) |
| `linspace(a,b,n)`, `geomspace(a,b,n)` | n evenly spaced (or log-spaced) numbers from a to b |
| `uniform(lo,hi)`, `loguniform(lo,hi)`, `normal(mu,sigma)`, `randint(lo,hi)` | a distribution: needs `--sample N` |

List axes form a grid (Cartesian product, the first --set varying slowest). With `--sample N
--seed S` every distribution draws N values (numpy's default_rng(S), in the order of the --set
options) and the grid is crossed with these N points, so each grid point sees the same samples.
"""
import copy
import itertools
import math
import re

import numpy as np

from ..errors import ConfigError

FUNCTION = re.compile(r"^\s*([a-z]+)\s*\((.*)\)\s*$")
RANGE = re.compile(r"^\s*(-?\d+)\s*\.\.\s*(-?\d+)\s*$")
PATH_PART = re.compile(r"^([^.\[\]]+)((?:\[\d+\])*)$")
SPACES = {"linspace": np.linspace, "geomspace": np.geomspace}
DISTRIBUTIONS = {"uniform": 2, "loguniform": 2, "normal": 2, "randint": 2}
MAX_RUNS = 10_000         # runs a sweep may plan (values of an axis, points of the grid, --sample draws)


def scalar(text):
    """One value as YAML would read it, with 1e3 a number (YAML 1.1 reads it as text)."""
    text = text.strip()
    for kind in (int, float):
        try:
            return kind(text)
        except ValueError:
            pass
    low = text.lower()
    words = {"true": True, "false": False, "null": None, "~": None}
    if low in words:
        return words[low]
    return text[1:-1] if len(text) > 1 and text[0] == text[-1] and text[0] in "'\"" else text


def split_top(text):
    """Split at commas outside parentheses."""
    parts, depth, start = [], 0, 0
    for i, ch in enumerate(text):
        depth += (ch == "(") - (ch == ")")
        if ch == "," and depth == 0:
            parts.append(text[start:i])
            start = i + 1
    return parts + [text[start:]]


def _numbers(key, name, args, count):
    values = [scalar(a) for a in split_top(args)]
    if len(values) != count or not all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values):
        raise ConfigError(f"--set {key}: {name}() takes {count} numbers, got ({args})")
    return values


def _axis_values(key, item):
    """The values one comma-separated item stands for (a list) or a distribution (a tuple)."""
    m = FUNCTION.match(item)
    if m and m.group(1) in SPACES:
        a, b, n = _numbers(key, m.group(1), m.group(2), 3)
        if not isinstance(n, int) or n < 1 or (m.group(1) == "geomspace" and a * b <= 0):
            raise ConfigError(f"--set {key}: {m.group(1)}({m.group(2)}) needs n >= 1 (and a, b of one sign)")
        _check_count(key, n)
        return [float(v) for v in SPACES[m.group(1)](a, b, n)]
    if m and m.group(1) in DISTRIBUTIONS:
        return (m.group(1), *_numbers(key, m.group(1), m.group(2), DISTRIBUTIONS[m.group(1)]))
    if m:
        raise ConfigError(f"--set {key}: unknown function {m.group(1)}() (have: {', '.join([*SPACES, *DISTRIBUTIONS])})")
    r = RANGE.match(item)
    if r:
        a, b = int(r.group(1)), int(r.group(2))
        if b < a:
            raise ConfigError(f"--set {key}: empty range {item.strip()}")
        _check_count(key, b - a + 1)
        return list(range(a, b + 1))
    return [scalar(item)]


def _check_count(key, count, what="values"):
    """Refuse more than MAX_RUNS runs before any is made (a list, a range, a grid)."""
    if count > MAX_RUNS:
        raise ConfigError(f"--set {key}: {count:,} {what}, over the limit of {MAX_RUNS:,} runs in one sweep "
                          f"(split it into several sweeps)")


def parse_set(option):
    """"KEY=VALUES" -> (KEY, list of values) or (KEY, distribution tuple)."""
    key, eq, values = option.partition("=")
    key = key.strip()
    if not eq or not key or not values.strip():
        raise ConfigError(f"--set {option}: must be KEY=VALUES, e.g. master.K=0,3,8")
    parse_path(key)
    items, count = [], 0
    for item in split_top(values):
        items.append(_axis_values(key, item))
        count += len(items[-1]) if isinstance(items[-1], list) else 1
        _check_count(key, count)
    dists = [i for i in items if isinstance(i, tuple)]
    if dists and len(items) > 1:
        raise ConfigError(f"--set {key}: a distribution stands alone, not in a list")
    return key, dists[0] if dists else [v for item in items for v in item]


def parse_value(option):
    """"KEY=VALUE" of one run (`run --set`) -> (KEY, the one value), read as parse_set reads it."""
    key, values = parse_set(option)
    if not isinstance(values, list) or len(values) != 1:
        raise ConfigError(f"--set {key}: a run takes one value (a sweep takes lists and distributions)")
    return key, values[0]


VARIABLE_MAPPINGS = ("parameters", "start", "integers")


def parse_path(key):
    """"a.b[0].c" -> ["a", "b", 0, "c"]; a malformed path is a one-line ConfigError. Below
    subsystems.X.parameters (start, integers) the rest is one FMU variable name, dots included
    (subsystems.machine.parameters.resistor.R)."""
    out, parts = [], key.split(".")
    for k, part in enumerate(parts):
        if len(out) == 3 and out[0] == "subsystems" and out[2] in VARIABLE_MAPPINGS:
            return out + [".".join(parts[k:])]
        m = PATH_PART.match(part)
        if not m:
            raise ConfigError(f"--set {key}: not a key path (names joined by dots, [i] for a list entry)")
        out.append(m.group(1))
        out.extend(int(i) for i in re.findall(r"\[(\d+)\]", m.group(2)))
    return out


def _draw(rng, key, dist, n):
    """n values of one distribution; impossible bounds are a one-line ConfigError."""
    name, a, b = dist
    bad = b < 0 if name == "normal" else (b < a or (name == "loguniform" and a <= 0))
    if bad:
        need = {"normal": "sigma >= 0", "loguniform": "0 < lo <= hi"}.get(name, "lo <= hi")
        raise ConfigError(f"--set {key}: {name}({a},{b}) needs {need}")
    if name == "randint":
        return [int(v) for v in rng.integers(int(a), int(b), n, endpoint=True)]
    if name == "uniform":
        values = rng.uniform(a, b, n)
    elif name == "loguniform":
        values = np.exp(rng.uniform(np.log(a), np.log(b), n))
    else:
        values = rng.normal(a, b, n)
    return [float(v) for v in values]


def expand(axes, sample=None, seed=0):
    """[(key, values or distribution)] -> list of points, each a list of (key, value) in --set order."""
    keys = [k for k, _ in axes]
    twice = next((k for k in keys if keys.count(k) > 1), None)
    if twice:
        raise ConfigError(f"--set {twice}: given twice (give one list of values)")
    grid = [(k, v) for k, v in axes if isinstance(v, list)]
    dists = [(k, v) for k, v in axes if isinstance(v, tuple)]
    if dists and not sample:
        raise ConfigError(f"--set {dists[0][0]}: {dists[0][1][0]}() is a distribution; give --sample N")
    if sample and not dists:
        raise ConfigError("--sample: needs at least one --set KEY=distribution(...), e.g. uniform(0.1,0.5)")
    _check_count(keys[0] if keys else "", math.prod(len(v) for _, v in grid) * (sample or 1), "runs in the grid")
    rng = np.random.default_rng(seed)
    drawn = {k: _draw(rng, k, d, sample) for k, d in dists}
    samples = [dict((k, drawn[k][i]) for k, _ in dists) for i in range(sample or 1)]
    points = []
    for combo in itertools.product(*(values for _, values in grid)):
        fixed = dict(zip((k for k, _ in grid), combo))
        for s in samples:
            points.append([(k, fixed[k] if k in fixed else s[k]) for k, _ in axes])
    return points


def _step_into(node, part, key, create):
    """The child of node at part (a name or a list index), creating a mapping when allowed."""
    if isinstance(part, int):
        if not isinstance(node, list) or part >= len(node):
            raise ConfigError(f"--set {key}: no list entry [{part}] there")
        return node[part]
    if not isinstance(node, dict):
        raise ConfigError(f"--set {key}: {part!r} is below a value that is not a mapping")
    if part not in node or node[part] is None:
        if not create:
            raise ConfigError(f"--set {key}: no {part!r} in the scenario (have: {', '.join(map(str, node))})")
        node[part] = {}
    return node[part]


def apply_overrides(raw, overrides):
    """A deep copy of the raw YAML mapping with each (key path, value) set; missing sections are
    created, but not new subsystems or list entries."""
    raw = copy.deepcopy(raw)
    for key, value in overrides:
        parts = parse_path(key)
        node = raw
        for depth, part in enumerate(parts[:-1]):
            node = _step_into(node, part, key, create=not (depth == 1 and parts[0] == "subsystems"))
        last = parts[-1]
        if isinstance(last, int):
            _step_into(node, last, key, create=False)
        elif not isinstance(node, dict):
            raise ConfigError(f"--set {key}: {last!r} is below a value that is not a mapping")
        node[last] = value
    return raw


def short_label(point, width=40):
    """A folder-friendly label of one point: last key part and value, joined by '_'."""
    def one(key, value):
        name = str(parse_path(key)[-1])
        text = f"{value:.4g}" if isinstance(value, float) else str(value)
        return re.sub(r"[^A-Za-z0-9_.+-]", "", f"{name}-{text}")
    return "_".join(one(k, v) for k, v in point)[:width] or "run"
