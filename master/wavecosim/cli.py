"""The `wavecosim` command line: a thin shell over config, runner and sweep.

Every WavecosimError becomes one line on stderr and its class's exit code (2 for bad input)."""
import math
import sys
import time
from pathlib import Path

import click

from .scenario.config import load_scenario
from .errors import ConfigError, Interrupted, SweepFailed, WavecosimError
from . import api
from .api import simulate, with_overrides
from .core.gamma import parse_gamma
from .masters import ALGORITHMS, MASTERS
from .run.outputs import OutputFolder
from .run.recorder import write_json
from .run.runner import MAX_STEPS, check_steps
from .scenario.overrides import MAX_RUNS


C_INT_MAX = 2 ** 31 - 1           # the kernel takes budgets, intervals and counts as C ints


def whole(minimum, maximum=C_INT_MAX):
    """An integer option within [minimum, maximum]: by default what a C int holds."""
    return click.IntRange(min=minimum, max=maximum)


class Finite(click.FloatRange):
    """A number option that must be finite (nan and inf refused) and within the range given."""
    name = "finite number"

    def convert(self, value, param, ctx):
        number = super().convert(value, param, ctx)
        if not math.isfinite(number):
            self.fail(f"{value!r} is not a finite number", param, ctx)
        return number


POSITIVE = Finite(min=0, min_open=True)


def _progress(label, quiet, span=None):
    """A progress callback (n steps done of total) on stderr: on a terminal click's progress bar with
    the steps, the percentage, the time since the run began and the time left at the pace so far;
    elsewhere one line when the run is done. span: the time span (s) of a run whose step varies,
    whose progress is the share of it made (its steps are counted in the summary)."""
    if quiet:
        return None
    started, tty, bar, first = time.perf_counter(), sys.stderr.isatty(), None, None

    def report(n, total):
        nonlocal bar, first
        now = time.perf_counter()
        if not tty:
            if n == total:
                done = f"{n}/{total} steps done" if span is None else f"{span:g} s simulated"
                click.echo(f"  {label}: {done} in {now - started:.1f} s", err=True)
            return
        if bar is None:
            bar, first = click.progressbar(length=total, label=f"  {label}", file=sys.stderr, show_pos=span is None,
                                           show_percent=True, show_eta=False, item_show_func=str), (now, n)
        pace = (now - first[0]) / (n - first[1]) if n > first[1] else None        # seconds per step since the first
        left = f", ETA {pace * (total - n):.1f} s" if pace and n < total else ""
        bar.update(n - bar.pos, f"{now - started:.1f} s elapsed{left}")
        if n == total:
            bar.render_finish()
    return report


def _apply_overrides(scenario, K=None, eps=None, gamma=None, dt=None, T=None, algorithm=None, start_time=None,
                     outputs=None):
    """The scenario with the command line's values in place of the file's."""
    gamma = parse_gamma(gamma, "--gamma") if gamma is not None else None
    return with_overrides(scenario, master=algorithm, K=K, eps=eps, gamma=gamma, dt=dt, T=T, start_time=start_time,
                          outputs=outputs, where="--T/--dt")


def parse_budgets(ks, option="--Ks"):
    """--Ks "0,3,8" or "0..8" -> [0, 3, 8], each an integer >= 0."""
    from .scenario.overrides import parse_set
    try:
        _, Ks = parse_set(f"master.K={ks}")
    except ConfigError:
        Ks = None
    if not isinstance(Ks, list) or not all(isinstance(k, int) and not isinstance(k, bool) for k in Ks):
        raise ConfigError(f"{option}: must be comma-separated integers or a range a..b, got {ks!r}")
    if not Ks or min(Ks) < 0 or max(Ks) > C_INT_MAX:
        raise ConfigError(f"{option}: budgets must be integers from 0 to {C_INT_MAX}, got {ks!r}")
    return Ks


def _fmt(x):
    return f"{x:.3e}" if isinstance(x, float) else str(x)


def print_table(rows, fields):
    """A plain aligned text table of dicts."""
    cells = [[_fmt(r.get(f, "")) for f in fields] for r in rows]
    widths = [max(len(f), *(len(c[i]) for c in cells)) for i, f in enumerate(fields)]
    click.echo("  ".join(f.rjust(w) for f, w in zip(fields, widths)))
    for c in cells:
        click.echo("  ".join(v.rjust(w) for v, w in zip(c, widths)))


step_timeout_option = click.option(
    "--step-timeout", type=POSITIVE, metavar="SECONDS",
    help="End the run when a macro-step does not finish within SECONDS, as when a call into an FMU does not "
         "return (the scenario's step_timeout otherwise; default: no limit). Steps before it are kept.")


