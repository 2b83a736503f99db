"""One leg's geometric-condition set (paper §4.1): the polylines the inverse kinematics
intersects, whatever the leg's joint (:mod:`flexkin.solve.pinned_curves`,
:mod:`flexkin.solve.clamped_curves`)."""

from __future__ import annotations

from dataclasses import dataclass

from numpy.typing import NDArray

__all__ = ["LegCurve"]


@dataclass(frozen=True)
class LegCurve:
    """One leg's geometric-condition set: a list of polylines (branches).

    Each branch is a dict of equally long arrays: ``v``, ``ku = tanh v``, ``phis`` (unified chart),
    ``k``, ``psi``, ``kr``, ``mode`` (paper chart), ``input`` (SI), ``force`` (n, 2; world,
    on the rod tip), ``length`` (free rod length), ``tip_moment``, and the coordinates ``z`` (n, 2)
    of the chart ``chart`` (n,) the branch was traced in (unified, or seam near taut rods).
    """

    leg: int
    actuation: str
    branches: tuple[dict[str, NDArray], ...]
    #: polylines stopped at a numerical limit of the search (a clamped leg's grid force limit)
    limits: int = 0

    def __len__(self) -> int:
        return len(self.branches)
