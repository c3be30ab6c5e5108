"""Progress display for long loops (tqdm bars on stderr), off unless an application turns it on.

Library calls stay silent by default; the ``iga`` command line and the
benchmark scripts switch progress on for terminals (``enable(True)``), and
``--quiet`` or a non-terminal stderr keeps it off; ``with enabled(on):``
scopes it to a block.  The switch is a context variable, so a block restores
the caller's setting and other threads or tasks keep theirs.  Loops wrap their
iterable in :func:`bar`, which returns the iterable itself when progress is off.
"""

from __future__ import annotations

import sys
import time
from contextlib import contextmanager
from contextvars import ContextVar

__all__ = ["enable", "enabled", "bar", "active", "Stages"]

_ON: ContextVar[bool] = ContextVar("progress_on", default=False)


def enable(on: bool | None = True) -> None:
    """Turn progress bars on or off for the rest of the current context; ``None``: on when stderr is a terminal."""
    _ON.set(bool(sys.stderr.isatty()) if on is None else bool(on))


def active() -> bool:
    """Whether progress is displayed."""
    return _ON.get()


@contextmanager
def enabled(on: bool = True):
    """Progress on (or off) inside a ``with`` block."""
    token = _ON.set(bool(on))
    try:
        yield
    finally:
        _ON.reset(token)


def bar(iterable, total: int | None = None, desc: str = "", unit: str = "it", min_items: int = 2):
    """``iterable`` wrapped in a tqdm bar when progress is on and the loop has at least ``min_items`` items."""
    if not _ON.get():
        return iterable
    n = total if total is not None else (len(iterable) if hasattr(iterable, "__len__") else None)
    if n is not None and n < min_items:
        return iterable
    from tqdm import tqdm

    return tqdm(iterable, total=n, desc=desc, unit=unit, file=sys.stderr, leave=False, dynamic_ncols=True)


class Stages:
    """Numbered stage lines on stderr (``[2/6] tiling ... 0.41 s``) and the time of each stage."""

    def __init__(self, n: int):
        self.n, self.i = n, 0
        self.timings: dict = {}
        self.name = ""
        self.t = time.perf_counter()

    def start(self, name: str) -> None:
        """Begin stage ``name`` (prints ``[i/n] name ...`` when progress is on)."""
        self.i += 1
        self.name, self.t = name, time.perf_counter()
        if _ON.get():
            print(f"[{self.i}/{self.n}] {name} ...", file=sys.stderr, flush=True)

    def done(self, detail: str = "") -> float:
        """End the current stage; records and returns its time in seconds."""
        dt = time.perf_counter() - self.t
        self.timings[self.name] = dt
        if _ON.get():
            print(f"[{self.i}/{self.n}] {self.name}: {dt:.2f} s {detail}".rstrip(), file=sys.stderr, flush=True)
        return dt
