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


def read_input_text(path, expected: str, error: type[FurutaError]) -> str:
    """The text of an input file; ``error`` naming the file when it is a directory, missing or unreadable.
    ``expected`` says what it should be (e.g. "a YAML file")."""
    from pathlib import Path

    path = Path(path)
    if path.is_dir():
        raise error(f"{path}: is a directory, expected {expected}")
    try:
        return path.read_text()
    except FileNotFoundError:
        raise error(f"{path}: no such file") from None
    except (OSError, UnicodeDecodeError) as err:
        raise error(f"{path}: cannot read ({err})") from None


def require_control_period(
    stated: float | None, period: float, where: str, control: str = "the control period"
) -> None:
    """Raise :class:`ConfigError` when a sampled block's ``stated`` period [s] (None: not stated) differs from
    the control period ``period`` [s] it is built with; ``where`` names the stated key, ``control`` the period."""
    if stated is not None and stated != period:
        raise ConfigError(
            f"{where} = {stated!r} differs from {control} = {period!r}; every sampled block runs at the control period"
        )
