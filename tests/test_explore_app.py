"""The explorer's Bokeh document without a server or a browser: what each frame sends.

:class:`Page` runs an :class:`~flexkin.explore.app.ExplorerApp` on a bare Bokeh ``Document``
and measures every change the server would send to the browser as the ``PATCH-DOC`` message
Bokeh's protocol makes of it (header, metadata, JSON content and binary buffers).  The
callbacks the server would run later (``add_next_tick_callback``) run when the test says, and
full solves run synchronously, so that a test can place them between the moves of a drag.

Before issue 26, a drag without a selection re-sent every drawn equilibrium with every move
once a solve had come back: 230-270 kB per move with the 54 equilibria at (0, 0.3 m, 90 deg)
of the prototype (3.2 MB for the 8-move drag of :func:`test_a_move_sends_only_what_changed`).
"""

from __future__ import annotations

import collections
import importlib.util
import math
import time
from pathlib import Path

import numpy as np
import pytest

pytestmark = pytest.mark.skipif(importlib.util.find_spec("bokeh") is None,
                                reason="the explorer's document needs the bokeh package")

ROOT = Path(__file__).resolve().parents[1]
PROTO = ROOT / "examples" / "prototype_3pfr.toml"
TH = math.radians(90.0)
P0 = (0.0, 0.3, TH)


class Page:
    """An ExplorerApp on a bare Document (module docstring)."""

    def __init__(self, mech, pose) -> None:
        from bokeh.document import Document
        from bokeh.protocol import Protocol

        from flexkin.explore.app import ExplorerApp

        self.protocol = Protocol()
        self.queue: collections.deque = collections.deque()
        self.sent: list[tuple[str, int]] = []
        doc = Document()
        doc.add_next_tick_callback = self.queue.append  # the server's next tick: when the test says
        doc.on_change(self._patched)
        self.doc = doc
        self.app = ExplorerApp(doc, mech, pose=pose)
        self.app.worker.stop()                  # full solves run here, synchronously
        self.app._solve_async = self.solve_later
        self.app._later = lambda fn, *a: self.queue.append(lambda: fn(*a))
        self.requests: list = []
        self.solve_now()

    def _patched(self, event) -> None:
        msg = self.protocol.create("PATCH-DOC", [event])
        size = (len(msg.header_json) + len(msg.metadata_json) + len(msg.content_json)
                + sum(memoryview(b.data).nbytes for b in msg.buffers))
        model = getattr(event, "model", None)
        self.sent.append((getattr(model, "name", None) or type(event).__name__, size))

    def solve_later(self) -> None:
        self.requests.append(self.app.state.request())

    def solve_now(self, oldest: bool = False) -> None:
        """Finish the oldest full solve asked for, or one for the current state."""
        from flexkin.explore.state import solve

        req = self.requests.pop(0) if oldest else self.app.state.request()
        out = solve(self.app.mech, req)
        self.queue.append(lambda: self.app._on_solved(out))
        self.drain()

    def drain(self) -> None:
        while self.queue:
            self.queue.popleft()()

    def frame(self) -> tuple[int, dict[str, int]]:
        """Bytes sent since the last frame, in total and by model."""
        by: dict[str, int] = collections.Counter()
        for name, n in self.sent:
            by[name] += n
        self.sent = []
        return sum(by.values()), dict(by)

    def move(self, target) -> None:
        """One pointer move of a drag of the platform."""
        self.app._dragging = True
        self.app._queue_move(target)
        self.drain()

    def page_data(self, name: str) -> dict[str, list]:
        """What the browser holds in data source ``name`` (arrays as lists)."""
        d = self.app.sources[name].data
        return {k: [np.asarray(v).tolist() if isinstance(v, np.ndarray) else v for v in col] for k, col in d.items()}


@pytest.fixture(scope="module")
def mech():
    import flexkin

    return flexkin.load_mechanism(PROTO)


def _kb(n: int) -> str:
    return f"{n / 1e3:.1f} kB"


def assert_page_shows_the_state(page: Page, table: bool = True) -> None:
    """Whatever was skipped, the browser's data sources hold the current drawing (and the
    table, except during a drag without a selection, which leaves the last list shown)."""
    from flexkin.explore.scene import scene

    for name, data in scene(page.app.state, page.app.cache).items():
        assert page.page_data(name) == data, name
    if table:
        assert page.app.table_src.data == page.app.state.rows()


