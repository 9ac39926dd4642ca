"""One exception hierarchy; the CLI maps each class to its exit code and prints one line.

| class | exit code | meaning |
|---|---|---|
| ConfigError, CouplingError | 2 | bad scenario, option or FMU choice, found before anything runs |
| FmuError | 3 | an FMU could not be loaded or a call returned Error/Fatal (its own message kept) |
| NumericalError | 4 | a non-finite value, a blow-up, an interface solve that did not converge |
| FmuCrashed | 5 | an FMU crashed the process (a signal such as SIGSEGV) or ended it (exit()) |
| StepTimeout | 6 | a macro-step did not finish within the step timeout (a call that does not return) |
| OutputError | 7 | the output folder cannot be written (not writable, disk full, in use, holds other files) |
| SweepFailed | 8 | a sweep ended with runs that did not finish (each one is a row saying why) |
| Interrupted | 130 | Ctrl-C (SIGINT); the steps done so far are on disk |
| Terminated | 143 | SIGTERM; the steps done so far are on disk |

`status` is the word summary.json gives a run that stopped with the error.
"""


def brief_text(text, limit=400):
    """A message cut to about `limit` characters in its middle (a huge value quoted in it), so it stays
    one readable line: its start names the culprit, its end what was expected."""
    if len(text) <= limit:
        return text
    tail = limit // 4
    return f"{text[:limit - tail]} ... [{len(text) - limit} characters left out] ... {text[-tail:]}"


def optional(module, extra, needed_by):
    """The optional dependency `module` imported, or a ConfigError in one line naming the extra of
    wavecosim that installs it (`needed_by`: what asked for it, e.g. "--scheduler")."""
    import importlib
    try:
        return importlib.import_module(module)
    except ImportError:
        top = module.split(".", 1)[0]
        raise ConfigError(f"{needed_by} needs {top}, which is not installed here: "
                          f"pip install 'wavecosim[{extra}]'") from None


class WavecosimError(Exception):
    """Root of every error the product reports to users."""
    exit_code = 1
    status = "failed"


class ConfigError(WavecosimError):
    """A scenario file or option is malformed; the message names the key and the file."""
    exit_code = 2


class CouplingError(ConfigError):
    """An interconnection is not lossless, not of full rank, or does not fit the ports."""


class FmuError(WavecosimError):
    """An FMU could not be loaded, or a call returned an error status."""
    exit_code = 3

    def __init__(self, message, subsystem=None, step=None, time=None, variable=None):
        super().__init__(message)
        self.subsystem, self.step, self.time, self.variable = subsystem, step, time, variable


class SimulationEnded(FmuError):
    """An FMU asked to end the simulation (fmi2Discard with fmi2Terminated; FMI 3 terminateSimulation):
    the run ends there, finished, with the steps before it (as fmpy's simulate ends)."""


class NumericalError(WavecosimError):
    """A non-finite value or a blow-up was detected."""
    exit_code = 4


class FmuCrashed(FmuError):
    """An FMU crashed the process or called exit(): the supervisor kept the steps before the fault."""
    exit_code = 5
    status = "crashed"


class StepTimeout(FmuError):
    """A macro-step did not finish within the step timeout (a call into an FMU that does not return)."""
    exit_code = 6
    status = "timed out"


class OutputError(WavecosimError):
    """The output folder cannot be used: not writable, full, in use by another run, or not a run's."""
    exit_code = 7


class SweepFailed(WavecosimError):
    """A sweep finished, and some of its runs did not (their rows say why)."""
    exit_code = 8


class Interrupted(WavecosimError):
    """The user stopped the run (Ctrl-C); `result` holds the steps done (also on disk)."""
    exit_code = 130
    status = "interrupted"

    def __init__(self, message, result=None):
        super().__init__(message)
        self.result = result


class Terminated(Interrupted):
    """SIGTERM stopped the run; as Interrupted."""
    exit_code = 143


class RunFailed(WavecosimError):
    """A run stopped early: `error` is the exception that stopped it (its class gives the exit code),
    `result` holds what was computed (also on disk)."""

    def __init__(self, error, result):
        super().__init__(str(error))
        self.error, self.result = error, result
        self.exit_code = error.exit_code
