"""The energy ledger's columns of steps.csv. The ledger itself belongs to the master that keeps it
(masters/ledger.py): it judges each commit and logs the step's figures, which this observer writes."""
from ...masters.ledger import ACTIONS
from ..recorder import Labels
from . import Observer


class LedgerColumns(Observer):
    """Iⁿ, Lⁿ, s, the action and the redo rounds of every step, as the master's ledger logged them."""
    blocks = True
    columns = ("interface_energy", "ledger", "scale", "ledger_action", "ledger_rounds")
    formats = {"ledger_action": Labels(ACTIONS)}
    when = "the energy ledger: `master.energy_guard: ledger` (DR's default) on a master that rolls back"
    described = {
        "interface_energy": ("Iⁿ, the energy the interface supplied in the step: Σᵢ ½(‖âᵢ‖² − ‖bᵢⁿ⁺¹‖²) on the "
                             "wave masters, Δt Σ e·f on the physical ones (after a redo: the redone step's)", "J"),
        "ledger": ("Lⁿ = Σ_{k≤n} Iᵏ, the energy the interface has supplied since the start; kept at or below "
                   "roundoff (10⁻¹² of the interface's traffic)", "J"),
        "scale": ("s, where the redone step's inputs lie on the segment from the correction's anchor (s = 0) to "
                  "the inputs first committed (s = 1); 1 when the step was kept", "1"),
        "ledger_action": (f"{', '.join(ACTIONS)}: the step as committed, or the redo stage that made it (the "
                          "rest of the inner budget, a projection against the supply's gradient, a blend towards "
                          "or the input of an anchor, a scaling towards zero, zero inputs)", "text"),
        "ledger_rounds": ("evaluation rounds (every subsystem's doStep once) the redo made; 0 when the step "
                          "was kept", "1"),
    }

    def block(self, n0, logs, readings):
        logged = logs.ledger_rows
        return logged[[0, 1, 3, 4, 5]].T                       # supplied, ledger; scale, action, rounds
