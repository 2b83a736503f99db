"""Rod-platform joints (SPEC §2; paper §3 and, for clamped tips, §8).

A joint owns the rod's boundary conditions at ``B_i`` and its moment contribution to the
platform's equilibrium (Eq. 15).  Each kind is one class in the registry :data:`JOINTS`.

* ``"pinned"`` (the paper's R joint): the tip sits at ``B_i`` and turns freely, so the tip
  moment vanishes: the rod is an inflectional elastica ending at an inflection point,
  ``phi_2 = (2 q - 1) pi / 2`` (Eq. 11).  Two tip equations (position).
* ``"clamped"`` (welded, paper §8): the tip sits at ``B_i`` with its tangent at
  ``theta_P + tip_angle``; ``phi_2`` is free and the tip moment ``m_i(L)`` (on the rod, by the
  platform) enters the moment balance: ``sum (B_i - P) x n_i + sum m_i(L) = M_z``.  Three tip
  equations (position and angle).

The compiled equation system (:mod:`flexkin.system`) reads :attr:`Joint.code`,
:attr:`Joint.tip_angle` and :attr:`Joint.n_tip_equations`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import ClassVar

__all__ = ["Joint", "Pinned", "Clamped", "JOINTS", "PINNED", "CLAMPED"]

PINNED, CLAMPED = 0, 1


@dataclass(frozen=True)
class Joint:
    """Base class of the rod-platform joints.

    Parameters
    ----------
    tip_angle : float
        Rod tangent at ``B_i`` in the platform frame (rad); used by clamped joints only.
    """

    tip_angle: float = 0.0

    name: ClassVar[str] = ""
    code: ClassVar[int] = -1
    #: tip equations: position (2) and, for a clamped tip, its angle (1)
    n_tip_equations: ClassVar[int] = 2
    #: whether the tip moment is free (clamped) rather than zero (pinned)
    carries_moment: ClassVar[bool] = False


@dataclass(frozen=True)
class Pinned(Joint):
    """Revolute joint at ``B_i``: zero tip moment."""

    name: ClassVar[str] = "pinned"
    code: ClassVar[int] = PINNED


@dataclass(frozen=True)
class Clamped(Joint):
    """Rod welded to the platform: tip tangent ``theta_P + tip_angle``, tip moment carried."""

    name: ClassVar[str] = "clamped"
    code: ClassVar[int] = CLAMPED
    n_tip_equations: ClassVar[int] = 3
    carries_moment: ClassVar[bool] = True


#: joint kinds by name (the file's ``joint``)
JOINTS: dict[str, type[Joint]] = {cls.name: cls for cls in (Pinned, Clamped)}
