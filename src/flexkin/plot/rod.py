"""Single-rod figures: equilibria of a pinned rod, the Fig. 19 sweep, parameter spaces (Figs. 2, 6)."""

from __future__ import annotations

from typing import Any

import numpy as np

from .style import mode_color, new_figure, save

__all__ = ["plot_rod_solutions", "plot_rod_sweep", "plot_parameter_space"]


def plot_rod_solutions(result, path: str | None = None) -> Any:
    """Deformed shapes of every equilibrium of a :class:`~flexkin.rod.RodInverseResult`."""
    fig = new_figure(figsize=(6.4, 5.2), layout="constrained")
    ax = fig.add_subplot()
    for i, s in enumerate(result.solutions, 1):
        xy = s.shape(201)
        ax.plot(xy[:, 0], xy[:, 1], color=mode_color(s.mode), lw=1.8,
                label=f"#{i} d-mode {s.mode}, |F| = {s.R:.3g} N")
    ax.plot(*result.clamp, marker="s", ms=9, color="0.3", label="clamp")
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
    or the tip height ``y/L`` (``quantity="y"``) for d-mode ``mode``.
    """
    from ..rod.closed_form import k_from_kr, tip_unit, to_unified

    psi = np.linspace(1e-3, 2 * np.pi - 1e-3, n)
    kr = np.concatenate([np.linspace(-1 + 1e-4, -1e-4, n // 2), np.linspace(1e-4, 1 - 1e-4, n // 2)])
    KR, PSI = np.meshgrid(kr, psi, indexing="ij")
    K = k_from_kr(KR, PSI)
    ku, ph = to_unified(K, PSI, mode)
    t = tip_unit(ku, ph)
    if quantity == "R":
        Z, lab = np.log10(np.maximum(t.R, 1e-12)), "log10(R L²/EI)"
    else:
        Z, lab = t.y, "tip y/L"
    fig = new_figure(figsize=(10, 4.2), layout="constrained")
    a1, a2 = fig.subplots(1, 2)
    m1 = a1.pcolormesh(np.degrees(PSI), K, Z, shading="gouraud", cmap="viridis")
    kmin = np.abs(np.cos(psi / 2))
    a1.plot(np.degrees(psi), kmin, "w--", lw=1)
    a1.plot(np.degrees(psi), -kmin, "w--", lw=1)
    a1.set_xlabel("ψ [deg]")
    a1.set_ylabel("k")
    a1.set_title(f"(k, ψ) space, d-mode {mode} (dashed: ±k_min = ±|cos ψ/2|)", fontsize=9)
    a2.pcolormesh(np.degrees(PSI), KR, Z, shading="auto", cmap="viridis")
    a2.set_xlabel("ψ [deg]")
    a2.set_ylabel("k_r (Eq. 14)")
    a2.set_title("rectangular (k_r, ψ) space", fontsize=9)
    fig.colorbar(m1, ax=[a1, a2], label=lab)
    if path:
        save(fig, path)
    return fig
