"""Progress on stderr that suits where stderr goes: a tqdm bar on a terminal, plain periodic lines when
stderr is a file or a pipe (a log gets ``runs: 40/120 (33 %), 12 s`` every ``PLAIN_EVERY_S`` seconds and
at the end, never carriage-return updates)."""
from __future__ import annotations

import sys
import threading
import time

PLAIN_EVERY_S = 10.0
"""Seconds between two plain progress lines."""
SHOW_AFTER_S = 2.0
"""A phase that ends sooner than this prints no plain line at all."""


def is_terminal(stream=None) -> bool:
    stream = sys.stderr if stream is None else stream
    try:
        return bool(stream.isatty())
    except (AttributeError, ValueError):
        return False


class PlainProgress:
    """The plain-line counterpart of a tqdm bar: ``update(n)``, ``close()``, a context manager."""

    def __init__(self, total: int, desc: str, unit: str = "it", initial: int = 0, stream=None,
                 every_s: float = PLAIN_EVERY_S, show_after_s: float = SHOW_AFTER_S):
        self.total, self.desc, self.unit, self.n = int(total), desc, unit, int(initial)
        self.stream = sys.stderr if stream is None else stream
        self.every_s, self.show_after_s = every_s, show_after_s
        self.t0 = time.monotonic()
        self.last = self.t0
        self.printed: int | None = None  # the count last printed
        self.closed = False
        if self.n:  # resumed: say where it starts
            self._line(" done earlier")

    def _line(self, note: str = "") -> None:
        pct = f" ({100.0 * self.n / self.total:.0f} %)" if self.total else ""
        self.stream.write(f"{self.desc}: {self.n}/{self.total} {self.unit}{pct}{note}, "
                          f"{time.monotonic() - self.t0:.0f} s\n")
        self.stream.flush()
        self.printed = self.n

    def update(self, n: int = 1) -> None:
        self.n += n
        now = time.monotonic()
        if now - self.t0 >= self.show_after_s and now - self.last >= self.every_s:
            self.last = now
            self._line()

    def close(self) -> None:
        if self.closed:
            return
        self.closed = True
        if self.printed != self.n and (self.printed is not None or time.monotonic() - self.t0 >= self.show_after_s):
            self._line()

    def __enter__(self) -> PlainProgress:
        return self

    def __exit__(self, *exc) -> None:
        self.close()


class _Silent:
    def update(self, n: int = 1) -> None:
        pass

    def close(self) -> None:
        pass

    def __enter__(self) -> _Silent:
        return self

    def __exit__(self, *exc) -> None:
        pass


def progress_bar(total: int, desc: str, unit: str = "it", enabled: bool = True, initial: int = 0, leave: bool = False):
    """A progress display for ``total`` steps: nothing when not ``enabled``; a tqdm bar when stderr is a
    terminal; else ``PlainProgress`` lines."""
    if not enabled:
        return _Silent()
    if not is_terminal():
        return PlainProgress(total, desc, unit, initial=initial)
    from tqdm import tqdm

    return tqdm(total=total, initial=initial, desc=desc, unit=unit, file=sys.stderr, mininterval=0.5,
                dynamic_ncols=True, leave=leave)


class slow_phase:
    """A phase that says so only when it is slow: nothing if it ends within ``after_s`` seconds; else a
    line ``magbench: <desc> ...`` once it has taken that long (from a timer thread, so a phase busy in one
    long call is reported too) and ``magbench: <desc>: done in N s`` at its end.  Plain lines, so logs stay
    readable; ``enabled=False`` (--json, --quiet) prints nothing."""

    def __init__(self, desc: str, enabled: bool = True, after_s: float = SHOW_AFTER_S, stream=None):
        self.desc, self.enabled, self.after_s = desc, enabled, after_s
        self.stream = sys.stderr if stream is None else stream
        self.announced = False
        self._timer: threading.Timer | None = None

    def _announce(self) -> None:
        self.announced = True
        self.stream.write(f"magbench: {self.desc} ...\n")
        self.stream.flush()

    def __enter__(self) -> slow_phase:
        self.t0 = time.monotonic()
        if self.enabled:
            self._timer = threading.Timer(self.after_s, self._announce)
            self._timer.daemon = True
            self._timer.start()
        return self

    def __exit__(self, *exc) -> None:
        if self._timer is not None:
            self._timer.cancel()
            self._timer.join()
        if self.announced and exc[0] is None:
            self.stream.write(f"magbench: {self.desc}: done in {time.monotonic() - self.t0:.0f} s\n")
            self.stream.flush()


class BarSafeStream:
    """A stream for lines written while a progress display may be on the terminal: through tqdm's own
    ``write`` (the bar is cleared, the line written, the bar redrawn) when ``bar`` is a tqdm bar, else
    straight to stderr (plain lines need no care)."""

    def __init__(self, bar=None):
        self.bar = bar

    def write(self, text: str) -> None:
        if self.bar is not None and type(self.bar).__module__.startswith("tqdm"):
            from tqdm import tqdm

            tqdm.write(text.rstrip("\n"), file=sys.stderr)
        else:
            sys.stderr.write(text)

    def flush(self) -> None:
        sys.stderr.flush()
