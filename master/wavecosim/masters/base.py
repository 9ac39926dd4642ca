"""The contract every master meets, so the runner never asks a master for its name.

A master advances every subsystem of a Scene by one macro-step in `step(n, t)`, its own
`make_step` and then its guard's verdict on the commit, and returns a StepLog; the run calls it, its
`route()` and `close()` in the order docs/architecture.md gives, and nothing else. Class attributes
say what it needs and how it is shown:
  wave            the FMUs run in wave port mode (else physical port variables)
  needs_rollback  it freezes and restores FMU states (so FMUs must get and set their state)
  budgets         the grid of inner budgets K `compare` tries ((None,): no inner budget)
  style           (colour, marker) in the comparison plots
  iterates        it gives the DR iterates u^0 and u^K, so Theorem 1's residual, the Condition 1
                  watch and the monolithic energy guard apply
  default_guard   the energy guard it runs with when the scenario names none (DR: ledger; the
                  classical masters: off, as other tools run them)
  evaluations     FMU evaluations per subsystem of one macro-step when fixed (DR: K + 1), else None;
                  it paces the sampled certificates (certificates.sampling)
  variable        its macro-step varies (the tolerance mode, masters/adaptive.py): time_at(k) and
                  more(n) give the grid, and nothing runs in blocks
  guardable       its commit can supply energy, and it can undo the commit and redo it with other
                  inputs (_undo_step, _recommit, _probe, _supply): the energy guards apply
Wave masters (WaveMaster) own the compiled wave map P, J_L and the committed wave b^n: nothing
else writes them. The methods with a leading underscore are the seam between a master and its
guard (masters/ledger.py, masters/energy_guard.py): nothing outside masters/ calls them.
"""
import math
from typing import Optional, Protocol, runtime_checkable

from ..errors import ConfigError
from ..kernel.drkernel import REASONS as KERNEL_REASONS
from ..kernel.linalg import dot, matvec
from .energy_guard import EnergyGuard
from .ledger import EnergyLedger
from .monolithic import solve_interface
from .steplog import StepLog


MIN_INNER_S = 1e-9        # an inner deadline this short stops the loop after its first iteration
REASONS = (*KERNEL_REASONS, "none")          # drkernel.h DRReason, and a step no loop ran for


def kernel_refusal(scene, mode):
    """Why a master's Python reference runs instead of its kernel route (None: the kernel can run),
    for master.fast `mode`; `true` insists (a config error when the kernel cannot run)."""
    if mode == "false":
        return "master.fast is false"
    why = scene.kernel_unusable()
    if why is not None and mode == "true":
        raise ConfigError(f"{scene.scenario.source}: master.fast: true, but {why}")
    return why


@runtime_checkable
class Route(Protocol):
    """The kernel route of a master: what the runner may ask of a master whose macro-steps run in C,
    in blocks of many macro-steps per kernel call, bit for bit its Python reference made step by
    step. `Master.route()` gives it, or None when the master runs step by step only."""

    def can_run_steps(self, n) -> bool:
        """Whether run_steps may make macro-step n now."""

    def observe(self, names, steps=0, bound=None):
        """The variables of each subsystem read after every commit (names[i], H_i first), with room
        for blocks of `steps` steps; an empty BlockLog of the blocks' layout. bound:
        (limit, indices of observed values over all subsystems): run_steps also stops after a step
        where one of them is above the limit in magnitude (run/bounds.py)."""

    def set_passes(self, passes):
        """The passes over the log (kernel/blocks.py, Pass) run_steps makes as it logs the steps."""

    def run_steps(self, n0, count, H_cap=None, passes=False):
        """Macro-steps n0 .. n0 + count - 1 in one call, each guarded as step() guards it, stopping
        early after a step whose H may exceed H_cap (None: what the master's guard sets), whose
        observed values are not finite, or whose bounded ones are above the bound: (steps done, their
        BlockLog, an FmuError or None); a stopped call's last step judged by the guard is the log's
        `last` (None: booked in the log). passes: the kernel makes the passes (set_passes) over the
        steps as it goes, the BlockLog's `passed` first ones."""

    def step_log(self, log, j) -> StepLog:
        """The StepLog of row j of a BlockLog."""

    def step_in_progress(self) -> int:
        """The macro-step the kernel is making now (asked from another thread during run_steps)."""

    def salvage(self, n0):
        """After the process faulted inside run_steps(n0, ...), which never returned: (the steps it made
        before the fault, their BlockLog), as run_steps would have given them."""


