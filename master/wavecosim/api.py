"""The public Python API (`import wavecosim`): load a scenario, simulate it, sweep K, compare masters.

The CLI is a thin layer over these functions, so a number from Python and from the command line is
the same to the last bit. Nothing is written to disk unless `out_dir` is given. Errors raise the
classes of `wavecosim.errors` (ConfigError, FmuError, NumericalError, RunFailed, Interrupted) with
the same one-line messages the CLI prints; RunFailed and Interrupted carry the partial `result`.
"""
from contextlib import nullcontext
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable, Mapping, Optional, Sequence, Union

import numpy as np

from .scenario.config import Scenario, _Checker, load_scenario, output_patterns
from .errors import ConfigError
from .masters import ALGORITHMS
from .core.gamma import parse_gamma
from .run.outputs import OutputFolder
from .run.runner import MAX_STEPS, RunResult, check_steps, run

ScenarioLike = Union[str, Path, Scenario]


def load(path: Union[str, Path, None] = None, *, master: Optional[str] = None, K: Optional[int] = None,
         eps: Optional[float] = None, gamma=None, dt: Optional[float] = None, T: Optional[float] = None,
         start_time: Optional[float] = None, outputs: Optional[Sequence[str]] = None,
         ports: Union[str, Path, None] = None, parameter_set: Optional[str] = None,
         input: Union[str, Path, None] = None, warn: Optional[Callable[[str], None]] = None,
         changes: Optional[Mapping[str, Any]] = None, tolerance: Optional[float] = None) -> Scenario:
    """Read and validate a scenario file (the built-in Table I scene when `path` is None; an example
    by its name, `wavecosim examples`), an SSP
    system (.ssd, .ssp, folder) with the overlay `ports` and the parameter sets named
    `parameter_set`, or one FMU (.fmu) driven by the CSV file `input`, with the given values in
    place of the file's (the CLI's options; `outputs`: glob patterns of the columns to record;
    `tolerance`: the tolerance mode, master.tolerance).
    Notes of an SSP or FMU import go to `warn` (default: Python warnings). `changes` sets keys of the
    scenario's mapping before it is checked, as `--set` does: {"subsystems.A.parameters.k": 2.0}."""
    from .scenario.fmu import is_fmu, load_fmu
    from .scenario.ssp import is_ssp, load_ssp, ssp_only
    from .examples import resolve
    path, times, changes = resolve(path), {"dt": dt, "T": T, "start_time": start_time}, list((changes or {}).items())
    ssp_only(path, ports, parameter_set)
    if input is not None and not is_fmu(path):
        raise ConfigError("input: only for an FMU (.fmu)")
    if path is not None and is_ssp(path):
        settings = {**times, "gamma": parse_gamma(gamma, "gamma") if gamma is not None else None}
        scenario, imported = load_ssp(path, ports, parameter_set, settings, changes)
        for note in imported.notes:
            (warn or _python_warning)(note)
    elif is_fmu(path):
        scenario = load_fmu(path, input, times, warn or _python_warning, changes)
    else:
        scenario = load_scenario(path, times, changes)
    return with_overrides(scenario, master=master, K=K, eps=eps, gamma=gamma, dt=dt, T=T, start_time=start_time,
                          outputs=outputs, tolerance=tolerance)


def _python_warning(message):
    import warnings
    warnings.warn(message, stacklevel=3)


def with_overrides(scenario: Scenario, *, master=None, K=None, eps=None, gamma=None, dt=None, T=None,
                   start_time=None, outputs=None, tolerance=None, where="options") -> Scenario:
    """The scenario with some values replaced, each checked as in a file (one-line ConfigError);
    `outputs` (glob patterns) narrows the recorded columns; `tolerance` sets the tolerance mode."""
    K, eps, dt, T, start_time, tolerance = (_plain(v) for v in (K, eps, dt, T, start_time, tolerance))
    check = _Checker(where)
    if K is not None:
        check.integer(K, "K", minimum=0)
    for name, value in (("eps", eps), ("dt", dt), ("T", T), ("start_time", start_time), ("tolerance", tolerance)):
        if value is not None:
            check.number(value, name, positive=name in ("dt", "eps", "tolerance"))
    changes = {k: v for k, v in (("K", K), ("eps", eps), ("algorithm", master), ("tolerance", tolerance))
               if v is not None}
    if master is not None and master not in ALGORITHMS:
        raise ConfigError(f"{where}: master: must be one of {', '.join(ALGORITHMS)}, got {master!r}")
    if changes:
        scenario = scenario.with_master("master" if where == "options" else "--master", **changes)
    top = {k: v for k, v in (("dt", dt), ("T", T), ("start_time", start_time)) if v is not None}
    if top:
        top["times_from"] = {**scenario.times_from, **{k: "the command line" for k in top}}
    if outputs:
        top["output_patterns"] = output_patterns(list(outputs), lambda msg: _fail_outputs(where, msg))
    if gamma is not None:
        top["gamma"] = parse_gamma(gamma, f"{where}: gamma" if where != "options" else "gamma")
    return scenario.with_changes(where, **top)


def _plain(value):
    """A numpy scalar (np.int64(5), np.float64(0.1)) as the Python number it holds; anything else as given."""
    return value.item() if isinstance(value, np.generic) else value


def _budgets(Ks):
    """Budgets K as Python integers >= 0 within a C int (numpy's integers taken), else a one-line ConfigError."""
    check = _Checker("Ks")
    return [check.integer(_plain(K), f"[{i}]", minimum=0) for i, K in enumerate(Ks)]


def _fail_outputs(where, message):
    raise ConfigError(f"{'--outputs' if where != 'options' else 'outputs'}: {message}")


