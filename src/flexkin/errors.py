"""Exception and warning classes of flexkin."""

from __future__ import annotations

__all__ = ["MechanismError", "FlexkinWarning"]


class MechanismError(ValueError):
    """A mechanism file or mechanism parameters are invalid.

    The message is meant for the user as is: it names the file (when there is one), the
    offending key path (e.g. ``leg[2].origin``) and the problem.
    """


class FlexkinWarning(UserWarning):
    """Warning category for everything flexkin warns about."""
