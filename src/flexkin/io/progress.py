"""Progress display for the command line: tqdm bars on stderr, only when stderr is a terminal.

:func:`progress_wanted` decides (``--quiet`` silences); :class:`Ticker` shows the elapsed time
of a call that reports no progress of its own (the FK search, a path), refreshed by a
background thread, and removes itself when the call returns.
"""

from __future__ import annotations

import sys
import threading
from typing import Any

__all__ = ["progress_wanted", "Ticker", "bar"]


def progress_wanted(quiet: bool = False, stream: Any = None) -> bool:
    """Whether to draw progress: not ``quiet`` and ``stream`` (default ``sys.stderr``) is a terminal."""
    if quiet:
        return False
    stream = sys.stderr if stream is None else stream
    try:
        return bool(stream is not None and stream.isatty())
    except (AttributeError, ValueError):  # closed or unusual streams
        return False


def bar(total: int | None, desc: str, unit: str = "it", enabled: bool = True, **kw: Any):
    """A tqdm bar on stderr (a disabled one when not ``enabled``).

    Parameters
    ----------
    total : int or None
        Number of units of work (``None``: unknown).
    desc : str
        Label.
    unit : str
        Name of one unit.
    enabled : bool
        Draw it.
    **kw
        Passed to ``tqdm``.

    Returns
    -------
    tqdm.tqdm
    """
    from tqdm.auto import tqdm

    return tqdm(total=total, desc=desc, unit=unit, file=sys.stderr, disable=not enabled, leave=False,
                dynamic_ncols=True, **kw)


class Ticker:
    """Context manager: ``desc: 12.3 s`` on stderr, refreshed every ``interval`` seconds while the
    body runs (for calls that have no progress callback).  Does nothing when not ``enabled``.

    Parameters
    ----------
    desc : str
        Label.
    enabled : bool
        Draw it.
    interval : float
        Refresh period (s).
    """

    def __init__(self, desc: str, enabled: bool = True, interval: float = 0.25) -> None:
        self.desc, self.enabled, self.interval = desc, enabled, interval
        self._bar = None
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def __enter__(self) -> "Ticker":
        if self.enabled:
            self._bar = bar(None, self.desc, enabled=True, bar_format="{desc}: {elapsed} elapsed")
            self._thread = threading.Thread(target=self._run, daemon=True)
            self._thread.start()
        return self

    def _run(self) -> None:
        while not self._stop.wait(self.interval):
            try:
                self._bar.refresh()
            except Exception:  # pragma: no cover - a display problem never stops the work
                return

    def __exit__(self, *exc: Any) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        if self._bar is not None:
            self._bar.close()