overwrite_option = click.option(
    "--overwrite", is_flag=True, help="Write into OUT even when it holds files that are not a wavecosim run's "
    "(they are left alone; an earlier run's files are always replaced).")


system_argument = click.argument("config", required=False, type=click.Path(path_type=Path))   # also an SSP folder
common = [
    click.option("--K", "K", type=whole(0), help="Inner-iteration budget K per macro-step."),
    click.option("--eps", type=POSITIVE, help="Inner tolerance: stop when |u_new - u| <= eps."),
    click.option("--gamma", help="Scattering impedance (> 0), or auto / auto-retune / fast-unsafe."),
    click.option("--dt", type=POSITIVE,
                 help="Macro-step size (s); default: the file's, else the smallest DefaultExperiment stepSize of the FMUs."),
    click.option("--T", "T", type=Finite(),
                 help="Stop time (s); default: the file's, else the largest DefaultExperiment stopTime of the FMUs."),
    click.option("--quiet", is_flag=True, help="No progress output."),
]


def options(opts):
    """A decorator adding the click options `opts` in their order."""
    def add(f):
        for opt in reversed(opts):
            f = opt(f)
        return f
    return add


with_common = options(common)


@click.group(context_settings={"help_option_names": ["-h", "--help"]})
@click.version_option(package_name="wavecosim", message="%(prog)s %(version)s")
def cli():
    """wavecosim: early-terminable, energy-safe FMI co-simulation (wave variables + Douglas-Rachford).

    Without CONFIG, commands use the built-in default scenario (the paper's benchmark,
    configs/two_oscillators.yaml)."""


output_options = [
    click.option("--output-interval", type=whole(1), default=1, show_default=True,
                 help="Record every N-th macro-step (and the last) in the CSV files; figures use every step."),
    click.option("--format", "formats", type=click.Choice(["csv", "mat"]), multiple=True,
                 help="Also write MATLAB files (trajectory.mat, steps.mat) with --format mat; CSV is always written."),
]


with_output = options(output_options)


plot_option = click.option(
    "--plot", "plot_patterns", multiple=True, metavar="PATTERN",
    help="Draw these columns in the trajectory figure (a glob over the column names, e.g. 'machine.*'; repeat "
         "for more; implies --plots); default: the error columns, else the power ports', at most 8.")


def _plot_note(message):
    """One line on stderr for a figure or columns that --plots left out."""
    click.echo(f"plots: {message}", err=True)


ssp_options = options([
    click.option("--ports", type=click.Path(dir_okay=False, path_type=Path),
                 help="SSP input: a YAML overlay with the power ports and the run's settings (docs/your-fmus.md)."),
    click.option("--parameter-set", help="SSP input: use only the parameter sets of this name."),
])


experiment_options = options([
    click.option("--start-time", type=Finite(), help="Start time t0 (s) of the grid t0 + n dt; default: the file's, "
                 "else the DefaultExperiment startTime of the FMUs, else 0."),
])


def _read_config(config, ports, parameter_set, dt=None, T=None, gamma=None, start_time=None, input_csv=None,
                 sets=()):
    """A scenario file, an SSP system (.ssd, .ssp, folder) with its overlay, or one FMU (.fmu) with
    its input file; the command line's times go in before the file's are checked, `--set KEY=VALUE`
    into its mapping; import notes are warnings."""
    from .scenario.fmu import is_fmu
    from .scenario.overrides import parse_value
    from .scenario.ssp.archive import is_ssp           # the archive module alone: a scenario file needs no more
    from .examples import resolve
    config = resolve(config)
    times, changes = {"dt": dt, "T": T, "start_time": start_time}, dict(parse_value(s) for s in sets)
    warn = lambda note: click.echo(f"warning: {note}", err=True)        # noqa: E731
    if ports or parameter_set or (config is not None and is_ssp(config)):
        return api.load(config, ports=ports, parameter_set=parameter_set, gamma=gamma, warn=warn, changes=changes,
                        **times)
    if input_csv is not None or is_fmu(config):
        return api.load(config, input=input_csv, warn=warn, changes=changes, **times)
    return load_scenario(config, times, list(changes.items()))


