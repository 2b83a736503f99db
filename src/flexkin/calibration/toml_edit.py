"""The calibrated mechanism file: the input TOML with only the fitted keys changed.

The standard library reads TOML but does not write it; tomlkit (the format-preserving TOML
library of the Poetry project) edits the document in place, so comments, order and layout stay.
Each fitted key is set in its table (``[rod]``, the i-th ``[[leg]]``, ``[platform]``); a key the
table does not have yet (a leg's first ``offset``) is added to it.  The result is parsed again
by :mod:`tomllib` and compared with the expected content.
"""

from __future__ import annotations

import copy
import math
import tomllib
from typing import Any, Sequence

import tomlkit

from .params import Parameter

__all__ = ["calibrated_toml", "planned_edits"]


def planned_edits(raw: dict[str, Any], params: Sequence[Parameter], values_display: Sequence[float]
                  ) -> list[tuple[tuple[str, int | None], str, Any]]:
    """The edits ``((table, index), key, new value)`` that set the fitted parameters in the file
    (display units: m, deg, Pa, N m^2)."""
    data = copy.deepcopy(raw)
    edits: dict[tuple[tuple[str, int | None], str], Any] = {}
    for p, v in zip(params, values_display):
        v = float(v)
        if p.prop.startswith("attach"):
            pts = edits.get((("platform", None), "attach"), copy.deepcopy(data["platform"]["attach"]))
            pts[p.targets[0]][0 if p.prop == "attach_x" else 1] = v
            edits[(("platform", None), "attach")] = pts
            continue
        if p.name.startswith("rod."):
            edits[(("rod", None), p.prop)] = v
            if p.prop == "E" and "EI" in data.get("rod", {}):  # [rod].EI would contradict the new E
                edits[(("rod", None), "EI")] = None
            continue
        for i in p.targets:
            if p.prop in ("origin_x", "origin_y"):
                cur = edits.get((("leg", i), "origin"), list(data["leg"][i]["origin"]))
                cur[0 if p.prop == "origin_x" else 1] = v
                edits[(("leg", i), "origin")] = cur
            else:
                edits[(("leg", i), p.prop)] = v
                if p.prop == "E":  # a leg's own EI would contradict its new E
                    if "EI" in data["leg"][i]:
                        edits[(("leg", i), "EI")] = None
    return [(t, k, v) for (t, k), v in edits.items()]


def _expected(raw: dict[str, Any], edits) -> dict[str, Any]:
    data = copy.deepcopy(raw)
    for (table, idx), key, v in edits:
        t = data[table] if idx is None else data[table][idx]
        if v is None:
            t.pop(key, None)
        else:
            t[key] = v
    return data


def _edit_document(text: str, edits) -> str:
    doc = tomlkit.parse(text)
    for (table, idx), key, v in edits:
        t = doc[table] if idx is None else doc[table][idx]
        if v is None:
            if key in t:
                del t[key]
        else:
            t[key] = v
    return tomlkit.dumps(doc)


def _same(a: Any, b: Any) -> bool:
    if isinstance(a, dict) and isinstance(b, dict):
        return a.keys() == b.keys() and all(_same(a[k], b[k]) for k in a)
    if isinstance(a, list) and isinstance(b, list):
        return len(a) == len(b) and all(_same(x, y) for x, y in zip(a, b))
    if isinstance(a, (int, float)) and isinstance(b, (int, float)) and not isinstance(a, bool):
        return math.isclose(float(a), float(b), rel_tol=1e-9, abs_tol=0.0) or float(a) == float(b)
    return a == b


def calibrated_toml(text: str, raw: dict[str, Any], params: Sequence[Parameter], values_display: Sequence[float],
                    note: str = "") -> str:
    """The mechanism file ``text`` with the fitted parameters set to ``values_display``.

    Parameters
    ----------
    text : str
        The starting mechanism file.
    raw : dict
        Its parsed content.
    params : sequence of Parameter
    values_display : sequence of float
        The estimates in the file's units (m, deg, Pa, N m^2).
    note : str
        A comment line put at the top (e.g. where the values come from).

    Returns
    -------
    str
        The new file; it parses to ``raw`` with exactly the fitted keys changed.
    """
    edits = planned_edits(raw, params, values_display)
    want = _expected(raw, edits)
    head = "".join(f"# {line}\n" for line in note.splitlines()) if note else ""
    new = _edit_document(text, edits)
    got = tomllib.loads(new)
    if not _same(got, want):  # pragma: no cover - tomlkit round-trips; this guards the planned edits
        raise RuntimeError("the calibrated mechanism file does not parse to the fitted values")
    return head + new
