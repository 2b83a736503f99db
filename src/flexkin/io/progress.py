"""Progress display for the command line: tqdm bars on stderr, only when stderr is a terminal.

:func:`progress_wanted` decides (``--quiet`` silences).  Solvers that report progress
(``flexkin.ik``, ``flexkin.fk``, ``flexkin.follow_path``) take a callback
``progress(fraction, stage)``, ``fraction`` the share of the work done (0 to 1) and ``stage``
what they are doing; :class:`ProgressBar` is such a callback that draws a bar, and
:func:`substage` maps a part of the work onto a range of the bar.  :class:`Ticker` shows the
elapsed time of a call that reports no progress of its own.
"""

from __future__ import annotations

import sys
import threading
from typing import Any, Callable

__all__ = ["progress_wanted", "Ticker", "bar", "ProgressBar", "substage", "Progress"]

#: A solver's progress callback: ``progress(fraction, stage)``, ``fraction`` in [0, 1].
Progress = Callable[[float, str], None]


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


def substage(progress: Progress | None, lo: float, hi: float, stage: str) -> Progress | None:
    """The callback of a part of the work that spans ``[lo, hi]`` of ``progress``.

    Parameters
    ----------
    progress : callable or None
        The whole work's callback (``None``: no report, and ``None`` is returned).
    lo, hi : float
        The part's share of the whole, ``0 <= lo <= hi <= 1``.
    stage : str
        Its name, passed on with every report.

    Returns
    -------
    callable or None
        ``sub(fraction, detail="")`` reports ``lo + fraction (hi - lo)`` and
        ``"stage: detail"`` (or ``stage``).
    """
    if progress is None:
        return None

    def sub(fraction: float, detail: str = "") -> None:
        f = min(max(float(fraction), 0.0), 1.0)
        progress(lo + f * (hi - lo), f"{stage}: {detail}" if stage and detail else (detail or stage))

    return sub


class ProgressBar:
    """A progress callback (``bar(fraction, stage)``) that draws a tqdm bar of the fraction done,
    with the stage and the elapsed time, on stderr; a context manager that removes the bar at
    the end.  The elapsed time is refreshed every ``interval`` seconds while a stage runs.  Does
    nothing when not ``enabled``.

    Parameters
    ----------
    desc : str
        Label before the stage.
    enabled : bool
        Draw it.
    interval : float
        Refresh period (s).
    """

    def __init__(self, desc: str, enabled: bool = True, interval: float = 0.5) -> None:
        self.desc, self.enabled, self.interval = desc, enabled, interval
        self._bar = None
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self.fraction, self.stage = 0.0, ""

    def __enter__(self) -> "ProgressBar":
        if self.enabled:
            self._bar = bar(1000, self.desc, enabled=True,
                            bar_format="{desc}: {percentage:3.0f}%|{bar}| {elapsed}")
            self._thread = threading.Thread(target=self._run, daemon=True)
            self._thread.start()
        return self

    def __call__(self, fraction: float, stage: str = "") -> None:
        self.fraction = min(max(float(fraction), self.fraction), 1.0)  # never backwards
        self.stage = stage
        if self._bar is not None:
            with self._lock:
                self._bar.n = int(round(1000 * self.fraction))
                self._bar.set_description_str(f"{self.desc}: {stage}" if stage else self.desc, refresh=False)
                self._bar.refresh()

    def _run(self) -> None:
        while not self._stop.wait(self.interval):
            try:
                with self._lock:
                    self._bar.refresh()
            except Exception:  # pragma: no cover - a display problem never stops the work
                return

    def __exit__(self, *exc: Any) -> None:
        self._stop.set()
        if self._thread is not None:
            self._thread.join()
        if self._bar is not None:
            self._bar.close()