class Master:
    """Base of all masters; see the module docstring for the contract."""
    wave = True
    needs_rollback = True
    budgets = (None,)
    style = ("gray", "o")
    iterates = False          # gives the DR iterates u^0, u^K (Theorem 1, Condition 1 watch, energy guard)
    guardable = False         # an energy guard applies (_undo_step, _recommit, _probe, _supply)
    default_guard = "off"     # master.energy_guard when the scenario does not say
    evaluations = None        # FMU evaluations per subsystem of a macro-step, when fixed
    variable = False          # the macro-step varies (masters/adaptive.py)

    def __init__(self, scene, settings):
        self.scene, self.settings = scene, settings
        self.subsystems = scene.subsystems
        self.dt, self.t0 = scene.scenario.dt, scene.scenario.start_time      # t_n = t0 + n dt
        self.deadline_s = settings.deadline_us * 1e-6 if settings.deadline_us else None
        self.inner_deadline_s = self.deadline_s          # the inner loop's share of the deadline
        self.step_started = 0.0                          # perf_counter() when the last step began
        self.guard = chosen_guard(self, settings)        # what judges each commit (energy_guard), or None

    def _reserve_time(self, seconds):
        """Stop the inner loop `seconds` before master.deadline_us, leaving them for a redo."""
        if self.deadline_s is not None:
            self.inner_deadline_s = max(self.deadline_s - seconds, MIN_INNER_S)

    def step(self, n, t) -> StepLog:
        """Macro-step n: the master's own step (make_step), then its guard's verdict on the commit
        (it may undo the commit and make it again)."""
        log = self.make_step(n, t)
        return log if self.guard is None else self.guard.after_commit(n, t, log)

    def make_step(self, n, t) -> StepLog:
        """Macro-step n as the master's algorithm makes it, with its one commit."""
        raise NotImplementedError

    def route(self) -> Optional[Route]:
        """The kernel route of this master when it runs (blocks of macro-steps in C), else None."""
        return None

    def _probe(self, inputs):
        """After _undo_step: the outputs of macro-step n from x^n with `inputs` (stacked); state discarded."""
        return self.scene.S(inputs)

    def _redo_in_kernel(self, supplied, budget, left_s, round_s):
        """The energy ledger's redo of the step just made, done in C with left_s seconds to its
        deadline and round_s per evaluation round: (s, supply, traffic, action, rounds); None where
        there is no kernel (the ledger then redoes it through the methods above)."""
        return None

    def _anchor_queries(self):
        """Inputs of the step just made whose outputs from x^n are known, as (inputs, outputs, supply),
        that the energy ledger may commit instead (DR: its queries); none by default."""
        return []

    def _remaining_iterations(self, log):
        """Inner iterations the step's budget has left after it stopped, that the energy ledger may
        spend (_iterate_on) before it changes the inputs; none by default."""
        return 0

    def kernel_certificates(self, floor):
        """The sampled certificates computed inside this master's blocks of steps (kernel/certs.py), or
        None: the observers then compute them step by step."""
        return None

    def enable_trace(self, on=True):
        """Record the inner loop's queries (u, S(u)) of each macro-step; False if this master cannot."""
        return False

    @property
    def trace(self):
        """The last macro-step's queries [(u^k, S(u^k))], or None when not recorded."""
        return None

    def run_info(self) -> dict:
        """Figures for the run summary (e.g. which code path ran)."""
        return {}

    def close(self):
        """Release anything the master holds beyond the scene (threads, C buffers)."""