tolerance_options = options([
    click.option("--tolerance", type=click.FloatRange(min=0, min_open=True),
                 help="The tolerance mode: the macro-step varies to keep the error near this relative tolerance "
                      "(--dt is the first step; master.tolerance)."),
    click.option("--atol", type=click.FloatRange(min=0, min_open=True), help="The tolerance mode's absolute tolerance."),
    click.option("--dt-min", type=click.FloatRange(min=0, min_open=True), help="The tolerance mode's smallest step (s)."),
    click.option("--dt-max", type=click.FloatRange(min=0, min_open=True), help="The tolerance mode's largest step (s)."),
    click.option("--output-step", type=click.FloatRange(min=0, min_open=True),
                 help="The tolerance mode: steps also end on the times start + k OUTPUT_STEP (s)."),
    click.option("--estimate", type=click.Choice(["auto", "predictor", "coupling", "doubling"]),
                 help="The tolerance mode's error estimate (default: auto: coupling for FMUs set up with a "
                      "tolerance under explicit and gauss-seidel, else predictor)."),
    click.option("--fmu-tolerance", metavar="auto|null|X",
                 help="The largest tolerance an FMU with a solver of its own is set up with (default: auto: "
                      "1e-3 x --tolerance in the tolerance mode; null: the FMUs' own; master.fmu_tolerance)."),
])


def tolerance_sets(**given):
    """The tolerance options as --set entries (master.KEY=VALUE) for those given."""
    return tuple(f"master.{k}={v!r}" if not isinstance(v, str) else f"master.{k}={v}" for k, v in given.items()
                 if v is not None)


@cli.command("run")
@click.argument("config", required=False, type=click.Path(path_type=Path))
@with_common
@experiment_options
@with_output
@ssp_options
@click.option("--input", "input_csv", type=click.Path(dir_okay=False, path_type=Path),
              help="FMU input: a CSV file (a time column, one column per input; true/false for Booleans; a time "
                   "given twice for an event), applied as fmpy applies it.")
@click.option("--outputs", "outputs", multiple=True, metavar="PATTERN",
              help="Record only the columns matching this glob (e.g. 'IO.y_*'; repeat for more); default: every "
                   "output and connected input, named COMPONENT.variable (or the file's outputs).")
@click.option("--master", "algorithm", type=click.Choice(ALGORITHMS),
              help="Master algorithm (default: from CONFIG; else dr where there are power bonds, explicit without).")
@click.option("--set", "sets", multiple=True, metavar="KEY=VALUE", help="Set a scenario key for this run, "
              "KEY as in sweep --set (master.K=8, subsystems.A.parameters.k=2.5). Repeat for more.")
@click.option("--out", type=click.Path(path_type=Path, resolve_path=True), default=Path("out/run"), show_default=True,
              help="Output folder for trajectory.csv, steps.csv, summary.json and metadata.json.")
@click.option("--no-certificates", is_flag=True, help="Skip FNE sampling, the augmented-storage check and the Condition 1 watch (faster).")
@click.option("--no-reference", is_flag=True, help="Skip the monolithic reference run (no error figures).")
@click.option("--reference", "fine", type=click.Choice(["fine"]), help="fine: also run the monolithic reference "
              "at a refined step and report true_error, the error against it (docs/masters.md).")
@tolerance_options
@click.option("--plots", is_flag=True, help="Also write PNG figures into the output folder.")
@plot_option
@click.option("--threads", help="Threads evaluating the subsystems: auto, or N (up to min(N, CPUs, subsystems)); "
                                "the numbers are the same for any N.")
@step_timeout_option
@click.option("--setup-timeout", type=click.FloatRange(min=0, min_open=True), default=60.0, show_default=True,
              metavar="SECONDS", help="End the run when its set-up (loading the FMUs, instantiating and initializing "
              "them, their probes) makes no progress for SECONDS; compiling the kernel or an FMU does not count.")
@overwrite_option
@click.option("--force", is_flag=True, help=f"Run even more than {MAX_STEPS:,} macro-steps.")
def run_cmd(config, K, eps, gamma, dt, T, quiet, start_time, output_interval, formats, ports, parameter_set, input_csv,
            outputs, algorithm, sets, out, no_certificates, no_reference, fine, tolerance, atol, dt_min, dt_max,
            output_step, estimate, fmu_tolerance, plots, plot_patterns, threads, step_timeout, setup_timeout, overwrite,
            force):
    """Run one scenario (with the monolithic reference alongside where there are power bonds) and
    write its trajectory, per-step certificates, summary and metadata. CONFIG is a scenario file,
    an SSP system (.ssd, .ssp, folder) or one FMU (.fmu), run as fmpy's simulate runs it.

    The steps are made in a child process: an FMU that crashes, calls exit() or (with --step-timeout)
    does not return leaves every step before it on disk, a summary.json saying what happened, and
    an exit code of its own (docs/troubleshooting.md). An earlier run's files in OUT are replaced."""
    sets = sets + tolerance_sets(tolerance=tolerance, atol=atol, dt_min=dt_min, dt_max=dt_max, output_step=output_step,
                                 estimate=estimate, fmu_tolerance=fmu_tolerance)
    scenario = _apply_overrides(_read_config(config, ports, parameter_set, dt, T, gamma, start_time, input_csv, sets),
                                K, eps, gamma, dt, T, algorithm, start_time, outputs)
    if threads is not None:
        from .scenario.config import threads_option
        scenario = scenario.with_master(threads=threads_option(threads))
    max_steps = None if force else MAX_STEPS
    check_steps(scenario, max_steps)

    span = scenario.T - scenario.start_time if scenario.master.tolerance is not None else None

    def work():
        result = simulate(scenario, out_dir=out, progress=_progress("run", quiet, span) or False,
                          certificates=not no_certificates, reference=fine or not no_reference,
                          output_interval=output_interval, formats=("csv", *formats), max_steps=max_steps)
        _report_run(scenario, result, out)
        if plots or plot_patterns:
            from .plots import run_plots
            for p in run_plots(result, result.reference, out, scenario, plot_patterns, _plot_note):
                click.echo(f"wrote {p}")
    with OutputFolder(out, overwrite):
        return _supervised(work, out / "summary.json", step_timeout or scenario.step_timeout, setup_timeout)