def _scenario(scenario: ScenarioLike, **overrides) -> Scenario:
    if isinstance(scenario, Scenario):
        return with_overrides(scenario, **overrides)
    return load(scenario, **overrides)


def _progress_printer(enabled, variable=False):
    """progress=True prints a line every 10 % to stderr (variable: a run whose step varies, as the
    share of its time span made); a callable gets (step, total)."""
    if callable(enabled) or not enabled:
        return enabled or None
    import sys
    last = [0]                                        # the tenth of the run last printed

    def report(n, total):
        tenth = (10 * n) // total
        if n == total or tenth != last[0]:
            last[0] = tenth
            print(f"  {100 * n // total} % of the time span" if variable else f"  {n}/{total} steps",
                  file=sys.stderr, flush=True)
    return report


def simulate(scenario: ScenarioLike = None, *, master: Optional[str] = None, K: Optional[int] = None,
             eps: Optional[float] = None, gamma=None, dt: Optional[float] = None, T: Optional[float] = None,
             start_time: Optional[float] = None, outputs: Optional[Sequence[str]] = None,
             tolerance: Optional[float] = None,
             out_dir: Union[str, Path, None] = None, reference: Union[bool, str] = True, certificates: bool = True,
             progress: Union[bool, Callable[[int, int], None]] = False, output_interval: int = 1,
             formats: Sequence[str] = ("csv",), warn: Optional[Callable[[str], None]] = None,
             overwrite: bool = False, max_steps: Optional[int] = MAX_STEPS) -> RunResult:
    """Run one scenario (a path, a Scenario, or None for Table I) and return its RunResult.

    `result.trajectory` is a structured array whose first field is `time` (the grid t0 + n dt), so
    `fmpy.util.plot_result(result.trajectory)` draws it; `result.steps` holds the per-step figures,
    `result.summary` the figures of summary.json, `result.reference` the monolithic reference run
    alongside (reference=True) or None; reference="fine" also runs it at a refined step after the run
    and adds `true_error` to the summary (run/fine.py). `tolerance` runs the tolerance mode: the
    macro-step varies to keep the error near it (master.tolerance; `dt` is the first step). Files
    are written only into `out_dir`, which is locked while the run writes; an earlier run's files
    there are replaced, and other files refused unless `overwrite` (run/outputs.py). More than
    max_steps macro-steps are refused (None: no limit)."""
    sc = _scenario(scenario, master=master, K=K, eps=eps, gamma=gamma, dt=dt, T=T, start_time=start_time,
                   outputs=outputs, tolerance=tolerance)
    check_steps(sc, max_steps)
    with OutputFolder(out_dir, overwrite) if out_dir is not None else nullcontext():
        printer = _progress_printer(progress, sc.master.tolerance is not None)
        result = run(sc, out_dir, label=sc.master.algorithm, reference="lockstep" if reference else None,
                     certificates=certificates, progress=printer, warn=warn,
                     file_suffix=False, output_interval=output_interval, formats=tuple(formats), max_steps=max_steps)
        if reference == "fine":
            _true_error(sc, result, out_dir)
        return result


def _true_error(scenario, result, out_dir):
    """The run's error against the fine reference into its summary (and summary.json)."""
    from .run.fine import fine_reference, true_error
    from .run.recorder import write_json
    result.summary.update(true_error(result, fine_reference(scenario, result)))
    if out_dir is not None:
        write_json(Path(out_dir) / "summary.json", result.summary)


@dataclass
class Table:
    """Results of several runs: `rows` (one dict per run, as in the JSON files), `results` (the
    RunResults) and `reference` (the monolithic run they were measured against)."""
    rows: list
    results: list
    reference: RunResult

    def array(self, fields: Sequence[str] = None) -> np.ndarray:
        """The rows as a structured array of the given (default: every numeric) fields."""
        fields = list(fields or [k for k, v in self.rows[0].items() if isinstance(v, (int, float))
                                 and not isinstance(v, bool)])
        out = np.empty(len(self.rows), dtype=[(f, "f8") for f in fields])
        for f in fields:
            out[f] = [r.get(f, np.nan) if isinstance(r.get(f), (int, float)) else np.nan for r in self.rows]
        return out


def sweep(scenario: ScenarioLike = None, Ks: Sequence[int] = (0, 3, 8, 20, 35, 50), *, out_dir=None,
          certificates: bool = True, progress=False, **overrides) -> Table:
    """The paper's experiment: DR at every budget K against the monolithic reference."""
    from .sweeps.budget import sweep as run_sweep
    sc = _scenario(scenario, **overrides)
    reference, results, rows = run_sweep(sc, _budgets(Ks), out_dir, progress=_labelled(progress),
                                         certificates=certificates)
    return Table(rows, results, reference)


def compare(scenario: ScenarioLike = None, masters: Optional[Sequence[str]] = None,
            Ks: Optional[Sequence[int]] = None, *, out_dir=None, certificates: bool = True, progress=False,
            options: Sequence[str] = (), **overrides) -> Table:
    """Every master (default: all) over its grid of budgets (or `Ks`) against the monolithic reference,
    and DR with each named option in `options` (wavecosim.sweeps.comparison.DR_OPTIONS)."""
    from .sweeps.comparison import compare as run_compare, parse_options
    sc = _scenario(scenario, **overrides)
    reference, results, rows = run_compare(sc, out_dir, masters, Ks if Ks is None else _budgets(Ks),
                                           progress=_labelled(progress),
                                           certificates=certificates, options=parse_options(options))
    return Table(rows, results, reference)


def _labelled(progress):
    """sweep/compare take progress(label) -> a per-run callback: True prints, a one-argument callable
    is used as that factory (the CLI's)."""
    if callable(progress):
        return progress
    printer = _progress_printer(progress)
    return (lambda label: printer) if printer else None
