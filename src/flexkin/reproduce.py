"""``flexkin reproduce``: the paper's whole analysis on the bundled examples, as one report.

Writes into a directory ``report.md``, a self-contained ``report.html`` (the same report with
every figure embedded as base64; the tables' CSV files are linked), PNG figures and CSV tables:

1. the rod model checked against an ODE integration, and the Fig. 19 force sweep;
2. the parameter space of Fig. 2(a) and its rectangular ``k_r`` form (Fig. 6);
3. the geometric-condition curves of Fig. 7 (prototype at 90°);
4. all IK solutions (d-modes 1–2) of the 3-P̲FR, 3-R̲FR and 3-PF̲R case studies (Figs. 10–15):
   each opens with the count per d-mode combination and the stable solutions; the full table
   is a CSV file;
5. the FK solutions of the 3-R̲FR (Fig. 16);
6. a constant-orientation workspace (Fig. 17);
7. Tables 1 and 2 (theory columns) on the prototype, flexkin beside the paper;
8. Tables 1 and 2 refined with a Cosserat model (extension and shear, paper §7's EA and GA),
   and the prototype in a vertical plane under its own weight: which FK solutions survive and
   how far the stable ones move (:mod:`flexkin.cosserat`);
9. calibrating the prototype on the measured columns of Tables 1 and 2
   (``examples/prototype_measurements.csv``): the three input offsets, then the offsets and E,
   with residuals before and after, leave-one-out errors and what five rows can identify
   (:mod:`flexkin.calibration`).

Numbers are printed to the precision that means something: positions to 0.1 µm (a computed
2e-14 m is 0), actuator strokes to 0.1 mm, angles to 0.01°.
"""

from __future__ import annotations

import csv
import re
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable

import numpy as np

from .core.geometry2d import wrap_to_pi
from .io.html_report import markdown_to_html

__all__ = ["reproduce", "ReproduceResult", "PAPER_TABLE1", "PAPER_TABLE2", "fmt_length"]

#: paper Table 1 (theory): FK of the prototype at rho = 25 mm, platform orientations (deg)
PAPER_TABLE1 = (90.0, -75.7)
#: paper Table 2 (theory): IK of the prototype, orientation (deg) -> rho (m)
PAPER_TABLE2 = {60.0: -0.007, 90.0: 0.025, 120.0: 0.058}

_EXAMPLES = Path(__file__).resolve().parents[2] / "examples"
CASE_POSE = (0.05, 0.02, 20.0)  # m, m, deg: the IK case studies
#: positions below this (m) are printed as 0: the solvers' resolution on a metre-size mechanism
LENGTH_RESOLUTION = 1e-7


@dataclass(frozen=True)
class ReproduceResult:
    """What :func:`reproduce` wrote and measured."""

    out: Path
    report: Path
    figures: tuple[Path, ...]
    table1: list[dict[str, Any]]
    table2: list[dict[str, Any]]
    rod_check: dict[str, float]
    elapsed: float
    counts: dict[str, dict[str, int]] = field(default_factory=dict)
    html: Path | None = None
    tables: tuple[Path, ...] = ()


def _examples_dir() -> Path:
    if _EXAMPLES.is_dir():
        return _EXAMPLES
    return Path.cwd() / "examples"


def fmt_length(v: float, resolution: float = LENGTH_RESOLUTION) -> str:
    """A length in m to the given resolution: ``2.04e-14`` -> ``"0"``, ``0.024950`` -> ``"0.02495"``.

    Parameters
    ----------
    v : float
        Length (m).
    resolution : float
        Smallest length that means something (m).

    Returns
    -------
    str
    """
    if not np.isfinite(v):
        return "–"
    if abs(v) < resolution:
        return "0"
    decimals = max(0, int(-np.floor(np.log10(resolution))))
    s = f"{v:.{decimals}f}".rstrip("0").rstrip(".")
    return "0" if s in ("-0", "") else s


