"""One exception hierarchy; the CLI maps each class to an exit code and prints one line."""


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

    def __init__(self, message, subsystem=None, step=None, time=None):
        super().__init__(message)
        self.subsystem, self.step, self.time = subsystem, step, time


class NumericalError(WavecosimError):
    """A non-finite value or a blow-up was detected."""
    exit_code = 4


class Interrupted(WavecosimError):
    """The user stopped the run (Ctrl-C); results so far are on disk."""
    exit_code = 130
