"""Errors of the master.  Every message is one line, which an application shows as it is; what a command
exits with for each is the application's to decide (the master defines no exit code of its own)."""
from __future__ import annotations

class CosimError(Exception):
    """A failure the user must see as one line (no traceback)."""

    def __init__(self, message: str) -> None:
        super().__init__(" ".join(str(message).split()))


class ScenarioError(CosimError):
    """A scenario or system file is invalid: names the file, the field and the reason."""

    def __init__(self, file: str, field: str, reason: str) -> None:
        self.file, self.field, self.reason = file, field, reason
        super().__init__(f"{file}: {field}: {reason}" if field else f"{file}: {reason}")

    def __reduce__(self) -> tuple[object, ...]:   # (a worker process's error unpickles in the parent)
        return type(self), (self.file, self.field, self.reason)


class MissingVariableError(ScenarioError):
    """A scenario names a variable its instance's FMU does not have (``ref``: "instance.variable", the
    scenario's name); the resolution then looks for every other such name, to list them in one message."""

    def __init__(self, file: str, field: str, reason: str, ref: str) -> None:
        self.ref = ref
        super().__init__(file, field, reason)

    def __reduce__(self) -> tuple[object, ...]:
        return type(self), (self.file, self.field, self.reason, self.ref)


class OtherFileError(ScenarioError):
    """A file given as a scenario is another kind of file (``kind``: "a paper manifest", "a sweep file")."""

    def __init__(self, file: str, kind: str) -> None:
        self.kind = kind
        super().__init__(file, "", f"not a scenario but {kind}")

    def __reduce__(self) -> tuple[object, ...]:
        return type(self), (self.file, self.kind)


class FmuLoadError(CosimError):
    """An FMU file is missing, unsafe, not FMI 2.0 co-simulation, or cannot be loaded."""


class OutputError(CosimError):
    """A results folder cannot be written, or another run holds it."""


class RunError(CosimError):
    """The run stopped: a non-OK status, a non-finite output, or an exception while stepping."""

    def __init__(self, message: str, instance: str = "", time: float | None = None) -> None:
        self.instance, self.time = instance, time
        super().__init__(message)

    def __reduce__(self) -> tuple[object, ...]:
        return type(self), (str(self), self.instance, self.time)