def _rod_check(n: int = 24) -> dict[str, float]:
    """Closed form (Eqs. 9–14) against an ODE integration from the clamp (scipy solve_ivp)."""
    from scipy.integrate import solve_ivp

    from .rod.closed_form import tip_chart

    rng = np.random.default_rng(0)
    v = rng.uniform(-3, 3, n)
    ph = rng.uniform(-4.5, 1.4, n)
    t = tip_chart(v, ph)
    err_p = err_t = 0.0
    for i in range(n):
        fx, fy, m0 = float(t.fx[i]), float(t.fy[i]), float(t.m0[i])

        def rhs(s, y):
            return [np.cos(y[2]), np.sin(y[2]), y[3], fx * np.sin(y[2]) - fy * np.cos(y[2])]

        sol = solve_ivp(rhs, (0, 1), [0, 0, 0, m0], rtol=1e-12, atol=1e-13, method="DOP853")
        y = sol.y[:, -1]
        err_p = max(err_p, float(np.hypot(y[0] - t.x[i], y[1] - t.y[i])))
        err_t = max(err_t, abs(wrap_to_pi(y[2] - t.theta[i])), abs(float(y[3])))
    return {"rods": n, "max_tip_position_error_per_L": err_p, "max_tip_angle_or_moment_error": err_t}


# ---- tables ---------------------------------------------------------------------------------
def _verdict(s) -> str:
    return "undecided" if s.stable is None else ("yes" if s.stable else "no")


def write_solutions_csv(res, path: Path) -> Path:
    """Every solution of ``res`` with its id, d-modes, pose, inputs (display units), energy,
    stability, Jacobian measures and feasibility (with reasons) as CSV."""
    units = [leg.input_unit for leg in res.mechanism.legs]
    feas = res.feasibility()
    with open(path, "w", newline="", encoding="utf-8") as fh:
        w = csv.writer(fh)
        w.writerow(["id", "modes", "x_m", "y_m", "theta_deg"] + [f"u{i + 1}_{u}" for i, u in enumerate(units)]
                   + ["energy_J", "stable", "stability_margin", "det_J_IK", "det_J_FK", "cond", "feasible",
                      "reasons"])
        for s, f in zip(res.solutions, feas):
            jac = s.jacobian
            w.writerow([s.id, s.mode_label, f"{s.pose[0]:.9g}", f"{s.pose[1]:.9g}", f"{np.degrees(s.pose[2]):.6f}"]
                       + [f"{v:.9g}" for v in s.inputs_display()]
                       + [f"{s.energy:.6g}", _verdict(s),
                          "" if s.stability_margin is None else f"{s.stability_margin:.4g}",
                          "" if jac is None else f"{jac.det_ik:.4g}", "" if jac is None else f"{jac.det_fk:.4g}",
                          "" if jac is None else f"{jac.cond:.4g}", "yes" if f.feasible else "no",
                          "; ".join(f.reasons)])
    return path


def _md_solutions(res, sols, feas) -> list[str]:
    """A Markdown table of ``sols``: the inputs for an IK result (the pose is the given one), the
    pose for an FK result; positions to 1 µm, strokes to 0.1 mm, angles to 0.01°."""
    units = [leg.input_unit for leg in res.mechanism.legs]
    ik_ = res.problem == "ik"
    cols = ([f"u{i + 1} [{u}]" for i, u in enumerate(units)] if ik_ else ["x [m]", "y [m]", "θ [deg]"])
    head = "| id | d-modes | " + " | ".join(cols) + " | energy [J] | feasible |"
    lines = [head, "|" + "---|" * (head.count("|") - 1)]
    for s, f in zip(sols, feas):
        if ik_:
            vals = [f"{v:.2f}" if un == "deg" else fmt_length(v, 1e-4) for v, un in zip(s.inputs_display(), units)]
        else:
            vals = [fmt_length(s.pose[0], 1e-6), fmt_length(s.pose[1], 1e-6), f"{np.degrees(s.pose[2]):.2f}"]
        why = "yes" if f.feasible else "no: " + "; ".join(f.reasons)
        lines.append(f"| {s.id} | {s.mode_label} | " + " | ".join(vals) + f" | {s.energy:.4g} | {why} |")
    return lines


