"""A subsystem as the masters see it: an FMU, its port channels, and its frozen port map S_i^n.

`freeze()` saves x_i^n; `query(a)` is S_i^n(a) (paper eq. 12): restore x_i^n, apply a, one doStep
(or `substeps` doSteps of dt / substeps, the input held: multi-rate), read b, discard the state;
`advance(a)` is Phi_i (eq. 21): the same from x_i^n, but the state is kept. Calls go straight to the
FMU's C functions with pre-converted arguments (in fmi2 form; for an FMI 3 FMU, wavecosim/fmi/fmi3.py
puts its fmi3 functions behind the same signatures). How a becomes b is the subsystem's port
(wavecosim/core/ports.py): the FMU's own wave mode, or the wave adapter for an FMU with only a
physical port.
"""
import math
from dataclasses import dataclass, field

import numpy as np

from ..kernel import cvalues, queries
from ..errors import FmuError, SimulationEnded
from ..fmi.fmu import CALLS, fails
from ..kernel.fmicall import FUNCTION_NAMES
from .adapter_kernel import KernelAdapter
from .ports import DirectPort, WaveAdapter


@dataclass
class PortSpec:
    """Variable names of a subsystem's port channels (one entry per channel)."""
    wave_in: list
    wave_out: list
    effort: list
    flow: list
    physical_in: list = field(default_factory=list)
    input_is_flow: list = field(default_factory=list)
    energy: str = "H"                  # None: the FMU has no stored-energy output
    physical_out: list = field(default_factory=list)      # given: a physical port (effort/flow are its in/out)
    sign: list = field(default_factory=list)              # power into the FMU = sign e f, per channel

    @property
    def m(self):
        return len(self.physical_out or self.wave_in)

    @property
    def physical(self):
        """A declared physical port: the FMU's input and output variables are the port."""
        return bool(self.physical_out)


