"""What a run gives back: its tables as NumPy arrays, its summary and status (RunResult), and the
grid of times its rows are on."""
from dataclasses import dataclass, field

import numpy as np

from ..masters.base import REASONS
from .recorder import Table, Texts


def grid_inverse(dt):
    """1/dt when it is a whole number (the grid is then k / (1/dt)), else 0 (the grid is k * dt)."""
    inverse = round(1.0 / dt)
    return inverse if inverse > 0 and abs(inverse * dt - 1.0) < 1e-12 else 0


def grid_clock(dt):
    """k -> the grid value k dt: k / (1/dt) when 1/dt is a whole number (so t = 0.3 is 0.3, not
    0.30000000000000004), else k * dt."""
    inverse = grid_inverse(dt)
    if inverse:
        return lambda k: k / inverse
    return lambda k: k * dt


def grid_times(k, dt):
    """grid_clock for an array of step indices."""
    return grid_clock(dt)(np.asarray(k, float))


def _structured(table):
    """A table's rows as a NumPy structured array, one float field per column ('reason' and the
    recorded String outputs as text)."""
    data = table.array()
    texts = {c: f.texts for c, f in zip(table.columns, table.formats) if isinstance(f, Texts)}
    fields = [(c, "U12" if c == "reason" else f"U{max(map(len, texts[c]), default=1) or 1}" if c in texts
               else "f8") for c in table.columns]
    out = np.empty(len(data), dtype=fields)
    for j, (name, _) in enumerate(fields):
        if name == "reason" or name in texts:
            names = REASONS if name == "reason" else texts[name]
            out[name] = [names[int(v)] for v in data[:, j]]
        else:
            out[name] = data[:, j]
    return out


@dataclass
class RunResult:
    """What a run produced: `trajectory` and `steps` as NumPy structured arrays whose first field is
    `time` (fmpy's plot_result and write_csv take them as they are), `summary` (as summary.json),
    status and message; arrays of long runs are read back from their files when asked."""
    label: str
    master: str
    K: int
    columns: list
    units: dict
    error_columns: list
    trajectory_table: Table = None
    steps_table: Table = None
    first: dict = field(default_factory=dict)      # values at t = 0 that steps.csv has no row for
    summary: dict = field(default_factory=dict)
    status: str = "finished"
    message: str = ""
    reference: "RunResult" = None                  # the lockstep monolithic reference, when one ran

    @property
    def trajectory(self):
        return _structured(self.trajectory_table)

    @property
    def steps(self):
        return _structured(self.steps_table)

    @property
    def t(self):
        return self.trajectory_table.array()[:, 0]

    @property
    def outputs(self):
        return self.trajectory_table.array()[:, 1:]

    def column(self, name):
        return self.outputs[:, self.columns.index(name)]

    def _series(self, key, column):
        """A per-step column with its value at t = 0 in front: one entry per trajectory row."""
        if column not in self.steps_table.columns:
            return None
        data = self.steps_table.array()[:, self.steps_table.columns.index(column)]
        return np.concatenate([[self.first.get(key, np.nan)], data])

    @property
    def energy(self):
        """Total stored energy H at every recorded grid point, t = 0 included."""
        return self._series("H", "H_total")

    @property
    def error(self):
        """Error against the monolithic reference at every recorded grid point (None without one)."""
        return self._series("error", "error")

    def per_subsystem(self, prefix):
        """The per-subsystem columns `prefix<name>` of steps (r_, fne_, gamma_) as one 2-D array."""
        cols = [c for c in self.steps_table.columns if c.startswith(prefix) and c != "fne_watch"]
        data = self.steps_table.array()
        return data[:, [self.steps_table.columns.index(c) for c in cols]]

    def to_pandas(self):
        """The trajectory as a pandas DataFrame indexed by time (pandas is not a dependency)."""
        import pandas as pd
        return pd.DataFrame(self.trajectory).set_index("time")


