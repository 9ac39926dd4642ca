"""One exception hierarchy; the CLI maps each class to its exit code and prints one line.

| class | exit code | meaning |
|---|---|---|
| ConfigError, CouplingError | 2 | bad scenario, option or FMU choice, found before anything runs |
| FmuError | 3 | an FMU could not be loaded or a call returned Error/Fatal (its own message kept) |
| NumericalError | 4 | a non-finite value, a blow-up, an interface solve that did not converge |
| Interrupted | 130 | Ctrl-C; the steps done so far are on disk |
"""


class WavecosimError(Exception):
    """Root of every error the product reports to users."""
    exit_code = 1


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


class Interrupted(WavecosimError):
    """The user stopped the run (Ctrl-C); `result` holds the steps done (also on disk)."""
    exit_code = 130

    def __init__(self, message, result=None):
        super().__init__(message)
        self.result = result


class RunFailed(WavecosimError):
    """A run stopped early: `error` is the exception that stopped it (its class gives the exit code),
    `result` holds what was computed (also on disk)."""

    def __init__(self, error, result):
        super().__init__(str(error))
        self.error, self.result = error, result
        self.exit_code = error.exit_code