def _supervised(work, summary, step_timeout, setup_timeout=None):
    """work() in a supervised child process (run/supervisor.py); its exit code, raised as ChildExit
    when it is not 0 (the child has printed its one line). WAVECOSIM_IN_PROCESS=1 runs it here (for a
    debugger or a profiler; a crash then takes everything with it)."""
    import os
    if os.environ.get("WAVECOSIM_IN_PROCESS", "") not in ("", "0"):
        work()
        return 0
    from .run.supervisor import supervise
    from .run.supervisor import SETUP_TIMEOUT_S
    code = supervise(lambda: _exit_status(work), summary=summary, step_timeout=step_timeout,
                     setup_timeout=setup_timeout or SETUP_TIMEOUT_S)
    if code:
        raise ChildExit(code)
    return 0


def _report_run(scenario, result, out):
    s = result.summary
    budget = f" K={s['K']}" if MASTERS[s["master"]].budgets != (None,) else ""
    click.echo(f"{scenario.name}: {s['master']}{budget} {scenario.times_line()} -> {out}")
    if s.get("gamma_mode", "fixed") != "fixed":
        each = lambda d: ", ".join(f"{k} {v:.6g}" for k, v in d.items())      # noqa: E731
        click.echo(f"gamma: {s['gamma_mode']} -> {each(s['gamma_initial'])} (FNE bounds {each(s['gamma_fne_bounds'])}; "
                   f"predicted inner rate {s['gamma_rate_estimate']:.3f}; final {each(s['gamma_final'])} after "
                   f"{s['gamma_changes']} changes; "
                   f"{'inside the FNE bounds' if s['gamma_guaranteed'] else 'OUTSIDE an FNE bound: Theorem 1 not guaranteed'}"
                   f"{'' if s.get('fne_watch_ok', True) else '; the Condition 1 watch found a violation'})")
    print_table([s], [f for f in ("steps", "rejected_steps", "max_error", "true_error", "rms_error", "final_error", "max_passivity_pos",
                                  "max_augmented_pos", "min_fne_margin", "iterations_mean", "wall_time_s",
                                  "total_time_s", "energy_guard_steps") if f in s])
    if "signal_note" in s:
        click.echo(f"note: {s['signal_note']}")
    if s["status"] == "finished" and s.get("message"):
        click.echo(f"note: {s['message']}")
    if s.get("threads", 1) > 1 or scenario.master.threads not in ("auto", "1"):
        click.echo(f"threads: {s.get('thread_note', 'serial')}")


# sweep: the common options with --K a list, plus those of general sweeps
sweep_options = options([
    click.option("--K", "--Ks", "--K-list", "ks", help="Budgets K: a list like 0,3,8 or a range 0..63 "
                 "(default for the paper's experiment: 0,3,8,20,35,50)."),
    *[opt for opt in common if opt is not common[0]],
    click.option("--out", type=click.Path(path_type=Path, resolve_path=True), default=Path("out/sweep"),
                 show_default=True),
    click.option("--no-certificates", is_flag=True, help="Skip FNE sampling, the augmented-storage check and "
                 "the Condition 1 watch."),
    click.option("--plots", is_flag=True, help="Also write PNG figures (the paper's Figs. 4-6; with --set, "
                 "each --plot-y figure against the first swept key)."),
    plot_option,
    click.option("--set", "sets", multiple=True, metavar="KEY=VALUES", help="Sweep a scenario key: "
                 "KEY=0,3,8 | a..b | linspace(a,b,n) | geomspace(a,b,n) | uniform(lo,hi) | loguniform(lo,hi) | "
                 "normal(mu,sigma) | randint(lo,hi) (see docs/sweeps.md). Repeat for a grid."),
    click.option("--sample", type=whole(1, MAX_RUNS), help="Monte Carlo: draw N values of each distribution."),
    click.option("--seed", type=whole(0, 2 ** 63 - 1), default=0, show_default=True,
                 help="Seed of the Monte Carlo draws."),
    click.option("--workers", type=whole(1, 1024), help="Processes (or LocalCluster workers); "
                 "default: the number of CPUs; 1 runs in this process."),
    click.option("--scheduler", help="Run on Dask: a scheduler address (tcp://host:8786) or 'local' for an "
                 "embedded LocalCluster of --workers processes."),
    click.option("--resume", is_flag=True, help="Skip runs whose folder already holds a finished run; run "
                 "those that did not finish once more."),
    click.option("--no-reference", is_flag=True, help="No monolithic reference per run (no error figures)."),
    click.option("--plot-y", default="max_error", show_default=True,
                 help="Comma-separated figures to plot against the first swept key (with --plots)."),
    step_timeout_option,
    overwrite_option,
])


