"""An FMI 2.0 model-exchange FMU stepped as a co-simulation one (for FMUs that only have model
exchange, as OMSimulator runs them): `fmi2DoStep(t, h)` integrates the FMU from t to t + h with its
inputs held, with fmpy's CVode (BDF, relative tolerance the set-up one: the FMU's DefaultExperiment
tolerance unless the scenario gives one, else 1e-4), and handles time, state and step events as fmpy's simulate_fmu does. Everything else (get
and set, state save and restore where the FMU offers it) is the FMU's own fmi2 function, so the
masters and the recorder see the same calls as for a co-simulation FMU: fmu.py's ModelExchange2
is this side over its FMI 2 one (Fmi2)."""
import ctypes
import math

from fmpy.fmi2 import FMU2Model


DO_STEP = ctypes.CFUNCTYPE(ctypes.c_int, ctypes.c_void_p, ctypes.c_double, ctypes.c_double, ctypes.c_int)
DEFAULT_TOLERANCE = 1e-4
OK, ERROR = 0, 3


class _Held:
    """The solver's input: nothing to apply, the inputs are held over the step as they were set."""

    @staticmethod
    def apply(time, continuous=True, discrete=True, after_event=False):
        return None


class FMU2ModelSettled(FMU2Model):
    """fmpy's FMU2Model whose exitInitializationMode also settles the initial events and enters
    continuous-time mode (what a co-simulation FMU does inside its own). fmpy picks the functions it
    loads by the class name's prefix, hence FMU2..."""

    def __init__(self, owner, **kwargs):
        super().__init__(**kwargs)
        self.owner = owner

    def exitInitializationMode(self):
        status = super().exitInitializationMode()
        self.owner.settle(self)
        return status


class ModelExchange:
    """The model-exchange side of one Fmu over its FMI 2 binding (a mixin before Fmi2): its
    FMU2Model, its solver, doStep in fmi2 form."""
    interface = "modelExchange"

    def __init__(self, fmu, model_identifier):
        self._fmu, self.solver, self.start, self.next_event, self.at = fmu, None, 0.0, math.inf, None
        self.inputs = [v.valueReference for v in fmu.description.modelVariables
                       if v.causality == "input" and v.type == "Real"]
        self.held = None
        self._callbacks = self._make_callbacks(fmu.messages)
        self.slave = FMU2ModelSettled(self, guid=fmu.description.guid, unzipDirectory=str(fmu.folder),
                            modelIdentifier=model_identifier, instanceName=fmu.name)
        fmu.checked(self.slave.instantiate, "fmi2Instantiate", callbacks=self._callbacks)
        self.component, self.tolerance = self.slave.component, DEFAULT_TOLERANCE
        self.needs_completed = bool(fmu.description.modelExchange.needsCompletedIntegratorStep)
        self._c_do_step = DO_STEP(lambda comp, t, h, flag: self.do_step(comp, t, h, flag))

    def setup_experiment(self, fmu, start_time, tolerance):
        """The start time and the tolerance (the FMU's DefaultExperiment one, else 1e-4) of the solver too."""
        self.start, self.tolerance = start_time, tolerance or DEFAULT_TOLERANCE
        super().setup_experiment(fmu, start_time, tolerance)

    def settle(self, model):
        """After initialization: the event iteration, continuous-time mode, a solver at the start time."""
        self._events(model)
        from fmpy.sundials import CVodeSolver
        md = self._fmu.description
        self.solver = CVodeSolver(nx=md.numberOfContinuousStates, nz=md.numberOfEventIndicators,
                                  get_x=model.getContinuousStates, set_x=model.setContinuousStates,
                                  get_dx=model.getDerivatives, get_z=model.getEventIndicators,
                                  get_nominals=model.getNominalsOfContinuousStates, set_time=model.setTime,
                                  input=_Held(), startTime=self.start, relativeTolerance=self.tolerance)

    def _events(self, model):
        """newDiscreteStates until the FMU needs no more, then continuous-time mode."""
        needed = True
        while needed:
            needed, terminate, _, _, defined, next_time = model.newDiscreteStates()
            if terminate:
                raise RuntimeError("the FMU asked to terminate the simulation")
        self.next_event = next_time if defined else math.inf
        model.enterContinuousTimeMode()

    def do_step(self, comp, t, h, no_set_prior):
        """Integrate from t to t + h; the FMU's status as an int (an exception becomes Error, its
        text kept as the FMU's last message)."""
        t, h = getattr(t, "value", t), getattr(h, "value", h)
        try:
            self._integrate(float(t), float(t) + float(h))
            return OK
        except Exception as exc:
            self._fmu.messages.append((ERROR, f"model exchange step from t = {t:.6g}: {exc}"))
            return ERROR

    def _integrate(self, time, end):
        """CVode from `time` to `end`; restarted at `time` when the inputs changed since the last step
        (the right-hand side jumps there) or the step does not begin where the last one ended (a
        restored state), and after an event."""
        model, solver = self.slave, self.solver
        eps = 1e-12 * max(1.0, abs(end))
        held = list(model.getReal(self.inputs)) if self.inputs else []
        if self.at is None or abs(self.at - time) > eps or held != self.held:
            solver.reset(time)
        self.held = held
        while time < end - eps:
            target = min(end, self.next_event)
            state_event, _, time = solver.step(time, target)
            model.setTime(time)
            step_event = self.needs_completed and model.completedIntegratorStep()[0]
            if state_event or step_event or time >= self.next_event - eps:
                model.enterEventMode()
                self._events(model)
                solver.reset(time)
        self.at = time

    def raw_function(self, fname):
        """The FMU's own fmi2 function, or for fmi2DoStep the integration above (same signature)."""
        if fname == "fmi2DoStep":
            return self.do_step
        return self.slave.dll[fname]

    def function_pointer(self, fname):
        """The address of the FMU's fmi2 function, or of a C callback into do_step for fmi2DoStep."""
        if fname == "fmi2DoStep":
            return ctypes.cast(self._c_do_step, ctypes.c_void_p).value
        return super().function_pointer(fname)
