"""Starting and stopping the explorer's Bokeh server.

:class:`ExplorerServer` serves one :class:`~flexkin.explore.app.ExplorerApp` per browser tab
at ``http://localhost:PORT/`` (bound to localhost by default), and the exports at
``/export/<session>/<file>``.  :meth:`ExplorerServer.run` blocks until

* Ctrl-C (SIGINT) or SIGTERM, or
* the last open tab was closed (its session ends about two seconds later; a reload within
  :attr:`ExplorerServer.idle_grace` seconds keeps the server).  Only a page that a browser
  rendered counts as a tab (it reports Bokeh's ``DocumentReady``): a page fetched without a
  browser (curl, a link preview) opens a session that ends unused, and that does not stop the
  server; or
* :meth:`ExplorerServer.stop` is called (from any thread),

then stops the background work of every session and closes the listening socket.  Background
threads are daemons, so no process or thread outlives the command.

**Host check.**  Every request (page, websocket, exports) whose ``Host`` header does not name
this machine's loopback (``localhost``, ``127.0.0.1``, ``[::1]``) is answered with 403.  A
page on another site whose name an attacker re-binds to 127.0.0.1 (DNS rebinding) sends its own
name as ``Host`` and as ``Origin``; without the check it could open sessions (each one runs a
full solve) and read their exports, since the browser treats it as the same origin.
"""

from __future__ import annotations

import signal
import sys
import threading
from typing import Any, Callable

from bokeh.application import Application
from bokeh.application.handlers.function import FunctionHandler
from bokeh.server.server import BaseServer
from bokeh.server.tornado import BokehTornado
from bokeh.server.util import bind_sockets, create_hosts_allowlist
from tornado.httpserver import HTTPServer
from tornado.ioloop import IOLoop
from tornado.web import HTTPError, RequestHandler

from .app import ExplorerApp
from .export import EXPORTS, export

__all__ = ["ExplorerServer", "serve", "DEFAULT_PORT"]

DEFAULT_PORT = 5006
#: the ``Host`` names the server answers (loopback only; module docstring)
LOCAL_HOSTS = ("localhost", "127.0.0.1", "[::1]")
#: tornado host pattern of every other name (matched against the Host header without its port)
_FOREIGN_HOST = r"(?!(?:localhost|127\.0\.0\.1|\[::1\])$).*"


class _ForeignHostHandler(RequestHandler):
    """Any request with a foreign ``Host`` header: 403 (module docstring)."""

    def prepare(self) -> None:
        raise HTTPError(403, reason="Forbidden: this explorer answers localhost only")


class _ExportHandler(RequestHandler):
    """GET /export/<session>/<file>: one of :data:`~flexkin.explore.export.EXPORTS` of that
    session's current state, computed off the event loop."""

    def initialize(self, server: "ExplorerServer") -> None:
        self.server = server

    async def get(self, sid: str, name: str) -> None:
        app = self.server.apps.get(sid)
        if app is None or name not in EXPORTS:
            raise HTTPError(404)
        snap, ws = app.snapshot()
        data, ctype = await IOLoop.current().run_in_executor(None, export, snap, name, ws)
        self.set_header("Content-Type", ctype)
        self.set_header("Content-Disposition", f'attachment; filename="flexkin_{name}"')
        self.set_header("Cache-Control", "no-store")
        self.write(data)


