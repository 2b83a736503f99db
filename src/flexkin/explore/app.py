"""The explorer's web document, built with a plain Bokeh server application.

Why Bokeh (and not Panel on top of it): the explorer is one drawing that the user drags plus
a handful of widgets and a table.  Bokeh gives exactly that -- pointer events on the plot
(``PanStart``/``Pan``/``PanEnd``/``Tap``) delivered to Python, sliders that report both the
live value and the value on release (``value`` / ``value_throttled``), a data table with
row selection, and data sources whose updates travel as small diffs over the session's
websocket -- and an embeddable :class:`bokeh.server.server.Server` with an explicit start and
stop, so the command owns the process (Ctrl-C and "last tab closed" end it cleanly).  Its
JavaScript is served by the server itself from the installed package, so nothing is fetched
from the network.  Panel would add its own layer (param, templates, extra JavaScript bundles)
without giving this app anything it needs; a plain Bokeh server also keeps the callback path
short, which matters for the 50 ms tracking budget.

All logic lives in :mod:`~flexkin.explore.state` (no web import); this module maps widgets and
pointer events to it, runs full solves, feasibility checks and the workspace in background
threads (:mod:`~flexkin.explore.jobs`) and pushes the results into the document with
``add_next_tick_callback``, so the page never freezes.
"""

from __future__ import annotations

import html
import math
import time
from collections import deque
from functools import partial
from typing import Any, Callable

import numpy as np
from bokeh.events import DocumentReady, Pan, PanEnd, PanStart, Tap
from bokeh.layouts import column, row
from bokeh.models import (ColumnDataSource, DataTable, Div, HoverTool, NumberFormatter, NumericInput,
                          RadioButtonGroup, Range1d, Select, Slider, TableColumn, Toggle)
from bokeh.plotting import figure

from .jobs import Worker, WorkspaceJob, overlay, warm_up
from .scene import BASE_COLOR, PLATFORM_FILL, PLATFORM_LINE, ShapeCache, base_layers, empty_scene, scene
from .state import ExplorerState, feasibility_of, input_bounds, pose_bounds, solve

__all__ = ["ExplorerApp", "EVENT_COLORS"]

#: colour of each kind of event in the log
EVENT_COLORS = {
    "mode_change": "#6a3d9a", "stability_lost": "#d62728", "stability_regained": "#2ca02c",
    "stability_undecided": "#8c564b", "ik_singularity": "#000000", "fk_singularity": "#ff7f0e",
    "infeasible": "#d62728", "feasible": "#2ca02c", "branch_end": "#d62728", "not_found": "#8c564b",
    "no_solution": "#7f7f7f",
}
PANEL_WIDTH = 400
FRAME_MAX = 620
LOG_LINES = 60
#: layers whose polylines go to the page as float64 arrays (binary, 1.8x smaller than JSON
#: number lists, and as exact); short ones (platforms: 3 points) are smaller as JSON
ROD_LAYERS = ("rods_solid", "rods_dashed", "rods_selected")
WS_PROGRESS_INTERVAL = 0.25  # s between workspace progress updates


def _step_for(span: float) -> float:
    return float(10.0 ** math.floor(math.log10(max(span, 1e-12) / 500.0)))