class WaveMaster(Master):
    """A master on the wave interface a = P b; it owns P, J_L and the committed wave b^n."""

    def __init__(self, scene, settings):
        super().__init__(scene, settings)
        self._compile()
        self._b = [0.0] * scene.n_channels                             # b^0 = 0
        self._b_step_start = self._b

    @property
    def b(self):
        """The committed outgoing waves b^n (read only)."""
        return self._b

    def _compile(self):
        coupling = self.scene.wave_map()
        self.P, self.J_L = coupling.P_sparse, coupling.J_L_sparse        # linalg.Sparse; np.asarray gives them dense

    def _set_b(self, b):
        self._b = b

    def _commit(self, a_hat):
        """Lines 20-22, eq. (21): advance every subsystem from x^n with a_hat; b^{n+1} becomes b^n."""
        self._b_step_start = self._b
        self._set_b(self.scene.advance(a_hat))

    def retune(self, b):
        """Between macro-steps, after the scene's gammas changed: recompile P, J_L and take b^n
        re-scattered to the new impedances."""
        self._compile()
        self._set_b(list(b))

    def _undo_step(self):
        """Put every subsystem back at x^n and b^n back, after the commit of macro-step n."""
        self.scene.restore_frozen()
        self._set_b(self._b_step_start)

    def fixed_point(self, n, t):
        """b* = S^n(P b*) at the frozen x^n (eq. 15), solved from b^n (u* = P b* of the certificates);
        the FMUs are left at x^n."""
        return solve_interface(self.scene, self.P, self._b, where=f" at step {n} (t = {t:.6g})")[0].tolist()

    def _interface_solution(self, n, t, tag=""):
        """The monolithic incident waves at the frozen x^n: a = P b*, b* = S^n(P b*) (eqs. 14-15),
        solved from b^n; returns (a, iterations, residual)."""
        b_star, iters, res, _ = solve_interface(self.scene, self.P, self._b, where=f"{tag} at step {n} (t = {t:.6g})")
        return matvec(self.P, b_star.tolist()), iters, res

    def _recommit(self, a_hat):
        """After _undo_step: commit macro-step n again with other incident waves; returns b^{n+1}."""
        self._commit(a_hat)
        return self._b

    @property
    def _committed_outputs(self):
        """The outputs of the last commit: b^{n+1}."""
        return self._b

    @staticmethod
    def _committed_inputs(log):
        """The stacked inputs the step committed with: the incident waves a_hat."""
        return log.a_hat

    @staticmethod
    def _supply(inputs, outputs):
        """Energy the interface supplies over a step, 1/2 (|a|^2 - |b|^2) (eq. 5), and its traffic
        1/2 (|a|^2 + |b|^2), the scale of its roundoff."""
        aa, bb = dot(inputs, inputs), dot(outputs, outputs)
        return 0.5 * (aa - bb), 0.5 * (aa + bb)


def chosen_guard(master, settings):
    """The guard of master.energy_guard (else the master's default) where it applies: the ledger on a
    master that can undo its commit, the monolithic guard on one that iterates where every subsystem
    has a stored energy H; None without a port (nothing exchanges energy)."""
    mode, scene = settings.energy_guard or master.default_guard, master.scene
    if not master.guardable or not scene.n_channels:
        return None
    if mode == "ledger":
        return EnergyLedger(master)
    if mode == "monolithic" and master.iterates and all(s.port.energy is not None for s in scene.subsystems):
        return EnergyGuard(master)
    return None


def require_wave_tuning(master, mode, source):
    """auto-retune changes gamma between macro-steps: only wave masters can follow it."""
    if mode == "auto-retune" and not isinstance(master, WaveMaster):
        raise ConfigError(f"{source}: gamma: auto-retune needs a wave master that can change gamma between "
                          f"macro-steps (dr, newton)")


class KernelOwner:
    """Mixin of a master that may run its macro-steps in a C kernel (self.kernel, or None on the
    Python reference): what it reports of the route, and the kernel closed with the master."""

    def run_info(self):
        return {"fast_path": self.kernel is not None, "fast_note": self.fast_note}

    def close(self):
        if self.kernel is not None:
            self.kernel.close()
            self.kernel = None
        super().close()


def error_order(master) -> int:
    """The order in h of a master's error over the run: 2 for an iterating wave master over FMUs' own
    wave ports that no signal drives (each step is the FMUs' implicit step with the solved
    interface), else 1 (an input is held over the step: a signal's, the wave adapter's, or a master's
    that does not iterate)."""
    own_waves = master.wave and not any(s.adapter for s in master.subsystems)
    signals = master.scene.signals
    held = signals is not None and bool({s.name for s in master.subsystems} & set(signals.driven))
    return 2 if master.needs_rollback and own_waves and not held else 1
