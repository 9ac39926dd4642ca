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

    def __init__(self, master):
        self.master = master

    def after_step(self, n, t, log, reading, row):
        r = self.master.step_record
        row[0], row[1], row[2], row[3] = r.dt, r.estimate, r.rejected, r.inner_eps

    def summary(self):
        return {"accepted_steps": self.master.accepted, "rejected_steps": self.master.rejected}