class ExplorerApp:
    """One browser session: an :class:`ExplorerState`, the widgets and the drawing.

    Parameters
    ----------
    doc : bokeh.document.Document
    mech : Mechanism
    pose, load, max_mode : see :class:`ExplorerState`.
    session_id : str, optional
        Used in the export links (``/export/<session_id>/<file>``).
    on_destroy : callable, optional
        Called (with this app) when the session ends.
    on_ready : callable, optional
        Called (with this app) when a browser has rendered the page (Bokeh's
        ``DocumentReady``); :attr:`shown` is then true.  A page fetched without a browser never
        gets there.
    """

    def __init__(self, doc, mech, *, pose=None, load=None, max_mode: int = 2, session_id: str | None = None,
                 on_destroy: Callable[["ExplorerApp"], None] | None = None,
                 on_ready: Callable[["ExplorerApp"], None] | None = None) -> None:
        self.doc = doc
        self.mech = mech
        self.state = ExplorerState(mech, pose, load=load, max_mode=max_mode)
        self.session_id = session_id or "local"
        self.on_destroy = on_destroy
        self.on_ready = on_ready
        self.shown = False  # a browser rendered this session's page
        self.alive = True
        self.cache = ShapeCache()
        self.worker = Worker(on_error=self._error_from_thread)
        self.ws_job: WorkspaceJob | None = None
        self.ws_result: Any = None
        self.ws_key: tuple | None = None
        self._sel_token = 0
        self._syncing = False
        self._dragging = False
        self._grab = (0.0, 0.0)
        self._pending_target: tuple[float, float, float] | None = None
        self._move_scheduled = False
        self._warmed = False
        self._ws_last_progress = 0.0
        #: timings (s) of the last callbacks, for benchmarks: "move", "apply"
        self.timings: dict[str, deque[float]] = {k: deque(maxlen=2000) for k in ("move", "apply", "solve")}
        self._build()
        doc.title = f"flexkin explore: {mech.name}"
        doc.add_root(self.layout)
        doc.on_session_destroyed(self._session_destroyed)
        doc.on_event(DocumentReady, self._document_ready)
        self._render()
        self._solve_async()

    # ------------------------------------------------------------------------------------------
    # construction
    # ------------------------------------------------------------------------------------------
    def _build(self) -> None:
        mech, st = self.mech, self.state
        x0, x1, y0, y1 = pose_bounds(mech, st.pose)
        self.bounds = (x0, x1, y0, y1)
        w, h = x1 - x0, y1 - y0
        if w >= h:
            fw, fh = FRAME_MAX, max(200, int(round(FRAME_MAX * h / w)))
        else:
            fw, fh = max(200, int(round(FRAME_MAX * w / h))), FRAME_MAX
        p = figure(name="plot", x_range=Range1d(x0, x1), y_range=Range1d(y0, y1), frame_width=fw, frame_height=fh,
                   tools="pan,wheel_zoom,reset", active_drag=None, active_scroll="wheel_zoom", match_aspect=True,
                   x_axis_label="X [m]", y_axis_label="Y [m]", toolbar_location="above",
                   title=f"{mech.name} [{mech.kind}]")
        p.grid.grid_line_alpha = 0.4
        self.plot = p
        src = {k: ColumnDataSource(v, name=k) for k, v in empty_scene().items()}
        self.sources = src
        self._sent: dict[str, dict[str, list]] = dict(empty_scene())  # what the page has, by source name
        self.overlay_src = ColumnDataSource({"image": [], "x": [], "y": [], "dw": [], "dh": []}, name="overlay")
        base = base_layers(mech)
        guides = ColumnDataSource(base["guides"], name="guides")
        origins = ColumnDataSource(base["origins"], name="origins")
        p.image_rgba(image="image", x="x", y="y", dw="dw", dh="dh", source=self.overlay_src, level="underlay")
        p.multi_line("xs", "ys", source=guides, line_color="color", line_width=7, line_alpha=0.45)
        p.scatter("x", "y", source=origins, size=9, fill_color="white", line_color=BASE_COLOR, line_width=1.5)
        p.text("lx", "ly", text="label", source=origins, text_color="color", text_font_style="bold",
               text_align="center", text_baseline="middle", text_font_size="13px")
        solid = p.multi_line("xs", "ys", source=src["rods_solid"], line_color="color", line_width=1.3, line_alpha=0.5)
        dashed = p.multi_line("xs", "ys", source=src["rods_dashed"], line_color="color", line_width=1.3,
                              line_alpha=0.5, line_dash="dashed")
        p.patches("xs", "ys", source=src["platforms"], fill_color=PLATFORM_FILL, fill_alpha="fill_alpha",
                  line_color=PLATFORM_LINE, line_alpha="line_alpha")
        p.patches("xs", "ys", source=src["handle"], fill_color=PLATFORM_FILL, fill_alpha=0.9, line_color=PLATFORM_LINE,
                  line_width=1.5)
        sel = p.multi_line("xs", "ys", source=src["rods_selected"], line_color="color", line_width=3.5)
        p.scatter("x", "y", source=src["clamps"], marker="square", size=10, fill_color="color", line_color="black")
        p.scatter("x", "y", source=src["joints"], size=7, fill_color="white", line_color=PLATFORM_LINE, line_width=1.3)
        p.scatter("px", "py", source=src["handle"], marker="x", size=12, line_color=PLATFORM_LINE, line_width=2.5)
        p.add_tools(HoverTool(renderers=[solid, dashed, sel], tooltips=[("solution", "#@sid"), ("leg", "@leg")],
                              line_policy="nearest"))
        p.on_event(PanStart, self._on_pan_start)
        p.on_event(Pan, self._on_pan)
        p.on_event(PanEnd, self._on_pan_end)
        p.on_event(Tap, self._on_tap)

        # ---- controls --------------------------------------------------------------------
        self.mode = RadioButtonGroup(labels=["IK: move the platform", "FK: move the inputs"], active=0, name="mode",
                                     width=PANEL_WIDTH)
        self.mode.on_change("active", self._on_mode)
        sx = _step_for(x1 - x0)
        self.sx = Slider(title="x [m]", start=x0, end=x1, value=float(st.pose[0]), step=sx, name="x",
                         format="0.000", width=PANEL_WIDTH)
        self.sy = Slider(title="y [m]", start=y0, end=y1, value=float(st.pose[1]), step=sx, name="y",
                         format="0.000", width=PANEL_WIDTH)
        th = math.degrees(st.pose[2])
        self.sth = Slider(title="theta [deg]", start=min(-180.0, th), end=max(180.0, th), value=th, step=0.5,
                          name="theta", format="0.0", width=PANEL_WIDTH)
        for s in (self.sx, self.sy, self.sth):
            s.on_change("value", self._on_pose_slider)
            s.on_change("value_throttled", self._on_release)
        self.su: list[Slider] = []
        for i, leg in enumerate(mech.legs):
            lo, hi = input_bounds(mech, i)
            unit = leg.input_unit
            s = Slider(title=f"u{i + 1} [{unit}] ({leg.actuation})", start=lo, end=hi, value=0.5 * (lo + hi),
                       step=0.1 if unit == "deg" else _step_for(hi - lo), name=f"u{i + 1}",
                       format="0.0" if unit == "deg" else "0.0000", width=PANEL_WIDTH)
            s.on_change("value", self._on_input_slider)
            s.on_change("value_throttled", self._on_release)
            self.su.append(s)
        self.load_in = []
        for lab, v, name in zip(("Fx [N]", "Fy [N]", "Mz [N m]"), st.load, ("Fx", "Fy", "Mz")):
            n = NumericInput(title=lab, value=float(v), mode="float", width=PANEL_WIDTH // 3 - 8, name=name)
            n.on_change("value", self._on_load)
            self.load_in.append(n)
        self.show = Select(title="draw", value="all", options=[("all", "all equilibria"), ("stable", "stable only"),
                                                               ("feasible", "feasible only"),
                                                               ("selected", "selected only")],
                           width=PANEL_WIDTH // 2 - 8, name="show")
        self.show.on_change("value", self._on_show)
        self.ws_toggle = Toggle(label="Workspace overlay", active=False, name="workspace", width=PANEL_WIDTH // 2 - 8,
                                button_type="default")
        self.ws_toggle.on_change("active", self._on_ws_toggle)
        self.status = Div(name="status", width=PANEL_WIDTH)
        self.notice = Div(name="notice", width=PANEL_WIDTH)
        self.ws_status = Div(name="ws_status", width=PANEL_WIDTH)
        self.events = Div(name="events", width=PANEL_WIDTH, height=190,
                          styles={"overflow-y": "auto", "border": "1px solid #ddd", "padding": "4px",
                                  "font-size": "12px"})
        self.exports = Div(name="exports", width=PANEL_WIDTH, text=self._export_links())
        help_text = ("<b>Drag the platform</b> (blue triangle) or use the sliders; a slider or a drag tracks the "
                     "selected equilibrium continuously, release solves for all of them. <b>Click</b> a rod or a "
                     "table row to select an equilibrium. Bold: selected (rods in leg colours 1 blue, 2 orange, "
                     "3 green); thin: the others in their d-mode colour, dashed if not stable.")
        self.help = Div(text=f"<div style='font-size:12px;color:#444'>{help_text}</div>", width=PANEL_WIDTH)
        cols = [
            TableColumn(field="id", title="#", width=32),
            TableColumn(field="modes", title="d-modes", width=58),
        ]
        for i, leg in enumerate(mech.legs):
            fmt = NumberFormatter(format="0.00" if leg.input_unit == "deg" else "0.00000")
            cols.append(TableColumn(field=f"u{i + 1}", title=f"u{i + 1} [{leg.input_unit}]", formatter=fmt, width=82))
        self.pose_cols = [
            TableColumn(field="x", title="x [m]", formatter=NumberFormatter(format="0.00000"), width=78, visible=False),
            TableColumn(field="y", title="y [m]", formatter=NumberFormatter(format="0.00000"), width=78, visible=False),
            TableColumn(field="theta", title="theta [deg]", formatter=NumberFormatter(format="0.00"), width=78,
                        visible=False),
        ]
        self.input_cols = cols[2:]
        cols += self.pose_cols
        cols += [
            TableColumn(field="stable", title="stability", width=74),
            TableColumn(field="margin", title="margin", width=70),
            TableColumn(field="det_ik", title="det J_IK", width=74),
            TableColumn(field="det_fk", title="det J_FK", width=74),
            TableColumn(field="feasible", title="feasible", width=300),
        ]
        self.table_src = ColumnDataSource(self.state.rows(), name="table_source")
        self.table = DataTable(source=self.table_src, columns=cols, name="table", selectable=True,
                               index_position=None, width=fw + 90 + PANEL_WIDTH, height=260, sortable=False)
        self.table_src.selected.on_change("indices", self._on_table_select)
        title = Div(text=(f"<h2 style='margin:4px 0'>flexkin explore &mdash; {html.escape(mech.name)}</h2>"
                          f"<div style='color:#555'>{html.escape(mech.kind)}; all equilibria up to d-mode "
                          f"{st.max_mode}</div>"), name="title")
        ik_box = column(self.sx, self.sy, self.sth, name="ik_box")
        fk_box = column(*self.su, name="fk_box")
        self.ik_box, self.fk_box = ik_box, fk_box
        fk_box.visible = False
        panel = column(self.mode, ik_box, fk_box, row(*self.load_in), row(self.show, self.ws_toggle),
                       self.status, self.notice, self.ws_status, self.events, self.exports, self.help,
                       width=PANEL_WIDTH)
        self.layout = column(title, row(p, panel), self.table, name="root")

    # ------------------------------------------------------------------------------------------
    # rendering
    # ------------------------------------------------------------------------------------------
    def _export_links(self) -> str:
        base = f"/export/{self.session_id}"
        links = [("figure.png", "Figure PNG"), ("figure.svg", "Figure SVG"), ("solutions.json", "Solutions JSON"),
                 ("rods.csv", "Rod shapes CSV")]
        a = " &middot; ".join(f"<a href='{base}/{f}' download='flexkin_{f}' class='export' data-file='{f}'>{t}</a>"
                              for f, t in links)
        return f"<div style='font-size:13px'>Export: {a}</div>"

    def _push(self, source: ColumnDataSource, data: dict[str, list]) -> bool:
        """Give ``source`` new ``data`` only if it differs from what the page has: Bokeh sends
        a whole data source to the browser on every assignment, equal or not, so a drag without
        a selection re-sent every drawn equilibrium with each move (~250 kB per move with 54
        equilibria).  Returns whether anything was sent."""
        if self._sent.get(source.name) == data:
            return False
        if source.name in ROD_LAYERS:
            data_out = {k: [np.asarray(v, dtype=float) for v in col] if k in ("xs", "ys") else col
                        for k, col in data.items()}
        else:
            data_out = data
        source.data = data_out
        self._sent[source.name] = data
        return True

    def _render(self, table: bool = True) -> None:
        """Push what changed in the state into the document (call on the document's thread)."""
        st = self.state
        for name, data in scene(st, self.cache).items():
            self._push(self.sources[name], data)
        self._render_status()
        if table:
            self._render_table()
        self._render_log()

    def _render_status(self) -> None:
        st = self.state
        text = html.escape(st.status())
        color = "#b30000" if text.startswith("No equilibrium") else ("#555" if st.stale else "#111")
        sel = html.escape(st.selection_text())
        self.status.text = (f"<div class='status' style='font-size:15px;font-weight:bold;color:{color}'>{text}</div>"
                            f"<div class='selection' style='font-size:13px;color:#222'>{sel}</div>")
        self.notice.text = (f"<div class='notice' style='color:#8a4b00;font-size:13px'>{html.escape(st.notice)}</div>"
                            if st.notice else "")

    def _render_table(self) -> None:
        st = self.state
        rows = st.rows()
        picked = [i for i, s in enumerate(rows["selected"]) if s]
        changed = self._sent.get(self.table_src.name) != rows
        if not changed and list(self.table_src.selected.indices) == picked:
            return
        self._syncing = True
        try:
            if changed:
                # clear the selection first: the browser's table remembers selected rows that a
                # shorter list hides and restores them when the list grows again (an echo of an
                # old row index, i.e. of another solution)
                self.table_src.selected.indices = []
                # the table redraws when its row count changes; new values in as many rows are
                # not redrawn (bokeh 3.9, cf. bokeh issue 13859): pass through an empty table
                self.table_src.data = {k: [] for k in rows}
                self.table_src.data = rows
                self._sent[self.table_src.name] = rows
            self.table_src.selected.indices = picked
        finally:
            self._syncing = False

    def _render_log(self) -> None:
        lines = []
        for e in reversed(self.state.log[-LOG_LINES:]):
            col = EVENT_COLORS.get(e.kind, "#333")
            lines.append(f"<div class='ev ev-{e.kind}' style='color:{col}'>{e.seq}. "
                         f"{html.escape(e.text(self.mech))}</div>")
        body = "".join(lines) or "<div style='color:#888'>Events along the tracked branch appear here.</div>"
        self.events.text = f"<div class='events'><b>Events</b>{body}</div>"

    def _sync_sliders(self) -> None:
        st = self.state
        self._syncing = True
        try:
            if st.mode == "ik":
                for s, v in zip((self.sx, self.sy), st.pose[:2]):
                    s.start, s.end = min(s.start, float(v)), max(s.end, float(v))
                    s.value = float(v)
                th = math.degrees(st.pose[2])
                th = (th + 180.0) % 360.0 - 180.0 if abs(th) > 180.0 else th
                self.sth.value = th
            elif st.inputs is not None:
                for i, (s, u) in enumerate(zip(self.su, st.inputs)):
                    v = float(self.mech.legs[i].to_display(u))
                    lo, hi = input_bounds(self.mech, i, v)
                    s.start, s.end = min(s.start, lo), max(s.end, hi)
                    s.value = v
        finally:
            self._syncing = False

    # ------------------------------------------------------------------------------------------
    # background work
    # ------------------------------------------------------------------------------------------
    def _later(self, fn: Callable, *args: Any) -> None:
        """Run ``fn(*args)`` on the document's thread (safe from any thread)."""
        if not self.alive:
            return
        try:
            self.doc.add_next_tick_callback(partial(fn, *args))
        except Exception:  # noqa: BLE001 - the session is going away
            pass

    def _error_from_thread(self, e: BaseException) -> None:
        self._later(self._show_error, f"{type(e).__name__}: {e}")

    def _show_error(self, msg: str) -> None:
        self.state.notice = f"Internal error: {msg}"
        self._render(table=False)

    def _solve_async(self) -> None:
        req = self.state.request()
        mech = self.mech
        self.worker.submit("solve", lambda cancelled: solve(mech, req), lambda out: self._later(self._on_solved, out))

    def _on_solved(self, out) -> None:
        t0 = time.perf_counter()
        applied = self.state.apply(out)
        self.timings["solve"].append(out.elapsed)
        self._render()
        self.timings["apply"].append(time.perf_counter() - t0)
        if not applied:
            return
        self._sync_sliders()
        st = self.state
        sols, serial = st.solutions, st.serial
        if sols:
            mech = self.mech
            self.worker.submit("feasibility", lambda cancelled: feasibility_of(mech, sols, cancelled),
                               lambda feas: self._later(self._on_feasibility, serial, feas))
            if not self._warmed:
                seed = next((s for s in sols if s.stable), sols[0])
                load = st.load
                self._warmed = True
                self.worker.submit("warmup", lambda cancelled: warm_up(mech, seed, load), lambda _t: None)
        self._maybe_workspace()

    def _on_feasibility(self, serial: int, feas) -> None:
        if self.state.apply_feasibility(serial, feas):
            self._render_table()
            self._render_status()
            if self.state.show == "feasible":
                self._render(table=False)

    # ------------------------------------------------------------------------------------------
    # moving: pointer and sliders
    # ------------------------------------------------------------------------------------------
    def _queue_move(self, target: tuple[float, float, float]) -> None:
        self._pending_target = target
        if not self._move_scheduled:
            self._move_scheduled = True
            self.doc.add_next_tick_callback(self._flush_move)

    def _flush_move(self) -> None:
        self._move_scheduled = False
        tgt, self._pending_target = self._pending_target, None
        if tgt is None:
            return
        t0 = time.perf_counter()
        out = self.state.move(tgt)
        if self.state.mode == "ik":
            self._hide_stale_overlay()
        self._render(table=out.tracked)
        if self._dragging:
            self._sync_sliders()
        self.timings["move"].append(time.perf_counter() - t0)
        if out.needs_solve:
            self._solve_async()

    def _release(self) -> None:
        if self._pending_target is not None:
            self._flush_move()
        self._solve_async()

    def _inside_handle(self, x: float, y: float) -> bool:
        st = self.state
        if st.mode != "ik":
            return False
        B = np.asarray(self.mech.platform.world(st.pose), dtype=float)
        px_per_m = self.plot.frame_width / max(self.plot.x_range.end - self.plot.x_range.start, 1e-12)
        tol = 14.0 / px_per_m
        pts = np.vstack([B, st.pose[:2]])
        if np.min(np.hypot(pts[:, 0] - x, pts[:, 1] - y)) <= tol:
            return True
        # inside the triangle
        a, b, c = B
        def side(p, q, r):  # noqa: E306
            return (q[0] - p[0]) * (r[1] - p[1]) - (q[1] - p[1]) * (r[0] - p[0])
        s1, s2, s3 = side(a, b, (x, y)), side(b, c, (x, y)), side(c, a, (x, y))
        return (s1 >= 0 and s2 >= 0 and s3 >= 0) or (s1 <= 0 and s2 <= 0 and s3 <= 0)

    def _on_pan_start(self, ev) -> None:
        self._dragging = self._inside_handle(ev.x, ev.y)
        if self._dragging:
            self._grab = (float(self.state.pose[0] - ev.x), float(self.state.pose[1] - ev.y))

    def _on_pan(self, ev) -> None:
        if not self._dragging:
            return
        self._queue_move((ev.x + self._grab[0], ev.y + self._grab[1], float(self.state.pose[2])))

    def _on_pan_end(self, ev) -> None:
        if not self._dragging:
            return
        self._queue_move((ev.x + self._grab[0], ev.y + self._grab[1], float(self.state.pose[2])))
        self._dragging = False
        self._release()

    def _on_tap(self, ev) -> None:
        if self._inside_handle(ev.x, ev.y) or self.state.stale:
            return
        px_per_m = self.plot.frame_width / max(self.plot.x_range.end - self.plot.x_range.start, 1e-12)
        sid = self.state.pick(ev.x, ev.y, 8.0 / px_per_m)
        if sid is not None:
            self._select(sid)

    def _on_pose_slider(self, attr, old, new) -> None:
        if self._syncing or self.state.mode != "ik":
            return
        th = math.radians(float(self.sth.value))
        th += 2.0 * math.pi * round((float(self.state.pose[2]) - th) / (2.0 * math.pi))  # the slider shows theta
        self._queue_move((float(self.sx.value), float(self.sy.value), th))              # mod 360: no full turns

    def _on_input_slider(self, attr, old, new) -> None:
        if self._syncing or self.state.mode != "fk":
            return
        u = [float(leg.from_display(s.value)) for s, leg in zip(self.su, self.mech.legs)]
        self._queue_move(tuple(u))  # type: ignore[arg-type]

    def _on_release(self, attr, old, new) -> None:
        if self._syncing:
            return
        self._release()

    # ------------------------------------------------------------------------------------------
    # other controls
    # ------------------------------------------------------------------------------------------
    def _select(self, sid: int | None) -> None:
        try:
            self.state.select(sid)
        except ValueError as e:
            self.state.notice = str(e)
        self._sel_token += 1
        self._render()
        self._maybe_workspace()

    def _on_table_select(self, attr, old, new) -> None:
        if self._syncing or len(new) != 1:  # a click selects one row; anything else is the table's own echo
            return
        ids = self.table_src.data["id"]
        i = new[0]
        if 0 <= i < len(ids) and ids[i] != self.state.selected_id and not self.state.stale:
            self._select(int(ids[i]))

    def _on_mode(self, attr, old, new) -> None:
        mode = "ik" if new == 0 else "fk"
        self.state.set_mode(mode)
        self.ik_box.visible = mode == "ik"
        self.fk_box.visible = mode == "fk"
        for c in self.input_cols:  # IK lists the inputs of each solution, FK its pose
            c.visible = mode == "ik"
        for c in self.pose_cols:
            c.visible = mode == "fk"
        self._sync_sliders()
        self._hide_stale_overlay(force=True)
        self._render()
        self._solve_async()

    def _on_load(self, attr, old, new) -> None:
        try:
            self.state.set_load([float(n.value if n.value is not None else 0.0) for n in self.load_in])
        except ValueError as e:
            self.state.notice = str(e)
            self._render(table=False)
            return
        if self.state.stale:
            self._render()
            self._solve_async()

    def _on_show(self, attr, old, new) -> None:
        self.state.set_show(new)
        self._render(table=False)

    # ------------------------------------------------------------------------------------------
    # workspace overlay
    # ------------------------------------------------------------------------------------------
    def _ws_wanted_key(self) -> tuple | None:
        st = self.state
        s = st.selected
        if s is None or st.stale:
            return None
        return (round(float(s.pose[2]), 9), st.load, self._sel_token, st.mode)

    def _hide_stale_overlay(self, force: bool = False) -> None:
        if self.ws_key is None:
            return
        st = self.state
        if force or st.mode != "ik" or abs(float(st.pose[2]) - self.ws_key[0]) > 1e-9:
            self.overlay_src.data = {"image": [], "x": [], "y": [], "dw": [], "dh": []}
            self.ws_key = None

    def _maybe_workspace(self) -> None:
        if not self.ws_toggle.active:
            return
        key = self._ws_wanted_key()
        if key is None:
            if self.state.selected is None and not self.state.stale:
                self.ws_status.text = ("<div class='ws' style='font-size:13px'>Workspace: select an equilibrium "
                                       "to map its aspect.</div>")
            return
        if key == self.ws_key or (self.ws_job is not None and getattr(self.ws_job, "key", None) == key
                                  and not self.ws_job.done):
            return
        if self.ws_job is not None:
            self.ws_job.cancel()
        x0, x1, y0, y1 = self.bounds
        job = WorkspaceJob(self.mech, self.state.selected, load=self.state.load, bounds=(x0, x1, y0, y1),
                           time_budget=60.0, on_progress=lambda j: self._later(self._ws_progress, j),
                           on_done=lambda j: self._later(self._ws_done, j))
        job.key = key  # type: ignore[attr-defined]
        job.sid = self.state.selected_id  # type: ignore[attr-defined]
        self.ws_job = job
        self.ws_status.text = "<div class='ws' style='font-size:13px'>&#8987; Workspace: starting...</div>"
        job.start()

    def _ws_progress(self, job: WorkspaceJob) -> None:
        if job is not self.ws_job or job.done:
            return
        now = time.perf_counter()
        if now - self._ws_last_progress < WS_PROGRESS_INTERVAL:
            return
        self._ws_last_progress = now
        self.ws_status.text = (f"<div class='ws' style='font-size:13px'>&#8987; Workspace: computing... "
                               f"{job.steps} continuation steps, {job.elapsed:.1f} s</div>")

    def _ws_done(self, job: WorkspaceJob) -> None:
        if job is not self.ws_job or not self.ws_toggle.active:
            return
        if job.error or job.result is None:
            self.ws_status.text = (f"<div class='ws' style='font-size:13px;color:#b30000'>Workspace failed: "
                                   f"{html.escape(job.error)}</div>")
            return
        ov = overlay(job.result)
        cells = ov.pop("cells")
        self.overlay_src.data = ov
        self.ws_result, self.ws_key = job.result, job.key  # type: ignore[attr-defined]
        msg = f" ({html.escape(job.result.message)})" if job.result.message else ""
        self.ws_status.text = (
            f"<div class='ws ws-done' style='font-size:13px'>Workspace of #{job.sid}'s aspect at "  # type: ignore
            f"theta = {math.degrees(job.theta):.1f} deg: {cells} cells reached in {job.elapsed:.1f} s{msg}. "
            "Black: IK-singularity boundary; orange: FK-singularity / instability boundary.</div>")

    def _on_ws_toggle(self, attr, old, new) -> None:
        if new:
            self._maybe_workspace()
        else:
            if self.ws_job is not None:
                self.ws_job.cancel()
            self.ws_job = None
            self.overlay_src.data = {"image": [], "x": [], "y": [], "dw": [], "dh": []}
            self.ws_key, self.ws_result = None, None
            self.ws_status.text = ""

    # ------------------------------------------------------------------------------------------
    # exports and lifetime
    # ------------------------------------------------------------------------------------------
    def snapshot(self) -> tuple[ExplorerState, Any]:
        """A consistent copy of the state (and the workspace shown) for an export in another
        thread: the state's fields are replaced, never mutated in place, by the callbacks."""
        import copy

        snap = copy.copy(self.state)
        snap.log = list(self.state.log)
        ws = self.ws_result if self.ws_key is not None else None
        return snap, ws

    def close(self) -> None:
        """Stop the background work of this session."""
        self.alive = False
        self.worker.stop()
        if self.ws_job is not None:
            self.ws_job.cancel()

    def _document_ready(self, event) -> None:
        self.shown = True
        if self.on_ready is not None:
            self.on_ready(self)

    def _session_destroyed(self, session_context) -> None:
        self.close()
        if self.on_destroy is not None:
            self.on_destroy(self)

