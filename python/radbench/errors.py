"""radbench's errors as Python exceptions: each carries radbench's message (``str(e)``) and
the exit code the command line gives the same error (``e.exit_code``, docs/exit-codes.md)."""

from __future__ import annotations

__all__ = ["RadbenchError", "InputError", "InstrumentError", "ProcessingError"]


class RadbenchError(Exception):
    """Any radbench error. ``exit_code``: what ``radbench`` would exit with (1 for a bug)."""

    def __init__(self, message: str, exit_code: int = 1) -> None:
        super().__init__(message)
        self.exit_code = exit_code


class InputError(RadbenchError, ValueError):
    """Bad input (exit code 2): an option, a file or a value radbench refuses, named with what
    is allowed."""

    def __init__(self, message: str, exit_code: int = 2) -> None:
        super().__init__(message, exit_code)


class InstrumentError(RadbenchError):
    """An instrument (or the simulated bench) failed or could not be reached (exit code 3)."""

    def __init__(self, message: str, exit_code: int = 3) -> None:
        super().__init__(message, exit_code)


class ProcessingError(RadbenchError):
    """The processing failed on this input (exit code 4)."""

    def __init__(self, message: str, exit_code: int = 4) -> None:
        super().__init__(message, exit_code)
