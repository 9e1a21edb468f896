"""The one small error hierarchy of uwcosim.

User errors (bad scenario, bad FMU, bad map...) are subclasses of :class:`UwcosimError`; the CLI
catches them once and prints a single line with a non-zero exit status.
"""


class UwcosimError(Exception):
    """Base class of every error uwcosim raises on purpose."""

    exit_code = 1


class ScenarioError(UwcosimError):
    """A scenario file or override is invalid (names the file, the key and what was expected)."""

    exit_code = 2


class FMUError(UwcosimError):
    """An FMU is missing, corrupt, for another platform, or failed during a run."""

    exit_code = 3


class MapError(UwcosimError):
    """A bathymetry map cannot be read or is unusable."""

    exit_code = 2


class FilterError(UwcosimError):
    """An estimator was misconfigured or diverged beyond repair."""


class AlgebraicLoopError(ScenarioError):
    """The connection graph between FMUs contains a loop of direct-feedthrough variables."""


class RunInterrupted(UwcosimError):
    """The run was interrupted (Ctrl-C); the log written so far was flushed."""

    exit_code = 130


class FilterDivergence(FilterError):
    """An estimator produced NaN or a covariance not positive definite beyond repair."""


class RegressionInputError(UwcosimError):
    """Bad input to a regression comparison: missing or unreadable log, no common signals,
    time ranges that do not overlap (exit status 2)."""

    exit_code = 2


class OutputError(UwcosimError):
    """An output cannot be written: a read-only folder, a directory where a file is expected,
    a full disk (names the path and what the system said)."""


#: errno values that mean the user named a wrong place (exit 2); others (a full disk, an I/O
#: error) are failures of the machine (exit 1)
_USER_ERRNOS = frozenset({1, 2, 13, 17, 20, 21, 30, 36, 40})  # EPERM ENOENT EACCES EEXIST
# ENOTDIR EISDIR EROFS ENAMETOOLONG ELOOP


def os_error_line(exc: OSError) -> tuple[str, int]:
    """One line and an exit status for an ``OSError`` that reached the command line: the
    file it names and what the system said (``PermissionError`` ->
    ``"/ro/report.md: cannot write (Permission denied)"``)."""
    name = exc.filename if exc.filename is not None else "?"
    if exc.filename2 is not None:
        name = f"{name} -> {exc.filename2}"
    reason = exc.strerror or str(exc) or type(exc).__name__
    return f"{name}: cannot read or write ({reason})", 2 if exc.errno in _USER_ERRNOS else 1