class ExplorerServer:
    """The explorer's web server (see the module docstring).

    Parameters
    ----------
    mech : Mechanism
    port : int
        0 picks a free port.
    address : str
        Interface to bind (default ``"localhost"``).
    pose, load, max_mode : passed to each session's :class:`~flexkin.explore.state.ExplorerState`.
    exit_when_idle : bool
        Stop when the last tab has closed (after ``idle_grace`` seconds without a new one).
    log : callable
        Receives one-line messages for the user (default: print to stderr).
    """

    def __init__(self, mech, *, port: int = DEFAULT_PORT, address: str = "localhost", pose=None, load=None,
                 max_mode: int = 2, exit_when_idle: bool = True, idle_grace: float = 3.0,
                 log: Callable[[str], None] | None = None) -> None:
        self.mech = mech
        self.address = address
        self.requested_port = int(port)
        self.options = {"pose": pose, "load": load, "max_mode": max_mode}
        self.exit_when_idle = exit_when_idle
        self.idle_grace = float(idle_grace)
        self.log = log or (lambda m: print(m, file=sys.stderr, flush=True))
        self.apps: dict[str, ExplorerApp] = {}
        self.sessions_seen = 0
        self._tab_closed = False  # a browser tab closed and no browser has shown a page since
        self.stop_reason = ""
        self.server: BaseServer | None = None
        self._port = 0
        self.io_loop: IOLoop | None = None
        self._stopped = threading.Event()

    # ---- construction -----------------------------------------------------------------------
    def _make_document(self, doc) -> None:
        sid = doc.session_context.id if doc.session_context is not None else "local"
        app = ExplorerApp(doc, self.mech, session_id=sid, on_destroy=self._app_gone, on_ready=self._app_ready,
                          **self.options)
        self.apps[sid] = app
        self.sessions_seen += 1

    def start(self) -> "ExplorerServer":
        """Bind the port and prepare the server (on the calling thread's event loop); raises
        ``OSError`` if the port is taken.

        Assembled from Bokeh's public parts (``BokehTornado``, a tornado ``HTTPServer``,
        ``BaseServer``) rather than ``bokeh.server.server.Server``, so that the tornado
        application is ours to give the host check (module docstring) before Bokeh's routes."""
        app = Application(FunctionHandler(self._make_document))
        sockets, port = bind_sockets(self.address, self.requested_port)
        try:
            web = BokehTornado(
                {"/": app}, extra_websocket_origins=create_hosts_allowlist(None, port),
                extra_patterns=[(r"/export/([^/]+)/([A-Za-z0-9_.]+)", _ExportHandler, {"server": self})],
                unused_session_lifetime_milliseconds=1500, check_unused_sessions_milliseconds=500,
                keep_alive_milliseconds=10000,
            )
            # tornado tries host-specific rules before the catch-all one that holds Bokeh's routes
            web.add_handlers(_FOREIGN_HOST, [(r".*", _ForeignHostHandler)])
            http = HTTPServer(web)
            http.add_sockets(sockets)
        except Exception:
            for sock in sockets:
                sock.close()
            raise
        self._port = port
        self.server = BaseServer(IOLoop.current(), web, http)
        self.server.start()
        self.io_loop = self.server.io_loop
        return self

    @property
    def port(self) -> int:
        assert self.server is not None, "start() first"
        return self._port

    @property
    def url(self) -> str:
        return f"http://localhost:{self.port}/"

    # ---- lifetime ---------------------------------------------------------------------------
    def _app_ready(self, app: ExplorerApp) -> None:
        self._tab_closed = False

    def _app_gone(self, app: ExplorerApp) -> None:
        self.apps.pop(app.session_id, None)
        if app.shown:
            self._tab_closed = True
        if self.exit_when_idle and self._tab_closed and not self.apps and self.io_loop is not None:
            self.io_loop.call_later(self.idle_grace, self._idle_check)

    def _idle_check(self) -> None:
        if not self.apps and self.exit_when_idle and self._tab_closed:
            self._shutdown("the last browser tab was closed")

    def _shutdown(self, reason: str) -> None:
        if self._stopped.is_set():
            return
        self._stopped.set()
        self.stop_reason = reason
        for app in list(self.apps.values()):
            app.close()
        self.apps.clear()
        if self.server is not None:
            try:
                self.server.stop(wait=False)
            except Exception:  # noqa: BLE001 - stopping anyway
                pass
        if self.io_loop is not None:
            self.io_loop.stop()

    def stop(self, reason: str = "stopped") -> None:
        """Stop the server (thread-safe)."""
        if self.io_loop is not None:
            self.io_loop.add_callback(self._shutdown, reason)

    def run(self, on_ready: Callable[[], Any] | None = None) -> str:
        """Serve until stopped (see the module docstring); returns why it stopped.  Installs
        SIGINT / SIGTERM handlers when called on the main thread."""
        assert self.io_loop is not None, "start() first"
        old: dict[int, Any] = {}
        if threading.current_thread() is threading.main_thread():
            for sig in (signal.SIGINT, signal.SIGTERM):
                old[sig] = signal.getsignal(sig)
                signal.signal(sig, lambda signum, frame: self.io_loop.add_callback_from_signal(  # type: ignore
                    self._shutdown, "interrupted" if signum == signal.SIGINT else "terminated"))
        if on_ready is not None:
            self.io_loop.add_callback(on_ready)
        try:
            self.io_loop.start()
        finally:
            for sig, h in old.items():
                signal.signal(sig, h)
            self._shutdown(self.stop_reason or "stopped")
        return self.stop_reason


def serve(mech, *, port: int | None = None, open_browser: bool = True, pose=None, load=None, max_mode: int = 2,
          log: Callable[[str], None] | None = None) -> int:
    """Run ``flexkin explore``: start the server (port ``port``; ``None``: 5006, or a free port
    when it is taken), print its address, open it in the browser unless ``open_browser`` is
    false, and serve until Ctrl-C or the last tab closes.  Returns the exit status."""
    say = log or (lambda m: print(m, file=sys.stderr, flush=True))
    kw = dict(pose=pose, load=load, max_mode=max_mode, log=say)
    try:
        srv = ExplorerServer(mech, port=DEFAULT_PORT if port is None else port, **kw).start()
    except OSError as e:
        if port is not None:
            say(f"flexkin explore: cannot listen on localhost port {port}: {e.strerror or e}")
            return 2
        srv = ExplorerServer(mech, port=0, **kw).start()
    print(f"flexkin explore: {mech.name} at {srv.url} (Ctrl-C to stop; closing the last tab stops it too)",
          flush=True)

    def ready() -> None:
        if open_browser:
            import webbrowser

            threading.Thread(target=webbrowser.open, args=(srv.url,), daemon=True).start()

    reason = srv.run(on_ready=ready)
    say(f"flexkin explore: {reason}; server stopped")
    return 0
