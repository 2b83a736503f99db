"""Background work for the explorer, so that the interface never freezes (no web import).

* :class:`Worker`: one daemon thread with a few *lanes* (``"solve"``, ``"warmup"``,
  ``"feasibility"``); each lane holds at most one pending job and a newer submission replaces
  the pending one (the latest request wins); lanes run in priority order.
* :class:`WorkspaceJob`: :func:`flexkin.workspace` in a daemon thread, with a progress count and
  cancellation (the progress callback raises once cancelled).
* :func:`overlay`: a workspace map as an RGBA image and boundary cells, for drawing.

Daemon threads never keep the process alive after the server stops.
"""

from __future__ import annotations

import threading
import time
from typing import Any, Callable

import numpy as np

__all__ = ["Cancelled", "Worker", "WorkspaceJob", "overlay", "warm_up"]

LANES = ("solve", "warmup", "feasibility")


class Cancelled(Exception):
    """Raised inside a background computation that was cancelled."""


class Worker:
    """A daemon thread running the latest job of each lane (see the module docstring).

    ``submit(lane, fn, done)`` runs ``done(fn(cancelled))`` in the worker thread, where
    ``cancelled()`` becomes true when a newer job is submitted to the same lane or to the
    ``"solve"`` lane (a new solve outdates the feasibility of the last one), or the worker stops; ``done`` is not called for a job whose ``fn`` raised
    :class:`Cancelled` (other exceptions go to ``on_error``).
    """

    def __init__(self, on_error: Callable[[BaseException], None] | None = None, name: str = "flexkin-explore") -> None:
        self._pending: dict[str, tuple[Callable, Callable]] = {}
        self._cv = threading.Condition()
        self._stop = False
        self._gen = 0
        self.busy_lane: str | None = None
        self.on_error = on_error
        self._thread = threading.Thread(target=self._run, name=name, daemon=True)
        self._thread.start()

    def submit(self, lane: str, fn: Callable[[Callable[[], bool]], Any], done: Callable[[Any], None]) -> None:
        if lane not in LANES:
            raise ValueError(f"unknown lane {lane!r}")
        with self._cv:
            self._pending[lane] = (fn, done)
            if self.busy_lane is not None and (lane == self.busy_lane or lane == "solve"):
                self._gen += 1  # the running job is outdated
            self._cv.notify()

    def clear(self, lane: str) -> None:
        with self._cv:
            self._pending.pop(lane, None)

    @property
    def idle(self) -> bool:
        with self._cv:
            return self.busy_lane is None and not self._pending

    def stop(self) -> None:
        with self._cv:
            self._stop = True
            self._gen += 1
            self._pending.clear()
            self._cv.notify()

    def join(self, timeout: float | None = None) -> None:
        self._thread.join(timeout)

    def _run(self) -> None:
        while True:
            with self._cv:
                while not self._pending and not self._stop:
                    self._cv.wait()
                if self._stop:
                    return
                lane = next(la for la in LANES if la in self._pending)
                fn, done = self._pending.pop(lane)
                self.busy_lane = lane
                gen = self._gen
            try:
                value = fn(lambda: self._gen != gen or self._stop)
            except Cancelled:
                value = Cancelled
            except BaseException as e:  # noqa: BLE001 - reported, the thread goes on
                value = Cancelled
                if self.on_error is not None:
                    self.on_error(e)
            finally:
                with self._cv:
                    self.busy_lane = None
            if value is not Cancelled and not self._stop:
                try:
                    done(value)
                except BaseException as e:  # noqa: BLE001
                    if self.on_error is not None:
                        self.on_error(e)


def warm_up(mech, solution, load=None) -> float:
    """Compile the tracker's kernels (the first move in a process takes seconds): move a
    throw-away tracker by a tiny step.  Returns the seconds it took."""
    from flexkin.solve.track import Tracker

    t0 = time.perf_counter()
    tr = Tracker(mech, solution, load=load, feasibility=True)
    p = np.asarray(solution.pose, dtype=float)
    tr.move_to(p + np.array([1e-6 * mech.length_scale, 0.0, 0.0]), kind="pose")
    return time.perf_counter() - t0


