"""The tolerance mode's record of each accepted step: its size, its error estimate, the steps
rejected before it and the inner stop it ran with (the controller itself is the master's,
masters/adaptive.py); the summary's accepted and rejected counts."""
from . import Observer


class StepControl(Observer):
    """Copies the master's StepRecord of each step into steps.csv."""
    when = "runs in the tolerance mode (`master.tolerance`)"
    described = {
        "dt": ("the macro-step the step was made with (the tolerance mode)", "s"),
        "error_estimate": ("the step's local error estimate over its allowance, per unit step (accepted at ≤ 1; "
                           "NaN where no estimate exists yet: the first steps of `predictor`)", "1"),
        "rejected": ("steps of larger size rejected and redone before this one was accepted", "1"),
        "inner_eps": ("the inner loop's stop the controller gave the step (iterating masters; NaN otherwise)",
                      "sqrt(J) (waves)"),
    }
    columns = tuple(described)

    def __init__(self, master, warn):
        self.master, self.warn, self.over = master, warn, 0

    def after_step(self, n, t, log, reading, row):
        r = self.master.step_record
        row[0], row[1], row[2], row[3] = r.dt, r.estimate, r.rejected, r.inner_eps
        if r.estimate > 1.0:
            self.over += 1
            if self.over == 1:
                self.warn(f"master.tolerance: the step to t = {t + r.dt:.6g} s was kept at {r.estimate:.3g} x its "
                          f"allowance ({self._why(r)}); the error can exceed the tolerance (steps_over_tolerance in "
                          f"summary.json, error_estimate in steps.csv)")

    def _why(self, r):
        """Why a step over its allowance was kept: no FMU to put back, or the smallest step."""
        if not self.master.can_reject:
            return "an FMU cannot get and set its state, so no step is redone"
        return f"dt_min = {self.master.control.h_min:g} s"

    def summary(self):
        return {"accepted_steps": self.master.accepted, "rejected_steps": self.master.rejected,
                "steps_over_tolerance": self.over}
