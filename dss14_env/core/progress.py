"""Progress of a long command on stderr, whether or not stderr is a terminal.

On a terminal :class:`Progress` is a tqdm bar with its rate and ETA.  Anywhere else (a log
file, a pipe, a batch job, a Ray worker) a bar would be one long line of carriage returns, so
it prints whole lines instead: one as it starts, one each time another tenth of the total is
done or :data:`LINE_EVERY_S` seconds have passed since the last line (whichever comes first),
and one at the end -- each with the count, the elapsed time and the ETA::

    seed_0: 0/50000 steps (0 %), starting
    seed_0: 5120/50000 steps (10 %), 0:12 elapsed, ETA 1:45

>>> import io
>>> out = io.StringIO()
>>> with Progress(4, "demo", unit="ep", stream=out, tty=False) as p:
...     p.update(4)
>>> print(out.getvalue().splitlines()[0])
demo: 0/4 ep (0 %), starting
"""

from __future__ import annotations

import sys
import time
from collections.abc import Callable
from typing import Any, TextIO

#: most seconds between two lines when stderr is not a terminal
LINE_EVERY_S = 30.0
#: a line whenever another 1/LINE_SHARES of the total is done (not a terminal)
LINE_SHARES = 10


def format_duration(seconds: float) -> str:
    """``h:mm:ss`` or ``m:ss`` (tqdm's notation, so that lines and bars read alike)."""
    s = max(0, int(round(seconds)))
    h, rest = divmod(s, 3600)
    m, s = divmod(rest, 60)
    return f"{h}:{m:02d}:{s:02d}" if h else f"{m}:{s:02d}"


def eta_seconds(done: float, total: float, elapsed: float) -> float | None:
    """Seconds left at the rate so far (None before any progress, or without a total)."""
    if done <= 0 or total <= 0 or elapsed <= 0:
        return None
    return max(0.0, elapsed * (total - done) / done)


def is_terminal(stream: TextIO) -> bool:
    """Whether ``stream`` is a terminal (a closed or fake stream is not)."""
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError, OSError):
        return False


def _number(x: float) -> str:
    return str(int(x)) if float(x).is_integer() else f"{x:.4g}"


class Progress:
    """A bar on a terminal, whole lines otherwise (see the module doc).

    :param total: the amount of work (steps, episodes, chunks); more done than that raises it
    :param desc: what is being done (the start of every line)
    :param unit: the unit of ``total`` in the plural
    :param enabled: False: nothing is shown
    :param initial: work already done (a resumed run): not counted in the rate
    :param stream: where to write (default: ``sys.stderr`` at the time of the call)
    :param tty: a bar (True) or lines (False); default: whether ``stream`` is a terminal
    :param every_s: most seconds between two lines (lines only)
    :param clock: seconds, monotonic (tests pass their own)
    """

    def __init__(self, total: float, desc: str, unit: str = "it", enabled: bool = True,
                 initial: float = 0, stream: TextIO | None = None, tty: bool | None = None,
                 every_s: float = LINE_EVERY_S, clock: Callable[[], float] = time.monotonic) -> None:
        self.stream = sys.stderr if stream is None else stream
        self.enabled = enabled
        self.desc, self.unit, self.note = desc, unit, ""
        self.total, self.n, self.initial = float(total), float(initial), float(initial)
        self.every_s, self.clock = every_s, clock
        self.t0 = self._last_t = clock()
        self._last_share = self._share()
        self._bar: Any = None
        if not enabled:
            return
        if is_terminal(self.stream) if tty is None else tty:
            from tqdm import tqdm

            self._bar = tqdm(total=total, initial=initial, desc=desc, unit=unit.rstrip("s") or unit,
                             file=self.stream, dynamic_ncols=True)
        else:
            self._line("starting" if initial == 0 else "continuing")

    # ---------------------------------------------------------------- what the caller calls
    def update(self, n: float = 1) -> None:
        """``n`` more done."""
        self.update_to(self.n + n)

    def update_to(self, n: float) -> None:
        """``n`` done in all (a count that only grows, e.g. a training's step counter)."""
        if n > self.total:
            self.total = float(n)  # more work than announced: the total follows
            if self._bar is not None:
                self._bar.total = n
        if not self.enabled:
            self.n = float(n)
            return
        if self._bar is not None:
            step = n - self.n
            self._bar.update(int(step) if float(step).is_integer() else step)
            self.n = float(n)
            return
        self.n = float(n)
        now = self.clock()
        if self._share() > self._last_share or now - self._last_t >= self.every_s:
            self._line(self._timing(now))

    def set_description(self, desc: str) -> None:
        """What is being done now (the bar's prefix, the lines' start)."""
        self.desc = desc
        if self._bar is not None:
            self._bar.set_description_str(desc, refresh=False)

    def set_note(self, note: str) -> None:
        """A short note after the counts (the bar's postfix; lines: in the next line)."""
        self.note = note
        if self._bar is not None:
            self._bar.set_postfix_str(note, refresh=False)

    def set_total(self, total: float) -> None:
        """Correct the amount of work."""
        self.total = float(total)
        if self._bar is not None:
            self._bar.total = total
            self._bar.refresh()

    def write(self, line: str) -> None:
        """A message line that does not break the bar."""
        if self._bar is not None:
            self._bar.write(line, file=self.stream)
        else:
            print(line, file=self.stream, flush=True)

    def close(self) -> None:
        """The last line (or the bar's final state)."""
        if not self.enabled:
            return
        self.enabled = False
        if self._bar is not None:
            self._bar.close()
        else:
            elapsed = self.clock() - self.t0
            print(f"{self.desc}: {self._count()} done in {format_duration(elapsed)}"
                  + (f", {self.note}" if self.note else ""), file=self.stream, flush=True)

    def __enter__(self) -> Progress:
        return self

    def __exit__(self, *exc: Any) -> None:
        self.close()

    # ---------------------------------------------------------------- lines
    def _share(self) -> int:
        """Tenths (1 / :data:`LINE_SHARES`) of the total done."""
        return int(self.n * LINE_SHARES // self.total) if self.total > 0 else 0

    def _count(self) -> str:
        pct = f" ({100 * self.n / self.total:.0f} %)" if self.total > 0 else ""
        return f"{_number(self.n)}/{_number(self.total)} {self.unit}{pct}"

    def _timing(self, now: float) -> str:
        elapsed = now - self.t0
        eta = eta_seconds(self.n - self.initial, self.total - self.initial, elapsed)
        return (f"{format_duration(elapsed)} elapsed, ETA "
                + (format_duration(eta) if eta is not None else "unknown"))

    def _line(self, tail: str) -> None:
        note = f", {self.note}" if self.note else ""
        print(f"{self.desc}: {self._count()}, {tail}{note}", file=self.stream, flush=True)
        self._last_t, self._last_share = self.clock(), self._share()


__all__ = ["LINE_EVERY_S", "LINE_SHARES", "Progress", "eta_seconds", "format_duration", "is_terminal"]
