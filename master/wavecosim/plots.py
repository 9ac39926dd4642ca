"""PNG figures of a run, a K-sweep (the paper's Figs. 4-6) and a comparison of masters (Agg backend).

Every function takes finished (or partial) RunResults, writes into `out` and returns the paths. A figure
whose data the run has not got (no stored energy, no reference, no certificates) is not drawn: `note`
gets one line saying which and why. Log axes cannot show zero or negative values: such points are
drawn at FLOOR and the axis says so.
"""
import fnmatch
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402
from matplotlib.ticker import NullFormatter  # noqa: E402

from .errors import ConfigError  # noqa: E402
from .masters import MASTERS  # noqa: E402
from .sweeps.comparison import group_name, style as _style  # noqa: E402

FLOOR = 1e-17
DPI = 130
MAX_TRAJECTORIES = 8          # panels of trajectories.png; --plot PATTERN picks others
NAMED = 12                    # left-out columns named in the note, the rest counted
PORT_KEYS = ("effort", "flow", "physical_in", "physical_out")
REFERENCE_LABEL = "monolithic (newton)"
NO_ENERGY = "not drawn: the total stored energy H needs every subsystem's (a port's `energy:` variable)"


def _quiet(_message):
    """The default `note`: figures left out are not reported."""


def _save(fig, path):
    fig.savefig(path, dpi=DPI, bbox_inches="tight")
    plt.close(fig)
    return path


def _finite(x, y):
    x, y = np.asarray(x, float)[:len(y)], np.asarray(y, float)
    keep = np.isfinite(y)
    return x[keep], y[keep]


def _has(series):
    """Whether a per-step series exists and holds a finite value."""
    return series is not None and bool(np.isfinite(np.asarray(series, float)).any())


def _floored(values):
    """Values for a log axis: <= 0 (and anything below FLOOR) at FLOOR; nan stays missing."""
    v = np.asarray(values, float)
    return np.where(np.isnan(v) | (v > FLOOR), v, FLOOR)


def _unit(result, col):
    u = result.units.get(col, "")
    return f"{col} ({u})" if u else col


def _error_label(result):
    cols = result.error_columns
    units = {result.units.get(c, "") for c in cols}
    unit = f" ({units.pop()})" if len(units) == 1 and "" not in units else ""
    return "‖(" + ", ".join(f"Δ{c}" for c in cols) + f")‖₂{unit}"


def _colors(n):
    return plt.cm.viridis(np.linspace(0.0, 0.9, max(n, 1)))


def _energy_t(result):
    return result.t[:len(result.energy)]


def _k_label(result):
    return f"K = {result.K}"


def run_label(result):
    """The legend of a run: its master, with its budget K where the master iterates."""
    master = MASTERS.get(result.master)
    return f"{result.master}, K = {result.K}" if master is not None and master.budgets != (None,) else result.master


# ---------------------------------------------------------------- which columns

def _port_columns(result, scenario):
    """The columns that record a power port's effort or flow (as SUBSYSTEM.variable or a named column)."""
    if scenario is None:
        return []
    refs = set()
    for sub in scenario.subsystems:
        for key in PORT_KEYS:
            names = (sub.port or {}).get(key) or []
            refs.update(f"{sub.name}.{v}" for v in ([names] if isinstance(names, str) else names))
    named = scenario.outputs if isinstance(scenario.outputs, dict) else {}
    return [c for c in result.columns if named.get(c, c) in refs]


def trajectory_columns(result, scenario=None, patterns=()):
    """(columns drawn, columns left out) of trajectories.png: those the glob `patterns` match, else
    the error columns, else the power ports' efforts and flows, else every column; at most
    MAX_TRAJECTORIES. A pattern list matching no column is a ConfigError naming some columns."""
    if patterns:
        chosen = [c for c in result.columns if any(fnmatch.fnmatchcase(c, p) for p in patterns)]
        if not chosen:
            have = ", ".join(result.columns[:8]) + (", ..." if len(result.columns) > 8 else "")
            raise ConfigError(f"--plot: {' '.join(patterns)} matches no column (have: {have or 'none'})")
    else:
        chosen = list(result.error_columns) or _port_columns(result, scenario) or list(result.columns)
    drawn = chosen[:MAX_TRAJECTORIES]
    return drawn, [c for c in result.columns if c not in drawn]


