"""The end of a run: its summary, the files closed and written (summary.json, metadata.json, MAT
files), the RunResult; what LiveRun adds to say what a run did."""
import time


from ..errors import OutputError
from ..masters import MASTERS
from ..masters.base import error_order
from .metadata import run_metadata
from .outputs import cannot
from .recorder import write_json, write_mat

from .parts import STEP_COLUMNS, STEP_DESCRIBED
from .result import RunResult


class RunFiles:
    """LiveRun's summary, verdict, units and files."""

    def summary(self, status, message):
        settings, sc = self.scenario.master, self.scenario
        n, iters = self.steps_done, self._iteration_totals()
        out = {"label": self.label, "scenario": sc.name, "master": settings.algorithm, "K": settings.K,
               "eps": settings.eps, "dt": sc.dt, "T": sc.T, "start_time": sc.start_time, "times_from": sc.times_from,
               "steps": n, "status": status, "message": message,
               "iterations_mean": iters[0] / n if n else 0.0, "iterations_max": iters[1],
               "wall_time_s": self.master_time, "total_time_s": time.perf_counter() - self.started,
               "loop_time_s": self.loop_time,
               "real_time_factor": self._simulated(n) / self.master_time if self.master_time > 0 else float("nan"),
               "fmu_calls": self.fmu_calls(), "fmu_calls_by_subsystem": self.fmu_calls_by_subsystem(),
               "fmu_tolerance": {s.name: s.fmu.tolerance for s in self.scene.subsystems + self.scene.signal_only
                                 if s.fmu.tolerance is not None},
               "output_interval": self.every,
               "energy_guard": self.guard_mode, "block_steps": self.block_steps,
               "quirks": {name: {"no_set_fmu_state_prior": d.no_set_fmu_state_prior, "chosen_by": d.chosen_by}
                          for name, d in self.scene.decisions.items()}, "notes": list(self.scene.notes)}
        if self.guard is not None:
            out.update(self.guard.summary())
        for o in self.observers:
            out.update(o.summary())
        if self.master is not None:
            out.update(self.master.run_info(), error_order=error_order(self.master))
            out.update(self.scene.port_info())
            out.update(self.scene.signal_info())
        return out

    def finish(self, status, message, release=True):
        """Close the tables and parts (the FMUs only with release), write summary.json (and metadata.json,
        MAT files); the RunResult. The rows still to write count in the run's own time (loop_time_s)."""
        started = time.perf_counter()
        self.write_error = self._close_tables()
        if self.write_error is not None and status == "finished":
            status, message = self.write_error.status, str(self.write_error)
        self.loop_time += time.perf_counter() - started
        status, message = self._verdict(status, message)
        summary = self.summary(status, message)
        if release:
            self.close()
        result = RunResult(self.label, self.scenario.master.algorithm, self.scenario.master.K, self.columns,
                           self.sampler.units, list(self.scenario.error), self.trajectory, self.steps,
                           getattr(self, "first", {}), summary, status, message)
        if self.out_dir is not None:
            try:
                self._write_files(result)
            except OutputError as exc:
                self.write_error = self.write_error or exc
        return result

    def _verdict(self, status, message):
        """A finished run that an observer found suspect (a frozen FMU) is `suspect`, with why."""
        why = [v for v in (o.verdict() for o in self.observers) if v]
        if status != "finished" or not why:
            return status, message
        return "suspect", "; ".join(why + ([message] if message else []))

    def units(self):
        """{"trajectory": {column: unit}, "steps": {column: unit}} of the recorded columns: the outputs'
        from the FMUs' modelDescriptions, the steps' from their descriptions (STEP_DESCRIBED, the
        observers'); "" where no unit is known."""
        steps = {c: STEP_DESCRIBED[c][1] for c in STEP_COLUMNS}
        if not MASTERS[self.scenario.master.algorithm].wave:     # a residual of port variables of any unit
            steps["inner_residual"] = ""
        for o in self.observers:
            steps.update({c: o.unit(c) for c in o.columns})
        if "error" in steps:                     # the units of the error columns (one, when they share it)
            steps["error"] = ", ".join(dict.fromkeys(self.sampler.units.get(c, "") for c in self.scenario.error))
        return {"trajectory": {"time": "s", **self.sampler.units}, "steps": steps}

    def _close_tables(self):
        """Write the last rows and close the files; the first OutputError (disk full, ...) or None.
        A table that could not write keeps its file to whole rows."""
        tables = [t for t in (getattr(self, "trajectory", None), getattr(self, "steps", None))
                  if t is not None and t.path is not None]                   # a table without a file: nothing to write
        errors = []
        for close in [t.flush for t in tables] + [t.close for t in tables]:     # both files' last rows at once
            try:
                close()
            except OutputError as exc:
                errors.append(exc)
        if self.fmu_log is not None:
            try:
                self.fmu_log.close()
            except OSError as exc:
                errors.append(cannot(self.fmu_log.path, exc))
        return errors[0] if errors else None

    def _write_files(self, result):
        name = (lambda kind, ext: self.out_dir / f"{kind}{self.suffix}.{ext}")
        write_json(name("summary", "json"), result.summary)
        write_json(name("metadata", "json"), run_metadata(self.scenario, self.scene, self.units()))
        if "mat" in self.formats:
            write_mat(name("trajectory", "mat"), self.trajectory)
            write_mat(name("steps", "mat"), self.steps)