def _case_block(res, label: str, csv_name: str) -> list[str]:
    """Count per d-mode combination, the stable solutions, the link to the full table."""
    counts = res.by_modes()
    feas = res.feasibility()
    stable = [(s, f) for s, f in zip(res.solutions, feas) if s.stable]
    undecided = sum(1 for s in res.solutions if s.stable is None)
    md = [f"{len(res)} equilibria, {len(stable)} stable" + (f", {undecided} undecided" if undecided else "")
          + f", {sum(f.feasible for _, f in stable)} of the stable ones feasible.", "",
          "| d-modes | " + " | ".join(sorted(counts)) + " | total |",
          "|---|" + "---|" * (len(counts) + 1),
          "| solutions | " + " | ".join(str(counts[k]) for k in sorted(counts)) + f" | {len(res)} |",
          "| stable | " + " | ".join(str(sum(1 for s, _ in stable if s.mode_label == k)) for k in sorted(counts))
          + f" | {len(stable)} |", ""]
    if stable:
        md += [f"Stable solutions of the {label} (ids as in the full table):", ""]
        md += _md_solutions(res, [s for s, _ in stable], [f for _, f in stable]) + [""]
    md += [f"Full table (every equilibrium, with stability, Jacobians and feasibility): [{csv_name}]({csv_name})", ""]
    return md


def _feasibility_summary(feas) -> str:
    """``"3 feasible; 5 rods intersect, 2 input out of range"`` style count of the reasons."""
    kinds: dict[str, int] = {}
    for f in feas:
        for r in f.reasons:
            key = re.sub(r"[0-9.eE+-]+", "#", r)
            key = ("rods intersect / collide" if key.startswith("rods ") else
                   "self-intersection / self-contact" if "self-" in key else
                   "rod crosses / touches the platform" if "platform" in key else
                   "strain above the limit" if key.startswith("strain") else
                   "input outside its range" if "outside range" in key else key)
            kinds[key] = kinds.get(key, 0) + 1
    n_ok = sum(f.feasible for f in feas)
    why = ", ".join(f"{k}: {v}" for k, v in sorted(kinds.items(), key=lambda kv: -kv[1]))
    return f"{n_ok} feasible" + (f" (reasons found on the others: {why})" if why else "")


# ---- HTML -----------------------------------------------------------------------------------
# ---- Cosserat refinement (issue 16) --------------------------------------------------------
#: the prototype's shear modulus (Pa): GA = 1.8e5 N over A = pi (1.5 mm)^2 (paper §7; EA = 4.8e5 N
#: follows from E = 68 GPa)
PROTOTYPE_G = 1.8e5 / (np.pi * 1.5e-3**2)
#: Nitinol's density (kg/m^3), for the prototype's self-weight
PROTOTYPE_DENSITY = 6450.0
#: gravity of the vertical-plane variant (m/s^2): the platform plane is vertical, y up
VERTICAL_GRAVITY = (0.0, -9.81)


def _small(v: float | None, resolution: float) -> str:
    """Two significant digits, ``"0"`` below ``resolution`` (the solvers' resolution)."""
    if v is None or not np.isfinite(v):
        return "–"
    return "0" if abs(v) < resolution else f"{v:.2g}"