def _left_out_note(name, drawn, left, note):
    """One line naming the columns a trajectory figure leaves out (the first NAMED, then a count)."""
    if left:
        more = f" and {len(left) - NAMED:,} more" if len(left) > NAMED else ""
        note(f"{name}: {len(drawn)} of {len(drawn) + len(left):,} columns drawn; left out: "
             f"{', '.join(left[:NAMED])}{more} (--plot PATTERN draws others; trajectory.csv has them all)")


def _trajectory_axes(result, cols, title, left, width=7.0):
    """A figure of one panel per column, each headed by its column and unit; the title counts what is left out."""
    height = 2.2 if len(cols) <= 3 else 1.6
    fig, axes = plt.subplots(len(cols), 1, figsize=(width, 0.8 + height * len(cols)), sharex=True,
                             squeeze=False, layout="constrained")
    for ax, col in zip(axes[:, 0], cols):
        ax.set_title(_unit(result, col), loc="left", fontsize=9)
        ax.grid(alpha=0.3)
    shown = f"; {len(cols)} of {len(cols) + len(left):,} columns" if left else ""
    fig.suptitle(title.replace("{shown}", shown), fontsize=11)
    axes[-1, 0].set_xlabel("t (s)")
    return fig, axes[:, 0]


def _legend_outside(fig, columns=4):
    """The lines' legend once, below the panels."""
    handles, labels = fig.axes[0].get_legend_handles_labels()
    fig.legend(handles, labels, loc="outside lower center", ncol=min(columns, len(labels)), fontsize=8,
               frameon=False)


# ---------------------------------------------------------------- one run

def run_plots(result, reference, out, scenario=None, patterns=(), note=_quiet):
    """trajectories.png (the columns of trajectory_columns, with the monolithic reference), energy.png
    (where the FMUs report their stored energy), error.png (where there is an error against the reference)."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    label = run_label(result)
    paths = [_run_trajectories(result, reference, label, out / "trajectories.png", scenario, patterns, note)]
    paths += [_run_energy(result, reference, label, out / "energy.png", note),
              _run_error(result, reference, out / "error.png", note)]
    return [p for p in paths if p is not None]


def _no_columns(result, path, note):
    """True, after a note, when the run recorded no column to draw."""
    if not result.columns:
        note(f"{path.name}: not drawn: the run recorded no column (its FMUs have no outputs and no driven inputs)")
    return not result.columns


def _run_trajectories(result, reference, label, path, scenario, patterns, note):
    if _no_columns(result, path, note):
        return None
    cols, left = trajectory_columns(result, scenario, patterns)
    fig, axes = _trajectory_axes(result, cols, f"{result.summary.get('scenario', '')}: trajectories "
                                 f"({result.status}{{shown}})", left)
    for ax, col in zip(axes, cols):
        ax.plot(*_finite(result.t, result.column(col)), label=label)
        if reference is not None and col in reference.columns:
            ax.plot(reference.t, reference.column(col), "k--", lw=1, label=REFERENCE_LABEL)
    _legend_outside(fig)
    _left_out_note(path.name, cols, left, note)
    return _save(fig, path)


def _run_energy(result, reference, label, path, note):
    if not _has(result.energy):
        note(f"{path.name}: {NO_ENERGY}")
        return None
    fig, ax = plt.subplots(figsize=(7, 3.2))
    ax.plot(*_finite(_energy_t(result), result.energy), label=label)
    if reference is not None and _has(reference.energy):
        ax.plot(_energy_t(reference), reference.energy, "k--", lw=1, label=REFERENCE_LABEL)
    ax.set(xlabel="t (s)", ylabel="stored energy H (J)", title="Total stored energy")
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    return _save(fig, path)


def _no_error_reason(result, reference):
    if reference is None:
        return "no monolithic reference ran (no power ports, or --no-reference)"
    return "the scenario names no error columns (`error:`)"


def _run_error(result, reference, path, note):
    if not _has(result.error):
        note(f"{path.name}: not drawn: {_no_error_reason(result, reference)}")
        return None
    fig, ax = plt.subplots(figsize=(7, 3.2))
    ax.semilogy(result.t[:len(result.error)], _floored(result.error))
    ax.set(xlabel="t (s)", ylabel=f"{_error_label(result)}; 0 drawn at {FLOOR:g}",
           title=f"Error against the monolithic reference ({run_label(result)})")
    ax.grid(alpha=0.3, which="both")
    return _save(fig, path)


# ---------------------------------------------------------------- K sweep (paper Figs. 4-6)

def sweep_plots(results, reference, out, scenario=None, patterns=(), note=_quiet):
    """fig4_trajectories.png, fig5_certificates.png, fig6_error.png and energy_by_K.png of a DR sweep,
    each where its data exists."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    Ks = [r.K for r in results]
    colors = _colors(len(results))
    drawn = [_fig4(results, reference, colors, out / "fig4_trajectories.png", scenario, patterns, note),
             _fig5(results, Ks, out / "fig5_certificates.png", note),
             _fig6(results, reference, Ks, colors, out / "fig6_error.png", note),
             _energy_by_run(results, reference, colors, out / "energy_by_K.png", note)]
    return [p for p in drawn if p is not None]


