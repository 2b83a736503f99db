"""Leg actuators (paper §3, Fig. 3): input -> clamp of the rod, input unit, geometric condition.

Each actuator kind is one class in the registry :data:`ACTUATORS` (the pattern of scipy's
``solve_ivp`` ``METHODS``).  An actuator knows

* its **clamp map**: the clamp point ``A``, the clamp tangent angle ``alpha`` and the free rod
  length ``L`` as functions of the input ``u``.  Every kind here is *affine* in the input,
  ``(A_x, A_y, alpha, L) = c0 + c1 u`` (:meth:`Actuator.affine`), which is all the compiled
  equation system needs;
* its **input unit**: metres, or degrees in files/CLI/JSON and radians inside (angular
  inputs are also wrapped into ``(-pi, pi]`` and compared with their ranges modulo 2 pi);
* its **geometric condition** (paper §4.1): the level set, on the unit rod's tip, of the rods
  that reach a given platform point ``B``, and the input that places such a rod there.

SPEC §2:

* ``"prismatic"``: ``u = rho`` (m); ``A = origin + rho (cos angle, sin angle)``, ``alpha = angle``;
* ``"revolute"``: ``u = phi`` (rad inside, deg outside); ``A = origin``, ``alpha = phi``;
* ``"length"``: ``u = s`` (m), the free rod length; ``A = origin``, ``alpha = angle``, ``L = s``.

Input zero offset (SPEC §4, ``[[leg]] offset``): the leg behaves as if its input were
``u + offset``.  It enters here and nowhere else: :meth:`Actuator.affine` maps ``u + offset``,
:meth:`Actuator.from_tip` returns the input ``u`` (the physical value minus the offset), and
ranges and :meth:`Actuator.check_input` see the commanded input ``u`` (the physical free length
of a length leg, ``u + offset``, must be > 0).
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from dataclasses import dataclass
from typing import Callable, ClassVar

import numpy as np
from numpy.typing import ArrayLike, NDArray

from ..core.geometry2d import wrap_to_pi

__all__ = ["Actuator", "Prismatic", "Revolute", "Length", "ACTUATORS", "LevelSet", "COND_LINE", "COND_CIRCLE",
           "COND_RAY"]

TWO_PI = 2.0 * math.pi
#: kinds of geometric condition (paper §4.1) on the unit rod's tip, for the compiled searches:
#: a line ``y = h`` (Fig. 5), a circle ``|tip| = r`` (Fig. 8), a ray of angle ``beta`` (Fig. 9)
COND_LINE, COND_CIRCLE, COND_RAY = 0, 1, 2


@dataclass(frozen=True)
class LevelSet:
    """A leg's geometric condition on unit-rod tips (local clamp frame): ``g(x, y) = 0``,
    restricted to ``mask(x, y)`` when given (paper Figs. 5, 8, 9)."""

    g: Callable[[NDArray, NDArray], NDArray]
    mask: Callable[[NDArray, NDArray], NDArray] | None = None


@dataclass(frozen=True)
class Actuator(ABC):
    """Base class: the actuated clamp of one leg.

    Parameters
    ----------
    origin : (float, float)
        Base point (m): start of the prismatic guide, revolute joint centre, or exit of the
        length-actuation guide.
    angle : float
        Guide direction (rad); for revolute legs unused by the kinematics (kept from the file).
    length : float or None
        The rod's free length (m) for fixed-length legs, ``None`` for length legs.
    range : (float, float) or None
        Actuator stroke in internal units (m or rad), on the commanded input ``u``.
    offset : float
        Input zero offset in internal units (m or rad): the clamp is that of ``u + offset``.
    """

    origin: tuple[float, float]
    angle: float
    length: float | None
    range: tuple[float, float] | None = None
    offset: float = 0.0

    #: registry name, one-letter code of the paper's notation, and the input's display unit
    name: ClassVar[str] = ""
    letter: ClassVar[str] = ""
    input_unit: ClassVar[str] = "m"
    #: whether the input is an angle (rad inside, deg outside, wrapped into (-pi, pi])
    angular: ClassVar[bool] = False

    # ---- clamp map -------------------------------------------------------------------------
    @abstractmethod
    def _affine(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(c0, c1)`` of the map without offset: ``(A_x, A_y, alpha, L) = c0 + c1 u_phys``."""

    def affine(self) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(c0, c1)``, each shape (4,): ``(A_x, A_y, alpha, L) = c0 + c1 u`` for the commanded
        input ``u`` (the offset is folded into ``c0``: ``c0 = c0_phys + c1 offset``)."""
        c0, c1 = self._affine()
        return c0 + c1 * self.offset, c1

    def affine_derivative(self, name: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """``(d c0, d c1)`` of :meth:`affine` with respect to one of the leg's parameters
        (exact; used by the calibration's implicit-function Jacobian).

        Parameters
        ----------
        name : {"origin_x", "origin_y", "offset", "angle", "length"}
            ``angle`` in rad, the others in internal units (m, or rad for a revolute offset).

        Returns
        -------
        dc0, dc1 : ndarray (4,)

        Raises
        ------
        ValueError
            If the parameter does not act on this kind of leg.
        """
        z = np.zeros(4)
        if name == "origin_x":
            return np.array([1.0, 0.0, 0.0, 0.0]), z
        if name == "origin_y":
            return np.array([0.0, 1.0, 0.0, 0.0]), z
        if name == "offset":
            return self._affine()[1].copy(), z
        return self._affine_derivative(name)

    def _affine_derivative(self, name: str) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        raise ValueError(f"a {self.name} leg has no parameter {name!r}")

    def clamp(self, u: ArrayLike) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Clamp point ``A`` (``u.shape + (2,)``), tangent angle ``alpha`` and free length ``L``
        for input(s) ``u`` in internal units."""
        u = np.asarray(u, dtype=float)
        c0, c1 = self.affine()
        q = c0 + u[..., None] * c1
        return q[..., :2], q[..., 2], q[..., 3]

    # ---- units and ranges -------------------------------------------------------------------
    def to_display(self, u: ArrayLike) -> NDArray[np.float64] | float:
        """Internal input (m or rad) to display units (m or deg)."""
        a = np.asarray(u, dtype=float)
        out = np.degrees(a) if self.angular else a.copy()
        return float(out) if out.ndim == 0 else out

    def from_display(self, v: ArrayLike) -> NDArray[np.float64] | float:
        """Display input (m or deg) to internal units (m or rad)."""
        a = np.asarray(v, dtype=float)
        out = np.radians(a) if self.angular else a.copy()
        return float(out) if out.ndim == 0 else out

    def wrap(self, u: ArrayLike) -> NDArray[np.float64]:
        """Canonical representative of input(s): angles in ``(-pi, pi]``, lengths unchanged."""
        u = np.asarray(u, dtype=float)
        return wrap_to_pi(u) if self.angular else u

    def in_range(self, u: ArrayLike) -> NDArray[np.bool_]:
        """Whether input(s) ``u`` lie in the stroke (always true without a range).  Angles are
        compared modulo 2 pi: -139.5 deg is 220.5 deg."""
        u = np.asarray(u, dtype=float)
        if self.range is None:
            return np.ones(u.shape, dtype=bool)
        lo, hi = self.range
        if self.angular:
            if hi - lo >= TWO_PI:
                return np.ones(u.shape, dtype=bool)
            return np.mod(u - lo, TWO_PI) <= (hi - lo) + 1e-12
        return (u >= lo) & (u <= hi)

    def input_scale(self, L_ref: float) -> float:
        """Scale of the input for dimensionless comparisons (``L_ref``, or 1 for angles)."""
        return 1.0 if self.angular else L_ref

    def check_input(self, u: float, i: int) -> None:
        """Raise ValueError for a physically impossible input of leg ``i`` (0-based)."""

    # ---- geometric condition (paper §4.1) --------------------------------------------------
    @abstractmethod
    def level_set(self, B: NDArray[np.float64]) -> LevelSet:
        """The rods (unit rods, local clamp frame) whose tip can reach the world point ``B``."""

    def from_tip(self, B: NDArray[np.float64], x: NDArray, y: NDArray
                 ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """Input ``u`` (commanded: the physical value minus the offset), clamp angle ``alpha``
        and length ``L`` that put unit-rod tips ``(x, y)`` (on :meth:`level_set`) at ``B``."""
        u, alpha, L = self._from_tip(B, x, y)
        return (u - self.offset if self.offset else u), alpha, L

    @abstractmethod
    def _from_tip(self, B: NDArray[np.float64], x: NDArray, y: NDArray
                  ) -> tuple[NDArray[np.float64], NDArray[np.float64], NDArray[np.float64]]:
        """:meth:`from_tip` for the physical input (no offset)."""

    @abstractmethod
    def condition(self, B: NDArray[np.float64]) -> tuple[int, NDArray[np.float64]]:
        """The geometric condition in the compact form the compiled searches read
        (:mod:`flexkin.solve.conditions`): a kind code and its parameters."""


@dataclass(frozen=True)
class Prismatic(Actuator):
    """Clamp on a linear actuator (3-P̲FR, paper Fig. 3a): ``u = rho`` along the guide."""

    name: ClassVar[str] = "prismatic"
    letter: ClassVar[str] = "P"

    def _affine(self):
        c0 = np.array([self.origin[0], self.origin[1], self.angle, float(self.length)])
        c1 = np.array([math.cos(self.angle), math.sin(self.angle), 0.0, 0.0])
        return c0, c1

    def _affine_derivative(self, name):
        ca, sa = math.cos(self.angle), math.sin(self.angle)
        if name == "angle":  # A = origin + (u + offset) (cos, sin)(angle), alpha = angle
            return (np.array([-self.offset * sa, self.offset * ca, 1.0, 0.0]), np.array([-sa, ca, 0.0, 0.0]))
        if name == "length":
            return np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(4)
        return super()._affine_derivative(name)

    def level_set(self, B):
        d = np.asarray(B, dtype=float) - np.asarray(self.origin)
        h = (-math.sin(self.angle) * d[0] + math.cos(self.angle) * d[1]) / float(self.length)
        return LevelSet(lambda x, y: y - h)  # Fig. 5: the tip at height h above the guide

    def _from_tip(self, B, x, y):
        d = np.asarray(B, dtype=float) - np.asarray(self.origin)
        L = float(self.length)
        u = math.cos(self.angle) * d[0] + math.sin(self.angle) * d[1] - L * np.asarray(x)
        return u, np.full_like(u, self.angle), np.full_like(u, L)

    def condition(self, B):
        d = np.asarray(B, dtype=float) - np.asarray(self.origin)
        h = (-math.sin(self.angle) * d[0] + math.cos(self.angle) * d[1]) / float(self.length)
        return COND_LINE, np.array([h, self.angle, 0.0])


@dataclass(frozen=True)
class Revolute(Actuator):
    """Clamp on a revolute actuator (3-R̲FR, paper Fig. 3b): ``u = phi`` is the clamp angle."""

    name: ClassVar[str] = "revolute"
    letter: ClassVar[str] = "R"
    input_unit: ClassVar[str] = "deg"
    angular: ClassVar[bool] = True

    def _affine(self):
        return (np.array([self.origin[0], self.origin[1], 0.0, float(self.length)]),
                np.array([0.0, 0.0, 1.0, 0.0]))

    def _affine_derivative(self, name):
        if name == "length":
            return np.array([0.0, 0.0, 0.0, 1.0]), np.zeros(4)
        return super()._affine_derivative(name)

    def level_set(self, B):
        r = float(np.hypot(*(np.asarray(B, dtype=float) - np.asarray(self.origin)))) / float(self.length)
        return LevelSet(lambda x, y: np.hypot(x, y) - r)  # Fig. 8: the tip on a circle

    def _from_tip(self, B, x, y):
        d = np.asarray(B, dtype=float) - np.asarray(self.origin)
        alpha = np.unwrap(math.atan2(d[1], d[0]) - np.arctan2(y, x)) if np.ndim(x) else \
            np.asarray(math.atan2(d[1], d[0]) - math.atan2(float(y), float(x)))
        return alpha, alpha, np.full_like(alpha, float(self.length))

    def condition(self, B):
        d = np.asarray(B, dtype=float) - np.asarray(self.origin)
        return COND_CIRCLE, np.array([float(np.hypot(*d)) / float(self.length), math.atan2(d[1], d[0]), 0.0])


@dataclass(frozen=True)
class Length(Actuator):
    """Rod fed through a fixed guide (3-PF̲R, paper Fig. 3c): ``u = s`` is the free length."""

    name: ClassVar[str] = "length"
    letter: ClassVar[str] = "L"

    def _affine(self):
        return (np.array([self.origin[0], self.origin[1], self.angle, 0.0]), np.array([0.0, 0.0, 0.0, 1.0]))

    def _affine_derivative(self, name):
        if name == "angle":
            return np.array([0.0, 0.0, 1.0, 0.0]), np.zeros(4)
        return super()._affine_derivative(name)

    def check_input(self, u, i):
        if not u + self.offset > 0:
            extra = f" (input {u!r} + offset {self.offset!r})" if self.offset else f", got {u!r}"
            raise ValueError(f"input {i + 1}: the free length of a length-actuated leg must be > 0{extra}")

    def level_set(self, B):
        d = np.asarray(B, dtype=float) - np.asarray(self.origin)
        beta = math.atan2(d[1], d[0]) - self.angle  # Fig. 9: on a unit rod, y/x = tan(beta)
        cb, sb = math.cos(beta), math.sin(beta)
        return LevelSet(lambda x, y: x * sb - y * cb, lambda x, y: x * cb + y * sb > 1e-9)

    def _from_tip(self, B, x, y):
        d = np.asarray(B, dtype=float) - np.asarray(self.origin)
        L = float(np.hypot(*d)) / np.hypot(x, y)
        return L, np.full_like(L, self.angle), L

    def condition(self, B):
        d = np.asarray(B, dtype=float) - np.asarray(self.origin)
        return COND_RAY, np.array([math.atan2(d[1], d[0]) - self.angle, self.angle, 0.0])


#: actuator kinds by name (the file's ``actuation``)
ACTUATORS: dict[str, type[Actuator]] = {cls.name: cls for cls in (Prismatic, Revolute, Length)}