def _cosserat_section(proto, fk_result, table1, table2) -> list[str]:
    """Tables 1 and 2 refined with extension and shear (the prototype lies on a table: no
    gravity in its plane), and the prototype stood up in a vertical plane under its own weight:
    which FK solutions survive, how far the stable ones move."""
    from .cosserat import CosseratParams, refine

    params = CosseratParams.from_material(proto.legs[0].rod.E, proto.legs[0].rod.radius, G=PROTOTYPE_G,
                                          density=PROTOTYPE_DENSITY)
    md = ["## 8. Refinement with a Cosserat model (extension, shear, self-weight)", "",
          f"Each Kirchhoff solution is followed by continuation from the Kirchhoff rod (τ = 0) to the planar "
          f"Cosserat rod (τ = 1): EA = {params.EA:.3g} N, GA = {params.GA:.3g} N (paper §7), Nitinol "
          f"{PROTOTYPE_DENSITY:g} kg/m³ ({params.mass_per_length * 1e3:.3g} g/m).", "",
          "### Tables 1 and 2, refined (horizontal plane: no weight in the plane)", "",
          "| table | Kirchhoff solution | outcome | platform moves [m] | θ changes [deg] | inputs change [m] | "
          "stable |", "|---|---|---|---|---|---|---|"]
    rows = [("Table 1", r["paper_theta_deg"], r["solution"]) for r in table1]
    rows += [("Table 2", r["theta_deg"], r["solution"]) for r in table2]
    refined_rows = []
    for table, problem in (("Table 1", "fk"), ("Table 2", "ik")):  # FK keeps the inputs, IK the pose
        sols = [s for t, _, s in rows if t == table and s is not None]
        if sols:
            refined_rows += refine(proto, sols, params=params, problem=problem, born_search=False).solutions
    refined = iter(refined_rows)
    for table, key, s in rows:
        if s is None:
            md.append(f"| {table} | θ = {key:g}°: not found | – | – | – | – | – |")
            continue
        r = next(refined)
        if not r.reached:
            moved = ["–", "–", "–"]
        elif table == "Table 1":  # FK: the inputs are the given ones
            moved = [_small(r.position_shift, 1e-9), _small(r.rotation_shift_deg, 1e-7), "given"]
        else:  # IK: the pose is the given one
            moved = ["given", "given", ", ".join(_small(v, 1e-9) for v in r.input_shift)]
        md.append(f"| {table} | θ = {key:g}°, #{s.id} ({s.mode_label}) | {r.status} | " + " | ".join(moved)
                  + f" | {_verdict(r)} |")
    md += ["", "Table 1 is FK (inputs fixed, the platform moves); Table 2 is IK (pose fixed, the inputs move). "
           "The paper expects changes of order 1e-5 from extension and shear on this prototype.", ""]
    refg = refine(proto, fk_result, params=params, gravity=VERTICAL_GRAVITY)
    reached = [(s, r) for s, r in zip(fk_result.solutions, refg.solutions) if r.reached]
    md += ["### The prototype in a vertical plane, under its own weight", "",
           f"FK at ρ = (25, 25, 25) mm with gravity ({VERTICAL_GRAVITY[0]:g}, {VERTICAL_GRAVITY[1]:g}) m/s² "
           f"(platform massless): {len(reached)} of {len(fk_result)} Kirchhoff solutions survive, "
           f"{len(refg.born)} new solution(s) appear. {refg.message}.", "",
           "| Kirchhoff solution | stable (Kirchhoff) | outcome | ends at τ | platform moves [m] | "
           "θ changes [deg] | stable (refined) |", "|---|---|---|---|---|---|---|"]
    for s, r in zip(fk_result.solutions, refg.solutions):
        md.append(f"| #{s.id} ({s.mode_label}) | {_verdict(s)} | {r.status} | {r.tau_end:.3g} | "
                  + ("–" if r.position_shift is None else f"{r.position_shift * 1e3:.2f} mm") + " | "
                  + ("–" if r.rotation_shift_deg is None else f"{r.rotation_shift_deg:.3f}")
                  + f" | {_verdict(r) if r.reached else '–'} |")
    return md


