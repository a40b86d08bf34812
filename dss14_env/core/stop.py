"""Stopping a long command with Ctrl-C (SIGINT) or SIGTERM, keeping its work.

:class:`Stopped` is the interruption a signal raises: a :class:`KeyboardInterrupt` that knows its
signal, so that a command exits with the shell's status for it (130 for SIGINT, 143 for SIGTERM).
:class:`terminate_as_interrupt` makes SIGTERM raise it, as Ctrl-C raises KeyboardInterrupt, so
that a killed command says what it kept instead of vanishing.

:class:`StopRequests` is for a loop that has safe points (a training between two environment
steps): while it is entered, the first SIGINT or SIGTERM is only recorded (:attr:`signum`), the
loop stops at its next safe point and saves its state; a second signal raises :class:`Stopped`
at once.  Signal handlers can only be set in the main thread: elsewhere (a Ray task's thread)
both do nothing and the signals act as before.
"""

from __future__ import annotations

import signal
import threading
from typing import Any

#: the signals that ask a command to stop
STOP_SIGNALS = (signal.SIGINT, signal.SIGTERM)


class Stopped(KeyboardInterrupt):
    """A stop asked for by a signal.

    :param signum: the signal (SIGINT or SIGTERM)
    """

    def __init__(self, signum: int = signal.SIGINT, *args: Any) -> None:
        self.signum = int(signum)
        super().__init__(*(args or (signal_name(signum),)))

    @property
    def exit_status(self) -> int:
        """128 + the signal's number: the status a shell gives a command the signal ended."""
        return 128 + self.signum


def signal_name(signum: int) -> str:
    """``"SIGINT"``, ``"SIGTERM"``, ..."""
    try:
        return signal.Signals(signum).name
    except ValueError:
        return f"signal {signum}"


def signal_of(exc: BaseException) -> int:
    """The signal behind an interruption: a :class:`Stopped`'s own, SIGINT for a plain Ctrl-C."""
    return exc.signum if isinstance(exc, Stopped) else int(signal.SIGINT)


def exit_status(exc: BaseException) -> int:
    """The exit status of an interrupted command: 128 + its signal (130 for Ctrl-C, 143 for
    SIGTERM).
    """
    return 128 + signal_of(exc)


def _in_main_thread() -> bool:
    return threading.current_thread() is threading.main_thread()


class _Handlers:
    """Set handlers for :data:`STOP_SIGNALS` on enter (main thread only), restore on exit."""

    signals: tuple[int, ...] = STOP_SIGNALS

    def __init__(self) -> None:
        self._old: dict[int, Any] = {}

    def _handle(self, signum: int, frame: Any) -> None:
        raise NotImplementedError

    def __enter__(self) -> Any:
        if _in_main_thread():
            for s in self.signals:
                self._old[s] = signal.signal(s, self._handle)
        return self

    def __exit__(self, *exc: Any) -> None:
        for s, old in self._old.items():
            signal.signal(s, old)
        self._old.clear()


class terminate_as_interrupt(_Handlers):
    """Context manager: SIGTERM raises :class:`Stopped` (as Ctrl-C raises KeyboardInterrupt)."""

    signals = (signal.SIGTERM,)

    def _handle(self, signum: int, frame: Any) -> None:
        raise Stopped(signum)


class StopRequests(_Handlers):
    """Context manager: record the first SIGINT or SIGTERM, raise :class:`Stopped` on the second
    (see the module doc).
    """

    def __init__(self) -> None:
        super().__init__()
        #: the first signal received, or None
        self.signum: int | None = None

    def _handle(self, signum: int, frame: Any) -> None:
        if self.signum is not None:
            raise Stopped(signum)
        self.signum = int(signum)


__all__ = ["STOP_SIGNALS", "StopRequests", "Stopped", "exit_status", "signal_name", "signal_of",
           "terminate_as_interrupt"]
