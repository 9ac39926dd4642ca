"""The scene as the C kernel's bindings take it (kernel/description.py): built here, once, when a master
opens its kernel route, from the Scene, its Subsystems and their Fmus, which the bindings never read.
Also why the kernel cannot run a scene (`unusable`), which asks the FMUs for their functions.
"""
from ..errors import FmuError
from ..kernel.abi import LayoutError
from ..kernel.cvalues import uints
from ..kernel.adapter import load_library as load_adapter_library
from ..kernel.description import KernelFmu, KernelScene, KernelSubsystem
from ..kernel.drkernel import FMI_NAMES, FUNCTIONS, DRFunctions, load_library

ALONE_NAMES = ("fmi2GetReal", "fmi2SetReal", "fmi2DoStep")     # all a subsystem stepped alone needs


def unusable(scene):
    """Why the kernel cannot run this scene, or None if it can (subsystems stepped alone need only
    getReal, setReal and doStep); a library whose structs differ from their mirrors is no reason to
    fall back but an error (abi.LayoutError)."""
    multi = next((s for s in scene.subsystems + scene.signal_only if s.substeps != 1 and not s.kernel_substeps()),
                 None)
    if multi is not None:
        why = "a wave adapter" if multi.adapter else "no port"
        return (f"subsystem {multi.name} makes {multi.substeps} substeps per macro-step with {why}, which the "
                f"kernel does not")
    for s in scene.signal_only:
        for name in ALONE_NAMES:
            try:
                s.fmu.function_pointer(name)
            except (AttributeError, FmuError):
                return f"subsystem {s.name}: the FMU does not export {s.fmu.function_name(name)}"
    for s in scene.subsystems:
        if not s.fmu.can_save_state:
            return f"subsystem {s.name} cannot get and set its FMU state"
        for name in FMI_NAMES:
            try:
                s.fmu.function_pointer(name)      # FMI 3: kernel/c/fmi3shim.c's, in fmi2 form
            except AttributeError:
                return f"subsystem {s.name}: the FMU does not export {s.fmu.function_name(name)}"
            except LayoutError:
                raise
            except FmuError as exc:
                return str(exc)
    try:
        load_library()
        if any(s.adapter for s in scene.subsystems):
            load_adapter_library()
    except LayoutError:
        raise
    except FmuError as exc:
        return str(exc)
    return None


def kernel_fmu(s):
    """A subsystem's FMU instance as the kernel calls it."""
    fmu = s.fmu
    return KernelFmu(s.name, fmu.component, fmu.function_pointer, fmu.real_vrs, fmu.status_error)


def _probe_vrs(s):
    """The effort's and flow's value references of a one-channel physical-variable wave port, else None."""
    names = [*s.port.effort, *s.port.flow]
    return s.fmu.real_vrs(names) if s.m == 1 and not s.port.physical and len(names) == 2 else None


def kernel_subsystem(s, offset):
    """Subsystem s as the DR kernel takes it; a wave adapter moves to C here (Subsystem.adapter_in_kernel)."""
    fmu = kernel_fmu(s)
    functions, component = tuple(fmu.pointer(name) for name in FMI_NAMES), fmu.component
    counters = impedance = adapter_error = None
    if s.adapter:
        table, component = s.adapter_in_kernel(DRFunctions(*functions), component, FUNCTIONS)
        functions, vr_in = tuple(table), uints(range(s.m))
        vr_out, counters, impedance, adapter_error = vr_in, s.map.counters(), s.map.impedance(), s.map.kernel_error
    else:
        vr_in, vr_out = s.port_vrs()
    return KernelSubsystem(fmu, s.m, int(offset), functions, component, s.state_handle_address(), vr_in, vr_out,
                           int(s.no_prior), s.port_scales(), counters, impedance, adapter_error,
                           s.plain_wave_port(), _probe_vrs(s), s.kernel_substeps())


def describe(scene):
    """The KernelScene of a scene (its signals' plan with its FMUs as KernelFmu)."""
    plan, alone = scene.kernel_signals(), scene.signal_only
    if plan is not None:
        plan = {**plan, "subsystems": [kernel_fmu(s) for s in plan["subsystems"]]}

    def book_alone(j, do_steps, n, t):
        alone[j].calls["doStep"] += do_steps
        if n is not None:
            alone[j].begin(n, t)

    return KernelScene([kernel_subsystem(s, off) for s, off in zip(scene.subsystems, scene.offsets)],
                       [kernel_fmu(s) for s in alone], scene.n_channels, scene.scenario.start_time,
                       scene.scenario.dt, plan, book_alone,
                       lambda: [scene.gammas[s.name] for s in scene.subsystems])