# ---- the report -----------------------------------------------------------------------------
# ---- calibration (issue 28) ----------------------------------------------------------------
def _calibration_section(out: Path, figs: list[Path]) -> list[str]:
    """Section 9: the prototype calibrated on the measured columns of Tables 1 and 2."""
    from .calibration import calibrate
    from .calibration.report import markdown

    ex = _examples_dir()
    mech, data = ex / "prototype_3pfr.toml", ex / "prototype_measurements.csv"
    r1 = calibrate(mech, data, ["leg[*].offset"])
    r2 = calibrate(mech, data, ["leg[*].offset", "rod.E"])
    f1, f2 = out / "calibration_offsets.png", out / "calibration_offsets_E.png"
    r1.plot(str(f1))
    r2.plot(str(f2))
    figs.extend([f1, f2])
    n_fk = sum(r.kind == "fk" for r in r1.rows)
    n_ik = len(r1.rows) - n_fk
    n_num = 3 * len(r1.rows)
    offs = ", ".join(f"{p.value * 1e3:.1f} ± {p.stderr * 1e3:.1f} mm" if p.stderr else f"{p.value * 1e3:.1f} mm"
                     for p in r1.parameters)
    E = r2.estimate("rod.E")
    e_seen = E.stderr is not None
    before, after, loo = r1.rms_before, r1.rms_after, r1.loo_rms

    def mm(v):
        return "–" if v is None else f"{v * 1e3:.1f} mm"

    def deg(v):
        return "–" if v is None else f"{v:.1f}°"

    md = ["## 9. Calibrating the prototype", "",
          f"The paper's prototype was measured without calibration (§7). `{data.name}` holds the measured columns "
          f"of Tables 1 and 2: {n_fk} FK rows (ρ = 25 mm set, pose measured) and {n_ik} IK rows (pose commanded, "
          f"strokes measured), {n_num} numbers in all, read to 1 mm and 1° (the default standard deviations). "
          "Each row is matched to the stable equilibrium nearest to it and followed as the parameters change "
          "(docs/calibration.md).", "",
          "### The three input offsets", "", markdown(r1, f1.name, f"flexkin calibrate {mech.name} --data "
                                                                    f"{data.name} --fit 'leg[*].offset'"),
          "### The offsets and Young's modulus", "", markdown(r2, f2.name, f"flexkin calibrate {mech.name} --data "
                                                                         f"{data.name} --fit 'leg[*].offset' "
                                                                         "--fit rod.E"),
          "### What five rows can and cannot identify", "",
          f"- **The offsets** are identified: with them the RMS error falls from {mm(before['xy'])}, "
          f"{deg(before['theta_deg'])} and {mm(before['u'])} (positions, orientations, strokes) to "
          f"{mm(after['xy'])}, {deg(after['theta_deg'])} and {mm(after['u'])}; leave-one-out predictions miss by "
          f"{mm(loo['xy'])}, {deg(loo['theta_deg'])} and {mm(loo['u'])}. The offsets are {offs}. The residual "
          f"scale is {r1.scale:.2g}: " + (
              f"what remains is {r1.scale:.2g} times the 1 mm / 1° reading precision, so the model still misses "
              "something that no input zero can absorb" if r1.scale > 1.5 else
              "what remains is at the 1 mm / 1° reading precision") + (
              " (the positions of the FK rows, which the offsets hardly move)."
              if before["xy"] and after["xy"] and after["xy"] > 0.8 * before["xy"] else "."),
          ("- **Young's modulus** is identified here (" + (f"{E.value / 1e9:.1f} ± {E.stderr / 1e9:.1f} GPa"
                                                             if e_seen else "") + ")." if e_seen else
           "- **Young's modulus** is not identifiable from these rows, and would not be from any number of rows "
           "like them: the prototype is unloaded, and scaling every rod's stiffness by the same factor scales every "
           "internal force and moves no equilibrium (the singular value of E's direction is "
           f"{min(r2.singular_values):.1g} of the largest). E needs loaded rows or measured forces; the fit keeps E "
           "at its starting value and says so."),
          "- **Leg placement.** A prismatic leg's offset and its origin along the guide move the clamp alike: "
          f"they are one parameter, and `flexkin calibrate` names such pairs. Fitting the origins across the "
          f"guides and the guide angles as well would put 9 parameters on {n_num} numbers that the offsets alone "
          f"already leave {r1.scale:.2g} times their precision apart: more rows at other poses, and loaded ones, are "
          "needed before the paper's inferred leg placement can be tested.", ""]
    return md


@dataclass
class _Report:
    """The report being written: its directory, Markdown lines, figures, tables and progress."""

    out: Path
    quick: bool
    tick: Callable[[str], None]
    md: list[str] = field(default_factory=list)
    figs: list[Path] = field(default_factory=list)
    tables: list[Path] = field(default_factory=list)

    def figures(self, files: list[Path], alt: str) -> None:
        """Add links to ``files`` (pages of one figure) to the report."""
        self.figs.extend(files)
        for k, f in enumerate(files, 1):
            self.md += [f"![{alt}" + (f", page {k} of {len(files)}" if len(files) > 1 else "") + f"]({f.name})", ""]


