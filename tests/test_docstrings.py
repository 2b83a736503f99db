"""Every public parameter is documented (after python-control's ``tests/docstrings_test.py``).

For every public function and class of flexkin's user-facing API -- the names exported by the
package ``flexkin`` and by its user-facing subpackages (:data:`API_PACKAGES`) -- each parameter of its signature must appear in the numpydoc ``Parameters``
section of its docstring (classes: the class or ``__init__`` docstring; dataclasses may list
their fields under ``Attributes`` instead).  ``self``/``cls``, ``*args``/``**kwargs`` and
names starting with ``_`` are exempt.  Exception classes are exempt too (their parameters are the
message).

For a class, a name documented in the docstring of any class in its MRO counts: a dataclass field
inherited from a base is documented once, on the base (e.g. ``solutions``, ``complete``,
``message``, ``elapsed`` and ``diagnostics`` under ``Attributes`` of
:class:`flexkin.results.Result`, which every solver result extends).
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
                    and id(obj) not in seen \
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


def _docstrings(obj) -> list[str]:
    """The docstrings whose documented names count for ``obj``.

    A function: its own.  A class: the docstring of every class in its MRO (but ``object``) --
    each class's *own* ``__doc__``, not the inherited one -- and of its ``__init__``.
    """
    if not inspect.isclass(obj):
        return [inspect.getdoc(obj) or ""]
    docs = [inspect.cleandoc(klass.__dict__["__doc__"]) for klass in obj.__mro__
            if klass is not object and isinstance(klass.__dict__.get("__doc__"), str)]
    if obj.__init__ is not object.__init__:
        docs.append(inspect.getdoc(obj.__init__) or "")
    return docs


def _undocumented(obj) -> list[str]:
    """The public parameters of ``obj`` that no counted docstring lists."""
    documented: set[str] = set()
    for doc in _docstrings(obj):
        documented |= _documented(doc)
    return [p for p in _params(obj) if p not in documented]


@pytest.mark.parametrize("obj, _", list(_items()))
def test_every_public_parameter_documented(obj, _):
    missing = _undocumented(obj)
    assert not missing, f"{obj.__module__}.{obj.__qualname__}: undocumented parameter(s) {missing}"


def test_checker_catches_undocumented_dataclass_field():
    """The check is not vacuous for classes: an undocumented field is reported, a field documented
    on a base class is not, and documenting the field clears it."""
    import dataclasses

    @dataclasses.dataclass(frozen=True)
    class _Base:
        """A base.

        Attributes
        ----------
        inherited : float
            Documented once, here.
        """
        inherited: float = 0.0

    @dataclasses.dataclass(frozen=True)
    class _Undocumented(_Base):
        """A result whose ``length`` field is not documented.

        Attributes
        ----------
        width : float
            Width, m.
        """
        width: float = 0.0
        length: float = 0.0

    @dataclasses.dataclass(frozen=True)
    class _Documented(_Undocumented):
        """Now documented.

        Attributes
        ----------
        length : float
            Length, m.
        """

    assert _undocumented(_Undocumented) == ["length"]
    assert _undocumented(_Documented) == []
    # a class is checked at all: the filter no longer drops every class
    assert any(inspect.isclass(p.values[0]) for p in _items())