@cli.command("sweep")
@system_argument
@sweep_options
@ssp_options
def sweep_cmd(config, ks, eps, gamma, dt, T, quiet, out, no_certificates, plots, plot_patterns, sets, sample, seed,
              workers, scheduler, resume, no_reference, plot_y, step_timeout, overwrite, ports, parameter_set):
    """Without --set: the paper's experiment, DR for each K against the monolithic reference
    (summary.json). With --set (or --sample, --workers, --scheduler, --resume, --no-reference):
    a general sweep over any scenario keys, one row per run in OUT/runs.csv and OUT/runs.json;
    each run is made in a child process of its own, and one that crashes or times out is a row
    saying so (the sweep then exits with code 8)."""
    if sets or sample or workers or scheduler or resume or no_reference:
        if plot_patterns:
            raise ConfigError("--plot: a sweep with --set draws its --plot-y figures, not trajectories")
        options = dict(no_certificates=no_certificates, plots=plots, sample=sample, seed=seed, workers=workers,
                       scheduler=scheduler, resume=resume, no_reference=no_reference, plot_y=plot_y, quiet=quiet,
                       step_timeout=step_timeout, ports=ports, parameter_set=parameter_set)
        return _general_sweep(config, ks, sets, (eps, gamma, dt, T), out, options)
    Ks = parse_budgets(ks or "0,3,8,20,35,50")
    scenario = _apply_overrides(_read_config(config, ports, parameter_set, dt, T, gamma), None, eps, gamma, dt, T)

    def work():
        from .sweeps.budget import SWEEP_FIELDS
        table = api.sweep(scenario, Ks, out_dir=out, progress=(lambda label: _progress(label, quiet)),
                          certificates=not no_certificates)
        reference, results, runs = table.reference, table.results, table.rows
        click.echo(f"{scenario.name}: sweep over K = {Ks} -> {out / 'summary.json'}")
        print_table(runs, list(SWEEP_FIELDS))
        if plots or plot_patterns:
            from .plots import sweep_plots
            for p in sweep_plots(results, reference, out, scenario, plot_patterns, _plot_note):
                click.echo(f"wrote {p}")
    with OutputFolder(out, overwrite):
        return _supervised(work, None, step_timeout or scenario.step_timeout)


def _general_sweep(config, ks, sets, changes, out, o):
    """A sweep over --set keys on the chosen executor; prints the rows' main figures."""
    import os

    from .scenario.overrides import parse_set, scalar
    from .sweeps.budget import plan, run_sweep
    from .sweeps.execute import check_scheduler
    if o["scheduler"]:
        check_scheduler(o["scheduler"])
    axes = [parse_set(s) for s in list(sets)]
    if ks:
        axes.insert(0, ("master.K", parse_budgets(ks, "--K")))
    fixed = [(k, scalar(v) if k == "gamma" else v)
             for k, v in zip(("master.eps", "gamma", "dt", "T"), changes) if v is not None]
    tasks = plan(config, axes, out, fixed, o["sample"], o["seed"], not o["no_reference"], not o["no_certificates"],
                 step_timeout=o["step_timeout"], ports=o["ports"], parameter_set=o["parameter_set"])
    workers = o["workers"] or os.cpu_count() or 1
    meta = {"config": tasks[0].config, "axes": [[k, list(v)] for k, v in axes], "fixed": fixed,
            "sample": o["sample"], "seed": o["seed"], "executor": o["scheduler"] or f"{workers} workers"}
    with OutputFolder(out, clear=False):
        rows = run_sweep(tasks, out, meta, workers, o["scheduler"], o["resume"],
                         None if o["quiet"] else _sweep_progress)
    keys = [k for k, _ in axes]
    failed = [r for r in rows if r.get("status") != "finished"]
    click.echo(f"{len(rows)} runs ({len(failed)} not finished) -> {out / 'runs.csv'}, {out / 'runs.json'}")
    print_table(rows, ["index", *keys, "status", "max_error", "iterations_mean", "task_time_s"])
    for r in failed:
        click.echo(f"run {r['index']} ({r['label']}): {r.get('status')}: {r.get('message')}")
    if o["plots"]:
        from .plots import figure_plots
        for p in figure_plots(rows, keys, [y.strip() for y in o["plot_y"].split(",") if y.strip()], out, _plot_note):
            click.echo(f"wrote {p}")
    if failed:
        raise SweepFailed(f"{len(failed)} of {len(rows)} runs did not finish (their rows say why: {out / 'runs.csv'})")


