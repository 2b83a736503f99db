"""Command-line interface: ``flexkin {show, rod, ik, fk, path, workspace, refine, reproduce, study,
explore, calibrate} ...`` (SPEC §4).

Thin: parse -> call the library -> print a table or the JSON contract -> write figures and data
files (every file written is named on stderr).  User mistakes (bad files, bad numbers) end with
one line on stderr and exit status 2; "no solution" is an answer (exit 0, explanation on
stderr).  Warnings (implausible values, :class:`~flexkin.errors.FlexkinWarning`) are one line
each on stderr.  Long work shows a progress bar on stderr when it is a terminal (``--quiet``
silences it).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
import warnings
from typing import Any, Sequence

import numpy as np

from .core import cli_args

__all__ = ["main"]

EXIT_USAGE = 2


class CLIError(Exception):
    """A user mistake reported as one line and exit status 2."""


class _Parser(argparse.ArgumentParser):
    def __init__(self, *args: Any, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        # negative numbers in exponent notation (-1e-3) are values, not options
        self._negative_number_matcher = re.compile(r"^-(\d+\.?\d*|\.\d+)([eE][-+]?\d+)?$")

    def error(self, message: str) -> None:  # one line on stderr and exit 2, no usage block
        raise CLIError(f"{self.prog}: {' '.join(message.split())} (see '{self.prog} --help')")


def _add_time_budget(k) -> None:
    k.add_argument("--time-budget", type=cli_args.positive, metavar="SECONDS",
                   help="seconds for the whole computation (search, refinement, stability, Jacobians, verification; "
                        "loading the compiled kernels at start-up not counted); when they run out the result holds "
                        "what was finished and says complete = false (default: no limit)")


def _add_common_kinematics(k, name: str) -> None:
    k.add_argument("--load", nargs=3, type=cli_args.finite, metavar=("FX", "FY", "MZ"),
                   help="load wrench at P [N, N, N m] (default: the file's [load] or zero)")
    k.add_argument("--max-mode", type=cli_args.max_mode, default=2,
                   help="largest d-mode of any rod: its inflection points on (0, L]; a clamped tip is not one "
                        "(default 2)")
    k.add_argument("--max-winding", type=cli_args.max_winding, default=1, metavar="W",
                   help="largest |winding| of a rod clamped to the platform: its total turning is delta + 2 pi w "
                        "with delta in (-pi, pi] (default 1)")
    k.add_argument("--quiet", "-q", action="store_true", help="no progress display on stderr")


def _build_parser() -> argparse.ArgumentParser:
    p = _Parser(prog="flexkin", description="Complete kinematic analysis of planar parallel continuum mechanisms.")
    p.add_argument("--version", action="version", version=f"flexkin {_version()}")
    sub = p.add_subparsers(dest="command", required=True, parser_class=_Parser)

    s = sub.add_parser("show", help="print a mechanism file and draw it")
    s.add_argument("mechanism", help="mechanism file (TOML, docs/mechanism_file.md)")
    s.add_argument("--plot", metavar="FILE", help="write a drawing of the mechanism")

    r = sub.add_parser("rod", help="every equilibrium of one rod with a pinned or clamped tip (paper Fig. 19)")
    r.add_argument("--length", type=cli_args.positive, help="rod length L [m]")
    r.add_argument("--EI", type=cli_args.positive, help="bending stiffness [N m^2]")
    r.add_argument("--E", type=cli_args.positive, help="Young's modulus [Pa] (with --radius)")
    r.add_argument("--radius", type=cli_args.positive, help="radius of the circular section [m]")
    r.add_argument("--tip", nargs=2, type=cli_args.finite, metavar=("X", "Y"), help="tip point [m]")
    r.add_argument("--tip-angle", type=cli_args.finite, metavar="DEG",
                   help="clamp the tip too, with this tangent angle [deg, world frame] (default: pinned tip)")
    r.add_argument("--clamp-angle", type=cli_args.finite, default=0.0, metavar="DEG",
                   help="clamp tangent angle [deg] (default 0)")
    r.add_argument("--max-mode", type=cli_args.max_mode, default=2, help="largest d-mode (default 2)")
    r.add_argument("--sweep", action="store_true",
                   help="sweep the tip abscissa at fixed height (defaults: the paper's Fig. 19 set-up)")
    r.add_argument("--tip-y", type=cli_args.finite, help="sweep: tip height [m] (default -0.2125)")
    r.add_argument("--x-range", nargs=2, type=cli_args.finite, metavar=("X0", "X1"),
                   help="sweep: tip abscissa range [m] (default 0.86 0.51)")
    r.add_argument("--points", type=int, default=36, help="sweep: number of abscissae (default 36)")
    r.add_argument("--json", action="store_true", help="print the JSON result")
    r.add_argument("--plot", metavar="FILE", help="write a figure (shapes, or force vs x for --sweep)")

    for name, helptext in (("ik", "inverse kinematics: every equilibrium at a platform pose"),
                           ("fk", "forward kinematics: every equilibrium pose for actuator inputs")):
        k = sub.add_parser(name, help=helptext)
        k.add_argument("mechanism", help="mechanism file (TOML, docs/mechanism_file.md)")
        if name == "ik":
            k.add_argument("--pose", nargs=3, type=cli_args.finite, metavar=("X", "Y", "THETA"), required=True,
                           help="platform pose: m, m, deg")
        else:
            k.add_argument("--inputs", nargs=3, type=cli_args.finite, metavar=("U1", "U2", "U3"), required=True,
                           help="actuator inputs: m for prismatic and length legs, deg for revolute legs")
        _add_time_budget(k)
        _add_common_kinematics(k, name)
        k.add_argument("--json", action="store_true", help="print the SPEC §4 JSON object")
        k.add_argument("--feasibility", action="store_true",
                       help="each solution's feasibility verdict and reasons (collisions, strain, input ranges): "
                            "a column of the table, or keys of the --json objects (always with --feasible-only); "
                            "computed only on request")
        k.add_argument("--plot", metavar="FILE",
                       help="figure with one panel per solution (pages of 20: FILE, FILE_2, ...)")
        k.add_argument("--shapes", metavar="FILE",
                       help="rod shapes of every listed solution: .csv (solution, leg, s, x, y, theta [deg], "
                            "moment) or .npz")
        k.add_argument("--stable-only", action="store_true", help="list only the stable equilibria")
        k.add_argument("--margin", action="store_true",
                       help="also compute every solution's stability margin (the table gains a margin column; "
                            "--json always carries it)")
        k.add_argument("--feasible-only", action="store_true",
                       help="list only the feasible equilibria (no collision, strain and inputs within limits)")
        k.add_argument("--model", choices=("kirchhoff", "cosserat"), default="kirchhoff",
                       help="kirchhoff (default), or cosserat: then refine every listed solution with extension, "
                            "shear and self-weight (needs E and radius; [rod] G or poisson, density)")
        k.add_argument("--gravity", nargs=2, type=cli_args.finite, metavar=("GX", "GY"),
                       help="with --model cosserat: gravity in the plane [m/s^2] (default: the file's "
                            "[environment] gravity, else none)")
        if name == "ik":
            k.add_argument("--curves", metavar="FILE", help="figure of the geometric-condition curves (Fig. 7)")

    rf = sub.add_parser("refine", help="refine every Kirchhoff equilibrium with a Cosserat model "
                                       "(extension, shear, self-weight)")
    rf.add_argument("mechanism", help="mechanism file (TOML, docs/mechanism_file.md); needs E and radius")
    g = rf.add_mutually_exclusive_group(required=True)
    g.add_argument("--pose", nargs=3, type=cli_args.finite, metavar=("X", "Y", "THETA"),
                   help="platform pose (IK): m, m, deg")
    g.add_argument("--inputs", nargs=3, type=cli_args.finite, metavar=("U1", "U2", "U3"),
                   help="actuator inputs (FK): m for prismatic and length legs, deg for revolute legs")
    rf.add_argument("--gravity", nargs=2, type=cli_args.finite, metavar=("GX", "GY"),
                    help="gravity in the plane [m/s^2] (default: the file's [environment] gravity, else none)")
    _add_common_kinematics(rf, "refine")
    rf.add_argument("--stable-only", action="store_true", help="refine only the stable Kirchhoff equilibria")
    rf.add_argument("--json", action="store_true", help="print the JSON result")
    rf.add_argument("--plot", metavar="FILE",
                    help="Kirchhoff and refined shapes drawn over each other (pages of 20: FILE, FILE_2, ...)")

    pa = sub.add_parser("path", help="follow one IK solution along a straight path of poses (singularities, stability)")
    pa.add_argument("mechanism", help="mechanism file (TOML, docs/mechanism_file.md)")
    pa.add_argument("--from", dest="start", nargs=3, type=cli_args.finite, metavar=("X", "Y", "THETA"), required=True,
                    help="start pose: m, m, deg")
    pa.add_argument("--to", dest="end", nargs=3, type=cli_args.finite, metavar=("X", "Y", "THETA"), required=True,
                    help="end pose: m, m, deg")
    pa.add_argument("--steps", type=cli_args.count, default=50, help="number of path intervals (default 50)")
    pa.add_argument("--solution", type=cli_args.count, default=None,
                    help="id of the IK solution at the start pose to follow, as numbered by 'flexkin ik' "
                         "(the '#' column and the JSON 'id', also after --stable-only; default: the first stable one)")
    pa.add_argument("--load", nargs=3, type=cli_args.finite, metavar=("FX", "FY", "MZ"),
                    help="load wrench at P [N, N, N m] (default: the file's [load] or zero)")
    pa.add_argument("--max-mode", type=cli_args.max_mode, default=2, help="largest d-mode for the start IK (default 2)")
    pa.add_argument("--json", action="store_true",
                    help="print the JSON result (per sample: pose, inputs, modes, stability, Jacobians, strain, "
                         "feasibility)")
    pa.add_argument("--plot", metavar="FILE", help="inputs, singularity functions, Jacobian determinants and "
                                                   "stability margin vs t")
    pa.add_argument("--shapes", metavar="FILE", help="rod shapes at every sample: .csv or .npz")
    _add_time_budget(pa)
    pa.add_argument("--quiet", "-q", action="store_true", help="no progress display on stderr")

    wk = sub.add_parser("workspace", help="constant-orientation workspace by wave propagation (paper Fig. 17)")
    wk.add_argument("mechanism", help="mechanism file (TOML, docs/mechanism_file.md)")
    wk.add_argument("--theta", type=cli_args.finite, action="append", required=True, metavar="DEG",
                    help="platform orientation [deg]; repeat for several orientations (computed in parallel)")
    wk.add_argument("--seed", nargs=2, type=cli_args.finite, metavar=("X", "Y"), default=(0.0, 0.0),
                    help="seed position [m] (default 0 0)")
    wk.add_argument("--step", type=cli_args.positive, help="grid step [m] (default: 1/100 of the bounds)")
    wk.add_argument("--bounds", nargs=4, type=cli_args.finite, metavar=("X0", "X1", "Y0", "Y1"),
                    help="grid box [m] (default: the legs' origins grown by a quarter rod length)")
    wk.add_argument("--load", nargs=3, type=cli_args.finite, metavar=("FX", "FY", "MZ"),
                    help="load wrench at P [N, N, N m] (default: the file's [load] or zero)")
    wk.add_argument("--max-mode", type=cli_args.max_mode, default=2, help="largest d-mode of the seed IK (default 2)")
    wk.add_argument("--first-aspect", action="store_true",
                    help="map only the aspect of the first stable seed solution (default: every stable one)")
    wk.add_argument("--constrained", action="store_true",
                    help="stop the propagation at infeasible cells (an input outside its leg's range, strain above "
                         "[limits] max_strain; with --collisions also colliding rods): the region the design can use "
                         "(default: every stable equilibrium reached, feasibility only marked)")
    wk.add_argument("--collisions", action="store_true",
                    help="also check rod-rod and rod-platform collisions at every cell (slower)")
    wk.add_argument("--color", default="modes", choices=["modes", "margin", "cond", "input1", "input2", "input3"],
                    help="colour the region by d-mode combination (default) or a quantity")
    wk.add_argument("--jobs", type=cli_args.count, default=None,
                    help="parallel processes for several orientations (default: the number of cores)")
    wk.add_argument("--save", metavar="FILE", help="save the maps (.npz; one file per orientation, suffixed)")
    wk.add_argument("--json", action="store_true", help="print a JSON summary")
    wk.add_argument("--plot", metavar="FILE",
                    help="figure like Fig. 17: one panel per aspect and orientation, same axes and colours "
                         "(pages of 20: FILE, FILE_2, ...)")
    _add_time_budget(wk)
    wk.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    from .explore.cli import add_explore_parser
    from .study.cli import add_study_parser

    add_study_parser(sub)
    from .calibration.cli import add_calibrate_parser

    add_calibrate_parser(sub)
    add_explore_parser(sub)
    rp = sub.add_parser("reproduce", help="run the paper's whole analysis on the bundled examples; write a report")
    rp.add_argument("--out", default="flexkin_report", help="output directory (default flexkin_report)")
    rp.add_argument("--quick", action="store_true", help="coarse grids and sweeps (about 15 s once compiled)")
    rp.add_argument("--quiet", "-q", action="store_true", help="no progress bar")
    return p


def _progress(a) -> bool:
    from .io.progress import progress_wanted

    return progress_wanted(bool(getattr(a, "quiet", False)))


def _written(path: Any) -> None:
    print(f"written: {path}", file=sys.stderr)


def _cmd_reproduce(a) -> int:
    from .reproduce import reproduce

    try:
        res = reproduce(a.out, quick=a.quick, progress=_progress(a))
    except PermissionError as e:
        raise CLIError(f"flexkin reproduce: cannot write to {a.out!r}: {e.strerror}") from None
    html = getattr(res, "html", None)
    print(f"report written to {res.report}" + (f" and {html}" if html else "")
          + f" ({len(res.figures)} figures, {res.elapsed:.0f} s)")
    for row in res.table2:
        rho = row["flexkin_rho"]
        print(f"  Table 2: theta = {row['theta_deg']:g} deg: rho = "
              + ("not found" if rho is None else f"{rho:.4f} m") + f" (paper {row['paper_rho']} m)")
    for row in res.table1:
        p = row["flexkin_pose"]
        shown = "not found" if p is None else _pose_text(p)
        print(f"  Table 1: paper theta = {row['paper_theta_deg']:g} deg: flexkin pose {shown}")
    return 0


def _pose_text(p: Sequence[float], tol: float = 1e-9) -> str:
    """``(x m, y m, theta deg)`` to meaningful precision (|x| below ``tol`` m is 0)."""
    def length(v: float) -> str:
        return "0" if abs(v) < tol else f"{v:.5g}"

    return f"({length(p[0])} m, {length(p[1])} m, {p[2]:.2f} deg)"


def _workspace_task(args: tuple) -> Any:
    from .solve.workspace import workspace

    mech, theta, kw = args
    return workspace(mech, theta, **kw)


def _cmd_workspace(a) -> int:
    from .solve.workspace import default_grid

    mech = _load_mech(a.mechanism)
    try:  # validate before starting any work
        default_grid(mech, a.step, a.bounds)
    except ValueError as e:
        opt = "--step" if str(e).startswith("step") else "--bounds"
        raise CLIError(f"flexkin workspace: {opt}: {e}") from None
    kw = dict(seed=tuple(a.seed), load=a.load, step=a.step, bounds=a.bounds, max_mode=a.max_mode,
              all_aspects=not a.first_aspect, constrained=a.constrained, collisions=a.collisions)
    thetas = [math.radians(t) for t in a.theta]
    jobs = min(len(thetas), a.jobs or os.cpu_count() or 1)
    if a.time_budget is not None:  # the orientations run `jobs` at a time: each gets its share
        kw["time_budget"] = a.time_budget / math.ceil(len(thetas) / jobs)
    show = _progress(a)
    if jobs > 1:
        from concurrent.futures import ProcessPoolExecutor, as_completed

        from .io.progress import bar

        with ProcessPoolExecutor(max_workers=jobs) as ex:
            futs = [ex.submit(_workspace_task, (mech, th, kw)) for th in thetas]
            with bar(len(futs), "workspace orientations", unit="map", enabled=show) as b:
                for _ in as_completed(futs):
                    b.update(1)
            results = [f.result() for f in futs]
    else:
        from .solve.workspace import workspace

        results = [workspace(mech, th, progress=show, **kw) for th in thetas]
    if a.save:
        root, ext = os.path.splitext(a.save)
        for t, ws in zip(a.theta, results):
            f = a.save if len(results) == 1 else f"{root}_theta{t:g}{ext or '.npz'}"
            ws.save(f)
            _written(f)
    if a.json:
        out = []
        for ws in results:
            out.append({"theta": float(math.degrees(ws.theta)), "step": ws.step, "seed": list(ws.seed),
                        "elapsed": ws.elapsed, "complete": ws.complete, "message": ws.message, "region": ws.region,
                        "constraints": list(ws.constraints), "constrained": ws.constrained, "grown": ws.grown,
                        "aspects": [{"seeds": list(mp.seeds), "cells": mp.area_cells,
                                     "area": mp.area_cells * ws.step**2,
                                     "feasible_cells": mp.feasible_cells,
                                     "feasible_area": mp.feasible_cells * ws.step**2,
                                     "modes": sorted({"".join(map(str, q)) for q in mp.modes[mp.reached]}),
                                     "boundary_ik_cells": int(mp.boundary_ik.sum()),
                                     "boundary_fk_cells": int(mp.boundary_fk.sum()),
                                     "boundary_infeasible_cells": int(mp.boundary_infeasible.sum()),
                                     "boundary_edge_cells": int(mp.boundary_edge.sum()),
                                     "unresolved_cells": int(mp.boundary_seam.sum())} for mp in ws.maps]})
        print(_dump({"problem": "workspace", "mechanism": mech.name, "workspaces": out}))
    else:
        for ws in results:
            print(ws.summary())
    for ws in results:
        if ws.message:
            print(f"flexkin workspace: theta = {math.degrees(ws.theta):g} deg: {ws.message}", file=sys.stderr)
    if a.plot:
        from .plot.workspace import write_workspace_pages

        for f in write_workspace_pages(results, a.plot, color_by=a.color):
            _written(f)
    return 0


def _cmd_explore(a) -> int:
    from .explore.cli import run_explore_command

    return run_explore_command(a)


def _cmd_calibrate(a) -> int:
    from .calibration.cli import run_calibrate_command

    return run_calibrate_command(a)


def _cmd_study(a) -> int:
    from .study.cli import run_study_command

    return run_study_command(a)


def _cmd_path(a) -> int:
    from .io import write_shapes
    from .io.progress import ProgressBar
    from .solve.path import follow_path

    mech = _load_mech(a.mechanism)
    start = (a.start[0], a.start[1], math.radians(a.start[2]))
    end = (a.end[0], a.end[1], math.radians(a.end[2]))
    with ProgressBar(f"flexkin path ({a.steps} steps)", enabled=_progress(a)) as bar:
        res = follow_path(mech, start, end, steps=a.steps, load=a.load, solution=a.solution, max_mode=a.max_mode,
                          time_budget=a.time_budget, feasibility=True, progress=bar)
        d = res.to_dict(feasibility=True)
    if a.json:
        print(_dump(d))
    else:
        sid = getattr(res.start_solution, "id", None)
        print(f"{mech.name}: path from ({a.start[0]:g} m, {a.start[1]:g} m, {a.start[2]:g} deg) to "
              f"({a.end[0]:g} m, {a.end[1]:g} m, {a.end[2]:g} deg), "
              + ("" if sid is None else f"solution {sid}, ")
              + f"{a.steps} steps, {len(res.t)} samples reached in {res.elapsed:.2f} s")
        if len(res.t):
            print(res.table())
            pts = d["points"]
            n_ok = sum(1 for q in pts if q.get("feasible"))
            strains = [q["max_strain"] for q in pts if q.get("max_strain") is not None]
            line = f"feasible at {n_ok} of {len(pts)} samples"
            if strains:
                line += f"; largest bending strain {max(strains):.3g}"
            bad = next((q for q in pts if not q.get("feasible")), None)
            if bad is not None:
                line += f"; first infeasible at t = {bad['t']:.3f}: {'; '.join(bad['feasibility']['reasons'])}"
            print(line)
    if res.message:
        print(f"flexkin path: {res.message}", file=sys.stderr)
    if a.plot and len(res.t):
        res.plot(a.plot)
        _written(a.plot)
    if a.shapes and len(res.t):
        _written(write_shapes(a.shapes, res))
    return 0


def _version() -> str:
    from .core.version import __version__

    return __version__


def _load_mech(path: str):
    from .errors import MechanismError
    from .mechanism import load_mechanism

    try:
        return load_mechanism(path)
    except MechanismError as e:
        raise CLIError(str(e)) from None


def _dump(obj: dict[str, Any]) -> str:
    try:
        return json.dumps(obj, indent=2, allow_nan=False)
    except ValueError as e:  # a NaN must never reach the JSON contract
        raise RuntimeError(f"internal error: non-finite number in the JSON output ({e})") from e


def _cmd_show(a) -> int:
    mech = _load_mech(a.mechanism)
    print(mech.summary())
    if a.plot:
        from .plot.mechanism import plot_mechanism_file

        plot_mechanism_file(mech, a.plot)
        _written(a.plot)
    return 0


def _rod_EI(a) -> float:
    from .mechanism.model import LENGTH_LIMITS, STIFFNESS_LIMITS

    if a.length is not None and not LENGTH_LIMITS[0] <= a.length <= LENGTH_LIMITS[1]:
        raise CLIError(f"flexkin rod: --length {a.length:g} is outside the supported range "
                       f"[{LENGTH_LIMITS[0]:g}, {LENGTH_LIMITS[1]:g}] m")
    if a.EI is not None:
        if a.E is not None or a.radius is not None:
            raise CLIError("flexkin rod: give either --EI or --E with --radius, not both")
        if not STIFFNESS_LIMITS[0] <= a.EI <= STIFFNESS_LIMITS[1]:
            raise CLIError(f"flexkin rod: --EI {a.EI:g} is outside the supported range "
                           f"[{STIFFNESS_LIMITS[0]:g}, {STIFFNESS_LIMITS[1]:g}] N m^2")
        return a.EI
    if a.E is not None and a.radius is not None:
        try:
            EI = a.E * math.pi * a.radius**4 / 4.0
        except OverflowError:
            EI = math.inf
        if not STIFFNESS_LIMITS[0] <= EI <= STIFFNESS_LIMITS[1]:
            raise CLIError(f"flexkin rod: --E {a.E:g} with --radius {a.radius:g} gives EI = E pi r^4/4 = {EI:g}, "
                           f"outside the supported range [{STIFFNESS_LIMITS[0]:g}, {STIFFNESS_LIMITS[1]:g}] N m^2")
        return EI
    if a.sweep and a.E is None and a.radius is None:
        from .solve.rod_sweep import FIG19

        return FIG19["E"] * math.pi * FIG19["radius"] ** 4 / 4.0
    raise CLIError("flexkin rod: the bending stiffness is missing: give --EI, or --E and --radius")


def _cmd_rod(a) -> int:
    from .solve.rod_inverse import solve_rod
    from .solve.rod_sweep import FIG19, rod_sweep

    EI = _rod_EI(a)
    if a.sweep:
        if a.tip_angle is not None:
            raise CLIError("flexkin rod: --tip-angle applies to one rod (--tip), not to --sweep")
        L = a.length if a.length is not None else FIG19["length"]
        ty = a.tip_y if a.tip_y is not None else FIG19["tip_y"]
        x0, x1 = a.x_range if a.x_range is not None else (FIG19["x_start"], FIG19["x_end"])
        if not 2 <= a.points <= 10000:
            raise CLIError("flexkin rod: --points must be between 2 and 10000")
        sw = rod_sweep(np.linspace(x0, x1, a.points), ty, L, EI, clamp_angle=math.radians(a.clamp_angle),
                       max_mode=a.max_mode)
        if a.json:
            print(_dump(sw.to_dict()))
        else:
            print(f"rod L = {L:g} m, EI = {EI:.6g} N m^2, tip y = {ty:g} m, clamp angle {a.clamp_angle:g} deg")
            print(sw.table())
        if a.plot:
            sw.plot(a.plot)
            _written(a.plot)
        return 0
    if a.length is None or a.tip is None:
        raise CLIError("flexkin rod: --length and --tip are required (or use --sweep)")
    tip_angle = None if a.tip_angle is None else math.radians(a.tip_angle)
    res = solve_rod(a.tip, a.length, EI, clamp_angle=math.radians(a.clamp_angle), tip_angle=tip_angle,
                    max_mode=a.max_mode)
    if a.json:
        print(_dump(res.to_dict()))
    else:
        joint = "pinned" if tip_angle is None else f"clamped at {a.tip_angle:g} deg"
        print(f"rod L = {a.length:g} m, EI = {EI:.6g} N m^2, tip ({a.tip[0]:g}, {a.tip[1]:g}) m {joint}, "
              f"clamp angle {a.clamp_angle:g} deg: {len(res)} equilibria with d-mode <= {a.max_mode}")
        if len(res):
            print(f"{'#':>3} {'mode':>4} {'k':>10} {'psi [deg]':>10} {'Fx [N]':>11} {'Fy [N]':>11} "
                  f"{'m0 [N m]':>11} {'mL [N m]':>11} {'energy [J]':>11}")
            for i, s in enumerate(res.solutions, 1):
                k = f"{s.k:>10.6f}" if np.isfinite(s.k) else f"{'-':>10}"
                print(f"{i:>3} {s.mode:>4} {k} {math.degrees(s.psi):>10.4f} {s.tip_force[0]:>11.5g} "
                      f"{s.tip_force[1]:>11.5g} {s.base_moment:>11.5g} {s.tip_moment:>11.5g} {s.energy:>11.5g}")
    if not len(res):
        print(f"flexkin rod: {res.message}", file=sys.stderr)
    if a.plot:
        from .plot.rod import plot_rod_solutions

        plot_rod_solutions(res, a.plot)
        _written(a.plot)
    return 0


def _kinematics(a, mech):
    """The IK or FK result of ``a`` (with a progress bar) and a one-line description."""
    from .io.progress import ProgressBar

    if getattr(a, "pose", None) is not None:
        from .solve.ik import ik

        pose = (a.pose[0], a.pose[1], math.radians(a.pose[2]))
        with ProgressBar("flexkin ik", enabled=_progress(a)) as bar:
            res = ik(mech, pose, load=a.load, max_mode=a.max_mode, max_winding=a.max_winding,
                     time_budget=getattr(a, "time_budget", None), progress=bar, margin=getattr(a, "margin", False))
        what = f"inverse kinematics at pose ({a.pose[0]:g} m, {a.pose[1]:g} m, {a.pose[2]:g} deg)"
        return res, what
    from .mechanism.plausibility import revolute_inputs_look_like_radians
    from .solve.fk import fk

    note = revolute_inputs_look_like_radians(mech, a.inputs)
    from .errors import FlexkinWarning

    if note:
        warnings.warn(note, FlexkinWarning, stacklevel=2)
    for i, (v, leg) in enumerate(zip(a.inputs, mech.legs)):
        if leg.actuation == "revolute":
            _angle_arg(v, f"--inputs U{i + 1}")
    u = [float(leg.from_display(v)) for v, leg in zip(a.inputs, mech.legs)]
    with ProgressBar("flexkin fk", enabled=_progress(a)) as bar:
        res = fk(mech, u, load=a.load, max_mode=a.max_mode, max_winding=a.max_winding,
                 time_budget=getattr(a, "time_budget", None), progress=bar, margin=getattr(a, "margin", False))
    units = [leg.input_unit for leg in mech.legs]
    what = "forward kinematics at inputs (" + ", ".join(f"{v:g} {un}" for v, un in zip(a.inputs, units)) + ")"
    return res, what


def _cosserat_setup(a, mech):
    """Per-leg Cosserat parameters and gravity (checked before any work)."""
    from .cosserat.params import cosserat_setup

    try:
        params, gravity = cosserat_setup(mech, a.gravity)
    except ValueError as e:
        raise CLIError(f"flexkin {a.command}: {e}") from None
    if gravity is not None and not any(p.mass_per_length > 0 for p in params):
        from .errors import FlexkinWarning

        warnings.warn("gravity is given but no rod has a density ([rod] density, kg/m^3): the rods are weightless",
                      FlexkinWarning, stacklevel=2)
    return params, gravity


def _refine(a, mech, res, setup):
    """Cosserat refinement of the solutions of ``res`` (with progress display)."""
    from .cosserat import refine
    from .io.progress import Ticker

    params, gravity = setup
    with Ticker(f"flexkin {a.command}: Cosserat refinement of {len(res)} solution(s)", enabled=_progress(a)):
        return refine(mech, res, params=params, gravity=gravity)


def _refined_entries(res, ref) -> dict[int, dict[str, Any]]:
    """Solution id -> its refined JSON object."""
    legs = tuple(res.mechanism.legs)
    return {s.id: r.to_dict(legs) for s, r in zip(res.solutions, ref.solutions)}


def _refine_table(res, ref) -> str:
    g = ref.gravity
    units = [leg.input_unit for leg in res.mechanism.legs]
    lines = ["Cosserat refinement (extension, shear" + ("" if g is None else f", gravity ({g[0]:g}, {g[1]:g}) m/s^2")
             + f"): {ref.message}",
             f"{'#':>3} {'status':>8} {'tau end':>8} {'dP [m]':>9} {'dth [deg]':>9} "
             + " ".join(f"{'du' + str(i + 1) + ' [' + u + ']':>11}" for i, u in enumerate(units))
             + f" {'stable':>6} {'verified':>8}"]

    def num(v, w):
        return f"{'-':>{w}}" if v is None else f"{v:>{w}.3g}"

    def row(tag, r):
        st = "?" if r.stable is None else ("yes" if r.stable else "no")
        du = r.input_shift if r.input_shift is not None else (None, None, None)
        return (f"{tag:>3} {r.status:>8} {r.tau_end:>8.3g} {num(r.position_shift, 9)} {num(r.rotation_shift_deg, 9)} "
                + " ".join(num(v, 11) for v in du)
                + f" {st if r.reached else '-':>6} {str(r.verified) if r.reached else '-':>8}")

    for s, r in zip(res.solutions, ref.solutions):
        lines.append(row(str(s.id), r))
    for b in ref.born:
        lines.append(row("new", b))
    return "\n".join(lines)


def _cmd_kinematics(a) -> int:
    from .io import write_shapes

    if a.gravity is not None and a.model != "cosserat":
        raise CLIError(f"flexkin {a.command}: --gravity needs --model cosserat")
    mech = _load_mech(a.mechanism)
    setup = _cosserat_setup(a, mech) if a.model == "cosserat" else None
    res, what = _kinematics(a, mech)
    if a.stable_only or a.feasible_only:
        res = res.select(stable_only=a.stable_only, feasible_only=a.feasible_only)
    ref = _refine(a, mech, res, setup) if setup is not None and len(res) else None
    if a.json:
        d = res.to_dict(feasibility=a.feasibility or a.feasible_only)
        if a.model == "cosserat":
            entries = _refined_entries(res, ref) if ref is not None else {}
            for e in d["solutions"]:
                e["refined"] = entries.get(e["id"])
            if ref is not None:
                rd = ref.to_dict()
                d["refinement"] = {k: rd[k] for k in ("gravity", "params", "line_loads", "message", "elapsed")}
                d["refinement"]["born"] = rd["born"]
        print(_dump(d))
    else:
        load = ", ".join(f"{v:g}" for v in res.load)
        scope = f"d-modes <= {res.max_mode}"
        if "clamped" in mech.joints:
            scope += f", |winding| <= {res.max_winding}"
        print(f"{mech.name}: {what}, load ({load}), {scope}: {len(res)} solution(s) "
              f"in {res.elapsed:.2f} s" + ("" if res.complete else " (search incomplete)"))
        if len(res):
            print("per d-mode combination: " + ", ".join(f"{k}: {v}" for k, v in sorted(res.by_modes().items())))
            print(res.table(feasibility=a.feasibility))
        if ref is not None:
            print(_refine_table(res, ref))
    if not len(res) or not res.complete:
        print(f"flexkin {a.command}: {res.message}", file=sys.stderr)
    if a.plot:
        if ref is not None:
            from .plot.refine import plot_refinement
            from .plot.solutions import page_paths

            figs = plot_refinement(res.solutions, ref, a.plot)
            files = page_paths(a.plot, len(figs))
        else:
            from .plot.solutions import write_solution_pages

            files = write_solution_pages(res, a.plot)
        for f in files:
            _written(f)
    if a.shapes:
        _written(write_shapes(a.shapes, res))
    if getattr(a, "curves", None):
        from .plot.curves import plot_curves

        plot_curves(res, a.curves)
        _written(a.curves)
    return 0


def _cmd_refine(a) -> int:
    mech = _load_mech(a.mechanism)
    a.command = "refine"
    setup = _cosserat_setup(a, mech)
    res, what = _kinematics(a, mech)
    if a.stable_only:
        res = res.select(stable_only=True)
    if not len(res):
        msg = res.message or "no Kirchhoff equilibrium to refine"
        if a.json:
            print(_dump({"problem": f"refine-{res.problem}", "mechanism": mech.name, "solutions": [], "born": [],
                         "message": msg}))
        print(f"flexkin refine: {msg}", file=sys.stderr)
        return 0
    ref = _refine(a, mech, res, setup)
    if a.json:
        d = ref.to_dict()
        for e, s in zip(d["solutions"], res.solutions):
            e["kirchhoff_modes"] = list(s.modes)
        if res.problem == "ik":
            d["pose"] = [res.given[0], res.given[1], float(np.degrees(res.given[2]))]
        else:
            d["inputs"] = [float(leg.to_display(u)) for u, leg in zip(res.given, mech.legs)]
        print(_dump(d))
    else:
        print(f"{mech.name}: {what}: {len(res)} Kirchhoff solution(s)"
              + (" (stable ones)" if a.stable_only else ""))
        print(_refine_table(res, ref))
    if a.plot:
        from .plot.refine import plot_refinement
        from .plot.solutions import page_paths

        figs = plot_refinement(res.solutions, ref, a.plot)
        for f in page_paths(a.plot, len(figs)):
            _written(f)
    return 0


_FIGURE_FORMATS = ("png", "pdf", "svg", "svgz", "jpg", "jpeg", "eps", "ps", "tif", "tiff", "webp", "pgf")


def _check_outputs(a) -> None:
    """Figure and data output paths are writable files of a known format, before any work."""
    for opt, formats in (("plot", _FIGURE_FORMATS), ("curves", _FIGURE_FORMATS), ("save", ("npz",)),
                         ("shapes", ("csv", "npz"))):
        path = getattr(a, opt, None)
        if not path:
            continue
        flag = "--" + opt
        if os.path.isdir(path):
            raise CLIError(f"flexkin: {flag} {path!r} is a directory; give a file name")
        ext = os.path.splitext(path)[1].lower().lstrip(".")
        if ext not in formats:
            raise CLIError(f"flexkin: {flag} {path!r}: unknown file type {('.' + ext) if ext else '(no extension)'}; "
                           f"use one of {', '.join('.' + f for f in formats)}")
        parent = os.path.dirname(os.path.abspath(path))
        if not os.path.isdir(parent):
            raise CLIError(f"flexkin: {flag} {path!r}: the directory {parent!r} does not exist")
        if not os.access(parent, os.W_OK):
            raise CLIError(f"flexkin: {flag} {path!r}: the directory {parent!r} is not writable")


def _angle_arg(value: float, what: str, note: bool = True) -> None:
    """An angle given in degrees on the command line: beyond the supported range a usage error
    naming the option; with ``note``, more than a full turn a one-line warning."""
    from .core.validation import angle_note, check_angle_deg

    try:
        check_angle_deg(value, what)
    except ValueError as e:
        raise CLIError(f"flexkin: {e}") from None
    text = angle_note(value, what) if note else None
    if text:
        from .errors import FlexkinWarning

        warnings.warn(text, FlexkinWarning, stacklevel=2)


def _check_angles(a) -> None:
    """Every angle option of ``a`` (degrees): see :func:`_angle_arg`; revolute inputs are checked
    where the mechanism is known.  The ends of a path may be several turns apart (no warning)."""
    if getattr(a, "pose", None) is not None:
        _angle_arg(a.pose[2], "--pose THETA")
    for opt in ("start", "end"):
        if getattr(a, opt, None) is not None:
            _angle_arg(getattr(a, opt)[2], ("--from" if opt == "start" else "--to") + " THETA", note=False)
    for t in getattr(a, "theta", None) or ():
        _angle_arg(t, "--theta")
    for opt in ("tip_angle", "clamp_angle"):
        if getattr(a, opt, None) is not None:
            _angle_arg(getattr(a, opt), "--" + opt.replace("_", "-"))


def _show_warning(message, category, filename, lineno, file=None, line=None) -> None:
    """Warnings as one line on stderr: ``flexkin: warning: <text>``."""
    text = " ".join(str(message).split())
    print(f"flexkin: warning: {text}", file=sys.stderr)


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``flexkin`` command.

    Parameters
    ----------
    argv : sequence of str, optional
        Arguments without the program name (default ``sys.argv[1:]``).

    Returns
    -------
    int
        Exit status: 0, or 2 for a usage error (one line on stderr).
    """
    from .errors import FlexkinWarning

    os.environ.setdefault("MPLBACKEND", "Agg")  # figures are files; matplotlib is imported only to draw one
    with warnings.catch_warnings():
        warnings.simplefilter("always", FlexkinWarning)
        warnings.showwarning = _show_warning
        try:
            a = _build_parser().parse_args(argv)
            _check_outputs(a)
            _check_angles(a)
            handler = {"show": _cmd_show, "rod": _cmd_rod, "ik": _cmd_kinematics, "fk": _cmd_kinematics,
                       "path": _cmd_path, "workspace": _cmd_workspace, "reproduce": _cmd_reproduce,
                       "study": _cmd_study, "explore": _cmd_explore, "refine": _cmd_refine,
                       "calibrate": _cmd_calibrate}[a.command]
            return handler(a)
        except CLIError as e:
            print(str(e), file=sys.stderr)
            return EXIT_USAGE
        except (ValueError, OSError) as e:  # library argument checks, unwritable figure path
            print(f"flexkin: {e}", file=sys.stderr)
            return EXIT_USAGE


#: commands that leave no thread, process pool or temporary file behind (see :func:`console`)
_ONE_SHOT = frozenset({"show", "rod", "ik", "fk", "path", "refine", "calibrate"})


def console() -> None:
    """The installed ``flexkin`` command: :func:`main` on ``sys.argv``, then the exit.

    After a one-shot command (show, rod, ik, fk, path, refine, calibrate) the process ends with
    ``os._exit`` as soon as stdout and stderr are flushed and a temporary kernel cache (read-only
    cache directory) is removed: the interpreter's teardown of numba's compiler state would add
    about 0.15 s, a fifth of an IK command (docs/speed.md).  Every file those commands write is
    closed when :func:`main` returns.  Other commands (workspace pools, studies, the explorer,
    reproduce) exit normally.
    """
    argv = sys.argv[1:]
    code = main(argv)
    if argv and argv[0] in _ONE_SHOT:
        try:
            sys.stdout.flush()
            sys.stderr.flush()
        except (OSError, ValueError):  # a closed or broken pipe: the ordinary exit reports it
            sys.exit(code)
        from .core.jit import remove_temporary_caches

        remove_temporary_caches()
        os._exit(code)
    sys.exit(code)


if __name__ == "__main__":  # pragma: no cover
    console()
