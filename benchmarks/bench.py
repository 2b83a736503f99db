"""flexkin benchmark: medians of the operations users wait for.

Run:  python benchmarks/bench.py [--repeat N] [--quick]

Prints a table with the machine's core count.  Timings are wall-clock medians on one
process (numpy may use more than one thread for large arrays; set OMP_NUM_THREADS=1 for a
strict one-core figure).
"""

from __future__ import annotations

import argparse
import os
import statistics
import time
from pathlib import Path

import numpy as np

import flexkin
from flexkin.mechanism import symmetric_mechanism
from flexkin.rod.closed_form import tip_chart

ROOT = Path(__file__).resolve().parents[1]


def _median_time(fn, repeat: int) -> float:
    fn()  # warm-up (atlas, caches)
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__)
    ap.add_argument("--repeat", type=int, default=5)
    ap.add_argument("--quick", action="store_true", help="fewer repeats, skip the FK rows")
    a = ap.parse_args()
    rep = 2 if a.quick else a.repeat
    proto = flexkin.load_mechanism(ROOT / "examples" / "prototype_3pfr.toml")
    rfr = symmetric_mechanism("revolute")
    rows = []

    rng = np.random.default_rng(0)
    n = 100_000
    v = rng.uniform(-8, 8, n)
    ph = rng.uniform(-4.7, 1.5, n)
    t = _median_time(lambda: tip_chart(v, ph), rep)
    rows.append(("closed-form rod tip, vectorised", f"{1e9 * t / n:.0f} ns / rod", f"{n} rods per call"))

    t = _median_time(lambda: flexkin.solve_rod((0.6, -0.2125), 0.908, 0.2704), rep)
    rows.append(("single-rod inverse (all equilibria, q<=2)", f"{1e3 * t:.1f} ms", "Fig. 19 point x=0.6 m"))

    for name, mech, pose in (("prototype 3-PFR", proto, (0.0, 0.0, np.radians(90))),
                             ("unit 3-RFR", rfr, (0.05, 0.02, np.radians(20)))):
        t = _median_time(lambda: flexkin.ik(mech, pose), rep)
        nsol = len(flexkin.ik(mech, pose))
        rows.append((f"full IK, max_mode 2, {name}", f"{1e3 * t:.0f} ms", f"{nsol} solutions"))
    if not a.quick:
        for name, mech, u in (("prototype 3-PFR", proto, (0.025, 0.025, 0.025)),
                              ("unit 3-RFR", rfr, tuple(flexkin.ik(rfr, (0.05, 0.02, np.radians(20))).solutions[0].inputs))):
            t = _median_time(lambda: flexkin.fk(mech, u), max(1, rep // 2))
            nsol = len(flexkin.fk(mech, u))
            rows.append((f"full FK, max_mode 2, {name}", f"{t:.2f} s", f"{nsol} solutions"))

    # continuation and workspace (paper §6)
    from flexkin.kinematics.continuation import continue_ik
    from flexkin.kinematics.system import MechArrays
    from flexkin.workspace import workspace

    m = MechArrays.from_mechanism(proto)
    sol = [s for s in flexkin.ik(proto, (0.0, 0.0, np.radians(90))).solutions if s.stable][0]
    x0 = np.concatenate([sol.zrod, sol.inputs])
    for batch in (1, 200):
        X0 = np.repeat(x0[None], batch, 0)
        p0 = np.repeat(np.array([[0.0, 0.0, np.radians(90)]]), batch, 0)
        p1 = p0 + np.array([0.01, 0.0, 0.0])
        t = _median_time(lambda: continue_ik(m, X0, p0, p1, np.zeros(3)), rep)
        rows.append((f"continuation step, batch of {batch}", f"{1e6 * t / batch:.0f} us / step", "prototype"))
    t = _median_time(lambda: workspace(proto, np.radians(90), all_aspects=False), max(1, rep // 2))
    ws = workspace(proto, np.radians(90), all_aspects=False)
    rows.append(("workspace map 101 x 90, prototype theta=90 deg", f"{t:.1f} s",
                 f"{ws.maps[0].area_cells} cells, {ws.steps} steps, {1e6 * t / max(ws.steps, 1):.0f} us/step"))

    print(f"flexkin {flexkin.__version__} benchmark — {os.cpu_count()} cores, median of {rep} runs")
    w = max(len(r[0]) for r in rows)
    for r in rows:
        print(f"  {r[0]:<{w}}  {r[1]:>14}   {r[2]}")


if __name__ == "__main__":
    main()
