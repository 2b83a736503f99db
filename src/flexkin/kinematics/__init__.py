"""Inverse and forward kinematics of planar PCMs (paper §§4–5)."""

from .ik import ik
from .results import KinematicsResult, Solution

__all__ = ["ik", "KinematicsResult", "Solution"]
