"""Plain-text tables of a calibration result (the CLI's output without ``--json``)."""

from __future__ import annotations

import math
from typing import Any

import numpy as np

__all__ = ["result_table", "fmt_value", "rms_text"]


def fmt_value(v: float | None, unit: str) -> str:
    """A parameter value in a readable unit: m as mm, Pa as GPa."""
    if v is None or not math.isfinite(v):
        return "-"
    if unit == "m":
        return f"{v * 1e3:.3f} mm"
    if unit == "Pa":
        return f"{v / 1e9:.3f} GPa"
    if unit == "deg":
        return f"{v:.3f} deg"
    return f"{v:.5g} {unit}"


def _q(r, which: str) -> str:
    v = {"before": r.residual_before, "after": r.residual_after, "loo": r.loo}[which]
    if v is None:
        return "-"
    if r.kind == "fk":
        return f"{math.hypot(v[0], v[1]) * 1e3:6.2f} mm {abs(v[2]):6.2f} deg"
    parts = [f"{x * 1e3:+6.2f}" if u == "m" else f"{x:+6.2f}d" for x, u in zip(v, r.units)]
    return " ".join(parts) + (" mm" if "m" in r.units else "")


def rms_text(d: dict[str, Any], named: bool = True) -> str:
    """RMS residuals ``d`` (keys ``xy`` m, ``theta_deg``, ``u`` m, ``u_deg``) as one phrase in
    mm and deg, each part named (``position``, ``orientation``) when ``named``; ``-`` if empty."""
    parts = []
    if d.get("xy") is not None:
        parts.append(("position " if named else "") + f"{d['xy'] * 1e3:.2f} mm")
    if d.get("theta_deg") is not None:
        parts.append(("orientation " if named else "") + f"{d['theta_deg']:.2f} deg")
    if d.get("u") is not None:
        parts.append(f"inputs {d['u'] * 1e3:.2f} mm")
    if d.get("u_deg") is not None:
        parts.append(f"inputs {d['u_deg']:.2f} deg")
    return ", ".join(parts) or "-"


def _rms_line(name: str, d: dict[str, Any]) -> str:
    return f"  {name:<22} " + rms_text(d)


def result_table(res) -> str:
    """The human-readable report of a :class:`~flexkin.calibration.result.CalibrationResult`.

    Parameters
    ----------
    res : CalibrationResult

    Returns
    -------
    str
    """
    L = []
    m = res.mechanism
    n_fit = sum(not r.outlier for r in res.rows)
    L.append(f"calibration of {getattr(m, 'name', '?')} from {res.source}: {len(res.rows)} rows "
             f"({n_fit} fitted), {len(res.parameters)} parameters, loss {res.loss}"
             + ("" if res.model == "kirchhoff" else f", {res.model} model"))
    L.append("")
    head = f"  {'parameter':<24} {'initial':>14} {'estimate':>14} {'std. error':>14} {'95% interval':>30}"
    L += [head, "  " + "-" * (len(head) - 2)]
    for p in res.parameters:
        ci = "-" if p.ci95 is None else f"[{fmt_value(p.ci95[0], p.unit)}, {fmt_value(p.ci95[1], p.unit)}]"
        L.append(f"  {p.key:<24} {fmt_value(p.initial, p.unit):>14} {fmt_value(p.value, p.unit):>14} "
                 f"{fmt_value(p.stderr, p.unit):>14} {ci:>30}")
    sig = "sigmas as given" if res.absolute_sigma else (
        f"scaled by the residual scale {res.scale:.3g}" if math.isfinite(res.scale) else "no degrees of freedom")
    L.append(f"  chi2 = {res.chi2:.4g} on {res.dof} degrees of freedom; standard errors {sig}")
    if len(res.parameters) > 1 and res.correlation is not None:
        L.append("")
        L.append("  correlation:")
        for i, p in enumerate(res.parameters):
            row = " ".join("    -" if not np.isfinite(c) else f"{c:+5.2f}" for c in res.correlation[i])
            L.append(f"    {p.key:<24} {row}")
    L.append("")
    sv = ", ".join(f"{v:.3g}" for v in res.singular_values)
    L.append(f"  identifiability: singular values of the scaled parameter Jacobian (relative): {sv}")
    if not res.combinations:
        L.append("  every parameter is identified by these data")
    for c in res.combinations:
        what = "weakly identified" if c.identifiable else "NOT identifiable"
        L.append(f"  {what} (singular value {c.singular_value:.2g}): {c.text}")
    L.append("")
    head = f"  {'row':>3} {'kind':<4} {'sol':>4} {'modes':>5}  {'before':>26}  {'after':>26}  {'leave-one-out':>26}"
    L += [head, "  " + "-" * (len(head) - 2)]
    for r in res.rows:
        sol = "-" if r.solution is None else str(r.solution)
        L.append(f"  {r.index:>3} {r.kind:<4} {sol:>4} {r.modes or '-':>5}  {_q(r, 'before'):>26}  "
                 f"{_q(r, 'after') if not r.outlier else 'outlier':>26}  {_q(r, 'loo'):>26}")
        if r.outlier:
            L.append(f"        outlier: {r.reason}")
        if r.note:
            L.append(f"        note: {r.note}")
    L.append("")
    L.append("  RMS over the fitted rows:")
    L.append(_rms_line("before", res.rms_before))
    L.append(_rms_line("after", res.rms_after))
    L.append(_rms_line("leave-one-out", res.loo_rms))
    if res.message:
        L.append("")
        L.append(f"  note: {res.message}")
    return "\n".join(L)
