"""flexkin benchmark: the operations users wait for (issue 13's table), side by side with the
tests' own independent multi-start oracles.

Run::

    python benchmarks/bench.py [--repeat N] [--quick] [--json PATH] [--only GROUP ...]

``--only`` runs the named groups of rows: ``cli`` (whole-process IK and calibrate), ``ik``, ``fk``,
``continuation``, ``workspace``, ``extra`` (verification, explorer, Cosserat), ``oracle``,
``clamped`` (IK and FK of the mechanisms with clamped legs, issue 25; minutes) (the ``ik`` group
runs too when a later group needs its results).

Every row reports the median, min and max wall-clock time of ``N`` runs after one warm-up run
and the median CPU time (all threads of the process, and for whole-process rows of the child; on
a loaded machine the CPU time is the steadier figure)
(the warm-up loads the compiled kernels and builds the per-process caches; whole-process rows
start a fresh interpreter each time and so include import and kernel loading).  The header
gives the machine's core count and its load average: the figures are only comparable between
runs on an otherwise idle machine.

Oracle rows: one IK and one FK query are solved by flexkin and by the tests' multi-start
shooting oracles (``tests/ik_oracle.py`` ``oracle_ik``, ``tests/fk_oracle.py``
``fk_multistart``, with the default test budgets), and the ratio of the times is reported at
equal completeness: the row says whether flexkin's solution set contains every oracle solution
(same pose and tip forces; oracle solutions with an "extreme" rod outside flexkin's documented
scope are not required).

``--quick`` runs 2 repeats and skips the FK rows, the whole-process workspace, the oracles,
the Cosserat refinement and the clamped rows.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import platform
import resource
import statistics
import subprocess
import sys
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
PROTO = EXAMPLES / "prototype_3pfr.toml"
sys.path.insert(0, str(ROOT / "tests"))  # the oracles (they import no flexkin solver)


@dataclass
class Row:
    """One line of the table (times in seconds)."""

    name: str
    times: list[float]
    cpu: list[float] = field(default_factory=list)   # process CPU time of the same runs (in-process rows)
    target: float | None = None
    moonshot: float | None = None
    per: int = 1                      # the times are divided by this (per-step rows)
    unit: str = "ms"
    note: str = ""
    extra: dict[str, Any] = field(default_factory=dict)

    def stat(self, f: Callable[[list[float]], float]) -> float | None:
        return f(self.times) / self.per if self.times else None

    @property
    def median(self) -> float | None:
        return self.stat(statistics.median)

    @property
    def met(self) -> bool | None:
        m = self.median
        return None if m is None or self.target is None else bool(m <= self.target)

    def to_dict(self) -> dict[str, Any]:
        d = asdict(self)
        d.update(median=self.median, min=self.stat(min), max=self.stat(max), runs=len(self.times), met=self.met,
                 cpu_median=statistics.median(self.cpu) / self.per if self.cpu else None)
        return d


_SCALE = {"s": 1.0, "ms": 1e3, "us": 1e6}


def _fmt(v: float | None, unit: str) -> str:
    if v is None:
        return "-"
    x = v * _SCALE[unit]
    return f"{x:.3g} {unit}" if x < 100 else f"{x:.0f} {unit}"


#: process CPU times of the last :func:`_times` call (all threads of this process)
_CPU: list[float] = []


def _times(fn: Callable[[], Any], repeat: int, warm: bool = True) -> list[float]:
    """Wall-clock seconds of ``repeat`` runs of ``fn`` after an optional warm-up run; their
    CPU seconds (this process and its finished children) are left in :data:`_CPU`."""
    if warm:
        fn()
    out = []
    _CPU.clear()
    for _ in range(repeat):
        c = time.process_time() + _children_cpu()
        t = time.perf_counter()
        fn()
        out.append(time.perf_counter() - t)
        _CPU.append(time.process_time() + _children_cpu() - c)
    return out


def _children_cpu() -> float:
    """User + system seconds of the finished child processes (whole-process rows)."""
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def _cpu() -> list[float]:
    return list(_CPU)


def _cli() -> list[str]:
    """The ``flexkin`` command as its console script runs it (``flexkin.cli:console``), with this
    interpreter: independent of the installed script's age and of shims on the PATH (pyenv's
    adds its own start-up)."""
    return [sys.executable, "-c", "from flexkin.cli import console; console()"]


def _process(args: list[str]) -> Callable[[], None]:
    def run() -> None:
        subprocess.run(_cli() + args, check=True, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, cwd=ROOT)
    return run


# ---- the rows -------------------------------------------------------------------------------------
def ik_rows(rep: int, rows: list[Row], ctx: dict) -> None:
    import flexkin
    from flexkin.mechanism import symmetric_mechanism

    proto = flexkin.load_mechanism(PROTO)
    rfr = symmetric_mechanism("revolute")
    ctx.update(proto=proto, rfr=rfr)
    for name, mech, pose, target, moon in (
            ("full IK in-process, prototype (0, 0, 90 deg), max_mode 2", proto, (0.0, 0.0, math.radians(90)), 0.040,
             0.015),
            ("full IK in-process, unit 3-RFR (0.05, 0.02, 20 deg)", rfr, (0.05, 0.02, math.radians(20)), 0.015, 0.005)):
        t = _times(lambda: flexkin.ik(mech, pose), rep)
        res = flexkin.ik(mech, pose)
        ctx[name] = res
        rows.append(Row(name, t, _cpu(), target, moon, note=f"{len(res)} solutions"))
    ctx["ik_proto"] = ctx[rows[-2].name]
    ctx["ik_rfr"] = ctx[rows[-1].name]


def cli_ik_row(rep: int, rows: list[Row], ctx: dict) -> None:
    run = _process(["ik", str(PROTO), "--pose", "0", "0", "90", "--json"])
    rows.append(Row("`flexkin ik examples/prototype_3pfr.toml --pose 0 0 90 --json`, whole process",
                    _times(run, rep), _cpu(), 0.5, 0.3, unit="s"))


def cli_calibrate_row(rep: int, rows: list[Row], ctx: dict) -> None:
    run = _process(["calibrate", str(PROTO), "--data", str(EXAMPLES / "prototype_measurements.csv"),
                    "--fit", "leg[*].offset"])
    rows.append(Row("`flexkin calibrate examples/prototype_3pfr.toml --data examples/prototype_measurements.csv "
                    "--fit 'leg[*].offset'`, whole process", _times(run, rep), [], 10.0, 3.0, unit="s"))


def fk_rows(rep: int, rows: list[Row], ctx: dict) -> None:
    import flexkin

    proto, rfr = ctx["proto"], ctx["rfr"]
    u3 = flexkin.load_mechanism(EXAMPLES / "unit_3pfr.toml")
    u_rfr = tuple(ctx["ik_rfr"].solutions[0].inputs)
    u_worst = tuple(flexkin.ik(u3, (0.05, -0.03, math.radians(15))).solutions[40].inputs)
    for name, mech, u, target, moon in (
            ("full FK in-process, prototype rho = 0.025", proto, (0.025, 0.025, 0.025), 0.2, 0.1),
            ("full FK in-process, unit 3-RFR (inputs of IK solution 1 at (0.05, 0.02, 20 deg))", rfr, u_rfr, 0.5,
             0.15),
            ("full FK, worst test case (unit 3-PFR, inputs of IK solution 41 at (0.05, -0.03, 15 deg))", u3,
             u_worst, 2.0, 0.5)):
        t = _times(lambda: flexkin.fk(mech, u), max(1, rep // 2))
        cpu = _cpu()
        res = flexkin.fk(mech, u)
        rows.append(Row(name, t, cpu, target, moon, unit="s", note=f"{len(res)} solutions, complete={res.complete}"))


def continuation_rows(rep: int, rows: list[Row], ctx: dict) -> None:
    from flexkin.solve.continuation import continue_ik
    from flexkin.system import System

    proto = ctx["proto"]
    system = System.from_mechanism(proto)
    sol = next(s for s in ctx["ik_proto"].solutions if s.stable)
    lay = system.layout
    for batch, target, moon in ((1, 50e-6, 20e-6), (200, 20e-6, 5e-6)):
        X0 = np.repeat(np.asarray(sol.x)[None], batch, 0)
        C0 = np.repeat(np.asarray(sol.charts)[None], batch, 0)
        p1 = X0[:, lay.pose] + np.array([1e-3 * system.L_ref, 0.0, 0.0])
        n = max(rep, 20) if batch == 1 else rep
        t = _times(lambda: continue_ik(system, X0, C0, p1, np.zeros(3)), n)
        cpu = _cpu()
        ok = continue_ik(system, X0, C0, p1, np.zeros(3))[2]
        rows.append(Row("one continuation step, alone" if batch == 1 else "continuation step, batch of 200", t,
                        cpu, target, moon, per=batch, unit="us",
                        note=f"prototype, step L_ref/1000, {int(ok.sum())}/{batch} accepted"))


def workspace_rows(rep: int, rows: list[Row], ctx: dict, quick: bool) -> None:
    import flexkin

    proto = ctx["proto"]
    box: dict = {}

    def one() -> None:
        box["ws"] = flexkin.workspace(proto, math.radians(90), all_aspects=False)
    t = _times(one, max(1, rep // 2))
    ws = box["ws"]
    rows.append(Row("workspace 101 x 90, prototype theta = 90 deg, one aspect, stability at every cell", t, _cpu(), 0.5,
                    0.2, unit="s",
                    note=f"{ws.maps[0].area_cells} cells, {ws.steps} continuation steps"))
    if not quick:
        run = _process(["workspace", str(PROTO), "--theta", "90"])
        rows.append(Row("`flexkin workspace examples/prototype_3pfr.toml --theta 90` (all aspects), whole process",
                        _times(run, 1, warm=False), [], 5.0, 3.0, unit="s", note="one run"))


def extra_rows(rep: int, rows: list[Row], ctx: dict, quick: bool) -> None:
    import importlib.util

    proto = ctx["proto"]
    res = ctx["ik_proto"]
    # verification (issue 12), if present
    if importlib.util.find_spec("flexkin.analysis.verify") is not None:
        from flexkin.analysis.verify import verify_solutions
        from flexkin.system import System

        system = System.from_mechanism(proto)
        X = np.array([s.x for s in res.solutions])
        ch = np.array([s.charts for s in res.solutions])
        modes = np.array([s.modes for s in res.solutions])
        t = _times(lambda: verify_solutions(system, X, ch, np.asarray(res.load), modes), rep)
        rows.append(Row(f"verification (ODE re-integration) of the {len(X)} prototype IK solutions", t, _cpu(),
                        note="flexkin.analysis.verify.verify_solutions"))
    else:
        rows.append(Row("verification of the 88 prototype IK solutions", [], note="skipped: no flexkin.analysis.verify"))
    # explorer responsiveness
    from explore_responsiveness import TARGET_REFRESH_MS, TARGET_TRACK_MS, responsiveness

    r = responsiveness(PROTO, moves=max(20, 10 * rep), refreshes=max(3, rep))
    for key, label, target in (("track", "explorer: tracked drag (one move, server side)", TARGET_TRACK_MS / 1e3),
                               ("refresh", "explorer: full refresh on release (server side)", TARGET_REFRESH_MS / 1e3)):
        m = r[key]["median_ms"] / 1e3
        note = f"median of {r[key]['n']}, p90 {r[key]['p90_ms']:.0f} ms, max {r[key]['max_ms']:.0f} ms"
        if key == "refresh":
            note += f", of which flexkin.ik {r.get('refresh_solver_median_ms', float('nan')):.0f} ms"
        rows.append(Row(label, [m], [], target, note=note, extra={"responsiveness": r[key]}))
    # Cosserat refinement of the 88 IK solutions
    if not quick:
        from flexkin.cosserat import CosseratParams, params_for_mechanism, refine

        try:
            params = params_for_mechanism(proto)
            which = "rods' E and radius"
        except ValueError:
            params = CosseratParams.kirchhoff()
            which = "Kirchhoff limit"
        box: dict = {}

        def run() -> None:
            box["r"] = refine(proto, res, params=params)
        t = _times(run, 1, warm=True)
        rows.append(Row(f"Cosserat refinement of the {len(res)} prototype IK solutions at (0, 0, 90 deg)", t, _cpu(),
                        2.0, unit="s", note=f"params from the {which}"))


def clamped_rows(rep: int, rows: list[Row], ctx: dict) -> None:
    """Issue 25's rows: IK and FK of the two mechanisms with rods clamped to the platform, and the
    ratio to the IK oracle (``oracle_ik`` in its quick test configuration) on the mixed one."""
    import flexkin
    import ik_oracle as IO

    n = max(1, rep // 2)
    fk_cases = []
    for file, pose in (("unit_3pff.toml", (0.0, 0.0, math.radians(20))), ("mixed_clamped.toml", (0.02, -0.05, 0.1))):
        mech = flexkin.load_mechanism(EXAMPLES / file)
        t = _times(lambda: flexkin.ik(mech, pose), n)
        cpu = _cpu()
        res = flexkin.ik(mech, pose)
        rows.append(Row(f"full IK in-process, `examples/{file}` at {tuple(round(v, 4) for v in pose)}", t, cpu, 0.150,
                        unit="s", note=f"{len(res)} solutions, complete={res.complete}"))
        ctx[f"ik_{file}"] = res
        ctx[f"ik_{file}_s"] = statistics.median(t)
        # the FK at the inputs of the least loaded IK solution (the test's default pick)
        s = min(res.solutions, key=lambda q: max(math.hypot(*r.tip_force) for r in q.rods))
        fk_cases.append((file, mech, tuple(s.inputs)))
    for file, mech, u in fk_cases:
        t = _times(lambda: flexkin.fk(mech, u), 1)
        cpu = _cpu()
        res = flexkin.fk(mech, u)
        rows.append(Row(f"full FK in-process, `examples/{file}` (inputs of the least loaded IK solution)", t, cpu, 2.0,
                        unit="s", note=f"{len(res)} solutions, complete={res.complete}"))
    mech = flexkin.load_mechanism(EXAMPLES / "mixed_clamped.toml")
    pose = (0.02, -0.05, 0.1)
    med = ctx["ik_mixed_clamped.toml_s"]
    t0 = time.perf_counter()
    sols = IO.oracle_ik(mech, pose, load=mech.load, max_mode=2, max_turn=math.pi, n_starts=300, seed=3)
    t_or = time.perf_counter() - t0
    rows.append(Row("oracle ratio, IK `examples/mixed_clamped.toml`: oracle_ik (quick test configuration) / flexkin",
                    [t_or], [], unit="s", note=f"ratio {t_or / med:.1f}x; oracle {len(sols)} solutions (rods turning "
                                               f"by at most pi), flexkin {len(ctx['ik_mixed_clamped.toml'])}",
                    extra={"ratio": t_or / med, "flexkin_s": med, "oracle_n": len(sols)}))


def oracle_rows(rows: list[Row], ctx: dict) -> None:
    import flexkin
    import fk_oracle as FO
    import ik_oracle as IO

    # IK: unit 3-RFR at (0.05, 0.02, 20 deg), the test's default budget
    mech = ctx["rfr"]
    pose = (0.05, 0.02, math.radians(20))
    t_flex = _times(lambda: flexkin.ik(mech, pose), 3)
    res = flexkin.ik(mech, pose)
    t0 = time.perf_counter()
    sols = IO.oracle_ik(mech, pose, load=(0.0, 0.0, 0.0), max_mode=2, n_starts=400, scan=(160, 320),
                        max_triples=2000, seed=1)
    t_or = time.perf_counter() - t0
    F_ref = IO.Geom.of(mech).F_ref
    flex_forces = [[r.tip_force for r in s.rods] for s in res.solutions]
    missed = [s for s in sols if not s.extreme and not any(IO.match(ff, s.forces, F_ref) for ff in flex_forces)]
    med = statistics.median(t_flex)
    rows.append(Row("oracle ratio, IK unit 3-RFR (0.05, 0.02, 20 deg): oracle_ik time / flexkin time", [t_or], [],
                    note=f"ratio {t_or / med:.0f}x (target >= 300x); flexkin {len(res)} solutions in {1e3 * med:.0f} ms, "
                         f"oracle {len(sols)}; flexkin contains the oracle's: {not missed}",
                    unit="s", extra={"ratio": t_or / med, "flexkin_s": med, "contains": not missed,
                                     "flexkin_n": len(res), "oracle_n": len(sols)}))
    # FK: prototype, paper Table 1 inputs, the test's default budget
    proto = ctx["proto"]
    u = (0.025, 0.025, 0.025)
    t_flex = _times(lambda: flexkin.fk(proto, u, load=(0, 0, 0)), 1)
    res = flexkin.fk(proto, u, load=(0, 0, 0))
    t0 = time.perf_counter()
    sols = FO.fk_multistart(proto, u, load=(0.0, 0.0, 0.0), max_mode=2, n_random=300, n_forward=300,
                            anchors=(150, 36, 0.97), s_max=1.5, seed=1)
    t_or = time.perf_counter() - t0
    F_ref = IO.Geom.of(proto).F_ref

    def same(f, o) -> bool:
        if not FO.pose_match(f.pose, o.pose, 1e-6, 1e-5):
            return False
        a = np.array([r.tip_force for r in f.rods], float)
        return float(np.max(np.abs(a - o.forces))) <= 1e-5 * max(float(np.max(np.abs(o.forces))), F_ref)
    missed = [o for o in sols if not getattr(o, "extreme", False) and not any(same(f, o) for f in res.solutions)]
    med = statistics.median(t_flex)
    rows.append(Row("oracle ratio, FK prototype rho = 0.025: fk_multistart time / flexkin time", [t_or], [],
                    note=f"ratio {t_or / med:.0f}x (target >= 200x); flexkin {len(res)} solutions in {med:.2f} s, "
                         f"oracle {len(sols)}; flexkin contains the oracle's: {not missed}",
                    unit="s", extra={"ratio": t_or / med, "flexkin_s": med, "contains": not missed,
                                     "flexkin_n": len(res), "oracle_n": len(sols)}))


#: the groups of rows, in the order they run (``--only``)
GROUPS = ("cli", "ik", "fk", "continuation", "workspace", "extra", "oracle", "clamped")


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--repeat", type=int, default=5, help="timed runs per row after a warm-up (default 5)")
    ap.add_argument("--quick", action="store_true", help="2 repeats; skip FK, whole-process workspace, oracles, "
                                                         "Cosserat")
    ap.add_argument("--json", metavar="PATH", help="also write the rows as JSON to PATH")
    ap.add_argument("--no-oracle", action="store_true", help="skip the oracle rows (minutes)")
    ap.add_argument("--only", nargs="+", metavar="GROUP", choices=GROUPS,
                    help="run only these groups of rows: " + ", ".join(GROUPS))
    a = ap.parse_args(argv)
    if a.repeat < 1:
        ap.error("--repeat must be >= 1")
    rep = 2 if a.quick else a.repeat
    import flexkin

    rows: list[Row] = []
    ctx: dict = {}
    t_all = time.perf_counter()
    want = set(a.only or GROUPS)
    if want & {"cli"}:
        cli_ik_row(rep, rows, ctx)
        cli_calibrate_row(rep, rows, ctx)
    if want - {"cli"}:  # the other groups use the IK results
        n = len(rows)
        ik_rows(rep, rows, ctx)
        if "ik" not in want:
            del rows[n:]
    if "fk" in want and not a.quick:
        fk_rows(rep, rows, ctx)
    if "continuation" in want:
        continuation_rows(rep, rows, ctx)
    if "workspace" in want:
        workspace_rows(rep, rows, ctx, a.quick)
    if "extra" in want:
        extra_rows(rep, rows, ctx, a.quick)
    if "oracle" in want and not (a.quick or a.no_oracle):
        oracle_rows(rows, ctx)
    if "clamped" in want and not a.quick:
        clamped_rows(rep, rows, ctx)
    cores = os.cpu_count()
    load = os.getloadavg() if hasattr(os, "getloadavg") else (float("nan"),) * 3
    print(f"flexkin {flexkin.__version__} benchmark: {cores} cores, load average {load[0]:.1f} / {load[1]:.1f} / "
          f"{load[2]:.1f}, median (min, max) of {rep} runs after a warm-up; {time.perf_counter() - t_all:.0f} s")
    w = max(len(r.name) for r in rows)
    print(f"  {'operation':<{w}}  {'median':>10} {'min':>10} {'max':>10} {'cpu med':>10}  {'target':>9}  met   note")
    for r in rows:
        met = {None: "  - ", True: " yes", False: "  NO"}[r.met]
        cpu = statistics.median(r.cpu) / r.per if r.cpu else None
        print(f"  {r.name:<{w}}  {_fmt(r.median, r.unit):>10} {_fmt(r.stat(min), r.unit):>10} "
              f"{_fmt(r.stat(max), r.unit):>10} {_fmt(cpu, r.unit):>10}  {_fmt(r.target, r.unit):>9} {met}   {r.note}")
    if a.json:
        out = {"flexkin": flexkin.__version__, "cores": cores, "loadavg": list(load), "repeat": rep,
               "python": platform.python_version(), "time": time.strftime("%Y-%m-%dT%H:%M:%S%z"),
               "rows": [r.to_dict() for r in rows]}
        Path(a.json).write_text(json.dumps(out, indent=1))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
