"""Mechanism description: rods, legs, platform; TOML loading and validation; builders."""

from __future__ import annotations

from flexkin.mechanism.builders import symmetric_mechanism
from flexkin.mechanism.loader import load_mechanism, mechanism_from_dict
from flexkin.mechanism.model import ACTUATIONS, Actuation, Leg, Mechanism, Platform, Rod, circular_EI

__all__ = [
    "Actuation",
    "ACTUATIONS",
    "Rod",
    "Leg",
    "Platform",
    "Mechanism",
    "circular_EI",
    "load_mechanism",
    "mechanism_from_dict",
    "symmetric_mechanism",
]
