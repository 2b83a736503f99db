"""Import paths of earlier releases that moved: they keep working for one more release, with a
``FutureWarning`` naming the new path (issue 27, item 10; CHANGELOG.md lists them).

A meta-path finder answers the old names.  An old module name is the new module itself (the
same object: classes, functions and ``isinstance`` checks are shared), except:

* ``flexkin.kinematics``, a package of flexkin 0.1 whose ``__init__`` re-exported ``ik``,
  ``fk``, ``KinematicsResult`` and ``Solution``: a small module with those names;
* ``flexkin.workspace``, the module of flexkin 0.1: a module that forwards to
  :mod:`flexkin.solve.workspace` and that can be called like the function
  :func:`flexkin.workspace` whose name it takes on the package once imported.

To keep a path that moves alive, add it to :data:`MOVED` (and to CHANGELOG.md).
"""

from __future__ import annotations

import importlib
import importlib.abc
import importlib.util
import sys
import types
import warnings
from typing import Any

__all__ = ["MOVED", "PACKAGES", "REMOVED_IN", "install"]

#: old module -> (new module, release that moved it)
MOVED: dict[str, tuple[str, str]] = {
    "flexkin.kinematics.ik": ("flexkin.solve.ik", "0.2.0"),
    "flexkin.kinematics.fk": ("flexkin.solve.fk", "0.2.0"),
    "flexkin.kinematics.curves": ("flexkin.solve.curves", "0.2.0"),
    "flexkin.kinematics.equilibrium": ("flexkin.solve.equilibrium", "0.2.0"),
    "flexkin.kinematics.continuation": ("flexkin.solve.continuation", "0.2.0"),
    "flexkin.kinematics.path": ("flexkin.solve.path", "0.2.0"),
    "flexkin.kinematics.stability": ("flexkin.analysis.stability", "0.2.0"),
    "flexkin.kinematics.feasibility": ("flexkin.analysis.feasibility", "0.2.0"),
    "flexkin.kinematics.jacobian": ("flexkin.analysis.jacobian", "0.2.0"),
    "flexkin.kinematics.results": ("flexkin.results", "0.2.0"),
    "flexkin.kinematics.system": ("flexkin.system", "0.2.0"),
    "flexkin.workspace": ("flexkin.solve.workspace", "0.2.0"),
    "flexkin.rod.inverse": ("flexkin.solve.rod_inverse", "0.3.0"),
    "flexkin.rod.sweep": ("flexkin.solve.rod_sweep", "0.3.0"),
}
#: old package -> (where its names are now, the names it exported, release that moved it)
PACKAGES: dict[str, tuple[str, tuple[str, ...], str]] = {
    "flexkin.kinematics": ("flexkin", ("fk", "ik", "KinematicsResult", "Solution"), "0.2.0"),
}
#: the release that removes the old paths
REMOVED_IN = "0.4.0"


def _message(old: str, new: str, moved_in: str) -> str:
    return (f"{old} moved to {new} in flexkin {moved_in}; the old import path is deprecated and will be removed "
            f"in flexkin {REMOVED_IN}: import {new} instead")


class _CallableModule(types.ModuleType):
    """``flexkin.workspace`` of flexkin 0.1: forwards attributes to the new module and calls
    its ``workspace`` function."""

    def __init__(self, name: str, target: types.ModuleType) -> None:
        super().__init__(name, target.__doc__)
        self.__dict__["_target"] = target

    def __getattr__(self, name: str) -> Any:
        return getattr(self.__dict__["_target"], name)

    def __dir__(self) -> list[str]:
        return dir(self.__dict__["_target"])

    def __call__(self, *args: Any, **kwargs: Any) -> Any:
        return self.__dict__["_target"].workspace(*args, **kwargs)


class _Loader(importlib.abc.Loader):
    def __init__(self, old: str) -> None:
        self.old = old

    def create_module(self, spec: Any) -> types.ModuleType:
        if self.old in PACKAGES:
            where, names, _ = PACKAGES[self.old]
            src = importlib.import_module(where)
            mod = types.ModuleType(self.old, f"Deprecated alias: the names of {self.old} are in {where}.")
            for n in names:
                setattr(mod, n, getattr(src, n))
            mod.__all__ = list(names)
            mod.__path__ = []  # a package: its old submodules are found by this finder too
            return mod
        new = importlib.import_module(MOVED[self.old][0])
        if self.old == "flexkin.workspace":
            return _CallableModule(self.old, new)
        return new

    def exec_module(self, module: types.ModuleType) -> None:
        if self.old in PACKAGES:
            where, names, moved_in = PACKAGES[self.old]
            msg = (f"the package {self.old} was dissolved in flexkin {moved_in}: its names ({', '.join(names)}) are "
                   f"in {where}; the old import path is deprecated and will be removed in flexkin {REMOVED_IN}: "
                   f"use {where}.{names[0]} etc. instead (and MOVED in flexkin._moved for its modules)")
        else:
            msg = _message(self.old, *MOVED[self.old])
        # stacklevel 2: the import statement (the import machinery's frames are skipped)
        warnings.warn(msg, FutureWarning, stacklevel=2)


class _Finder(importlib.abc.MetaPathFinder):
    def find_spec(self, fullname: str, path: Any = None, target: Any = None) -> Any:
        if fullname in MOVED or fullname in PACKAGES:
            return importlib.util.spec_from_loader(fullname, _Loader(fullname), is_package=fullname in PACKAGES)
        return None


def install() -> None:
    """Answer the old import paths (once per process)."""
    if not any(isinstance(f, _Finder) for f in sys.meta_path):
        sys.meta_path.append(_Finder())
