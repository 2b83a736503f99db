"""Figure of a calibration (``flexkin calibrate --plot``/``--report``): measured vs predicted.

Three panels:

* **poses (FK rows)**: the measured platform positions (black crosses) and the predicted ones
  before (grey) and after (blue) the fit, in mm, each with a short stroke showing its
  orientation and a thin line to its measurement;
* **inputs (IK rows)**: predicted minus measured input of every leg of every row, before
  (grey) and after (blue), in mm (or deg for revolute legs);
* **residuals per row**: the row's standardized error (RMS of its three residuals over their
  standard deviations) before and after the fit and, hollow, its leave-one-out prediction
  error; outliers are hatched and labelled.

It reads only the result's rows (duck-typed), so it sits below the calibration layer.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np

from .style import new_figure, save

__all__ = ["plot_calibration"]

_BEFORE, _AFTER, _MEAS = "0.6", "tab:blue", "k"


def _z_norm(z) -> float:
    return float(math.sqrt(np.mean(np.square(z)))) if z is not None else math.nan


def plot_calibration(res: Any, path: str | None = None, title: str | None = None):
    """Draw a calibration result.

    Parameters
    ----------
    res : CalibrationResult
        The result of :func:`flexkin.calibrate`.
    path : str, optional
        Where to save the figure (format from the extension).
    title : str, optional
        Figure title (default: the mechanism and the fitted keys).

    Returns
    -------
    matplotlib.figure.Figure
    """
    rows = list(res.rows)
    fig = new_figure(figsize=(14, 4.6))
    ax1, ax2, ax3 = fig.subplots(1, 3, gridspec_kw={"width_ratios": [1.0, 1.1, 1.1]})
    # ---- poses -------------------------------------------------------------------------
    fk = [r for r in rows if r.kind == "fk"]
    if fk:
        span = []
        for r in fk:
            mx, my, mth = r.measured
            span += [mx, my]
            for pr, col in ((r.predicted_before, _BEFORE), (r.predicted_after, _AFTER)):
                if pr is not None:
                    span += [pr[0], pr[1]]
        ext = max(1e-3, 0.6 * (max(span) - min(span)) if span else 1e-3)
        arm = 0.25 * ext * 1e3
        for r in fk:
            mx, my, mth = r.measured
            for pr, col, lab in ((r.predicted_before, _BEFORE, "before"), (r.predicted_after, _AFTER, "after")):
                if pr is None or (r.outlier and lab == "after"):
                    continue
                px, py, pth = pr[0] * 1e3, pr[1] * 1e3, math.radians(pr[2])
                ax1.plot([mx * 1e3, px], [my * 1e3, py], color=col, lw=0.6, alpha=0.7)
                ax1.plot(px, py, "o", color=col, ms=6, label=lab if r is fk[0] else None)
                ax1.plot([px, px + arm * math.cos(pth)], [py, py + arm * math.sin(pth)], color=col, lw=2)
            t = math.radians(mth)
            ax1.plot(mx * 1e3, my * 1e3, "x", color=_MEAS, ms=9, mew=2, label="measured" if r is fk[0] else None)
            ax1.plot([mx * 1e3, mx * 1e3 + arm * math.cos(t)], [my * 1e3, my * 1e3 + arm * math.sin(t)],
                     color=_MEAS, lw=1.2, ls="--")
            ax1.annotate(f"row {r.index}" + (" (outlier)" if r.outlier else ""), (mx * 1e3, my * 1e3),
                         textcoords="offset points", xytext=(6, -12), fontsize=8)
        ax1.set_aspect("equal", adjustable="datalim")
        ax1.legend(fontsize=8, loc="best")
        ax1.set_xlabel("x [mm]")
        ax1.set_ylabel("y [mm]")
        ax1.set_title("FK rows: platform poses\n(stroke: orientation)", fontsize=10)
        ax1.grid(alpha=0.3)
    else:
        ax1.text(0.5, 0.5, "no FK rows", ha="center", va="center", transform=ax1.transAxes)
        ax1.set_axis_off()
    # ---- inputs ------------------------------------------------------------------------
    ik = [r for r in rows if r.kind == "ik"]
    if ik:
        labels, xs = [], []
        x = 0.0
        for r in ik:
            for j in range(3):
                unit = r.units[j]
                f = 1e3 if unit == "m" else 1.0
                for pr, col, dx, lab in ((r.residual_before, _BEFORE, -0.18, "before"),
                                         (r.residual_after, _AFTER, 0.18, "after")):
                    if pr is None or (r.outlier and lab == "after"):
                        continue
                    first = r is ik[0] and j == 0
                    ax2.bar(x + dx, pr[j] * f, width=0.34, color=col, label=lab if first else None,
                            hatch="//" if r.outlier else None, edgecolor="k" if r.outlier else None)
                if r.loo is not None:
                    ax2.plot(x + 0.18, r.loo[j] * f, "o", mfc="none", mec="tab:red", ms=6,
                             label="leave-one-out" if (r is ik[0] and j == 0) else None)
                labels.append(f"{r.index}.{j + 1}")
                xs.append(x)
                x += 1.0
            x += 0.6
        ax2.axhline(0, color="k", lw=0.8)
        ax2.set_xticks(xs)
        ax2.set_xticklabels(labels, fontsize=7)
        unit = "mm" if all(u == "m" for r in ik for u in r.units) else "mm or deg"
        ax2.set_ylabel(f"predicted - measured input [{unit}]")
        ax2.set_xlabel("row.leg")
        ax2.set_title("IK rows: input errors", fontsize=10)
        ax2.legend(fontsize=8, loc="best")
        ax2.grid(alpha=0.3, axis="y")
    else:
        ax2.text(0.5, 0.5, "no IK rows", ha="center", va="center", transform=ax2.transAxes)
        ax2.set_axis_off()
    # ---- residuals per row ------------------------------------------------------------
    idx = np.arange(len(rows))
    zb = [_z_norm(r.z_before) for r in rows]
    za = [_z_norm(r.z_after) if not r.outlier else math.nan for r in rows]
    ax3.bar(idx - 0.2, zb, width=0.4, color=_BEFORE, label="before")
    ax3.bar(idx + 0.2, np.nan_to_num(za), width=0.4, color=_AFTER, label="after")
    for k, r in enumerate(rows):
        if r.outlier:
            ax3.bar(k + 0.2, max(zb[k] if math.isfinite(zb[k]) else 1.0, 1.0), width=0.4, color="none",
                    edgecolor="tab:red", hatch="//")
            ax3.annotate("outlier", (k, 0), textcoords="offset points", xytext=(0, 3), ha="center", fontsize=7,
                         color="tab:red", rotation=90)
        if r.loo is not None and r.sigma is not None:
            zl = np.array(r.loo, float) / np.array(r.sigma, float)
            if np.all(np.isfinite(zl)):
                ax3.plot(k + 0.2, _z_norm(zl), "o", mfc="none", mec="tab:red", ms=7,
                         label="leave-one-out" if k == 0 else None)
    ax3.set_xticks(idx)
    ax3.set_xticklabels([f"{r.index}\n{r.kind}" for r in rows], fontsize=8)
    ax3.set_ylabel("RMS residual / sigma")
    ax3.set_title("residuals per row", fontsize=10)
    ax3.legend(fontsize=8, loc="best")
    ax3.grid(alpha=0.3, axis="y")
    keys = ", ".join(dict.fromkeys(p.fit_key for p in res.parameters))
    fig.suptitle(title or f"calibration of {getattr(res.mechanism, 'name', '')}: fit {keys}", fontsize=11)
    fig.tight_layout()
    if path is not None:
        save(fig, path)
    return fig
