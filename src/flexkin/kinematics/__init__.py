"""Inverse and forward kinematics of planar PCMs (paper §§4–5)."""

from .fk import fk
from .ik import ik
from .results import KinematicsResult, Solution

__all__ = ["fk", "ik", "KinematicsResult", "Solution"]
