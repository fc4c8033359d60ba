"""Errors the command line turns into one clear line and exit code 2 (bad input) or 3 (diverged run)."""


class FurutaError(Exception):
    """Base class of the errors this package raises on purpose."""


class ConfigError(FurutaError, ValueError):
    """A configuration, rig file or parameter is malformed or non-physical; the message names where."""


class LogError(FurutaError, ValueError):
    """A log file is malformed; the message names the file, line and column."""


class SimulationDiverged(FurutaError, RuntimeError):
    """A simulation left its safe envelope; the message says when and why."""

    def __init__(self, message: str, time: float, cause: str):
        super().__init__(message)
        self.time = time
        self.cause = cause
