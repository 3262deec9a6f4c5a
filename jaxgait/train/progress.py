"""Progress output of a training run: plain lines, or a live bar on a terminal.

:func:`jaxgait.train.train` hands every notice and every iteration's line (iteration,
population, best score with the time, distance and speed its rollout walked, rollouts/s,
lane use, ETA) to its ``progress`` callable.  A callable with an ``iteration(done, total,
line)`` method gets the iteration lines there; :class:`Progress` is one: when its stream is
a terminal it redraws one line ``[#####-----] line`` in place, cut to the terminal's width,
and ends it with a newline after the last iteration; otherwise (a file, a pipe, a CI log)
every line is printed in full on its own line.
"""

from __future__ import annotations

import shutil
import sys
from typing import TextIO

#: Width of the bar in characters.
BAR = 20


def bar(done: int, total: int, width: int = BAR) -> str:
    """``"[#####---------------]"``: ``done`` of ``total`` as ``width`` characters."""
    frac = 0.0 if total <= 0 else min(max(done / total, 0.0), 1.0)
    k = int(round(frac * width))
    return "[" + "#" * k + "-" * (width - k) + "]"


class Progress:
    """Prints training progress to ``stream`` (default stdout).

    Args:
      stream: where to write.
      live: redraw one bar line in place; default: whether ``stream`` is a terminal.
    """

    def __init__(self, stream: TextIO | None = None, live: bool | None = None):
        self.stream = sys.stdout if stream is None else stream
        if live is None:
            isatty = getattr(self.stream, "isatty", None)
            live = bool(isatty and isatty())
        self.live = live
        self._open = False  # a bar line is drawn and not yet ended

    def _end_bar(self) -> None:
        if self._open:
            self.stream.write("\r\033[K")
            self._open = False

    def __call__(self, line: str) -> None:
        """A notice: on its own line (a bar being drawn is cleared first)."""
        self._end_bar()
        self.stream.write(line + "\n")
        self.stream.flush()

    def iteration(self, done: int, total: int, line: str) -> None:
        """The line of iteration ``done`` of ``total``."""
        if not self.live:
            self(line)
            return
        text = f"{bar(done, total)} {line}"
        if done >= total:
            self._end_bar()
            self.stream.write(text + "\n")
        else:
            cols = shutil.get_terminal_size((120, 24)).columns
            self.stream.write("\r\033[K" + text[: max(cols - 1, 10)])
            self._open = True
        self.stream.flush()

    def close(self) -> None:
        """End a bar line left open (e.g. after an interruption)."""
        if self._open:
            self.stream.write("\n")
            self.stream.flush()
            self._open = False
