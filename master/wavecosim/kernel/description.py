"""What the kernel's bindings know of a scene: plain values, addresses and a few callbacks, built once
by the scene (core/kernel_scene.py) when a master opens its kernel route and handed in, so that no
binding reads a Scene, Subsystem or Fmu. Callbacks stay on the scene's side: the error of a failed
FMU call (the FMU names it), value references by name, the bookkeeping of FMU calls and the current
gammas.
"""
from dataclasses import dataclass
from typing import Callable, Optional


@dataclass
class KernelFmu:
    """One FMU instance as the kernel calls it: its fmi2Component and its functions by fmi2 name."""
    name: str
    component: int
    pointer: Callable          # fmi2 name -> the address of the function (FMI 3: fmi3shim.c's)
    vrs: Callable              # variable names -> their value references
    error: Callable            # (fmi2 name, status, n, t) -> the FmuError of a failed call


@dataclass
class KernelSubsystem:
    """A subsystem with a port, as the DR kernel takes it (drkernel.h, dr_set_subsystem)."""
    fmu: KernelFmu
    m: int                     # its channels
    offset: int                # its first channel among the scene's
    functions: tuple           # the addresses of drkernel.FMI_NAMES it is called through (the FMU's or a shim's)
    component: int             # the fmi2Component passed with them
    state: int                 # the address of the handle x_i^n is saved into (shared with the scene)
    vr_in: object              # C arrays of the value references a query sets and reads
    vr_out: object
    no_prior: int              # noSetFMUStatePriorToCurrentPoint of its doSteps
    scales: Optional[tuple]    # (in_scale, out_scale) of a signed physical port (portview.c's shim), or None
    counters: Optional[tuple]  # a wave adapter in C: addresses of its worst_accepted and do_steps, else None
    impedance: Optional[tuple]  # a wave adapter in C: addresses of its gamma and k, else None
    adapter_error: Optional[Callable]    # (n, t) -> the wave adapter's own failure, or None
    plain_wave: bool           # the port is the FMU's own wave map (no adapter, no input scaling)
    probe_vrs: Optional[list]  # one wave channel: value references of its effort and flow (the watch's probe)
    substeps: Optional[tuple] = None    # multi-rate: (substeps, input scale, stage value references, address of
                                        # the stage values; both None for a physical port), else None

    @property
    def name(self):
        return self.fmu.name


@dataclass
class KernelScene:
    """A scene as the kernel takes it (Kernel, ClassicalKernel, NewtonKernel, KernelCertificates)."""
    subsystems: list           # KernelSubsystem, in the scene's order
    alone: list                # KernelFmu of each subsystem stepped alone (signals only)
    n: int                     # channels in all
    t0: float                  # the start time
    dt: float                  # the macro-step
    signals: Optional[dict]    # signals.c's plan (core/scene.py, Scene.kernel_signals), its FMUs as KernelFmu
    book_alone: Callable       # (index into alone, doSteps, last step n, its t): book the calls of one stepped alone
    gammas: Callable           # () -> the gamma of each subsystem now