def _fig4(results, reference, colors, path, scenario, patterns, note):
    if _no_columns(results[0], path, note):
        return None
    cols, left = trajectory_columns(results[0], scenario, patterns)
    fig, axes = _trajectory_axes(results[0], cols, "Fig. 4: trajectories for each inner budget K and the "
                                 "monolithic reference{shown}", left, width=7.5)
    for ax, col in zip(axes, cols):
        for r, c in zip(results, colors):
            ax.plot(*_finite(r.t, r.column(col)), color=c, lw=1.1, label=_k_label(r))
        if reference is not None and col in reference.columns:
            ax.plot(reference.t, reference.column(col), "k--", lw=1.2, label=REFERENCE_LABEL)
    _legend_outside(fig, columns=7)
    _left_out_note(path.name, cols, left, note)
    return _save(fig, path)


CONDITION2 = (("max_passivity_pos", r"passivity: $\max_{n,i}\,(r_i^n)_+$, eq. (27)", "o"),
              ("max_augmented_pos", r"augmented storage: $\max_n\,(\cdot)_+$, eq. (32)", "s"))


def _number(value):
    return float(value) if isinstance(value, (int, float)) and not isinstance(value, bool) else np.nan


def _fig5(results, Ks, path, note):
    """Condition 1 margins and Condition 2 / Theorem 1 residuals against K: the panels whose certificates
    the runs sampled (none where the FMUs give no wave port or stored energy)."""
    names = [n for n in results[0].summary.get("min_fne_margin_by_subsystem") or {}
             if _has([_number((r.summary.get("min_fne_margin_by_subsystem") or {}).get(n)) for r in results])]
    residuals = [(key, label, marker, [_number(r.summary.get(key)) for r in results])
                 for key, label, marker in CONDITION2]
    residuals = [each for each in residuals if _has(each[3])]
    if not names and not residuals:
        note(f"{path.name}: not drawn: no certificate was sampled (`certificates:` or --no-certificates "
             "left them out, or a subsystem reports no stored energy H)")
        return None
    panels = (["fne"] if names else []) + (["residual"] if residuals else [])
    fig, axes = plt.subplots(1, len(panels), figsize=(5.5 * len(panels), 3.8), squeeze=False, layout="constrained")
    axes = dict(zip(panels, axes[0]))
    if names:
        _fne_panel(axes["fne"], results, Ks, names)
    if residuals:
        _residual_panel(axes["residual"], Ks, residuals)
    return _save(fig, path)


def _fne_panel(a, results, Ks, names):
    for name in names:
        a.plot(Ks, [_number(r.summary["min_fne_margin_by_subsystem"].get(name)) for r in results], "o-",
               label=f"subsystem {name}: min over steps and sampled pairs")
    a.axhline(0.0, color="k", lw=0.8, ls="--", label="FNE threshold 0")
    a.set(xlabel="inner budget K", ylabel="normalized FNE margin Δ/‖α−β‖²",
          title="(a) Condition 1: FNE margins")
    a.grid(alpha=0.3)
    a.legend(fontsize=8)


