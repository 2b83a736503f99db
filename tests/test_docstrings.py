"""Every public parameter is documented (after python-control's ``tests/docstrings_test.py``).

For every public function and class of flexkin's user-facing API -- the names exported by the
package ``flexkin`` and by its user-facing subpackages (:data:`API_PACKAGES`) -- each parameter of its signature must appear in the numpydoc ``Parameters``
section of its docstring (classes: the class or ``__init__`` docstring; dataclasses may list
their fields under ``Attributes`` instead).  ``self``/``cls``, ``*args``/``**kwargs`` and
names starting with ``_`` are exempt.
"""

from __future__ import annotations

import importlib
import inspect
import re

import pytest


#: the packages whose ``__all__`` is the documented user API (internal modules -- kernels,
#: layouts, continuation internals -- are documented in their module headers instead)
API_PACKAGES = ("flexkin", "flexkin.cosserat", "flexkin.study", "flexkin.mechanism", "flexkin.io",
                "flexkin.analysis.indices", "flexkin.analysis.feasibility", "flexkin.analysis.verify",
                "flexkin.analysis.stability", "flexkin.analysis.jacobian", "flexkin.plot", "flexkin.calibration")


def _documented(doc: str) -> set[str]:
    """Names listed in the Parameters / Other Parameters / Attributes sections."""
    names: set[str] = set()
    section = None
    for line in doc.splitlines():
        s = line.strip()
        if re.fullmatch(r"-{3,}", s):
            continue
        if s in ("Parameters", "Other Parameters", "Attributes", "Keyword Arguments"):
            section = s
            continue
        if s in ("Returns", "Yields", "Raises", "See Also", "Notes", "Examples", "References", "Warns"):
            section = None
            continue
        if section and line[:1] not in (" ", "\t") or (section and re.match(r"^    \S", line)):
            m = re.match(r"^\s*\*{0,2}([A-Za-z_][\w, *]*?)\s*(:|$)", line)
            if m:
                names.update(n.strip().lstrip("*") for n in m.group(1).split(","))
    return names


def _items():
    seen = set()
    for modname in API_PACKAGES:
        mod = importlib.import_module(modname)
        for name in getattr(mod, "__all__", ()):
            obj = getattr(mod, name, None)
            if (inspect.isfunction(obj) or inspect.isclass(obj)) and obj.__module__.startswith("flexkin") \
                    and id(obj) not in seen and not issubclass(type(obj), type(Exception)) \
                    and not (inspect.isclass(obj) and issubclass(obj, BaseException)):
                seen.add(id(obj))
                yield pytest.param(obj, obj, id=f"{obj.__module__}.{obj.__qualname__}")


def _params(obj):
    target = obj.__init__ if inspect.isclass(obj) else obj
    try:
        sig = inspect.signature(target)
    except (TypeError, ValueError):
        return []
    return [p.name for p in sig.parameters.values()
            if p.name not in ("self", "cls") and not p.name.startswith("_")
            and p.kind not in (p.VAR_POSITIONAL, p.VAR_KEYWORD)]


@pytest.mark.parametrize("obj, _", list(_items()))
def test_every_public_parameter_documented(obj, _):
    params = _params(obj)
    if not params:
        return
    doc = inspect.getdoc(obj) or ""
    if inspect.isclass(obj) and obj.__init__ is not object.__init__:
        doc += "\n" + (inspect.getdoc(obj.__init__) or "")
    missing = [p for p in params if p not in _documented(doc)]
    assert not missing, f"{obj.__module__}.{obj.__qualname__}: undocumented parameter(s) {missing}"