def _section_rod(rep: _Report) -> dict[str, float]:
    """1. The rod model against an ODE integration, and Fig. 19."""
    from .mechanism.model import circular_EI
    from .plot.rod import plot_rod_sweep
    from .solve.rod_sweep import FIG19, rod_sweep

    rc = _rod_check(8 if rep.quick else 24)
    rep.tick("rod model")
    rep.md += ["## 1. Rod model (Eqs. 9–14) against an ODE integration", "",
               f"{rc['rods']} random rods (d-modes 1–3, both signs of k): largest tip position error "
               f"{rc['max_tip_position_error_per_L']:.1e} L, largest tip angle / tip moment error "
               f"{rc['max_tip_angle_or_moment_error']:.1e} (both at the integration's tolerance).", ""]
    EI = circular_EI(FIG19["E"], FIG19["radius"])
    xs = np.linspace(FIG19["x_start"], FIG19["x_end"], 6 if rep.quick else 36)
    sweep = rod_sweep(xs, FIG19["tip_y"], FIG19["length"], EI)
    f = rep.out / "fig19_rod_forces.png"
    plot_rod_sweep(sweep, str(f))
    rep.tick("Fig. 19")
    rep.md += ["### Fig. 19: tip force of one rod along a sweep of its tip", "",
               f"Nitinol rod L = {FIG19['length']} m, r = {FIG19['radius'] * 1e3:g} mm, tip height "
               f"{FIG19['tip_y']} m, tip abscissa {FIG19['x_start']} → {FIG19['x_end']} m.", ""]
    rep.figures([f], "Fig. 19")
    return rc


def _section_parameter_space(rep: _Report) -> None:
    """2. The parameter space (Fig. 2a) and its rectangular form (Fig. 6)."""
    from .plot.rod import plot_parameter_space

    f1, f2 = rep.out / "fig2_parameter_space_mode1.png", rep.out / "fig2_parameter_space_mode2.png"
    n = 121 if rep.quick else 361
    plot_parameter_space(1, "R", str(f1), n=n)
    plot_parameter_space(2, "R", str(f2), n=n)
    rep.tick("parameter space")
    rep.md += ["## 2. Parameter space (Fig. 2a) and its rectangular k_r form (Fig. 6)", ""]
    rep.figures([f1], "mode 1")
    rep.figures([f2], "mode 2")


def _section_curves(rep: _Report, proto) -> None:
    """3. The geometric-condition curves of the prototype (Fig. 7)."""
    from .solve.ik import ik
    from .plot.curves import plot_curves

    r90 = ik(proto, (0.0, 0.0, np.radians(90)), load=(0, 0, 0))
    f = rep.out / "fig7_curves_prototype_90deg.png"
    plot_curves(r90, str(f))
    rep.tick("Fig. 7")
    rep.md += ["## 3. Geometric-condition curves (Fig. 7), prototype at (0, 0, 90°)", "",
               f"{len(r90)} IK solutions; dots are labelled with their ids (dots at one place share a label).", ""]
    rep.figures([f], "Fig. 7")


def _section_ik_cases(rep: _Report, ex: Path, pose: tuple[float, float, float]) -> dict[str, dict[str, int]]:
    """4. Full IK of the three case studies (Figs. 10–15); the solution counts by d-modes."""
    from .mechanism import load_mechanism
    from .solve.ik import ik
    from .plot.solutions import write_solution_pages

    counts: dict[str, dict[str, int]] = {}
    rep.md += ["## 4. Full inverse kinematics of the case studies (Figs. 10–15)", "",
               f"Pose ({CASE_POSE[0]} m, {CASE_POSE[1]} m, {CASE_POSE[2]}°), unloaded, d-modes 1–2. Solutions are "
               "numbered by id, the same in the tables, the CSV files and the figures; colours are d-mode "
               "combinations.", ""]
    for key, fname, label in (("IK 3-PFR", "unit_3pfr.toml", "3-P̲FR (prismatic)"),
                              ("IK 3-RFR", "unit_3rfr.toml", "3-R̲FR (revolute)"),
                              ("IK 3-PFR(length)", "unit_3pfr_length.toml", "3-PF̲R (length)")):
        mech = load_mechanism(ex / fname)
        res = ik(mech, pose, load=(0, 0, 0))
        counts[key] = res.by_modes()
        stem = f"ik_{fname.replace('.toml', '')}"
        tab = write_solutions_csv(res, rep.out / f"{stem}.csv")
        rep.tables.append(tab)
        rep.md += [f"### {label}", ""] + _case_block(res, label, tab.name)
        shown = res.select(stable_only=True) if rep.quick else res
        what = "the stable solutions" if rep.quick else "every solution"
        rep.md += [f"Figure: {what}" + (f" ({len(shown)})" if rep.quick else "") + ".", ""]
        rep.figures(write_solution_pages(shown, rep.out / f"{stem}.png"), key)
        rep.tick(key)
    return counts


