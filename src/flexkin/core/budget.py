"""Time budgets: one clock for a solver's whole work (:class:`Deadline`), and measured costs of
units of work (:class:`Rate`) to size the slices between two looks at the clock.

The contract every solver with a ``time_budget`` keeps (``ik``, ``fk``, ``follow_path``,
``workspace``):

* the budget counts from the call and covers **all** of the solver's work: the global search,
  the Newton refinement of its candidates, stability, Jacobians and the independent
  verification of every solution it returns (and, where the solver computes them,
  feasibility verdicts);
* it does **not** cover start-up: importing flexkin, loading the compiled kernels from their
  cache (or compiling them, minutes after a kernel change) and reading or building the cached
  atlases, which the first call in a process pays once;
* work is done in slices sized from measured rates so that one slice takes a small share of
  the budget (:meth:`Deadline.slice_seconds`); the clock is read between slices, so a run ends
  at most about one slice after its budget;
* when a look at the clock finds the time up, the solver stops, returns what it has finished,
  and says ``complete = False`` with a message naming the time budget.  Such a run is never
  reported complete: :attr:`Deadline.hit` records that the work was cut short.

A :class:`Deadline` can be passed as ``time_budget`` itself, so that a solver calling another
(a path starting with an IK, a workspace with its seed IK) shares one clock.
"""

from __future__ import annotations

import math
import time

from .validation import check_budget

__all__ = ["Deadline", "Rate", "timed_slices", "MIN_SLICE", "SLICE_SHARE", "POST_SHARE"]

#: share of the budget one slice of work may take (between two looks at the clock)
SLICE_SHARE = 0.05
#: shortest slice (s): below it the per-call overhead of a slice dominates
MIN_SLICE = 0.01
#: share of a budget a global search leaves for the refinement and analysis of what it found
#: (stability and verification cost from a millisecond to a few hundred per solution, depending
#: on the d-modes: known only once measured)
POST_SHARE = 0.3


class Deadline:
    """The clock of one time budget.

    Parameters
    ----------
    seconds : float, optional
        The budget (s, > 0); ``None``: no limit (every check passes).
    """

    def __init__(self, seconds: float | None = None) -> None:
        self.seconds = None if seconds is None else check_budget(seconds)
        self.start = time.perf_counter()
        self.end = math.inf if self.seconds is None else self.start + self.seconds
        #: whether a look at the clock found the time up (the work was cut short)
        self.hit = False
        self._parent: Deadline | None = None

    @classmethod
    def of(cls, time_budget: float | Deadline | None) -> Deadline:
        """``time_budget`` as a Deadline: the same object if it is one (a shared clock), else a
        new clock started now (the number is validated: a finite number of seconds > 0)."""
        if isinstance(time_budget, Deadline):
            return time_budget
        return cls(time_budget)

    @property
    def limited(self) -> bool:
        """Whether there is a budget at all."""
        return self.seconds is not None

    def elapsed(self) -> float:
        """Seconds since the clock started."""
        return time.perf_counter() - self.start

    def remaining(self) -> float:
        """Seconds left (``inf`` without a budget, never below 0)."""
        return max(self.end - time.perf_counter(), 0.0) if self.limited else math.inf

    def expired(self, reserve: float = 0.0) -> bool:
        """Whether the time is up, keeping ``reserve`` seconds for work that must follow (e.g.
        the refinement of the candidates found so far).  A ``True`` answer marks the run as
        cut short (:attr:`hit`)."""
        if not self.limited:
            return False
        up = time.perf_counter() + max(reserve, 0.0) >= self.end
        if up:
            self.hit = True
            if self._parent is not None:
                self._parent.hit = True
        return up

    def for_search(self) -> Deadline:
        """The clock of a global search within this budget: it ends :data:`POST_SHARE` of the
        budget early, leaving that for the refinement and analysis of what the search finds
        (a search cut short by it marks this budget as hit too)."""
        if not self.limited:
            return self
        d = Deadline.__new__(Deadline)
        d.seconds = (1.0 - POST_SHARE) * self.seconds
        d.start, d.end, d.hit, d._parent = self.start, self.end - POST_SHARE * self.seconds, False, self
        return d

    def slice_seconds(self) -> float:
        """How long the next slice of work may take: a small share of the budget
        (:data:`SLICE_SHARE`, at least :data:`MIN_SLICE`), and no more than what is left;
        ``inf`` without a budget."""
        if not self.limited:
            return math.inf
        return min(max(SLICE_SHARE * self.seconds, MIN_SLICE), max(self.remaining(), MIN_SLICE))

    def message(self, what: str = "") -> str:
        """``"time budget of S s exhausted[: what]"``."""
        head = f"time budget of {self.seconds:g} s exhausted" if self.limited else "time budget exhausted"
        return f"{head}: {what}" if what else head

    def __repr__(self) -> str:  # pragma: no cover - debugging aid
        return f"Deadline(seconds={self.seconds!r}, remaining={self.remaining():.3g}, hit={self.hit})"


class Rate:
    """Measured cost of one unit of some work (a candidate refined, a sample analysed, a node
    examined), to size slices and to reserve time for work that must follow.

    Parameters
    ----------
    guess : float
        Seconds per unit before anything was measured.
    """

    def __init__(self, guess: float) -> None:
        self._units = 0.0
        self._seconds = 0.0
        self._guess = float(guess)

    @property
    def per_unit(self) -> float:
        """Seconds per unit: the measured mean once something was measured, else the guess."""
        return self._seconds / self._units if self._units > 0 and self._seconds > 0 else self._guess

    def add(self, units: float, seconds: float) -> None:
        """Record that ``units`` units took ``seconds``."""
        if units > 0 and seconds >= 0:
            self._units += float(units)
            self._seconds += float(seconds)

    def cost(self, units: float) -> float:
        """Estimated seconds for ``units`` units."""
        return max(float(units), 0.0) * self.per_unit

    @property
    def measured(self) -> bool:
        """Whether anything was measured yet."""
        return self._units > 0

    def units_for(self, seconds: float, lo: int = 1, hi: int = 1 << 30) -> int:
        """How many units fit in ``seconds`` (at least ``lo``, at most ``hi``; ``hi`` when
        ``seconds`` is infinite)."""
        if not math.isfinite(seconds):
            return hi
        return min(max(int(seconds / max(self.per_unit, 1e-12)), lo), hi)


def timed_slices(n: int, deadline: Deadline, rate: Rate, *, max_slice: int = 1 << 30, first: int = 4):
    """Yield ``(lo, hi)`` index ranges covering ``0..n`` in slices sized so that each takes
    about :meth:`Deadline.slice_seconds` at ``rate`` (at most ``first`` units while nothing was
    measured); the caller records each slice's time with :meth:`Rate.add`.  Stops early (the
    deadline is then :attr:`~Deadline.hit`) when the time is up before a slice starts; without
    a budget, slices of ``max_slice``."""
    lo = 0
    while lo < n:
        if deadline.expired():
            return
        size = max_slice
        if deadline.limited:
            size = rate.units_for(deadline.slice_seconds(), 1, max_slice)
            if not rate.measured:
                size = min(size, first)
        hi = min(n, lo + size)
        yield lo, hi
        lo = hi
