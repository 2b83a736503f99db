"""The calibrated mechanism file: the input TOML with only the fitted keys changed.

The standard library reads TOML but does not write it, and the format-preserving writers
(tomlkit) are not among flexkin's dependencies, so the few values are replaced in the text:
each fitted key is found in its table (``[rod]``, the i-th ``[[leg]]``, ``[platform]``) and
its value (a number or an array, possibly over several lines) is replaced; a key the table
does not have yet (a leg's first ``offset``) is added after the table's last key.  Comments,
order and layout stay.  The result is parsed again and compared with the expected content;
if the edit could not be made in place (dotted keys, inline tables) the file is written from
the parsed content instead, with a comment saying so.
"""

from __future__ import annotations

import copy
import math
import re
import tomllib
from typing import Any, Sequence

from .params import Parameter

__all__ = ["calibrated_toml", "planned_edits"]

_HEADER = re.compile(r"^\s*(\[\[?)\s*([A-Za-z0-9_.\-\"' ]+?)\s*(\]\]?)\s*(#.*)?$")


def _num(v: float) -> str:
    return repr(float(v))  # the shortest text that reads back as the same double


def _fmt(v: Any) -> str:
    if isinstance(v, list):
        return "[" + ", ".join(_fmt(x) for x in v) + "]"
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, (int, float)):
        return _num(float(v))
    if isinstance(v, str):
        return '"' + v.replace("\\", "\\\\").replace('"', '\\"') + '"'
    raise TypeError(type(v))


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


def _sections(lines: list[str]) -> list[tuple[tuple[str, int | None], int, int]]:
    """(table id, first line, end line) of every table; the top level is ("", None)."""
    out = []
    counts: dict[str, int] = {}
    cur: tuple[str, int | None] = ("", None)
    start = 0
    depth = 0
    for n, line in enumerate(lines):
        m = _HEADER.match(line) if depth == 0 else None
        if m and m.group(1) in ("[", "[["):
            out.append((cur, start, n))
            name = m.group(2).strip()
            if m.group(1) == "[[":
                k = counts.get(name, 0)
                counts[name] = k + 1
                cur = (name, k)
            else:
                cur = (name, None)
            start = n + 1
        depth += _bracket_delta(line)
    out.append((cur, start, len(lines)))
    return out


def _bracket_delta(line: str) -> int:
    code = _code(line)
    return code.count("[") - code.count("]")


def _code(line: str) -> str:
    """The line without its comment (no '#' inside the numeric values and arrays here)."""
    out, q = [], None
    for ch in line:
        if q:
            if ch == q:
                q = None
        elif ch in "\"'":
            q = ch
        elif ch == "#":
            break
        out.append(ch)
    return "".join(out)


def _edit_text(text: str, edits) -> str:
    lines = text.splitlines()
    for (table, idx), key, v in edits:
        secs = _sections(lines)
        sec = [s for s in secs if s[0] == (table, idx)]
        if not sec:
            raise LookupError(f"table {table}")
        _, a, b = sec[0]
        pat = re.compile(rf"^(\s*){re.escape(key)}(\s*=\s*)")
        hit = None
        for n in range(a, b):
            if pat.match(lines[n]):
                hit = n
                break
        if hit is None:
            if v is None:
                continue
            last = a - 1
            for n in range(a, b):
                if _code(lines[n]).strip():
                    last = n
            while last + 1 < b and _bracket_delta("\n".join(lines[a:last + 1])) > 0:
                last += 1
            lines.insert(last + 1, f"{key} = {_fmt(v)}")
            continue
        # the value may continue over several lines (arrays)
        end = hit
        depth = _bracket_delta(lines[hit])
        while depth > 0 and end + 1 < b:
            end += 1
            depth += _bracket_delta(lines[end])
        comment = ""
        last = lines[end]
        c = _code(last)
        if len(c) < len(last):
            comment = "  " + last[len(c):].strip()
        if v is None:
            del lines[hit:end + 1]
            continue
        m = pat.match(lines[hit])
        lines[hit:end + 1] = [f"{m.group(1)}{key}{m.group(2)}{_fmt(v)}{comment}"]  # type: ignore[union-attr]
    return "\n".join(lines) + ("\n" if text.endswith("\n") else "")


def _serialize(data: dict[str, Any]) -> str:
    out = []
    for k, v in data.items():
        if not isinstance(v, dict) and not (isinstance(v, list) and v and isinstance(v[0], dict)):
            out.append(f"{k} = {_fmt(v)}")
    for k, v in data.items():
        if isinstance(v, dict):
            out += ["", f"[{k}]"] + [f"{kk} = {_fmt(vv)}" for kk, vv in v.items()]
        elif isinstance(v, list) and v and isinstance(v[0], dict):
            for t in v:
                out += ["", f"[[{k}]]"] + [f"{kk} = {_fmt(vv)}" for kk, vv in t.items()]
    return "\n".join(out) + "\n"


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
    try:
        new = _edit_text(text, edits)
        if _same(tomllib.loads(new), want):
            return head + new
    except (LookupError, tomllib.TOMLDecodeError, TypeError):
        pass
    return head + "# (written from the parsed file: its layout could not be kept)\n" + _serialize(want)