def _sweep_progress(total, skipped):
    """A per-run progress line with failures and ETA on stderr."""
    import time
    state = {"done": 0, "failed": 0, "t0": time.perf_counter()}
    todo = total - skipped

    def report(row):
        state["done"] += 1
        state["failed"] += row.get("status") != "finished"
        elapsed = time.perf_counter() - state["t0"]
        eta = elapsed / state["done"] * (todo - state["done"])
        click.echo(f"  sweep: {skipped + state['done']}/{total} runs ({skipped} resumed, {state['failed']} not "
                   f"finished), {elapsed:.1f} s, ETA {eta:.1f} s", err=True)
    return report


@cli.command("compare")
@system_argument
@with_common
@experiment_options
@ssp_options
@click.option("--masters", default=",".join(ALGORITHMS), show_default=True,
              help="Comma-separated masters to compare.")
@click.option("--Ks", "--K-list", "ks", default=None,
              help="Comma-separated budgets K for the iterative masters (default: a grid per master).")
@click.option("--out", type=click.Path(path_type=Path, resolve_path=True), default=Path("out/compare"), show_default=True)
@click.option("--no-certificates", is_flag=True, help="Skip FNE sampling, the augmented-storage check and the Condition 1 watch.")
@click.option("--plots", is_flag=True, help="Also write pareto.png and energy_by_master.png.")
@click.option("--options", "dr_options", default="", metavar="NAMES",
              help="Also DR with each of these named options (comma-separated, or all): relaxed, anderson, "
                   "warm, gamma-auto, gamma-fastest, fastest-relaxed, fastest-relaxed-anderson, "
                   "fastest-relaxed-extrapolated, fastest-relaxed-memory, fastest-memory, "
                   "fastest-memory-eps3, fastest-memory-eps5.")
@click.option("--tolerances", metavar="LIST", help="Instead: the tolerance mode at each of these tolerances (e.g. "
              "1e-2,1e-4,1e-6; with each of --masters, default dr,gauss-seidel) and step doubling, beside a grid of "
              "fixed (dt, K), all against one fine reference: tolerances.csv, tolerances.json, tolerances.png.")
@click.option("--peers", default="", metavar="NAMES", help="With --tolerances: also these peers at each tolerance "
              "on the same FMUs (ecco: libcosim's ECCO over the system's power bonds; needs the peers extra).")
@step_timeout_option
@overwrite_option
def compare_cmd(config, K, eps, gamma, dt, T, quiet, start_time, ports, parameter_set, masters, ks, out,
                no_certificates, plots, dr_options, tolerances, peers, step_timeout, overwrite):
    """Every master over a grid of budgets against the monolithic reference: error, energy, cost."""
    from .sweeps.comparison import COMPARE_FIELDS, parse_options
    options = parse_options(dr_options)
    names = [m.strip() for m in masters.split(",") if m.strip()]
    for name in names:
        if name not in ALGORITHMS:
            raise ConfigError(f"--masters: unknown master {name!r} (have: {', '.join(ALGORITHMS)})")
    if K is not None and ks is not None:
        raise ConfigError("--K and --Ks: give one budget (--K) or a list (--Ks), not both")
    Ks = [K] if K is not None else None
    if ks is not None:
        Ks = parse_budgets(ks)
    scenario = _apply_overrides(_read_config(config, ports, parameter_set, dt, T, gamma, start_time), None, eps,
                                gamma, dt, T, start_time=start_time)
    peer_names = _peer_list(peers, tolerances)
    if tolerances is not None:
        chosen = names if click.get_current_context().get_parameter_source("masters").name != "DEFAULT" else None
        return _compare_tolerances(scenario, _tolerance_list(tolerances), chosen, out, quiet, overwrite, peer_names)

    def work():
        table = api.compare(scenario, names, Ks, out_dir=out, progress=(lambda label: _progress(label, quiet)),
                            certificates=not no_certificates, options=options)
        reference, results, rows = table.reference, table.results, table.rows
        click.echo(f"{scenario.name}: {len(rows)} runs of {len(names)} masters -> {out / 'compare.json'} (the "
                   f"runs' files: one folder per master in {out})")
        print_table(rows, list(COMPARE_FIELDS))
        for r in rows:
            if r["status"] != "finished":
                click.echo(f"{r['master']} K={r['K']}: {r['status']} after {r['steps']} steps: {r['message']}")
        if plots:
            from .plots import compare_plots
            for p in compare_plots(rows, results, reference, out, _plot_note):
                click.echo(f"wrote {p}")
    with OutputFolder(out, overwrite):
        return _supervised(work, None, step_timeout or scenario.step_timeout)