class WorkspaceJob:
    """The constant-orientation workspace of ``solution``'s aspect at its orientation, computed
    by :func:`flexkin.workspace` in a daemon thread.

    ``on_progress(job)`` is called (from the thread) after each wave; ``on_done(job)`` at the
    end, with ``result`` (a ``Workspace``) or ``error`` set, unless the job was cancelled.
    ``steps`` counts continuation steps so far, ``elapsed`` the seconds.
    """

    def __init__(self, mech, solution, *, load=None, step: float | None = None,
                 bounds: tuple[float, float, float, float] | None = None, time_budget: float = 60.0,
                 on_progress: Callable[["WorkspaceJob"], None] | None = None,
                 on_done: Callable[["WorkspaceJob"], None] | None = None) -> None:
        self.mech, self.solution, self.load = mech, solution, load
        self.theta = float(solution.pose[2])
        self.step, self.bounds, self.time_budget = step, bounds, float(time_budget)
        self.on_progress, self.on_done = on_progress, on_done
        self.steps = 0
        self.result: Any = None
        self.error = ""
        self.cancelled = False
        self.done = False
        self.t0 = 0.0
        self.elapsed = 0.0
        self._thread: threading.Thread | None = None

    def start(self) -> "WorkspaceJob":
        self.t0 = time.perf_counter()
        self._thread = threading.Thread(target=self._run, name="flexkin-explore-workspace", daemon=True)
        self._thread.start()
        return self

    def run(self) -> "WorkspaceJob":
        """Compute in the calling thread (tests, benchmarks)."""
        self.t0 = time.perf_counter()
        self._run()
        return self

    def cancel(self) -> None:
        self.cancelled = True

    def join(self, timeout: float | None = None) -> None:
        if self._thread is not None:
            self._thread.join(timeout)

    def _progress(self, n: int) -> None:
        if self.cancelled:
            raise Cancelled
        self.steps += int(n)
        self.elapsed = time.perf_counter() - self.t0
        if self.on_progress is not None:
            self.on_progress(self)

    def _run(self) -> None:
        from flexkin.solve.workspace import workspace

        try:
            self.result = workspace(self.mech, self.theta, seed=self.solution, load=self.load, step=self.step,
                                    bounds=self.bounds, all_aspects=False, progress=self._progress,
                                    time_budget=self.time_budget)
        except Cancelled:
            self.elapsed = time.perf_counter() - self.t0
            return
        except Exception as e:  # noqa: BLE001 - shown to the user
            self.error = f"{type(e).__name__}: {e}"
        self.elapsed = time.perf_counter() - self.t0
        self.done = True
        if self.on_done is not None and not self.cancelled:
            self.on_done(self)


def _rgba(hex_color: str, alpha: float) -> tuple[int, int, int, int]:
    h = hex_color.lstrip("#")
    if len(h) != 6:  # a named colour
        from matplotlib.colors import to_hex

        h = to_hex(hex_color).lstrip("#")
    return (int(h[0:2], 16), int(h[2:4], 16), int(h[4:6], 16), int(round(alpha * 255)))


def overlay(ws, alpha: float = 0.35) -> dict[str, list]:
    """The first aspect map of workspace ``ws`` as an RGBA image (``image``: (ny, nx) uint32,
    cells coloured by d-mode combination like the library's workspace figures, IK-singularity
    boundary cells black, FK-singularity / instability boundary cells orange) with its placement
    ``x``, ``y``, ``dw``, ``dh`` (m), as one-row columns for an ``image_rgba`` glyph; also
    ``cells`` (number reached)."""
    from flexkin.plot.style import mode_color
    from flexkin.plot.workspace import FK_COLOR, IK_COLOR

    mp = ws.maps[0]
    x, y = np.asarray(ws.x, dtype=float), np.asarray(ws.y, dtype=float)
    reached = np.asarray(mp.reached, dtype=bool)
    ny, nx = reached.shape
    img = np.zeros((ny, nx, 4), dtype=np.uint8)
    modes = np.asarray(mp.modes)
    if reached.any():
        labels = (modes[..., 0].astype(int) * 100 + modes[..., 1].astype(int) * 10 + modes[..., 2].astype(int))
        for lab in np.unique(labels[reached]):
            img[reached & (labels == lab)] = _rgba(mode_color(f"{int(lab):03d}"), alpha)  # clamped rods: d-mode 0
    img[np.asarray(mp.boundary_fk, dtype=bool)] = _rgba(FK_COLOR, 0.9)
    img[np.asarray(mp.boundary_ik, dtype=bool)] = _rgba(IK_COLOR, 0.9)
    dx = float(x[1] - x[0]) if nx > 1 else 1e-3
    dy = float(y[1] - y[0]) if ny > 1 else 1e-3
    return {"image": [img.view(np.uint32).reshape(ny, nx)], "x": [float(x[0] - dx / 2)], "y": [float(y[0] - dy / 2)],
            "dw": [float(dx * nx)], "dh": [float(dy * ny)], "cells": int(reached.sum())}