def _section_fk(rep: _Report, rfr, pose: tuple[float, float, float]) -> dict[str, int]:
    """5. Full FK of the 3-RFR at the inputs of its first IK solution (Fig. 16)."""
    from .solve.fk import fk
    from .solve.ik import ik
    from .plot.solutions import write_solution_pages

    base = ik(rfr, pose, load=(0, 0, 0))
    u = base.solutions[0].inputs
    res = fk(rfr, u, load=(0, 0, 0))
    tab = write_solutions_csv(res, rep.out / "fk_unit_3rfr.csv")
    rep.tables.append(tab)
    st = res.select(stable_only=True)
    st111 = type(st)(**{**st.__dict__, "solutions": tuple(s for s in st.solutions if s.modes == (1, 1, 1)),
                        "_cache": {}})
    rep.md += ["## 5. Full forward kinematics of the 3-R̲FR (Fig. 16)", "",
               "Inputs (deg): " + ", ".join(f"{np.degrees(v):.2f}" for v in u)
               + f" (those of IK solution {base.solutions[0].id} of section 4).", ""]
    rep.md += _case_block(res, "FK", tab.name)
    rep.md += [f"Stable with d-modes 111: {len(st111)}, of which {_feasibility_summary(st111.feasibility())}. "
               "The paper finds 4 stable mode-111 solutions for its differently sized case.", ""]
    rep.figures(write_solution_pages(st111, rep.out / "fk_unit_3rfr_stable_111.png"), "Fig. 16")
    rep.tick("FK 3-RFR")
    return res.by_modes()


def _section_workspace(rep: _Report, rfr) -> None:
    """6. The constant-orientation workspace of the 3-RFR (Fig. 17)."""
    from .plot.workspace import plot_workspace
    from .solve.workspace import workspace

    step = 0.05 if rep.quick else 0.015
    ws = workspace(rfr, np.radians(20.0), step=step, bounds=(-0.6, 0.6, -0.6, 0.6), all_aspects=False)
    rep.tick("workspace")
    rep.md += ["## 6. Constant-orientation workspace (Fig. 17)", "", "```", ws.summary(), "```", "",
               "One aspect: the region reached from the first stable IK solution at the seed. Black: IK singularity "
               "(the continued solution folds back); orange: FK singularity / loss of stability; grey: unresolved "
               "(a rod straight under tension, see the README).", ""]
    f = rep.out / "fig17_workspace_unit_3rfr_20deg.png"
    plot_workspace([ws], str(f))
    rep.figures([f], "Fig. 17")


def _section_tables(rep: _Report, proto) -> tuple[Any, list[dict[str, Any]], list[dict[str, Any]]]:
    """7. Tables 1 and 2 (theory columns); the FK result of Table 1 and the rows of both."""
    from .solve.fk import fk
    from .solve.ik import ik

    r1 = fk(proto, (0.025, 0.025, 0.025), load=(0, 0, 0))
    table1 = []
    for target in PAPER_TABLE1:
        hit = [s for s in r1.solutions if s.stable and s.modes == (1, 1, 1)
               and abs(np.degrees(s.pose[2]) - target) < 5.0]
        s = hit[0] if hit else None
        table1.append({"paper_theta_deg": target,
                       "flexkin_pose": None if s is None else [s.pose[0], s.pose[1], float(np.degrees(s.pose[2]))],
                       "stable": None if s is None else s.stable, "id": None if s is None else s.id,
                       "solution": s})
    rep.tick("Table 1")
    table2 = []
    for th, rho_paper in PAPER_TABLE2.items():
        r = ik(proto, (0.0, 0.0, np.radians(th)), load=(0, 0, 0))
        sym = [s for s in r.solutions if s.stable and s.modes == (1, 1, 1) and np.ptp(s.inputs) < 1e-9]
        sym.sort(key=lambda s: abs(s.inputs[0] - rho_paper))
        table2.append({"theta_deg": th, "paper_rho": rho_paper,
                       "flexkin_rho": None if not sym else float(sym[0].inputs[0]),
                       "stable": None if not sym else sym[0].stable, "solution": None if not sym else sym[0]})
    rep.tick("Table 2")
    rep.md += ["## 7. Tables 1 and 2 (prototype `examples/prototype_3pfr.toml`, theory columns)", "",
               "### Table 1: FK at ρ = (25, 25, 25) mm", "",
               f"Positions to {LENGTH_RESOLUTION:g} m (the solvers' resolution here), angles to 0.01°.", "",
               "| paper θ [deg] | flexkin pose (x [m], y [m], θ [deg]) | stable |", "|---|---|---|"]
    for row in table1:
        p = row["flexkin_pose"]
        rep.md.append(f"| {row['paper_theta_deg']:g} | "
                      + ("not found" if p is None else f"({fmt_length(p[0])}, {fmt_length(p[1])}, {p[2]:.2f})")
                      + f" | {row['stable']} |")
    rep.md += ["", "### Table 2: IK at (0, 0, θ), symmetric stable d-mode-111 solution", "",
               "| θ [deg] | paper ρ [m] | flexkin ρ [m] | stable |", "|---|---|---|---|"]
    for row in table2:
        rep.md.append(f"| {row['theta_deg']:g} | {row['paper_rho']:.3f} | "
                      + ("not found" if row["flexkin_rho"] is None else f"{row['flexkin_rho']:.4f}")
                      + f" | {row['stable']} |")
    return r1, table1, table2