def _tolerance_list(text):
    """--tolerances "1e-2,1e-4" -> [0.01, 0.0001], each a number > 0."""
    try:
        values = [float(v) for v in text.split(",") if v.strip()]
    except ValueError:
        values = []
    if not values or not all(v > 0 for v in values):
        raise ConfigError(f"--tolerances: must be comma-separated numbers > 0, got {text!r}")
    return values


def _peer_list(text, tolerances):
    """--peers "ecco" -> ("ecco",): names of sweeps/ecco.py's PEERS, and only with --tolerances."""
    from .sweeps.ecco import PEERS
    names = tuple(p.strip() for p in text.split(",") if p.strip())
    unknown = [p for p in names if p not in PEERS]
    if unknown:
        raise ConfigError(f"--peers: unknown peer {unknown[0]!r} (have: {', '.join(PEERS)})")
    if names and tolerances is None:
        raise ConfigError("--peers: goes with --tolerances (the peers run at each tolerance)")
    return names


def _compare_tolerances(scenario, tolerances, masters, out, quiet, overwrite, peers=()):
    """compare --tolerances: the rows, the table on stdout, tolerances.png."""
    from .plots import tolerance_plots
    from .sweeps.tolerances import FIELDS, compare_tolerances

    def work():
        shown = None if quiet else (lambda row: click.echo(f"  {row['mode']} {row['master']}: true error "
                                                           f"{row['true_error']:.3g}", err=True))
        rows = compare_tolerances(scenario, tolerances, out, tuple(masters or ()), shown, peers,
                                  click.echo)
        click.echo(f"{scenario.name}: {len(rows)} runs -> {out / 'tolerances.csv'}")
        print_table(rows, list(FIELDS))
        for p in tolerance_plots(rows, scenario.name, out):
            click.echo(f"wrote {p}")
    with OutputFolder(out, overwrite):
        return _supervised(work, None, scenario.step_timeout)


@cli.command("validate")
@system_argument
@ssp_options
@click.option("--input", "input_csv", type=click.Path(dir_okay=False, path_type=Path), help="FMU input: a CSV file.")
@options([opt for opt in common if opt in (common[3], common[4])])
@experiment_options
def validate_cmd(config, ports, parameter_set, input_csv, dt, T, start_time):
    """Check a scenario file (an SSP system, or one FMU) and its FMUs without running it."""
    from .core.scene import build_scene
    scenario = _read_config(config, ports, parameter_set, dt, T, start_time=start_time, input_csv=input_csv)
    scene = build_scene(scenario, wave=True)
    try:
        for note in scene.notes:
            click.echo(f"warning: {note}", err=True)
        signals = (f", {len(scene.signal_only)} signal-only, {len(scenario.signals)} signals, "
                   f"{len(scenario.sources)} sources") if scene.signal_only or scenario.signals else ""
        waves = f", |P^T P - I| = {scene.wave_map().orthogonality_residual:.1e}" if scene.n_channels else ""
        click.echo(f"{scenario.source}: OK ({len(scene.subsystems)} subsystems{signals}, {scene.n_channels} channels"
                   f"{waves})")
    finally:
        scene.close()


@cli.command("import-ssp")
@click.argument("ssp", type=click.Path(exists=False, path_type=Path))
@ssp_options
@click.option("-o", "--out", type=click.Path(dir_okay=False, path_type=Path, resolve_path=True), required=True,
              help="The YAML draft to write.")
def import_ssp_cmd(ssp, ports, parameter_set, out):
    """Write an SSP system (.ssd, .ssp or a folder) as a scenario file to edit, each part commented
    with where it came from."""
    from .scenario.ssp import import_ssp
    from .scenario.ssp.draft import write_draft
    imported = import_ssp(ssp, ports, parameter_set)
    for note in imported.notes:
        click.echo(f"warning: {note}", err=True)
    click.echo(f"wrote {write_draft(imported, out)}")


