"""A subsystem as the masters see it: an FMU, its port channels, and its frozen port map S_i^n.

`freeze()` saves x_i^n; `query(a)` is S_i^n(a) (paper eq. 12): restore x_i^n, apply a, one doStep,
read b, discard the state; `advance(a)` is Phi_i (eq. 21): the same from x_i^n, but the state is
kept. Calls go straight to the FMU's C functions with pre-converted arguments.
"""
import ctypes
from dataclasses import dataclass, field

from .errors import FmuError


@dataclass
class PortSpec:
    """Variable names of a subsystem's port channels (one entry per channel)."""
    wave_in: list
    wave_out: list
    effort: list
    flow: list
    physical_in: list = field(default_factory=list)
    input_is_flow: list = field(default_factory=list)
    energy: str = "H"

    @property
    def m(self):
        return len(self.wave_in)


class Subsystem:
    """One FMU instance with a port; `wave` says whether it was instantiated in wave mode."""

    def __init__(self, name, fmu, port: PortSpec, dt, wave=True):
        self.name, self.fmu, self.port, self.dt, self.wave = name, fmu, port, dt, wave
        self.m = port.m
        self.step_index = 0
        m = self.m
        self._comp = ctypes.c_void_p(fmu.component)
        self._h = ctypes.c_double(dt)
        self._get_state = fmu.raw_function("fmi2GetFMUstate")
        self._set_state = fmu.raw_function("fmi2SetFMUstate")
        self._set_real = fmu.raw_function("fmi2SetReal")
        self._get_real = fmu.raw_function("fmi2GetReal")
        self._do_step = fmu.raw_function("fmi2DoStep")
        in_names = port.wave_in if wave else port.physical_in
        out_names = port.wave_out if wave else [e if flow_in else f for e, f, flow_in in
                                                zip(port.effort, port.flow, port.input_is_flow)]
        self._in_vr = (ctypes.c_uint * m)(*[fmu.vr(n) for n in in_names])
        self._out_vr = (ctypes.c_uint * m)(*[fmu.vr(n) for n in out_names])
        self._in_val = (ctypes.c_double * m)()
        self._out_val = (ctypes.c_double * m)()
        self._m = ctypes.c_size_t(m)
        self._state = ctypes.c_void_p()
        self._dirty = False
        self.t = 0.0
        self.calls = {"doStep": 0, "save": 0, "restore": 0}

    def _call(self, fn, name, *args):
        status = fn(*args)
        if status > 1:
            raise self.fmu.status_error(name, status, self.step_index, self.t)

    def begin(self, step_index, t):
        """Start macro-step n at time t without saving the state (masters that never roll back)."""
        self.step_index, self.t, self._t = step_index, t, ctypes.c_double(t)

    def freeze(self, step_index, t):
        """Save x_i^n, the state every query of this macro-step starts from."""
        self.begin(step_index, t)
        self._call(self._get_state, "fmi2GetFMUstate", self._comp, ctypes.byref(self._state))
        self.calls["save"] += 1
        self._dirty = False

    def _step(self, a):
        for j in range(self.m):
            self._in_val[j] = a[j]
        self._call(self._set_real, "fmi2SetReal", self._comp, self._in_vr, self._m, self._in_val)
        self._call(self._do_step, "fmi2DoStep", self._comp, self._t, self._h, 1)
        self.calls["doStep"] += 1
        self._call(self._get_real, "fmi2GetReal", self._comp, self._out_vr, self._m, self._out_val)
        return self._out_val[:]

    def _restore(self):
        self._call(self._set_state, "fmi2SetFMUstate", self._comp, self._state)
        self.calls["restore"] += 1

    def query(self, a):
        """S_i^n(a): restore x_i^n, apply a, one doStep, read the output; the state is discarded."""
        if self._dirty:
            self._restore()
        self._dirty = True
        return self._step(a)

    def advance(self, a):
        """Phi_i(x_i^n, a): like query, but the new state is kept (the one commit of the macro-step)."""
        if self._dirty:
            self._restore()
        self._dirty = False
        return self._step(a)

    def thaw(self):
        """Put the instance back at x_i^n after queries made outside the master (certificates)."""
        if self._dirty:
            self._restore()
            self._dirty = False

    def restore_frozen(self):
        """Back to x_i^n even after the commit: the energy guard undoes a macro-step with it."""
        self._restore()
        self._dirty = False

    def read(self, names):
        return self.fmu.get_real(self.fmu.vrs(names))

    def reader(self, names):
        """(read, buffer): read() fills the fixed ctypes buffer with `names` in one raw fmi2GetReal."""
        k = len(names)
        vr = (ctypes.c_uint * k)(*[self.fmu.vr(n) for n in names])
        buf, size = (ctypes.c_double * k)(), ctypes.c_size_t(k)
        get_real, comp, call = self._get_real, self._comp, self._call

        def read():
            call(get_real, "fmi2GetReal", comp, vr, size, buf)
            return buf
        return read, buf

    def state_handle_address(self):
        """Address of the handle x_i^n is saved into; the C kernel saves into it too, so after a
        kernel macro-step this Subsystem holds x_i^n exactly as after a Python one."""
        return ctypes.addressof(self._state)

    def note_kernel_step(self, step_index, t, iterations, steps=1):
        """Book `steps` macro-steps the C kernel made, the last one step n at t (frozen at x^n):
        each a save, its queries and one commit; `iterations` counts the queries of them all."""
        self.begin(step_index, t)
        self.calls["save"] += steps
        self.calls["doStep"] += iterations + steps
        self.calls["restore"] += iterations
        self._dirty = False

    def release(self):
        if self._state.value:
            self.fmu.free_state_handle(self._state)
            self._state = ctypes.c_void_p()

    def close(self):
        try:
            self.release()
        except FmuError:
            pass
        self.fmu.close()