class Subsystem:
    """One FMU instance with a port; `wave` says whether the masters exchange waves with it, and
    `adapter` whether those waves go through the wave adapter (an FMU without a wave mode)."""

    def __init__(self, name, fmu, port: PortSpec, dt, wave=True, adapter=False, gamma=1.0, substeps=1):
        self.name, self.fmu, self.port, self.dt, self.wave = name, fmu, port, dt, wave
        self.adapter, self.substeps = adapter, substeps
        self.m = port.m
        self.step_index = 0
        m = self.m
        self._comp = cvalues.pointer(fmu.component)
        self._h = cvalues.double(dt / substeps)
        self._tk = cvalues.double(0.0)       # a substep's communication point
        # The FMU's own wave mode scales its waves by sqrt(h): a substep takes a sqrt(h / dt) so that
        # e + gamma f = sqrt(2 gamma / dt) a holds at each, and b is its outgoing waves' mean at dt's scale.
        self._wave_scale = 1.0 / math.sqrt(substeps) if wave and not port.physical and not adapter else 1.0
        if self._wave_scale != 1.0:          # the macro-step's [e..., f..., b...] and 1.0 once made (both routes')
            self._stage_vr = cvalues.uints(fmu.real_vrs([*port.effort, *port.flow, *port.wave_out]))
            self._stage_val, self._3m = cvalues.doubles(3 * m), cvalues.size(3 * m)
            self._stage = cvalues.doubles(3 * m + 1)
        self._get_state = fmu.raw_function("fmi2GetFMUstate")
        self._set_state = fmu.raw_function("fmi2SetFMUstate")
        self._set_real = fmu.raw_function("fmi2SetReal")
        self._get_real = fmu.raw_function("fmi2GetReal")
        self._do_step = fmu.raw_function("fmi2DoStep")
        in_names = port.wave_in if wave and not port.physical else port.physical_in
        out_names = port.wave_out if wave and not port.physical else [e if flow_in else f for e, f, flow_in in
                                                                      zip(port.effort, port.flow, port.input_is_flow)]
        self._in_vr = cvalues.uints(fmu.real_vrs(in_names))
        self._out_vr = cvalues.uints(fmu.real_vrs(out_names))
        self._in_val = cvalues.doubles(m)
        self._out_val = cvalues.doubles(m)
        self._m = cvalues.size(m)
        self._state = cvalues.pointer()
        # _dirty[0]: the instance moved away from x_i^n; one flag, which the C queries and the wave
        # adapter read and set through its address (dirty_address)
        self._dirty = cvalues.ints([0])
        # noSetFMUStatePriorToCurrentPoint of the doSteps whose state may be restored after: 0 (the
        # standard's choice for a master that rolls back), or 1 where the FMU freezes with 0
        # (core/quirks.py). Either is by the book here: x_i^n is only ever restored at t_n, the
        # doSteps' own communication point, never before it.
        self.no_prior = 0
        self.alone_no_prior = 1              # the flag of step_alone: a signal-only subsystem is not stepped back
        self._batch = None                   # kernel.queries.Queries (False without it), on first raw_queries
        self.t = 0.0
        self._t = cvalues.double(0.0)
        self.map = self._port_map(gamma)

    @property
    def macro_stage(self):
        """Multi-rate wave mode: the last macro-step's [e..., f..., b...] (None before the first)."""
        return self._stage[:3 * self.m] if self.multi_rate_wave and self._stage[3 * self.m] == 1.0 else None

    @property
    def multi_rate_wave(self):
        """Substeps in the FMU's own wave mode: the macro-step's e, f and b are the substeps' means."""
        return self._wave_scale != 1.0

    def _port_map(self, gamma):
        """The port that turns the master's inputs into outputs (wavecosim/core/ports.py)."""
        port = self.port
        if self.adapter:
            return WaveAdapter(self, [not flow_in for flow_in in port.input_is_flow], port.sign, gamma)
        if port.physical and any(s != 1.0 for s in port.sign):
            return DirectPort(self, [s if flow_in else 1.0 for s, flow_in in zip(port.sign, port.input_is_flow)],
                              [1.0 if flow_in else s for s, flow_in in zip(port.sign, port.input_is_flow)])
        return DirectPort(self)

    def orient(self, signs):
        """Set the physical port's signs (power into the FMU = sign e f) and rebuild the port map."""
        gamma = self.map.gamma if self.adapter else 1.0
        self.port.sign = [float(x) for x in signs]
        self.map = self._port_map(gamma)

    @property
    def gamma(self):
        """The wave impedance this subsystem runs at (NaN when it has none)."""
        if self.adapter:
            return self.map.gamma
        return float(self.fmu.get_real(self.fmu.vrs(["gamma"]))[0]) if "gamma" in self.fmu.variables else float("nan")

    def set_gamma(self, gamma):
        """A new wave impedance (between macro-steps)."""
        if self.adapter:
            self.map.set_gamma(gamma)
        else:
            self.fmu.set_real(self.fmu.vrs(["gamma"]), [gamma])

    def stage(self):
        """Oriented stage effort and flow of the last step, [e..., f...] (power into the FMU = e f); a
        multi-rate subsystem in the FMU's own wave mode gives the macro-step's (the substeps' means)."""
        made = self.macro_stage
        if made is not None:
            return list(made[:2 * self.m])
        v = self.read(list(self.port.effort) + list(self.port.flow))
        if self.port.physical:
            v[self.m:] = [s * f for s, f in zip(self.port.sign, v[self.m:])]
        return list(v)

    @property
    def calls(self):
        """Its FMU's calls so far, {CALLS name: count}: the FMU's own counters (fmi/fmu.py Fmu.calls),
        which Python and the C kernel count in where each call is made."""
        return dict(zip(CALLS, self.fmu.calls))

    def _call(self, fn, name, *args):
        self.fmu.check(name, fn(*args), self.step_index, self.t)

    def begin(self, step_index, t):
        """Start macro-step n at time t without saving the state (masters that never roll back)."""
        self.step_index, self.t = step_index, t
        self._t.value = t

    def step_alone(self, step_index, t):
        """One doStep (or `substeps` of dt / substeps) from the current state with the inputs already set: a
        subsystem without a port (signals only), stepped once per macro-step and never frozen or rolled back."""
        self.begin(step_index, t)
        status = self._do_step(self._comp, self._t, self._h, self.alone_no_prior)
        for k in range(1, self.substeps):
            if fails(status):
                break
            self.fmu.count("fmi2DoStep")                 # the substep before went through (the last: check)
            self._tk.value = t + k * self._h.value
            status = self._do_step(self._comp, self._tk, self._h, self.alone_no_prior)
        reached = self.fmu.asked_to_end(status) if fails(status) else None
        if reached is not None:
            done = math.isclose(reached, t + self.dt, rel_tol=1e-12, abs_tol=1e-12 * self.dt)
            where = "after the step to" if done else "in the step from"
            error = SimulationEnded(f"subsystem {self.name} ended the simulation {where} t = "
                                    f"{t + self.dt if done else t:.6g}", subsystem=self.name, step=step_index, time=t)
            error.step_done = done
            raise error
        self.fmu.check("fmi2DoStep", status, step_index, t)

    def freeze(self, step_index, t):
        """Save x_i^n, the state every query of this macro-step starts from."""
        self.begin(step_index, t)
        self._call(self._get_state, "fmi2GetFMUstate", self._comp, cvalues.ref(self._state))
        self._dirty[0] = 0
        self.map.new_step()

    def _step(self, a):
        if self.substeps != 1:
            return self._substeps(a)
        for j in range(self.m):
            self._in_val[j] = a[j]
        self._call(self._set_real, "fmi2SetReal", self._comp, self._in_vr, self._m, self._in_val)
        self._call(self._do_step, "fmi2DoStep", self._comp, self._t, self._h, self.no_prior)
        self._call(self._get_real, "fmi2GetReal", self._comp, self._out_vr, self._m, self._out_val)
        return self._out_val[:]

    def _substeps(self, a):
        """Multi-rate: the input held over `substeps` doSteps of dt / substeps; a physical output as the
        last leaves it, the FMU's own wave mode's b as the mean of the substeps' (at dt's scale, so that
        the macro-step's map stays passive: the mean's square is at most the squares' mean)."""
        scale, n, m = self._wave_scale, self.substeps, self.m
        for j in range(m):
            self._in_val[j] = a[j] * scale
        self._call(self._set_real, "fmi2SetReal", self._comp, self._in_vr, self._m, self._in_val)
        total = [0.0] * (3 * m)
        for k in range(n):
            self._tk.value = self.t + k * self._h.value
            self._call(self._do_step, "fmi2DoStep", self._comp, self._tk, self._h, self.no_prior)
            if scale != 1.0:
                self._call(self._get_real, "fmi2GetReal", self._comp, self._stage_vr, self._3m, self._stage_val)
                total = [s + v for s, v in zip(total, self._stage_val)]
        if scale == 1.0:
            self._call(self._get_real, "fmi2GetReal", self._comp, self._out_vr, self._m, self._out_val)
            return self._out_val[:]
        self._stage[:] = [s / n for s in total[:2 * m]] + [s * scale for s in total[2 * m:]] + [1.0]
        return self._stage[2 * m:3 * m]

    def _restore(self):
        self._call(self._set_state, "fmi2SetFMUstate", self._comp, self._state)

    def query(self, a):
        """S_i^n(a): restore x_i^n, apply a, read the output; the state is discarded."""
        return self.map.query(a)

    def advance(self, a):
        """Phi_i(x_i^n, a): like query, but the new state is kept (the one commit of the macro-step)."""
        return self.map.advance(a)

    def raw_query(self, u):
        """Restore x_i^n, set the FMU's inputs u, one doStep, read its outputs; the state is discarded."""
        if self._dirty[0]:
            self._restore()
        self._dirty[0] = 1
        return self._step(u)

    def dirty_address(self):
        """The address of the flag saying the instance moved away from x_i^n (a C int, 0 or 1)."""
        return cvalues.address(self._dirty)

    def adapter_in_kernel(self, fns, comp):
        """The wave adapter moved to C over the FMU function table (fns, comp), once: the adapter's
        own (function table, component) for the DR kernel to call as a wave port."""
        if not isinstance(self.map, KernelAdapter):
            self.map = KernelAdapter(self.map, fns, comp)
        return self.map.shim()

    def port_scales(self):
        """(in_scale, out_scale) of a signed physical port (ports.DirectPort), or None: the kernel then
        calls the FMU through portview.c's signed shim, making the same products."""
        if isinstance(self.map, DirectPort) and self.map.in_scale is not None:
            return self.map.in_scale, self.map.out_scale
        return None

    def kernel_substeps(self):
        """(substeps, input scale, stage value references and the address of the stage values, or two
        Nones) for multirate.c's shim, or None without it: the kernel makes the same substeps and sums
        as _substeps, into the same stage values."""
        if self.substeps == 1 or self.adapter or not self.m:
            return None
        if not self.multi_rate_wave:
            return self.substeps, 1.0, None, None
        return self.substeps, self._wave_scale, list(self._stage_vr), cvalues.address(self._stage)

    def plain_wave_port(self):
        """Whether the port is the FMU's own wave map: no adapter, no input scaling, no substeps."""
        plain = not self.adapter and isinstance(self.map, DirectPort) and self.map.in_scale is None
        return plain and self.substeps == 1

    def queries(self, rows):
        """query of each row of a 2-D array, in order, as rows (one C call when the port is the FMU's own map)."""
        if self.plain_wave_port():
            return self.raw_queries(rows)
        return np.array([self.query(list(r)) for r in rows], float).reshape(len(rows), self.m)

    def raw_queries(self, rows):
        """raw_query of each row of a 2-D array, in order, as rows of outputs: one C call
        (kernel/c/queries.c) making the same FMU calls, or raw_query row by row without it."""
        if self._batch is None:
            self._batch = self.substeps == 1 and queries.batch(self.fmu.function_pointer, self.fmu.calls) or False
        if not self._batch:
            return np.array([self.raw_query(list(r)) for r in rows], float).reshape(len(rows), self.m)
        out, done, fn, status = self._batch(self._comp, self._state, self._in_vr, self._out_vr, self.m, self._t,
                                            self._h, rows, self._dirty, self.no_prior)
        if fn:
            raise self.fmu.status_error(FUNCTION_NAMES.get(fn), status, self.step_index, self.t)
        return out

    def raw_advance(self, u):
        """Like raw_query, but the new state is kept."""
        if self._dirty[0]:
            self._restore()
        self._dirty[0] = 0
        return self._step(u)

    def keep(self):
        """Keep the state the last raw_query left (it becomes the commit of the macro-step)."""
        self._dirty[0] = 0

    def thaw(self):
        """Put the instance back at x_i^n after queries made outside the master (certificates)."""
        if self._dirty[0]:
            self._restore()
            self._dirty[0] = 0

    def restore_frozen(self):
        """Back to x_i^n even after the commit: the energy guard undoes a macro-step with it."""
        self._restore()
        self._dirty[0] = 0

    def set_step(self, h):
        """A new communication step size h from the next doStep on (the tolerance mode); the wave
        adapter's weights follow, as its waves are scaled by sqrt(h)."""
        self.dt, self._h.value = h, h / self.substeps
        if self.adapter:
            self.map.set_gamma(self.map.gamma)

    def snapshot(self):
        """Save the instance's state into a handle of its own, apart from x_i^n (a step redone whole)."""
        if not hasattr(self, "_snap"):
            self._snap = cvalues.pointer()
        self._call(self._get_state, "fmi2GetFMUstate", self._comp, cvalues.ref(self._snap))

    def back_to_snapshot(self):
        """Put the instance back where snapshot() saved it."""
        self._call(self._set_state, "fmi2SetFMUstate", self._comp, self._snap)
        self._dirty[0] = 0

    def response(self, inputs, names):
        """The values `names` after one step from where snapshot() saved it with these inputs; the
        instance is then put back where it was (the tolerance mode's coupling estimate)."""
        if not hasattr(self, "_aside"):
            self._aside = cvalues.pointer()
        self._call(self._get_state, "fmi2GetFMUstate", self._comp, cvalues.ref(self._aside))
        self.back_to_snapshot()
        self.advance(inputs)
        out = self.read(names)
        self._call(self._set_state, "fmi2SetFMUstate", self._comp, self._aside)
        self._dirty[0] = 0
        return out

    def read(self, names):
        return self.fmu.get_real(self.fmu.vrs(names))

    def reader(self, names):
        """(read, buffer): read() fills the fixed C buffer with `names` in one raw fmi2GetReal."""
        k = len(names)
        vr = cvalues.uints(self.fmu.real_vrs(names))
        buf, size = cvalues.doubles(k), cvalues.size(k)
        get_real, comp, call = self._get_real, self._comp, self._call

        def read():
            call(get_real, "fmi2GetReal", comp, vr, size, buf)
            return buf
        return read, buf

    def port_vrs(self):
        """The value references (C arrays) of the inputs a query sets and the outputs it reads."""
        return self._in_vr, self._out_vr

    def has_saved_state(self):
        """Whether x_i^n is saved (a master that rolls back froze this macro-step)."""
        return bool(self._state)

    def state_handle_address(self):
        """Address of the handle x_i^n is saved into; the C kernel saves into it too, so after a
        kernel macro-step this Subsystem holds x_i^n exactly as after a Python one."""
        return cvalues.address(self._state)

    def note_kernel_step(self, step_index, t):
        """After macro-steps the C kernel made, the last one step n at t: frozen at x^n and at the
        commit (the kernel counted its FMU calls in the FMU's counters)."""
        self.begin(step_index, t)
        self._dirty[0] = 0

    def release(self):
        """Free the saved x_i^n (not after the FMU reported fatal). The handle object stays the same
        (the C kernels hold its address); it is NULL afterwards."""
        for handle in (self._state, getattr(self, "_snap", None), getattr(self, "_aside", None)):
            if handle is not None and handle.value and self.fmu.free_state_allowed():
                self.fmu.free_state_handle(handle)
            if handle is not None:
                handle.value = None

    def close(self):
        try:
            self.release()
        except FmuError:
            pass
        self.fmu.close()