def _residual_panel(b, Ks, residuals):
    top = 1e-6
    for _key, label, marker, vals in residuals:
        b.semilogy(Ks, _floored(vals), marker + "-", label=label)
        top = max([top] + [10 * v for v in vals if np.isfinite(v)])
    b.set(xlabel="inner budget K", ylabel=f"largest positive part (J); ≤ 0 drawn at {FLOOR:g}",
          title="(b) Condition 2 and Theorem 1", ylim=(FLOOR / 3, top))
    b.grid(alpha=0.3, which="both")
    b.legend(fontsize=8)


def _fig6(results, reference, Ks, colors, path, note):
    if not any(_has(r.error) for r in results):
        note(f"{path.name}: not drawn: {_no_error_reason(results[0], reference)}")
        return None
    fig, (a, b) = plt.subplots(1, 2, figsize=(11, 3.8), layout="constrained")
    for r, c in zip(results, colors):
        if r.error is not None:
            a.semilogy(r.t[:len(r.error)], _floored(r.error), color=c, lw=1, label=_k_label(r))
    a.set(xlabel="t (s)", ylabel=_error_label(results[0]), title="(a) Error history")
    a.grid(alpha=0.3, which="both")
    a.legend(ncol=2, fontsize=8)
    for key, label, marker in (("max_error", "max", "o"), ("rms_error", "time-RMS", "s"),
                               ("final_error", "final", "^")):
        b.semilogy(Ks, _floored([_number(r.summary.get(key)) for r in results]), marker + "-", label=label)
    b.set(xlabel="inner budget K", ylabel=_error_label(results[0]), title="(b) Error versus K")
    b.grid(alpha=0.3, which="both")
    b.legend(fontsize=8)
    return _save(fig, path)


def _energy_by_run(results, reference, colors, path, note):
    if not any(_has(r.energy) for r in results):
        note(f"{path.name}: {NO_ENERGY}")
        return None
    fig, ax = plt.subplots(figsize=(7.5, 3.6))
    for r, c in zip(results, colors):
        if _has(r.energy):
            ax.plot(*_finite(_energy_t(r), r.energy), color=c, lw=1.1, label=_k_label(r))
    if reference is not None and _has(reference.energy):
        ax.plot(_energy_t(reference), reference.energy, "k--", lw=1.2, label=REFERENCE_LABEL)
    ax.set(xlabel="t (s)", ylabel="stored energy H (J)", title="Total stored energy H(t)")
    ax.grid(alpha=0.3)
    ax.legend(ncol=2, fontsize=8)
    return _save(fig, path)


# ---------------------------------------------------------------- comparison of masters

