"""``flexkin explore``: an interactive explorer of all equilibria, in the browser.

The package is split by job so that everything but the web layer is testable without a
browser and without the web library installed:

* :mod:`~flexkin.explore.state` -- the app's state and logic (solving, tracking, events,
  matching solutions across updates, FK mode, no-solution handling); no web import;
* :mod:`~flexkin.explore.scene` -- the drawing data (rod polylines, platforms, colours);
* :mod:`~flexkin.explore.jobs` -- background work (latest-request-wins solver thread, the
  workspace overlay with progress and cancellation);
* :mod:`~flexkin.explore.export` -- figure (PNG/SVG), solutions (JSON) and rod shapes (CSV);
* :mod:`~flexkin.explore.app` -- the Bokeh document (widgets, figure, callbacks);
* :mod:`~flexkin.explore.server` -- start / stop of the Bokeh server, export downloads,
  exit when the last tab closes or on Ctrl-C;
* :mod:`~flexkin.explore.cli` -- ``flexkin explore MECH.toml [--port P] [--no-browser]``;

Only :mod:`~flexkin.explore.app` and :mod:`~flexkin.explore.server` import Bokeh.
"""

from __future__ import annotations

__all__ = ["ExplorerState"]


def __getattr__(name: str):
    if name == "ExplorerState":
        from .state import ExplorerState

        return ExplorerState
    raise AttributeError(f"module 'flexkin.explore' has no attribute {name!r}")
