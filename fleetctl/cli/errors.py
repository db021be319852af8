"""What every command may raise or return to the dispatcher: :class:`CliError` and the exit codes
the command line adds to a run's (docs/cli.md, exit status)."""

from __future__ import annotations

EXIT_USAGE = 2  # a bad mission file or option
EXIT_NOT_READY = 1  # status: a vehicle does not answer or is not ready
EXIT_TERMINATED = 143  # SIGTERM: like Ctrl-C (airborne rovers hold, records written)
EXIT_BROKEN_PIPE = 141  # stdout closed early (`fleetctl plan --json | head`)


class CliError(Exception):
    """A problem the user can fix; printed as one line, exit status 2."""


def check_speedup(speedup: float | None) -> None:
    """``--speedup X``: a simulated time factor must be > 0."""
    if speedup is not None and not speedup > 0:
        raise CliError(f"--speedup must be > 0, got {speedup}")


def check_timeout(timeout: float) -> None:
    """``--timeout S``: a wait must be > 0."""
    if not timeout > 0:
        raise CliError(f"--timeout must be > 0, got {timeout}")
