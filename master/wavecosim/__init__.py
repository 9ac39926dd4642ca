"""wavecosim: early-terminable, energy-safe FMI co-simulation (wave variables + Douglas-Rachford).

    import wavecosim as wc
    r = wc.simulate("configs/two_oscillators.yaml", K=20)
    r.summary["max_error"], r.trajectory["time"]

See `load`, `simulate`, `sweep`, `compare`; errors are the classes of `wavecosim.errors`.
"""
from .api import Table, compare, load, simulate, sweep, with_overrides
from .scenario.config import Scenario
from .errors import (ConfigError, CouplingError, FmuError, Interrupted, NumericalError, RunFailed,
                     WavecosimError)
from .masters import ALGORITHMS
from .run.runner import RunResult

__all__ = ["load", "simulate", "sweep", "compare", "with_overrides", "Scenario", "RunResult", "Table",
           "ALGORITHMS", "WavecosimError", "ConfigError", "CouplingError", "FmuError", "NumericalError",
           "RunFailed", "Interrupted"]
