"""The wave adapter port with its solve in C (wavecosim.kernel.adapter, kernel/c/adapter.c).

`KernelAdapter` takes over a subsystem's `ports.WaveAdapter` with all its memory (warm start,
slope, figures) and solves each query in C, operation by operation as the Python reference, so the
numbers are the same to the last bit. Its C struct is also an fmi2 component: `shim()` gives the
function table the DR kernel calls as a wave port (set a, doStep solves, get b), wrapping whatever
FMU function table it was given. Queries made from Python (gamma probes, certificates, a redone
commit) run the same C solve on the same memory, so both routes see one adapter.
"""
from ..fmi.fmu import fails
from ..kernel.fmicall import FUNCTION_NAMES
from ..kernel.adapter import AD_FMU, AD_SINGULAR, AD_STALLED, field_address, new_adapter, shim
from . import ports


class KernelAdapter(ports.AdapterPort):
    """ports.WaveAdapter with its solve in C; built from one (`port`), whose memory it takes over,
    over the FMU function table `fns` (drkernel.h DRFunctions) and component `comp`."""

    def __init__(self, port, fns, comp):
        super().__init__(port.sub, port.effort_in, port.sign)
        m, sub = self.m, port.sub
        memory = {"u": port.u, "y": port.y or [0.0] * m, "D": _flat(port.D, m), "J_inv": _flat(port.J_inv, m),
                  "have_slope": port.D is not None, "h2": port.h2, "u_scale": port.u_scale,
                  "evaluations": port.evaluations, "do_steps": port.doSteps, "accepted": port.accepted,
                  "worst_accepted": port.worst_accepted}
        # the Subsystem's x_i^n handle and its dirty flag, its physical input and output value references
        self.lib, self.struct, self._ref = new_adapter(fns, comp, sub.state_handle_address(), sub.dirty_address(),
                                                       sub._in_vr, sub._out_vr, self.effort_in, self.sign, memory)
        st = self.struct
        st.no_prior = sub.no_prior                            # the doStep flag of its FMU calls
        st.tol, st.accept, st.slope_rel = ports.TOL, ports.ACCEPT, ports.SLOPE_REL
        st.max_iter, st.stall = ports.MAX_ITER, ports.STALL
        self._set_weights(port.gamma)

    def shim(self):
        """(function table, component) of the adapter as an fmi2 wave port, for the DR kernel."""
        return shim(self.lib, self.struct)

    def impedance(self):
        """Addresses of the C struct's gamma and k (the kernel's port view reads them at each commit)."""
        return self._address("gamma"), self._address("k")

    def noise(self):
        """The address of the C struct's worst_accepted (the kernel's energy ledger reads it: Scene.map_noise)."""
        return self._address("worst_accepted")

    def _address(self, name):
        return field_address(self.struct, name)

    def _set_weights(self, gamma):
        self.weights(gamma)
        st = self.struct
        st.gamma, st.c, st.k = self.gamma, self.c, self.k
        for j in range(self.m):
            st.wu[j], st.wy[j] = self.wu[j], self.wy[j]

    def set_gamma(self, gamma):
        """A new impedance (between macro-steps); the Newton matrix follows in C."""
        self._set_weights(gamma)
        if self.lib.adapter_reinvert(self._ref):
            raise self.kernel_error(self.sub.step_index, self.sub.t)

    def new_step(self):
        """x_i^n changed (Subsystem.freeze): the slope no longer holds."""
        self.struct.have_slope = 0

    def _solve(self, a):
        """One query from Python: the C solve from the Subsystem's x_i^n (its FMU calls count in the FMU's counters)."""
        st, sub = self.struct, self.sub
        for j in range(self.m):
            st.a[j] = a[j]
        status = self.lib.adapter_solve(self._ref, sub.t, sub.dt)         # moving the Subsystem's own flag
        if fails(status):
            raise self.kernel_error(sub.step_index, sub.t)
        return st.e[:self.m], st.f[:self.m]

    def kernel_error(self, n, t):
        """The error of the adapter's last failed call, as the Python reference raises it at step n, or None."""
        st, m = self.struct, self.m
        if st.failure == AD_FMU:
            return self.sub.fmu.status_error(FUNCTION_NAMES.get(st.failed.function), st.failed.status, n, t)
        if st.failure == AD_SINGULAR:
            return self.error(st.failed_r[:m], ports.singular_why(st.y[:m]), n, t)
        if st.failure == AD_STALLED:
            return self.error(st.failed_r[:m], ports.stalled_why(st.failed_rel), n, t)
        return None

    @property
    def evaluations(self):
        return self.struct.evaluations

    @property
    def doSteps(self):
        return self.struct.do_steps

    @property
    def accepted(self):
        return self.struct.accepted

    @property
    def worst_accepted(self):
        return self.struct.worst_accepted


def _flat(M, m):
    return [0.0] * (m * m) if M is None else [float(x) for row in M for x in row]
