"""Single-rod figures: equilibria of a pinned rod, the Fig. 19 sweep, parameter spaces (Figs. 2, 6)."""

from __future__ import annotations

from typing import Any

import numpy as np

from .style import mode_color, new_figure, save

__all__ = ["plot_rod_solutions", "plot_rod_sweep", "plot_parameter_space"]


def plot_rod_solutions(result, path: str | None = None) -> Any:
    """Deformed shapes of every equilibrium of a :class:`~flexkin.solve.rod_inverse.RodInverseResult` (tip pinned,
    or clamped with ``result.tip_angle``: then the imposed tip tangent is drawn and the legend
    gives the tip moment), numbered as in the ``flexkin rod`` table.

    Parameters
    ----------
    result : RodInverseResult
        The equilibria of one rod (:func:`flexkin.solve_rod`).
    path : str, optional
        Save the figure there.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig = new_figure(figsize=(6.4, 5.2), layout="constrained")
    ax = fig.add_subplot()
    clamped = getattr(result, "tip_angle", None) is not None
    for i, s in enumerate(result.solutions, 1):
        xy = s.shape(201)
        extra = f", tip moment {s.tip_moment:.3g} N m" if clamped else ""
        ax.plot(xy[:, 0], xy[:, 1], color=mode_color(s.mode), lw=1.8,
                label=f"#{i} d-mode {s.mode}, |F| = {s.R:.3g} N{extra}")
    ax.plot(*result.clamp, marker="s", ms=9, color="0.3", label="clamp")
    if clamped:
        d = 0.08 * result.length * np.array([np.cos(result.tip_angle), np.sin(result.tip_angle)])
        t = np.asarray(result.tip, dtype=float)
        ax.plot([t[0] - d[0], t[0] + d[0]], [t[1] - d[1], t[1] + d[1]], color="k", lw=2.5, zorder=5)
        ax.plot(*t, marker="s", ms=7, mfc="white", mec="k", zorder=6,
                label=f"clamped tip, tangent {np.degrees(result.tip_angle):.4g}°")
    else:
        ax.plot(*result.tip, marker="o", ms=8, mfc="white", mec="k", label="pinned tip")
    ax.set_aspect("equal", adjustable="datalim")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.grid(True, lw=0.4, alpha=0.5)
    ax.set_title(f"Rod L = {result.length:.4g} m, EI = {result.EI:.4g} N m²: {len(result)} equilibria")
    ax.legend(fontsize=8, loc="best")
    if path:
        save(fig, path)
    return fig


def plot_rod_sweep(sweep, path: str | None = None) -> Any:
    """Tip-force components against the tip abscissa (paper Fig. 19, model curves).

    Top row: every branch (symmetric-log force axis, since the looped branches carry forces
    two orders of magnitude above the others).  Bottom row: linear axes restricted to the
    branch of least mean energy, the one a bench realises by continuity.

    Parameters
    ----------
    sweep : RodSweep
        The branches of :func:`flexkin.solve.rod_sweep.rod_sweep`.
    path : str, optional
        Save the figure there.

    Returns
    -------
    matplotlib.figure.Figure
    """
    fig = new_figure(figsize=(10.0, 7.5), layout="constrained")
    axes = fig.subplots(2, 2, sharex=True)
    energies = [float(np.mean(b["energy"])) for b in sweep.branches]
    order = np.argsort(energies) if energies else []
    for rank, b_id in enumerate(order):
        b = sweep.branches[b_id]
        modes = sorted(set(int(q) for q in b["mode"]))
        col = mode_color(modes[0]) if rank else "k"
        lab = f"branch {b_id + 1}: d-mode {'/'.join(map(str, modes))}, mean energy {energies[b_id]:.3g} J"
        ls = "-" if len(b["x"]) > 1 else "none"
        for j, c in enumerate(("fx", "fy")):
            axes[0, j].plot(b["x"], b[c], ls=ls, marker=".", ms=4, color=col, label=lab, lw=1.2,
                            alpha=1.0 if rank == 0 else 0.7)
            if rank == 0:
                axes[1, j].plot(b["x"], b[c], ls=ls, marker="o", ms=3, color=col, label=lab)
    for j, c in enumerate(("x", "y")):
        axes[0, j].set_yscale("symlog", linthresh=1.0)
        axes[0, j].set_ylabel(f"F{c} [N] on the rod tip (symlog)")
        axes[1, j].set_ylabel(f"F{c} [N] on the rod tip")
        axes[1, j].set_xlabel("tip abscissa x [m]")
        for i in range(2):
            axes[i, j].grid(True, lw=0.4, alpha=0.5)
    axes[0, 0].invert_xaxis()
    axes[0, 1].legend(fontsize=7, loc="best")
    axes[1, 1].legend(fontsize=7, loc="best")
    axes[0, 0].set_title("all equilibria", fontsize=9)
    axes[1, 0].set_title("least-energy branch", fontsize=9)
    fig.suptitle(f"Pinned-tip rod, tip y = {sweep.tip_y:g} m: every equilibrium (model of paper Fig. 19)",
                 fontsize=10)
    if path:
        save(fig, path)
    return fig


def plot_parameter_space(mode: int = 1, quantity: str = "R", path: str | None = None, n: int = 241) -> Any:
    """The (k, psi) parameter space (Fig. 2a) and its rectangular k_r form (Fig. 6b).

    Colours show ``log10`` of the dimensionless tip force ``R L^2/EI`` (``quantity="R"``)
    or the tip height ``y/L`` (``quantity="y"``) for d-mode ``mode``.  Both panels are images
    sampled on regular pixel grids (``n`` x ``n``), so no mesh edges or thin distorted quads
    alias into moiré; in the (k, psi) panel the band ``|k| < k_min = |cos psi/2|``, where no
    rod exists, is left blank.

    Parameters
    ----------
    mode : int
        d-mode of the rods drawn.
    quantity : {"R", "y"}
        What the colours show.
    path : str, optional
        Save the figure there.
    n : int
        Pixels per side of each panel (>= 8).

    Returns
    -------
    matplotlib.figure.Figure
    """
    from ..rod.closed_form import tip_unit, to_unified

    n = int(n)
    if n < 8:
        raise ValueError(f"n must be >= 8, got {n!r}")
    psi = np.linspace(0.0, 2 * np.pi, n + 1)[:-1] + np.pi / n  # pixel centres
    kk = np.linspace(-1.0, 1.0, n + 1)[:-1] + 1.0 / n

    def evaluate(K: np.ndarray, PSI: np.ndarray) -> np.ndarray:
        ku, ph = to_unified(K, PSI, mode)
        t = tip_unit(ku, ph)
        if quantity == "R":
            return np.log10(np.maximum(t.R, 1e-12))
        return np.asarray(t.y, dtype=float)

    lab = "log10(R L²/EI)" if quantity == "R" else "tip y/L"
    # (k, psi): the physical k; the forbidden band |k| < k_min is blank
    K, PSI = np.meshgrid(kk, psi, indexing="ij")
    kmin = np.abs(np.cos(PSI / 2))
    ok = np.abs(K) >= kmin
    Z1 = np.full(K.shape, np.nan)
    Kc = np.where(ok, K, np.copysign(np.maximum(kmin, 1e-12), np.where(K == 0, 1.0, K)))
    Z1[ok] = evaluate(Kc, PSI)[ok]
    # (k_r, psi): every pixel is a rod
    KR, PSI2 = np.meshgrid(kk, psi, indexing="ij")
    from ..rod.closed_form import k_from_kr

    Z2 = evaluate(k_from_kr(KR, PSI2), PSI2)
    finite = np.concatenate([Z1[np.isfinite(Z1)], Z2[np.isfinite(Z2)]])
    vmin, vmax = (float(np.percentile(finite, 0.5)), float(np.percentile(finite, 99.5))) if finite.size else (0, 1)
    fig = new_figure(figsize=(10, 4.2), layout="constrained")
    a1, a2 = fig.subplots(1, 2)
    ext = (0.0, 360.0, -1.0, 1.0)
    m1 = a1.imshow(np.ma.masked_invalid(Z1), origin="lower", extent=ext, aspect="auto", cmap="viridis",
                   vmin=vmin, vmax=vmax, interpolation="nearest")
    a1.plot(np.degrees(psi), np.abs(np.cos(psi / 2)), "w--", lw=1)
    a1.plot(np.degrees(psi), -np.abs(np.cos(psi / 2)), "w--", lw=1)
    a1.set_facecolor("0.92")
    a1.set_xlabel("ψ [deg]")
    a1.set_ylabel("k")
    a1.set_title(f"(k, ψ) space, d-mode {mode} (dashed: ±k_min = ±|cos ψ/2|; blank: no rod)", fontsize=9)
    a2.imshow(Z2, origin="lower", extent=ext, aspect="auto", cmap="viridis", vmin=vmin, vmax=vmax,
              interpolation="nearest")
    a2.set_xlabel("ψ [deg]")
    a2.set_ylabel("k_r (Eq. 14)")
    a2.set_title("rectangular (k_r, ψ) space", fontsize=9)
    for a in (a1, a2):
        a.set_xlim(0, 360)
        a.set_xticks(np.arange(0, 361, 60))
    fig.colorbar(m1, ax=[a1, a2], label=lab)
    if path:
        save(fig, path)
    return fig