@cli.command("build")
@click.option("--force", is_flag=True, help="Rebuild even when sources are unchanged.")
def build_cmd(force):
    """Build the package's FMUs and C kernel into the per-user cache (done on demand by every other command)."""
    from .fmi.builtin import build_all
    for ident, path in build_all(force=force, log=lambda msg: click.echo(msg, err=True)).items():
        click.echo(f"{ident}: {path}")


@cli.command("examples")
@click.argument("name", required=False)
def examples_cmd(name):
    """List the example scenarios shipped with wavecosim, each with its description, those that cannot
    run here with what they need; or print the path of one (NAME). Every command and wavecosim.simulate
    take an example by its name."""
    from . import examples
    if name is None:
        described = [examples.describe(each) for each in examples.names()]
        width = max(len(d["name"]) for d in described)
        for d in (d for d in described if not d["needs"]):
            click.echo(f"{d['name']:<{width}}  {d['description']}")
        lacking = [d for d in described if d["needs"]]
        if lacking:
            click.echo("\nnot runnable here:")
        for d in lacking:
            click.echo(f"{d['name']:<{width}}  {d['description']}\n{'':<{width}}  needs {d['needs']}")
        return
    try:
        click.echo(examples.path(name))
    except FileNotFoundError as exc:
        raise ConfigError(str(exc)) from None


@cli.command("info")
@click.argument("file", type=click.Path(path_type=Path))
@ssp_options
@click.option("--json", "as_json", is_flag=True, help="Print the description as JSON.")
def info_cmd(file, ports, parameter_set, as_json):
    """What FILE holds: an FMU's variables (causality, type, unit, start), default experiment and
    co-simulation capabilities; an SSP system's or scenario file's components, connections, power
    ports and couplings. Nothing is run."""
    import json
    from .scenario.info import describe, text
    info = describe(file, ports, parameter_set)
    click.echo(json.dumps(info, indent=1) if as_json else "\n".join(text(info)))


BENCH_S = {"quick": 40, "full": 160}     # measured wall time of `bench` (2 CPUs, warm build cache)


@cli.command("bench")
@click.option("--quick", is_flag=True, help=f"Fewer steps and repeats: about {BENCH_S['quick']} s instead of about "
                                           f"{BENCH_S['full']} s (2 CPUs).")
@click.option("--json", "json_file", type=click.Path(dir_okay=False, path_type=Path), help="Also write the figures here.")
@click.option("--only", type=click.Choice(["parallel_threads", "real_fmus"]),
              help="Measure this part alone (real_fmus: systems of real FMUs against the floor of their FMU "
                   "calls and libcosim).")
def bench_cmd(quick, json_file, only):
    """Time the inner iteration: plain fmpy loop, Python reference, C fast path and the C floor; the deadline
    bound; threads; real FMUs against their floor and libcosim."""
    from .bench.main import report, run_bench, run_part
    started = time.monotonic()
    progress = lambda msg: click.echo(f"[{time.monotonic() - started:5.0f} s] {msg}", err=True)      # noqa: E731
    if not only:
        seconds = BENCH_S["quick" if quick else "full"]
        click.echo(f"bench: about {seconds} s on 2 CPUs{'' if quick else ' (--quick: about %d s)' % BENCH_S['quick']}; "
                   f"the figures follow at the end", err=True)
    if only:
        result, lines = run_part(only, quick, progress)
    else:
        result = run_bench(quick=quick, progress=progress)
        lines = report(result)
    for line in lines:
        click.echo(line)
    if json_file:
        write_json(json_file, result)
        click.echo(f"wrote {json_file}")


class ChildExit(WavecosimError):
    """A supervised child ended with this exit code, after printing its own line."""

    def __init__(self, code):
        super().__init__("")
        self.exit_code = code


def _exit_status(work):
    """work(); its exit code: 0, or the code of the error it raised, after one line on stderr."""
    try:
        work()
        return 0
    except click.exceptions.Abort:
        click.echo("error: interrupted", err=True)
        return 130
    except click.ClickException as exc:
        click.echo(f"error: {exc.format_message()}", err=True)    # one line, naming the option
        return 2
    except ChildExit as exc:
        return exc.exit_code
    except Interrupted as exc:
        click.echo(f"interrupted: {exc}; results so far are on disk", err=True)
        return exc.exit_code
    except WavecosimError as exc:
        click.echo(f"error: {exc}", err=True)
        return getattr(exc, "exit_code", 1)
    except KeyboardInterrupt:
        click.echo("error: interrupted", err=True)
        return 130


def main(argv=None):
    sys.exit(_exit_status(lambda: cli.main(args=argv, standalone_mode=False)))


if __name__ == "__main__":
    main()
