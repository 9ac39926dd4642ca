"""The parts of one run, opened in set-up: the scene, the master (with its guard) and the gamma
tuner; the observers that write the steps' columns; the columns every run has."""
import sys


from ..core.gamma import GammaTuner
from ..masters import MASTERS
from ..masters.adaptive import adaptive
from ..masters.base import REASONS, WaveMaster, require_wave_tuning
from ..masters.dr_options import auto_gamma
from ..core.certificates import sampling
from .observers.certificates import CertificatePace, CertificateSampler
from ..masters.ledger import EnergyLedger
from .observers.energy_ledger import LedgerColumns
from .observers.errors import ErrorTracker, ScaledErrors
from .observers.fne_watch import FneWatch
from .observers.freeze_watch import FreezeWatch
from .observers.gamma import GammaLog, TunedGammaLog
from .observers.passivity import Passivity
from .observers.step_control import StepControl
from ..core.scene import build_scene

# The columns of steps.csv every run has, then the observers' (their `described`); docs/outputs.md
# is generated from these.
STEP_DESCRIBED = {
    "time": ("the grid time t₀ + (n + 1)·Δt at the end of macro-step n", "s"),
    "iterations": ("inner iterations made in the step (0 for a master that does not iterate)", "1"),
    "inner_residual": ("the size of the last inner update, |uᵏ⁺¹ − uᵏ| (wave masters, sqrt(J)) or |yᵏ⁺¹ − yᵏ| "
                       "(physical masters, the port variables' units: no one unit); NaN when no iteration ran", "sqrt(J)"),
    "reason": (f"why the inner loop stopped: {', '.join(REASONS)}", "text"),
}
STEP_COLUMNS = tuple(STEP_DESCRIBED)
OBSERVERS = (LedgerColumns, GammaLog, TunedGammaLog, FneWatch, CertificateSampler, CertificatePace,
             Passivity, FreezeWatch, StepControl, ErrorTracker, ScaledErrors)    # every observer, in the order they act (their columns too)


def _warn_stderr(message):
    print(f"warning: {message}", file=sys.stderr, flush=True)


def _once(warn):
    """`warn` that lets each distinct message through once."""
    seen = set()

    def once(message):
        if message not in seen:
            seen.add(message)
            warn(message)
    return once


def open_parts(scenario, warn, share=None):
    """Scene, master and gamma tuner of a run; whatever was opened is closed if set-up fails. A run
    alongside another (the lockstep reference) shares the other scene's FMU binaries and quirks."""
    cls = adaptive(MASTERS[scenario.master.algorithm], scenario.master)
    scene = build_scene(scenario, wave=cls.wave, needs_rollback=cls.needs_rollback,
                        pool=share.pool if share else None, quirks=share.quirks if share else None)
    for note in scene.notes:
        warn(note)
    master = None
    gamma = auto_gamma(scenario.gamma, scenario.master) if cls.iterates else scenario.gamma
    try:
        tuner = None
        if cls.wave and isinstance(gamma, str):
            tuner = GammaTuner(scene, gamma, warn if cls.iterates else None)
            tuner.initial([0.0] * scene.n_channels)                # sets the scene's per-subsystem gammas
        master = cls(scene, scenario.master)
        require_wave_tuning(master, gamma, scenario.source)
        return scene, master, tuner
    except BaseException:
        if master is not None:
            master.close()
        scene.close()
        raise


def make_observers(scenario, scene, master, tuner, certificates, warn):
    """The observers this run needs, in the order they write their columns (the energy ledger's
    first); none where no subsystem has a port (nothing exchanges energy)."""
    obs, unavailable = [], []
    if not scene.n_channels:
        return [StepControl(master, warn)] if master.variable else obs
    has_H = all(s.port.energy is not None for s in scene.subsystems)
    guard = scenario.master.energy_guard or master.default_guard
    if isinstance(master.guard, EnergyLedger):
        obs.append(LedgerColumns())
    elif guard == "monolithic" and master.guardable and master.iterates and not has_H:
        unavailable.append("energy_guard (monolithic: needs every subsystem's stored energy H)")
    if isinstance(master, WaveMaster):
        obs.append(TunedGammaLog(scene, master, tuner) if tuner and tuner.retune else GammaLog(scene, master, tuner))
    certs = scenario.certificates
    pace = sampling(certs, master.evaluations)
    if master.iterates and scenario.fne_watch and certificates:
        obs.append(FneWatch(scene, master, pace, warn))
    augmented = master.iterates and has_H
    if certificates and master.iterates and certs.augmented and not has_H:
        unavailable.append("max_augmented_pos (Theorem 1 needs every subsystem's stored energy H)")
    if certificates and scene.wave and (certs.fne_pairs or (certs.augmented and augmented)):
        obs.append(CertificateSampler(scene, master, certs, augmented=augmented, pace=pace))
    if any(isinstance(o, (FneWatch, CertificateSampler)) for o in obs):
        obs.append(CertificatePace(pace))
    obs.append(Passivity(scene, unavailable))
    obs.append(FreezeWatch(scene, warn))
    if master.variable:
        obs.append(StepControl(master, warn))
    return obs


