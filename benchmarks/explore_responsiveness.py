"""Responsiveness of the explorer, measured in-process (a row of ``benchmarks/bench.py``; run
``python benchmarks/explore_responsiveness.py MECH.toml`` alone for the JSON).

:func:`responsiveness` replays what the server does for a user who drags the platform of a
selected equilibrium and then releases it:

* *track*: one slider / pointer change -> :meth:`ExplorerState.move` (the tracker's
  continuation) -> the drawing data (:func:`~flexkin.explore.scene.scene`) and the table rows;
  target <= 50 ms;
* *refresh*: release -> the full IK (:func:`~flexkin.explore.state.solve`) -> applied to the
  state (matching the tracked equilibrium) -> drawing data and table; target <= 150 ms.
  The feasibility column is filled afterwards in the background; its time is reported apart.

It needs no web library.  Call it as ``responsiveness("examples/prototype_3pfr.toml")``.
"""

from __future__ import annotations

import math
import os
import statistics
import time
from typing import Any, Sequence

import numpy as np

__all__ = ["responsiveness", "TARGET_TRACK_MS", "TARGET_REFRESH_MS"]

TARGET_TRACK_MS = 50.0
TARGET_REFRESH_MS = 150.0


def _stats(ms: list[float]) -> dict[str, float]:
    a = np.asarray(ms, dtype=float)
    return {"median_ms": float(np.median(a)), "p90_ms": float(np.percentile(a, 90)), "max_ms": float(a.max()),
            "n": int(a.size)}


def responsiveness(mech_path: str | os.PathLike[str], pose: Sequence[float] | None = None, *, moves: int = 60,
                   step: float | None = None, refreshes: int = 5) -> dict[str, Any]:
    """Median (and p90, max) server-side times of a tracked move and of a full refresh.

    Parameters
    ----------
    mech_path : path of a mechanism file.
    pose : start pose (m, m, rad); default (0, 0.3, 90 deg) for the prototype-sized
        mechanisms, i.e. the base centroid shifted by a third of the length scale.
    moves : number of tracked moves (a drag back and forth).
    step : length of one move (m); default 1/400 of the length scale (about a pixel of a
        600-pixel view of the mechanism's box at a brisk drag).
    refreshes : number of full refreshes timed.

    Returns
    -------
    dict with ``track`` and ``refresh`` (``median_ms``, ``p90_ms``, ``max_ms``, ``n``),
    ``refresh_solver_median_ms`` (the part of a refresh spent in :func:`flexkin.ik`),
    ``feasibility`` (ms for the whole solution list, in the background), ``n_solutions``,
    ``targets_ms``, ``met`` (booleans), ``cores``, ``warmup_s`` (first solve and first move,
    including the one-off kernel loading).
    """
    import flexkin

    from flexkin.explore.scene import ShapeCache, scene
    from flexkin.explore.state import ExplorerState, feasibility_of

    mech = flexkin.load_mechanism(mech_path)
    L = float(mech.length_scale)
    if pose is None:
        c = np.asarray(mech.base_centroid, dtype=float)
        pose = (float(c[0]), float(c[1]) + L / 3.0, math.pi / 2)
    h = step if step is not None else L / 400.0
    t0 = time.perf_counter()
    st = ExplorerState(mech, pose)
    st.refresh()
    if not st.solutions:
        raise ValueError(f"no equilibrium at the start pose {tuple(pose)}: give another pose")
    sel = next((s for s in st.solutions if s.stable), st.solutions[0])
    st.select(sel.id)
    cache = ShapeCache()
    st.move(st.pose + np.array([h, 0.0, 0.0]))  # loads the tracker's kernels
    st.refresh()
    warm = time.perf_counter() - t0

    track: list[float] = []
    p0 = np.array(st.pose, dtype=float)
    half = max(1, moves // 2)
    path = [p0 + np.array([h * k, 0.0, 0.0]) for k in range(1, half + 1)]
    path += [p0 + np.array([h * k, 0.0, 0.0]) for k in range(half - 1, half - 1 - (moves - half), -1)]
    for tgt in path:
        t = time.perf_counter()
        out = st.move(tgt)
        scene(st, cache)
        st.rows()
        track.append(1e3 * (time.perf_counter() - t))
        if out.needs_solve:  # the branch ended: solve, pick the nearest stable one again
            st.refresh()
            if not st.solutions:
                break
            st.select(next((s for s in st.solutions if s.stable), st.solutions[0]).id)

    refresh: list[float] = []
    solve_ms: list[float] = []
    feas: list[float] = []
    n_sol = 0
    for k in range(refreshes):
        st.move(np.array(st.pose) + np.array([0.0, h * (1 if k % 2 else -1), 0.0]))
        t = time.perf_counter()
        out = st.refresh()
        scene(st, cache)
        st.rows()
        refresh.append(1e3 * (time.perf_counter() - t))
        solve_ms.append(1e3 * out.elapsed)
        n_sol = len(st.solutions)
        t = time.perf_counter()
        feasibility_of(mech, st.solutions)
        feas.append(1e3 * (time.perf_counter() - t))
        if st.selected is None and st.solutions:
            st.select(next((s for s in st.solutions if s.stable), st.solutions[0]).id)
    tr, rf = _stats(track), _stats(refresh)
    return {
        "mechanism": mech.name,
        "pose": [float(pose[0]), float(pose[1]), float(math.degrees(pose[2]))],
        "track": tr,
        "refresh": rf,
        "refresh_solver_median_ms": float(statistics.median(solve_ms)),  # flexkin.ik alone, inside "refresh"
        "feasibility": {"median_ms": float(statistics.median(feas)), "n_solutions": n_sol},
        "n_solutions": n_sol,
        "targets_ms": {"track": TARGET_TRACK_MS, "refresh": TARGET_REFRESH_MS},
        "met": {"track": tr["median_ms"] <= TARGET_TRACK_MS, "refresh": rf["median_ms"] <= TARGET_REFRESH_MS},
        "cores": os.cpu_count(),
        "warmup_s": warm,
    }


if __name__ == "__main__":  # pragma: no cover
    import json
    import sys

    print(json.dumps(responsiveness(sys.argv[1] if len(sys.argv) > 1 else "examples/prototype_3pfr.toml"), indent=2))