#: the steps of the report, in order (the progress bar's total)
STEPS = ("rod model", "Fig. 19", "parameter space", "Fig. 7", "IK 3-PFR", "IK 3-RFR", "IK 3-PFR(length)",
         "FK 3-RFR", "workspace", "Table 1", "Table 2", "Cosserat", "calibration", "report")


def reproduce(out: str | Path = "flexkin_report", quick: bool = False,
              progress: bool | Callable[[str], None] = True) -> ReproduceResult:
    """Run the paper's analysis and write the report into ``out``.

    Parameters
    ----------
    out : path
        Output directory (created).
    quick : bool
        Small grids and sweeps (for tests): same sections and tables, coarser figures; the
        case-study figures show the stable solutions only (every solution is in the CSV files).
    progress : bool or callable
        ``True`` shows a progress bar on stderr; a callable receives the name of each step.

    Returns
    -------
    ReproduceResult
    """
    import matplotlib

    matplotlib.use("Agg")
    from .mechanism import load_mechanism

    t0 = time.perf_counter()
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    ex = _examples_dir()
    bar = None
    if progress is True:
        from .io.progress import bar as progress_bar

        bar = progress_bar(len(STEPS), "flexkin reproduce", unit="step")

    def tick(name: str) -> None:
        if bar is not None:
            bar.set_postfix_str(name)
            bar.update(1)
        elif callable(progress):
            progress(name)

    rep = _Report(out, quick, tick, ["# flexkin: reproduction of the paper's analysis", "",
                                     "Generated by `flexkin reproduce`" + (" (quick mode: coarse grids)" if quick
                                                                          else "") + ".", ""])
    proto = load_mechanism(ex / "prototype_3pfr.toml")
    rfr = load_mechanism(ex / "unit_3rfr.toml")
    pose = (CASE_POSE[0], CASE_POSE[1], np.radians(CASE_POSE[2]))
    rc = _section_rod(rep)
    _section_parameter_space(rep)
    _section_curves(rep, proto)
    counts = _section_ik_cases(rep, ex, pose)
    counts["FK 3-RFR"] = _section_fk(rep, rfr, pose)
    _section_workspace(rep, rfr)
    r1, table1, table2 = _section_tables(rep, proto)
    rep.md += [""] + _cosserat_section(proto, r1, table1, table2)
    tick("Cosserat")
    rep.md += [""] + _calibration_section(out, rep.figs)
    tick("calibration")
    elapsed = time.perf_counter() - t0
    rep.md += ["", f"Total time {elapsed:.0f} s."]
    report = out / "report.md"
    text = "\n".join(rep.md) + "\n"
    report.write_text(text, encoding="utf-8")
    html_path = out / "report.html"
    html_path.write_text(markdown_to_html(text, out, "flexkin: reproduction of the paper's analysis"),
                         encoding="utf-8")
    tick("report")
    if bar is not None:
        bar.close()
    return ReproduceResult(out, report, tuple(rep.figs), table1, table2, rc, elapsed, counts, html_path,
                           tuple(rep.tables))