def compare_plots(rows, results, reference, out, note=_quiet):
    """pareto.png (error against wall time and FMU calls) where there is an error against the reference,
    and energy_by_master.png (H(t) per master) where the FMUs report their stored energy."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    scenario = reference.summary.get("scenario", "")
    paths = []
    if _has([_number(r.get("max_error")) for r in rows]):
        paths.append(_pareto(rows, _error_label(reference), scenario, out / "pareto.png", note))
    else:
        note(f"pareto.png: not drawn: no run has an error against the reference ({_no_error_reason(None, reference)})")
    if _has(reference.energy):
        paths.append(_energy_per_master(rows, results, reference, scenario, out / "energy_by_master.png"))
    else:
        note(f"energy_by_master.png: {NO_ENERGY}")
    return paths


def _by_master(rows, results):
    """{master or master:option: [(row, result), ...]} in the order of the rows."""
    groups = {}
    for row, res in zip(rows, results):
        groups.setdefault(group_name(row), []).append((row, res))
    return groups


def _pareto_label(name, members, ok):
    bad = [str(r["K"]) for r, _ in members if r not in ok]
    return name if not bad else f"{name} (diverged{'' if bad == ['-'] else ' at K = ' + ', '.join(bad)})"


def _pareto(rows, error_label, scenario, path, note):
    """Max error against master wall time and against doSteps per macro-step, and (where the FMUs report
    their stored energy) the energy growth max H/H(0) against doSteps per macro-step: every master and DR
    option, one line each."""
    growth = _has([_number(r.get("H_growth")) for r in rows])
    fig, axes = plt.subplots(1, 3 if growth else 2, figsize=(18 if growth else 12, 5.4), layout="constrained")
    for name, members in _by_master(rows, rows).items():
        color, marker = _style(name)
        ok = [r for r, _ in members if r["diverged"] == "no" and np.isfinite(_number(r["max_error"]))]
        label = _pareto_label(name, members, ok)
        for ax, xkey in zip(axes[:2], ("wall_time_s", "doSteps_per_step")):
            x, y = [float(r[xkey]) for r in ok], _floored([r["max_error"] for r in ok])
            ax.loglog(x, y, marker=marker, color=color, ls="-" if xkey != "wall_time_s" else "none", ms=4, lw=1,
                      label=label)
            for xi, yi, r in zip(x, y, ok if xkey == "doSteps_per_step" and len(members) > 1 else ()):
                ax.annotate(f"{r['K']}", (xi, yi), textcoords="offset points", xytext=(3, 2), fontsize=6, color=color)
        done = [r for r, _ in members if r["steps"]]
        if growth:
            axes[2].loglog([r["doSteps_per_step"] for r in done], [r["H_growth"] for r in done], marker=marker,
                           color=color, ls="-", ms=4, lw=1)
    axes[0].set(xlabel="master wall time (s), log", ylabel=f"max error {error_label}, log (0 drawn at {FLOOR:g})",
                title="Error against master wall time")
    axes[1].set(xlabel="FMU doSteps per macro-step, log", title="Error against FMU calls (numbers: budget K)")
    if growth:
        axes[2].axhline(1.0, color="k", lw=0.8, ls="--")
        axes[2].set(xlabel="FMU doSteps per macro-step, log", ylabel="energy growth max H(t)/H(0), log",
                    title="Energy growth (> 1: energy supplied)")
    else:
        note(f"{path.name}: the energy growth panel not drawn: {NO_ENERGY.split(': ', 1)[1]}")
    for ax in axes:
        ax.grid(alpha=0.3, which="both")
        ax.xaxis.set_minor_formatter(NullFormatter())
    fig.suptitle(f"{scenario}: accuracy against cost, every master, DR option and budget")
    _legend_outside(fig, columns=5)
    return _save(fig, path)


def _energy_per_master(rows, results, reference, scenario, path):
    """H(t) of each master at its smallest and largest budget; a diverging run leaves the top of the axes."""
    fig, axes = plt.subplots(1, 2, figsize=(12, 5.2), sharey=True)
    H0 = reference.energy[0]
    lows, highs = [np.nanmin(reference.energy)], [np.nanmax(reference.energy)]
    for ax, pick, title in ((axes[0], 0, "(a) smallest budget of each master"),
                            (axes[1], -1, "(b) largest budget of each master")):
        for name, members in _by_master(rows, results).items():
            if name == "newton" or ":" in name:         # newton is the reference, drawn dashed; DR options:
                continue                                # their energy growth is in the Pareto figure
            row, res = members[pick]
            color, _ = _style(name)
            t, H = _finite(_energy_t(res), res.energy)
            keep = H > 0
            tag = name if row["K"] == "-" else f"{name}, K = {row['K']}"
            if row["diverged"] == "yes":
                tag += f" (diverged, max H/H(0) = {row['H_growth']:.1e})"
            elif H[keep].size:
                lows.append(H[keep].min())
                highs.append(H[keep].max())
            ax.semilogy(t[keep], H[keep], color=color, lw=1.2, label=tag)
        ax.semilogy(_energy_t(reference), reference.energy, "k--", lw=1.2, label="monolithic (newton)")
        ax.set(xlabel="t (s)", title=title)
        ax.grid(alpha=0.3, which="both")
        ax.legend(fontsize=8, loc="upper center", bbox_to_anchor=(0.5, -0.14), ncol=2)
    diverging = any(r["diverged"] == "yes" for r in rows)
    axes[0].set_ylim(min(lows) / 2, H0 * 1e3 if diverging else max(highs) * 2)
    axes[0].set_ylabel("stored energy H (J), log")
    fig.suptitle(f"{scenario}: total stored energy H(t) per master (H(0) = {H0:.4g} J)")
    return _save(fig, path)


# ---------------------------------------------------------------- general sweep (rows of runs.csv)

def _numeric(values):
    return all(isinstance(v, (int, float)) and not isinstance(v, bool) for v in values)


def figure_plots(rows, keys, figures, out, note=_quiet):
    """<figure>_vs_<key>.png for each figure that some run has: the figure against the first swept key,
    one line per combination of the other swept keys; non-numeric keys on a categorical axis."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    if not keys or not rows:
        return []
    x_key, others = keys[0], keys[1:]
    groups = {}
    for row in rows:
        groups.setdefault(tuple(row.get(k) for k in others), []).append(row)
    xs = [row.get(x_key) for row in rows]
    categories = None if _numeric(xs) else list(dict.fromkeys(map(str, xs)))
    have = [y for y in figures if _has([_number(row.get(y)) for row in rows])]
    for y in figures:
        if y not in have:
            note(f"{y}: not drawn: no run has a number for it (runs.csv names the figures each run has)")
    return [_figure_vs_key(groups, x_key, others, y, categories, out) for y in have]


