"""Progress on stderr: a bar (tqdm) on a terminal, whole lines anywhere else.

A bar redraws itself with carriage returns, which a file or a pipe does not interpret: in
a redirected log its updates run together on one line. Where stderr is not a terminal,
progress is therefore a line per update, at most one every `LINE_INTERVAL_S` seconds (a
run shorter than that prints none), and a last line at the end if any was printed."""

from __future__ import annotations

import sys
import time
from typing import Any, TextIO

#: the shortest time between two progress lines where stderr is not a terminal [s]
LINE_INTERVAL_S = 5.0


def _is_terminal(stream: TextIO) -> bool:
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):  # no isatty, or a closed stream
        return False


class Lines:
    """tqdm's `n`, `update` and `close` as whole lines: "DESC  PCT%  COUNT", COUNT as
    `count_format` gives it (with n and total)."""

    def __init__(self, total: float, desc: str, count_format: str, file: TextIO):
        self.total, self.desc, self.count_format, self.file = float(total), desc, count_format, file
        self.n: float = 0
        self._last = time.monotonic()
        self._shown: float | None = None  # the count of the last line printed

    def _line(self) -> None:
        pct = 100.0 * self.n / self.total if self.total > 0 else 100.0
        count = self.count_format.format(n=self.n, total=self.total)
        self.file.write(f"{self.desc.rstrip()}  {pct:3.0f}%  {count}\n")
        self.file.flush()
        self._shown, self._last = self.n, time.monotonic()

    def update(self, k: float = 1) -> None:
        self.n += k
        if time.monotonic() - self._last >= LINE_INTERVAL_S:
            self._line()

    def close(self) -> None:
        if self._shown is not None and self._shown != self.n:
            self._line()


class _Off:
    """No progress (`enabled=False`)."""

    n: float = 0

    def update(self, k: float = 1) -> None:
        self.n += k

    def close(self) -> None:
        pass


def bar(
    total: float,
    desc: str,
    count_format: str,
    enabled: bool = True,
    file: TextIO | None = None,
    **tqdm_options: Any,
):
    """A progress display of `total` on `file` (default stderr) with tqdm's `n`, `update`
    and `close`: a tqdm bar (with `tqdm_options`) where `file` is a terminal, else `Lines`
    (`count_format`: the count on each line, e.g. "{n:.2f}/{total:.2f} s"); nothing when not
    `enabled`."""
    stream = sys.stderr if file is None else file
    if not enabled:
        return _Off()
    if not _is_terminal(stream):
        return Lines(total, desc, count_format, stream)
    from tqdm import tqdm

    return tqdm(total=total, desc=desc, file=stream, mininterval=0.2, **tqdm_options)