def test_a_move_sends_only_what_changed(mech):
    """An 8-move drag without a selection, the solver one move behind (each full solve comes
    back after the next move): a move sends the platform handle, its joints, the slider and the
    status (the first one also the platforms of the equilibria left behind), never the
    equilibria drawn already; a solve that comes back sends its new rods."""
    page = Page(mech, P0)
    n_drawn = len(page.app.state.result.solutions)
    assert n_drawn > 40
    page.frame()
    moves, solves = [], []
    for k in range(1, 9):
        page.move((0.01 * k, 0.3, TH))
        moves.append(page.frame())
        if len(page.requests) >= 2:   # the solve of the previous move finishes now
            page.solve_now(oldest=True)
            drawn = sum(len(page.app.sources[n].data["xs"]) for n in ("rods_solid", "rods_dashed"))
            solves.append((*page.frame(), drawn))
        assert_page_shows_the_state(page, table=False)
    move_bytes = [m[0] for m in moves]
    print(f"\nexplorer frames, 8-move drag without selection ({n_drawn} equilibria drawn): moves "
          f"{', '.join(_kb(b) for b in move_bytes)}; solves coming back "
          f"{', '.join(_kb(s[0]) for s in solves)}; total {_kb(sum(move_bytes) + sum(s[0] for s in solves))}")
    for k, (b, by) in enumerate(moves):
        assert not set(by) & {"rods_solid", "rods_dashed", "rods_selected", "table_source"}, by
        if k:   # the first move also draws the platforms of the equilibria it leaves behind
            assert b < 3000, by           # before: 230-270 kB once a solve had come back
    for b, by, n_rods in solves:         # new equilibria: their rods as binary float64 arrays
        assert by["rods_solid"] + by["rods_dashed"] < n_rods * (40 * 2 * 8 + 400), by


def test_tracked_drag_and_release_frames(mech):
    """With a selection, a move sends the tracked equilibrium (its three rods and clamps), its
    table row and the log; the release sends the new list once; an unchanged repetition sends
    nothing."""
    page = Page(mech, P0)
    st = page.app.state
    sel = next(s for s in st.solutions if s.stable)
    page.app._select(sel.id)
    page.drain()
    page.frame()
    sizes = []
    for k in range(1, 6):
        page.move((0.002 * k, 0.3, TH))
        b, by = page.frame()
        sizes.append(b)
        # the other equilibria: emptied by the first move (only the tracked one is drawn), then nothing
        assert by.get("rods_dashed", 0) + by.get("rods_solid", 0) < (600 if k == 1 else 1), by
        assert by.get("rods_selected", 0) < 3 * (90 * 2 * 8 + 400), by
    assert_page_shows_the_state(page)
    page.app._dragging = False
    page.app._release()
    page.drain()
    page.solve_now()
    release, by = page.frame()
    assert {"rods_solid", "table_source"} <= set(by)
    assert_page_shows_the_state(page)
    page.app._render()
    again, by = page.frame()
    print(f"\nexplorer frames, tracked drag: {', '.join(_kb(b) for b in sizes)} per move; release "
          f"{_kb(release)} ({len(st.solutions)} equilibria); the same render again {_kb(again)}")
    assert again == 0, by


def test_refresh_on_release_server_side(mech):
    """The server's part of a refresh after the full solve: applying the result, the drawing
    data (rod polylines), the table and the serialisation of what is sent.  Printed for the
    record (timings are measured by benchmarks/bench.py, not asserted here)."""
    page = Page(mech, P0)
    st = page.app.state
    sel = next(s for s in st.solutions if s.stable)
    page.app._select(sel.id)
    page.drain()
    from flexkin.explore.state import solve

    solve_s, rest_s = [], []
    for k in range(1, 4):
        page.move((0.002 * k, 0.3, TH))
        page.app._dragging = False
        t0 = time.perf_counter()
        out = solve(page.app.mech, st.request())
        t1 = time.perf_counter()
        page.app._on_solved(out)      # apply, drawing data, table, and PATCH-DOC serialisation
        t2 = time.perf_counter()
        page.drain()
        solve_s.append(t1 - t0)
        rest_s.append(t2 - t1)
        assert st.selected is not None and not st.stale
    print(f"\nexplorer refresh on release ({len(st.solutions)} equilibria): flexkin.ik "
          f"{1e3 * np.median(solve_s):.0f} ms, the explorer's own part {1e3 * np.median(rest_s):.0f} ms (medians)")