def _figure_vs_key(groups, x_key, others, y, categories, out):
    fig, ax = plt.subplots(figsize=(7, 4))
    colors = _colors(len(groups))
    values = []
    for color, (group, rows) in zip(colors, groups.items()):
        x = [categories.index(str(r.get(x_key))) if categories else r.get(x_key) for r in rows]
        v = [r.get(y) if isinstance(r.get(y), (int, float)) else float("nan") for r in rows]
        values += v
        label = ", ".join(f"{k} = {g}" for k, g in zip(others, group)) or None
        ax.plot(*_finite(x, v), "o-", color=color, ms=3, lw=1, label=label)
    finite = np.asarray([v for v in values if np.isfinite(v)], float)
    if finite.size and finite.min() > 0 and finite.max() > 100 * finite.min():
        ax.set_yscale("log")
    if categories:
        ax.set_xticks(range(len(categories)), categories, rotation=45, ha="right")
    ax.set(xlabel=x_key, ylabel=y, title=f"{y} against {x_key}")
    ax.grid(alpha=0.3, which="both")
    if 1 < len(groups) <= 12:
        ax.legend(fontsize=7, loc="upper left", bbox_to_anchor=(1.01, 1.0))
    name = "".join(c if c.isalnum() or c in "._-" else "_" for c in f"{y}_vs_{x_key}")
    return _save(fig, out / f"{name}.png")


def tolerance_plots(rows, scenario, out):
    """tolerances.png: true error against FMU doSteps and against wall time, one line per mode and
    master (the tolerance mode, step doubling, each fixed (master, K) over its grid of dt)."""
    groups = {}
    for r in rows:
        if np.isfinite(r.get("true_error", np.nan)):
            name = f"{r['mode']} {r['master']}" + (f" K={r['K']}" if r["mode"] == "fixed" and r["K"] != "" else "")
            groups.setdefault(name, []).append(r)
    fig, axes = plt.subplots(1, 2, figsize=(13, 5.2))
    for name, members in groups.items():
        color, marker = _style(name.split()[1])
        ls = {"tolerance": "-", "doubling": "--", "fixed": ":", "ecco": "-."}[name.split()[0]]
        for ax, key in zip(axes, ("doStep", "wall_time_s")):
            pts = sorted((float(r[key]), float(r["true_error"])) for r in members)
            ax.loglog([p[0] for p in pts], _floored([p[1] for p in pts]), marker=marker, color=color, ls=ls, ms=4,
                      lw=1, label=name)
    axes[0].set(xlabel="FMU doSteps, log", ylabel="true error (max over time / range), log",
                title="True error against FMU calls")
    axes[1].set(xlabel="wall time (s), log", title="True error against wall time")
    for ax in axes:
        ax.grid(alpha=0.3, which="both")
    fig.suptitle(f"{scenario}: what should I run? (solid: tolerance mode, dashed: step doubling, dotted: fixed dt, "
                 "dash-dot: libcosim's ECCO)")
    axes[0].legend(fontsize=7, loc="upper center", bbox_to_anchor=(1.1, -0.12), ncol=4)
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    return [_save(fig, out / "tolerances.png")]
