"""Hardening against bad input (SPEC §3, §4): generated bad mechanism files and bad command lines.

Contract under test
-------------------
* Loader: :func:`flexkin.load_mechanism` raises :class:`flexkin.MechanismError` (a ValueError)
  for every bad file, with ONE line ``"<file>: <key path>: <problem>"`` naming the file and the
  offending key.  Unknown keys are always errors, with a ``did you mean '<key>'?`` hint when the
  key is a likely misspelling of an allowed one.
* CLI (``flexkin show|rod|ik|fk|path``): bad input ends with exit status 2, nothing on stdout,
  no traceback, and exactly one message line on stderr (argparse's usage block aside) that
  names the problem (the option, the file and key, or the offending token).
* Extreme but valid input (huge or tiny numbers the CLI accepts) is either answered (exit 0)
  or rejected cleanly (exit 2, one message naming an option or the file); never a traceback.

Cases are generated from a seeded :class:`random.Random` (deterministic).  The default run
uses a few hundred cases of each kind; ``-m slow`` runs >= 2000 of each.  Everything runs
IN-PROCESS through :func:`flexkin.cli.main` (fast); a handful of cases also run in a
subprocess through the installed ``flexkin`` entry point.

Known bugs outside this file's reach (in ``cli.py`` or the solvers) are kept in ``KNOWN_BUGS``:
the generated loops count cases matching a known bug instead of failing on them, and one
``xfail(strict=True)`` test per bug reproduces it, so a fix shows up as an XPASS failure that
asks for the entry to be removed.
"""

from __future__ import annotations

import contextlib
import copy
import datetime as _dt
import io
import json
import math
import os
import random
import re
import shutil
import subprocess
import sys
import time
import tomllib
import traceback
from dataclasses import dataclass
from pathlib import Path
from typing import Any, Callable

import pytest

from flexkin import MechanismError, load_mechanism
from flexkin.cli import main

try:  # measurement registry printed by conftest's terminal summary
    from oracles import REPORT  # type: ignore
except ImportError:  # pragma: no cover
    REPORT = {}

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
PROTO = str(EXAMPLES / "prototype_3pfr.toml")
RFR = str(EXAMPLES / "unit_3rfr.toml")
LEN = str(EXAMPLES / "unit_3pfr_length.toml")
MIXED = str(EXAMPLES / "mixed_legs.toml")

SEED = 20240607
N_FILES_DEFAULT, N_FILES_SLOW = 250, 2500
N_ARGV_DEFAULT, N_ARGV_SLOW = 300, 3000
N_EXTREME_DEFAULT, N_EXTREME_SLOW = 40, 400


def record(key: str, value: Any) -> None:
    REPORT[f"fuzz: {key}"] = value
    print(f"[fuzz] {key}: {value}")


# ======================================================================================
# running the CLI in-process
# ======================================================================================
@dataclass
class Run:
    argv: list[str]
    rc: Any
    out: str
    err: str
    exc: str | None  # formatted traceback of an exception that escaped main()
    seconds: float

    @property
    def messages(self) -> list[str]:
        """Non-empty stderr lines outside argparse's usage block."""
        lines, in_usage = [], False
        for ln in self.err.splitlines():
            if ln.startswith("usage:"):
                in_usage = True
                continue
            if in_usage and (ln.startswith(" ") or not ln.strip()):
                continue
            in_usage = False
            if ln.strip():
                lines.append(ln)
        return lines


def run_cli(argv: list[str]) -> Run:
    """``flexkin.cli.main(argv)`` with stdout/stderr captured; exceptions are caught and recorded."""
    out, err = io.StringIO(), io.StringIO()
    exc = None
    t0 = time.perf_counter()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        try:
            rc = main(list(argv))
        except SystemExit as e:  # argparse's own exit (never expected for bad input)
            rc = ("SystemExit", e.code)
        except BaseException:  # noqa: BLE001 - the point is to see everything
            rc = None
            exc = traceback.format_exc()
    return Run(list(argv), rc, out.getvalue(), err.getvalue(), exc, time.perf_counter() - t0)


def bad_input_problems(r: Run, needles: tuple[str, ...], *, stdout_empty: bool = True,
                       single: bool = True) -> list[str]:
    """What is wrong with the CLI's reaction to bad input (empty list: all good).

    ``needles``: regular expressions that must all occur in the one message line.
    """
    probs = []
    if r.exc is not None:
        probs.append("uncaught exception:\n" + r.exc[-1500:])
        return probs
    if not isinstance(r.rc, int) or isinstance(r.rc, bool) or r.rc == 0:
        probs.append(f"exit status {r.rc!r}, expected non-zero")
    if "Traceback" in r.err or "Traceback" in r.out:
        probs.append("traceback printed")
    if stdout_empty and r.out:
        probs.append(f"stdout not empty: {r.out[:200]!r}")
    msgs = r.messages
    if not msgs:
        probs.append("no message on stderr")
    elif single and len(msgs) != 1:
        probs.append(f"{len(msgs)} message lines, expected one: {msgs}")
    text = "\n".join(msgs)
    for n in needles:
        if not re.search(n, text):
            probs.append(f"message does not match {n!r}: {text!r}")
    return probs


# ======================================================================================
# known bugs outside this file's reach (cli.py / solvers): see the module docstring
# ======================================================================================
def _opt(argv: list[str], name: str, n: int = 1) -> list[str] | None:
    if name not in argv:
        return None
    i = len(argv) - 1 - argv[::-1].index(name)
    return argv[i + 1:i + 1 + n]


def _rod_EI_unrepresentable(argv: list[str]) -> bool:
    """``flexkin rod --E E --radius R`` with E*pi*R**4/4 overflowing (OverflowError, or inf) or
    underflowing to 0."""
    if not argv or argv[0] != "rod" or "--EI" in argv:
        return False
    E, r = _opt(argv, "--E"), _opt(argv, "--radius")
    if not E or not r:
        return False
    try:
        e, rr = float(E[0]), float(r[0])
        if not (math.isfinite(e) and math.isfinite(rr) and e > 0 and rr > 0):
            return False
        EI = e * math.pi * rr**4 / 4.0
    except OverflowError:
        return True
    except ValueError:
        return False
    return not (0.0 < EI < math.inf)


def _rod_length_overflows(argv: list[str]) -> bool:
    """``flexkin rod --length L`` with L**2 beyond the float range (L > ~1.3e154)."""
    if not argv or argv[0] != "rod":
        return False
    L = _opt(argv, "--length")
    try:
        return bool(L) and math.isfinite(float(L[0])) and abs(float(L[0])) > 1.3e154
    except ValueError:
        return False


_NEG_EXP = re.compile(r"^-(\d+\.?\d*|\.\d+)[eE][-+]?\d+$")


def _negative_exponent_value(argv: list[str]) -> bool:
    """A negative number in exponent notation ('-1e-3', '-2.5E+10') anywhere in the command line."""
    return any(_NEG_EXP.match(a) for a in argv)


#: name -> (predicate on argv, reason)
KNOWN_BUGS: dict[str, tuple[Callable[[list[str]], bool], str]] = {}  # all fixed (see the regression tests)


def known_bug(argv: list[str]) -> str | None:
    for name, (pred, _reason) in KNOWN_BUGS.items():
        if pred(argv):
            return name
    return None


# ======================================================================================
# TOML writer (enough for mechanism files; Raw injects literal text)
# ======================================================================================
@dataclass(frozen=True)
class Raw:
    """A literal TOML value (e.g. ``1e400``, a 400-digit integer)."""

    text: str


_BARE = re.compile(r"^[A-Za-z0-9_-]+$")


def toml_key(k: str) -> str:
    return k if _BARE.match(k) else toml_str(k)


def toml_str(s: str) -> str:
    out = ['"']
    for ch in s:
        if ch == "\\":
            out.append("\\\\")
        elif ch == '"':
            out.append('\\"')
        elif ord(ch) < 0x20 or ord(ch) == 0x7F:
            out.append(f"\\u{ord(ch):04x}")
        else:
            out.append(ch)
    out.append('"')
    return "".join(out)


def toml_value(v: Any) -> str:
    if isinstance(v, Raw):
        return v.text
    if isinstance(v, bool):
        return "true" if v else "false"
    if isinstance(v, int):
        return str(v)
    if isinstance(v, float):
        if math.isnan(v):
            return "nan"
        if math.isinf(v):
            return "inf" if v > 0 else "-inf"
        return repr(v)
    if isinstance(v, str):
        return toml_str(v)
    if isinstance(v, (_dt.datetime, _dt.date, _dt.time)):
        return v.isoformat()
    if isinstance(v, list):
        return "[" + ", ".join(toml_value(x) for x in v) + "]"
    if isinstance(v, dict):
        return "{" + ", ".join(f"{toml_key(k)} = {toml_value(x)}" for k, x in v.items()) + "}"
    raise TypeError(type(v))


def to_toml(doc: dict[str, Any]) -> str:
    """Scalars first, then ``[table]`` for dict values and ``[[table]]`` for lists of dicts."""
    lines = []
    for k, v in doc.items():
        if not isinstance(v, dict) and not (isinstance(v, list) and v and all(isinstance(x, dict) for x in v)):
            lines.append(f"{toml_key(k)} = {toml_value(v)}")
    for k, v in doc.items():
        if isinstance(v, dict):
            lines.append(f"\n[{toml_key(k)}]")
            lines.extend(f"{toml_key(kk)} = {toml_value(vv)}" for kk, vv in v.items())
        elif isinstance(v, list) and v and all(isinstance(x, dict) for x in v):
            for item in v:
                lines.append(f"\n[[{toml_key(k)}]]")
                lines.extend(f"{toml_key(kk)} = {toml_value(vv)}" for kk, vv in item.items())
    return "\n".join(lines) + "\n"


# ======================================================================================
# valid base documents (the example files, as dicts) and the allowed keys (SPEC §3)
# ======================================================================================
def _base_docs() -> dict[str, dict[str, Any]]:
    docs = {}
    for stem in ("prototype_3pfr", "unit_3pfr", "unit_3rfr", "unit_3pfr_length", "mixed_legs"):
        with open(EXAMPLES / f"{stem}.toml", "rb") as fh:
            docs[stem] = tomllib.load(fh)
    # a prismatic variant with E/radius per leg, a load and a strain limit
    d = copy.deepcopy(docs["prototype_3pfr"])
    d["leg"][2]["radius"] = 1.6e-3
    d["load"] = {"force": [0.01, -0.02], "moment": 0.001}
    d["limits"] = {"max_strain": 0.05}
    docs["prototype_loaded"] = d
    return docs


BASES = _base_docs()
ALLOWED = {
    "": ("name", "rod", "platform", "leg", "load", "limits"),
    "rod": ("length", "E", "radius", "EI"),
    "leg": ("actuation", "origin", "angle", "range", "length", "E", "radius", "EI"),
    "platform": ("attach",),
    "load": ("force", "moment"),
    "limits": ("max_strain",),
}
ROD_KEYS = ("length", "E", "radius", "EI")
LENGTH_KEYS = ("length", "radius")


def key_text(k: str) -> str:
    """A key as the loader writes it in a key path."""
    return k if (k and all(c.isascii() and (c.isalnum() or c in "_-") for c in k)) else repr(k)


def osa(a: str, b: str) -> int:
    """Optimal string alignment distance (test-side oracle for the did-you-mean hint)."""
    d = [[0] * (len(b) + 1) for _ in range(len(a) + 1)]
    for i in range(len(a) + 1):
        d[i][0] = i
    for j in range(len(b) + 1):
        d[0][j] = j
    for i in range(1, len(a) + 1):
        for j in range(1, len(b) + 1):
            c = 0 if a[i - 1] == b[j - 1] else 1
            d[i][j] = min(d[i - 1][j] + 1, d[i][j - 1] + 1, d[i - 1][j - 1] + c)
            if i > 1 and j > 1 and a[i - 1] == b[j - 2] and a[i - 2] == b[j - 1]:
                d[i][j] = min(d[i][j], d[i - 2][j - 2] + 1)
    return d[-1][-1]


# ======================================================================================
# bad mechanism files
# ======================================================================================
@dataclass
class FileCase:
    kind: str  # mutation family
    detail: str  # what was done (for the report)
    content: bytes
    needles: tuple[str, ...]  # regexes that must all occur in the message
    base: str = ""

    def describe(self) -> str:
        txt = self.content[:400].decode("utf-8", "replace")
        return f"[{self.kind}] {self.detail} (base {self.base})\n--- file ---\n{txt}\n------------"


def _esc(s: str) -> str:
    return re.escape(s)


def _legs(doc) -> list[dict]:
    return doc["leg"]


def _number_slots(doc) -> list[tuple[str, Callable[[dict], dict], str]]:
    """(key path, getter of the containing table, key) of every plain-number slot present."""
    slots = []
    if "rod" in doc:
        for k in ROD_KEYS:
            if k in doc["rod"]:
                slots.append((f"rod.{k}", lambda d: d["rod"], k))
    for i, leg in enumerate(_legs(doc)):
        for k in ("angle",) + ROD_KEYS:
            if k in leg:
                slots.append((f"leg[{i + 1}].{k}", (lambda d, i=i: d["leg"][i]), k))
    if "load" in doc and "moment" in doc["load"]:
        slots.append(("load.moment", lambda d: d["load"], "moment"))
    if "limits" in doc and "max_strain" in doc["limits"]:
        slots.append(("limits.max_strain", lambda d: d["limits"], "max_strain"))
    return slots


def _positive_slots(doc):
    return [s for s in _number_slots(doc) if s[2] in ROD_KEYS or s[2] == "max_strain"]


def _pair_slots(doc) -> list[tuple[str, Callable[[dict], Any], Any, bool]]:
    """(key path, getter of the container, index/key, coordinate-bounded) of every 2-number slot."""
    slots = []
    for i, leg in enumerate(_legs(doc)):
        slots.append((f"leg[{i + 1}].origin", (lambda d, i=i: d["leg"][i]), "origin", True))
        if "range" in leg:
            slots.append((f"leg[{i + 1}].range", (lambda d, i=i: d["leg"][i]), "range",
                          leg["actuation"] != "revolute"))
    for j in range(3):
        slots.append((f"platform.attach[{j + 1}]", lambda d: d["platform"]["attach"], j, True))
    if "load" in doc and "force" in doc["load"]:
        slots.append(("load.force", lambda d: d["load"], "force", False))
    return slots


WRONG_FOR_NUMBER = ["1.0", "", "abc", True, False, [1.0], [], {"value": 1.0},
                    _dt.datetime(2024, 1, 2, 3, 4, 5), _dt.date(2024, 1, 2), _dt.time(7, 32)]
WRONG_FOR_PAIR = [1.5, 0, "1, 2", True, [], [1.0], [1.0, 2.0, 3.0], ["0.5", 1.0], [True, 1.0], [[1.0, 2.0]],
                  [1.0, [2.0]], {"x": 1.0, "y": 2.0}, _dt.date(2024, 1, 2), ["x", 1.0]]
WRONG_FOR_STRING = [3, 1.5, True, ["prismatic"], {"a": 1}, _dt.datetime(2024, 1, 2, 3, 4, 5)]
WRONG_FOR_TABLE = [1.0, "x", True, [1, 2], []]
NONFINITE = [math.nan, math.inf, -math.inf, Raw("1e400"), Raw("-1e400"), Raw("+nan"), Raw("-inf")]
NONPOSITIVE = [0, 0.0, -0.0, -1, -1.0, -1e-300, -1e300, Raw("-0"), Raw("-5e-324")]
HUGE_INT = Raw("1" + "0" * 400)


def _misspell(rng: random.Random, key: str) -> str:
    letters = "abcdefghijklmnopqrstuvwxyzEIR_"
    for _ in range(50):
        # (a one-letter key has no meaningful deletion or substitution)
        op = rng.choice(["delete", "insert", "substitute", "transpose", "case"] if len(key) > 1 else ["insert", "case"])
        k = list(key)
        i = rng.randrange(len(k))
        if op == "delete":
            del k[i]
        elif op == "insert":
            k.insert(rng.randrange(len(k) + 1), rng.choice(letters))
        elif op == "substitute":
            k[i] = rng.choice(letters)
        elif op == "transpose" and len(k) >= 2:
            i = rng.randrange(len(k) - 1)
            k[i], k[i + 1] = k[i + 1], k[i]
        elif op == "case":
            k[i] = k[i].swapcase()
        new = "".join(k)
        if new != key and new.lower() != "" and osa(new.lower(), key.lower()) <= 1:
            return new
    return key + "x"


JUNK_KEYS = ["foo", "banana", "x", "1", "-", "_", "a b", "ключ", "a\nb", "tab\there", "a.b", "'q'", "LEG", "Leg",
             "legs", "rods", "attachments", "origins", "forces", "moment_z", "maxstrain", "max-strain", "stiffness",
             "youngs_modulus", "r", "L", "ei", "angle_deg", "range_deg", "actuator", "type"]


def _table_for_key_mutation(rng, doc) -> tuple[str, str, dict]:
    """(table kind for ALLOWED, key path prefix, the table) of a random table of ``doc``."""
    opts = [("", "", doc), ("platform", "platform", doc["platform"])]
    if "rod" in doc:
        opts.append(("rod", "rod", doc["rod"]))
    for i, leg in enumerate(_legs(doc)):
        opts.append(("leg", f"leg[{i + 1}]", leg))
    for t in ("load", "limits"):
        if t in doc:
            opts.append((t, t, doc[t]))
    return rng.choice(opts)


def mutate_unknown_key(rng, doc) -> tuple[str, tuple[str, ...]]:
    kind, path, table = _table_for_key_mutation(rng, doc)
    allowed = ALLOWED[kind]
    present = [k for k in table if k in allowed]
    if present and rng.random() < 0.6:  # rename an existing key to a misspelling
        old = rng.choice(present)
        new = _misspell(rng, old)
        if new in allowed or new in table:
            new = old + "_x"
        table[new] = table.pop(old)
        dmin = min(osa(new.lower(), a.lower()) for a in allowed)
        hint_keys = [a for a in allowed if osa(new.lower(), a.lower()) == dmin]
        where = f"{path}.{key_text(new)}" if path else key_text(new)
        needles = (_esc(f"{where}: unknown key"),
                   r"did you mean '(" + "|".join(_esc(a) for a in hint_keys) + r")'\?")
        return f"renamed {path or '<top>'}.{old} -> {new!r}", needles
    new = rng.choice(JUNK_KEYS)
    if new in allowed or new in table:
        new = "zz_" + new
    table[new] = rng.choice([1.0, "x", [1, 2], True, {"a": 1}])
    where = f"{path}.{key_text(new)}" if path else key_text(new)
    return f"added {path or '<top>'}.{new!r}", (_esc(f"{where}: unknown key"), _esc("allowed keys here"))


def mutate_delete_required(rng, doc, base) -> tuple[str, tuple[str, ...]]:
    legs = _legs(doc)
    opts = ["platform", "attach", "leg", "actuation", "origin"]
    if any(leg["actuation"] != "revolute" for leg in legs):
        opts.append("angle")
    if any(leg["actuation"] != "length" for leg in legs):
        opts.append("length")
    opts.append("stiffness")
    what = rng.choice(opts)
    if what == "platform":
        del doc["platform"]
        return "deleted [platform]", (r"(^|: )platform: missing",)
    if what == "attach":
        del doc["platform"]["attach"]
        return "deleted platform.attach", (_esc("platform.attach: missing"),)
    if what == "leg":
        del doc["leg"]
        return "deleted every [[leg]]", (r"(^|: )leg: missing",)
    if what in ("actuation", "origin"):
        i = rng.randrange(3)
        del legs[i][what]
        return f"deleted leg[{i + 1}].{what}", (_esc(f"leg[{i + 1}].{what}: missing"),)
    if what == "angle":
        i = rng.choice([j for j, leg in enumerate(legs) if leg["actuation"] != "revolute"])
        del legs[i]["angle"]
        return f"deleted leg[{i + 1}].angle", (_esc(f"leg[{i + 1}].angle: missing"),)
    if what == "length":
        doc.get("rod", {}).pop("length", None)
        for leg in legs:
            if leg["actuation"] != "length":
                leg.pop("length", None)
        j = next(i for i, leg in enumerate(legs) if leg["actuation"] != "length")
        return "deleted every rod length", (_esc(f"leg[{j + 1}].length: missing"),)
    # stiffness: remove one ingredient everywhere
    keys = [k for k in ("EI", "E", "radius") if k in doc.get("rod", {}) or any(k in leg for leg in legs)]
    if "EI" in keys:
        drop = ("EI", "E", "radius")  # EI alone suffices: remove everything
        needle = r"leg\[1\]\.EI: missing"
    else:
        k = rng.choice(keys)
        drop = (k,)
        needle = r"leg\[\d\]\.(E|radius): missing"
    for t in [doc.get("rod", {})] + legs:
        for k in drop:
            t.pop(k, None)
    if "limits" in doc and "radius" in drop:
        pass  # the legs are checked (and fail) before [limits]
    return f"deleted {'/'.join(drop)} everywhere", (needle,)


def mutate_wrong_type(rng, doc) -> tuple[str, tuple[str, ...]]:
    choice = rng.choice(["name", "number", "number", "pair", "pair", "actuation", "attach", "table", "leg"])
    if choice == "name":
        doc["name"] = v = rng.choice(WRONG_FOR_STRING)
        return f"name = {toml_value(v)}", (r"(^|: )name: expected a string",)
    if choice == "number":
        path, get, k = rng.choice(_number_slots(doc))
        get(doc)[k] = v = rng.choice(WRONG_FOR_NUMBER)
        return f"{path} = {toml_value(v)}", (_esc(f"{path}: expected a number"),)
    if choice == "pair":
        path, get, k, _ = rng.choice(_pair_slots(doc))
        get(doc)[k] = v = rng.choice(WRONG_FOR_PAIR)
        return f"{path} = {toml_value(v)}", (_esc(f"{path}: expected"),)
    if choice == "actuation":
        i = rng.randrange(3)
        if rng.random() < 0.5:
            doc["leg"][i]["actuation"] = v = rng.choice(WRONG_FOR_STRING)
            return f"leg[{i + 1}].actuation = {toml_value(v)}", (_esc(f"leg[{i + 1}].actuation: expected a string"),)
        v = rng.choice(["Prismatic", "prismatc", "rotary", "", "PRISMATIC", "length ", "revolut", "linear", "P"])
        doc["leg"][i]["actuation"] = v
        return f"leg[{i + 1}].actuation = {v!r}", (_esc(f"leg[{i + 1}].actuation: unknown actuation"),)
    if choice == "attach":
        n = rng.choice([0, 1, 2, 4, 5])
        pts = doc["platform"]["attach"]
        new = [list(pts[j % 3]) for j in range(n)] if rng.random() < 0.7 else rng.choice([1.0, "pts", {"a": 1}])
        doc["platform"]["attach"] = new
        return f"platform.attach = {toml_value(new)}", (_esc("platform.attach: expected"),)
    if choice == "table":
        t = rng.choice(["rod", "platform", "load", "limits"])
        doc[t] = v = rng.choice(WRONG_FOR_TABLE)
        return f"{t} = {toml_value(v)}", (r"(^|: )" + t + r": expected a table",)
    # leg
    sub = rng.choice(["single", "scalar", "count", "items"])
    if sub == "single":
        doc["leg"] = doc["leg"][0]
        return "a single [leg] table", (r"(^|: )leg: .*single \[leg\] table",)
    if sub == "scalar":
        doc["leg"] = v = rng.choice([1, "legs", True])
        return f"leg = {toml_value(v)}", (r"(^|: )leg: expected three \[\[leg\]\] tables",)
    if sub == "count":
        n = rng.choice([0, 1, 2, 4, 5])
        doc["leg"] = [copy.deepcopy(doc["leg"][j % 3]) for j in range(n)]
        if n == 0:
            doc["leg"] = []
        return f"{n} legs", (r"(^|: )leg: expected exactly three \[\[leg\]\] tables, got " + str(n),)
    j = rng.randrange(3)
    doc["leg"][j] = v = rng.choice([1.0, "leg", [1, 2], True])
    return f"leg[{j + 1}] = {toml_value(v)}", (_esc(f"leg[{j + 1}]: expected a table"),)


def mutate_nonfinite(rng, doc) -> tuple[str, tuple[str, ...]]:
    v = rng.choice(NONFINITE)
    if rng.random() < 0.5:
        path, get, k = rng.choice(_number_slots(doc))
        get(doc)[k] = v
        return f"{path} = {toml_value(v)}", (_esc(f"{path}: expected a finite number"),)
    path, get, k, _ = rng.choice(_pair_slots(doc))
    pair = list(get(doc)[k])
    pair[rng.randrange(2)] = v
    get(doc)[k] = pair
    return f"{path} = {toml_value(pair)}", (_esc(f"{path}: expected finite numbers"),)


def mutate_nonpositive(rng, doc) -> tuple[str, tuple[str, ...]]:
    opts = _positive_slots(doc)
    if rng.random() < 0.3:  # a leg-level override that is not in the base
        i = rng.randrange(3)
        k = rng.choice(ROD_KEYS)
        opts = [(f"leg[{i + 1}].{k}", (lambda d, i=i: d["leg"][i]), k)]
    path, get, k = rng.choice(opts)
    get(doc)[k] = v = rng.choice(NONPOSITIVE)
    return f"{path} = {toml_value(v)}", (_esc(f"{path}: must be > 0"),)


def mutate_out_of_range(rng, doc, base) -> tuple[str, tuple[str, ...]]:
    choice = rng.choice(["rodkey", "rodkey", "coordinate", "hugeint", "derivedEI", "tinyplatform"])
    if choice == "derivedEI" and not any("EI" in t for t in [doc.get("rod", {})] + _legs(doc)) \
            and "E" in doc.get("rod", {}) and "radius" in doc.get("rod", {}):
        if rng.random() < 0.5:
            doc["rod"]["radius"] = r = 10.0 ** -rng.uniform(11.5, 12.0)  # inside the radius range
            doc["rod"]["E"] = 68e9
        else:
            doc["rod"]["E"] = 1e30
            doc["rod"]["radius"] = r = rng.uniform(1.0, 100.0)
        return f"rod E/radius giving EI out of range (radius {r:g})", (
            r"rod\.radius: the bending stiffness .* outside the supported range",)
    if choice == "tinyplatform":
        s = 10.0 ** -rng.uniform(12.5, 300)
        doc["platform"]["attach"] = [[x * s, y * s] for x, y in doc["platform"]["attach"]]
        return f"platform scaled by {s:g}", (r"platform\.attach: the platform is too small",)
    if choice == "coordinate":
        path, get, k, bounded = rng.choice([s for s in _pair_slots(doc) if s[3]])
        pair = list(get(doc)[k])
        pair[rng.randrange(2)] = rng.choice([1.0, -1.0]) * 10.0 ** rng.uniform(12.1, 308)
        get(doc)[k] = pair
        return f"{path} = {toml_value(pair)}", (_esc(f"{path}: values must be within"),)
    if choice == "hugeint":
        if rng.random() < 0.5:
            path, get, k = rng.choice(_number_slots(doc))
            get(doc)[k] = HUGE_INT
        else:
            path, get, k, _ = rng.choice(_pair_slots(doc))
            get(doc)[k] = [HUGE_INT, 0.0]
        return f"{path} = 1e400 as an integer", (_esc(f"{path}: expected a finite number, got an integer too large"),)
    # rodkey
    path, get, k = rng.choice([s for s in _number_slots(doc) if s[2] in ROD_KEYS])
    if k in LENGTH_KEYS:
        v = 10.0 ** rng.uniform(12.05, 308) if rng.random() < 0.5 else 10.0 ** -rng.uniform(12.05, 323)
    else:
        v = 10.0 ** rng.uniform(30.05, 308) if rng.random() < 0.5 else 10.0 ** -rng.uniform(30.05, 323)
    get(doc)[k] = v
    return f"{path} = {v!r}", (_esc(f"{path}: ") + r".* is outside the supported range",)


def mutate_geometry(rng, doc, base) -> tuple[str, tuple[str, ...]]:
    choice = rng.choice(["coincide", "collinear", "origins", "range", "EI", "strain"])
    pts = doc["platform"]["attach"]
    if choice == "coincide":
        i, j = sorted(rng.sample(range(3), 2))
        size = max(math.dist(pts[a], pts[b]) for a in range(3) for b in range(3))
        eps = rng.choice([0.0, 0.0, 1e-14 * size, 3e-13 * size])
        pts[j] = [pts[i][0] + eps, pts[i][1]]
        if rng.random() < 0.2:
            k = 3 - i - j
            pts[k] = list(pts[i])
        return f"attach points {i + 1} and {j + 1} coincide (eps {eps:g})", (r"platform\.attach: .*coincide",)
    if choice == "collinear":
        i, j, k = rng.sample(range(3), 3)
        t = rng.choice([rng.uniform(0.2, 0.8), rng.uniform(1.5, 3.0), rng.uniform(-2.0, -0.5)])
        pts[k] = [pts[i][0] + t * (pts[j][0] - pts[i][0]), pts[i][1] + t * (pts[j][1] - pts[i][1])]
        return f"attach point {k + 1} on the line of {i + 1}, {j + 1} (t = {t:.3f})", (r"platform\.attach: .*collinear",)
    if choice == "origins":
        i, j = sorted(rng.sample(range(3), 2))
        acts = rng.choice([("revolute", "revolute"), ("length", "revolute"), ("length", "length"),
                           ("revolute", "length")])
        for leg, act in zip((doc["leg"][i], doc["leg"][j]), acts):
            leg["actuation"] = act
            leg.pop("range", None)
            leg.setdefault("angle", 45.0)
            if act == "revolute":
                leg["length"] = 1.0
        doc["leg"][j]["origin"] = list(doc["leg"][i]["origin"])
        return f"legs {i + 1} and {j + 1} ({acts}) share an origin", (
            _esc(f"leg[{j + 1}].origin: coincides with leg[{i + 1}].origin"),)
    if choice == "range":
        i = rng.randrange(3)
        leg = doc["leg"][i]
        if leg["actuation"] == "length" and rng.random() < 0.5:
            lo = rng.choice([0.0, -0.5, -1e-9])
            leg["range"] = [lo, 1.0]
            return f"leg[{i + 1}].range = [{lo}, 1.0] on a length leg", (_esc(f"leg[{i + 1}].range: ") + r".*> 0",)
        lo = rng.uniform(-1, 1)
        hi = rng.choice([lo, lo - rng.uniform(1e-9, 1.0)])
        leg["range"] = [lo, hi]
        return f"leg[{i + 1}].range = [{lo}, {hi}]", (_esc(f"leg[{i + 1}].range: lower bound must be < upper bound"),)
    if choice == "EI" and "E" in doc.get("rod", {}) and "radius" in doc.get("rod", {}):
        from flexkin.mechanism.model import circular_EI

        EI = circular_EI(doc["rod"]["E"], doc["rod"]["radius"]) * rng.choice([1.01, 0.5, 2.0, 1 + 1e-6])
        if rng.random() < 0.5:
            doc["rod"]["EI"] = EI
            return f"rod.EI = {EI!r} disagrees with E, radius", (r"rod\.EI: .*disagrees",)
        i = rng.randrange(3)
        if any(k in doc["leg"][i] for k in ("E", "radius", "EI")):
            i = next((j for j in range(3) if not any(k in doc["leg"][j] for k in ("E", "radius", "EI"))), None)
            if i is None:
                return mutate_geometry(rng, doc, base)
        doc["leg"][i]["EI"] = EI
        return f"leg[{i + 1}].EI = {EI!r} disagrees with [rod] E, radius", (_esc(f"leg[{i + 1}].EI: ") + ".*disagrees",)
    if choice == "strain" and not any("radius" in t for t in [doc.get("rod", {})] + _legs(doc)):
        doc["limits"] = {"max_strain": 0.04}
        return "max_strain without any radius", (r"leg\[1\]\.radius: missing.*max_strain",)
    return mutate_geometry(rng, doc, base)


def _text_mutation(rng, text: str) -> tuple[str, str, tuple[str, ...]]:
    """Malformed TOML from a valid text: (new text, detail, needles)."""
    lines = text.split("\n")
    choice = rng.choice(["drop_bracket", "drop_quote", "drop_equals", "dup_key", "dup_table", "garbage",
                         "colon", "json", "truncate", "control", "unterminated_table", "bad_escape"])
    idx = list(range(len(lines)))
    rng.shuffle(idx)
    if choice == "drop_bracket":
        for i in idx:
            if "]" in lines[i]:
                pos = [p for p, c in enumerate(lines[i]) if c == "]"]
                p = rng.choice(pos)
                lines[i] = lines[i][:p] + lines[i][p + 1:]
                return "\n".join(lines), f"removed a ']' on line {i + 1}", (r"malformed TOML",)
    if choice == "drop_quote":
        for i in idx:
            if '"' in lines[i]:
                p = lines[i].rindex('"')
                lines[i] = lines[i][:p] + lines[i][p + 1:]
                return "\n".join(lines), f"removed a closing quote on line {i + 1}", (r"malformed TOML",)
    if choice == "drop_equals":
        for i in idx:
            if " = " in lines[i]:
                lines[i] = lines[i].replace(" = ", " ", 1)
                return "\n".join(lines), f"removed '=' on line {i + 1}", (r"malformed TOML",)
    if choice == "dup_key":
        for i in idx:
            if " = " in lines[i] and not lines[i].startswith("["):
                lines.insert(i + 1, lines[i].split(" = ")[0] + " = 1.0")
                return "\n".join(lines), f"duplicated the key of line {i + 1}", (r"malformed TOML",)
    if choice == "dup_table":
        for i in idx:
            if re.match(r"^\[[a-z]+\]$", lines[i]):
                lines.append(lines[i])
                return "\n".join(lines), f"table {lines[i]} twice", (r"malformed TOML",)
    if choice == "garbage":
        g = rng.choice(["@@@", "key value", "= 3", "[[", "[rod", "x = ", "x = [1, 2", "\"x\" = \"\"\"",
                        "x = 1 2", "x = 0.5.1", "x = 1e", "x = .5", "x = 01", "x = tru", "x = 'a", "]]"])
        lines.insert(rng.randrange(len(lines) + 1), g)
        return "\n".join(lines), f"inserted the line {g!r}", (r"malformed TOML",)
    if choice == "colon":
        for i in idx:
            if " = " in lines[i]:
                lines[i] = lines[i].replace(" = ", ": ", 1)
                return "\n".join(lines), f"YAML-style ':' on line {i + 1}", (r"malformed TOML",)
    if choice == "json":
        return json.dumps(tomllib.loads(text), indent=rng.choice([None, 2])), "the same data as JSON", (
            r"malformed TOML",)
    if choice == "truncate":
        for i in idx:
            ln = lines[i]
            if "[" in ln or '"' in ln:  # cut right after an opening bracket or quote
                stops = [p for p, c in enumerate(ln) if c == "["] + ([ln.index('"')] if '"' in ln else [])
                p = rng.choice(stops) + 1
                return "\n".join(lines[:i] + [ln[:p]]), f"truncated inside line {i + 1}", (r"malformed TOML",)
    if choice == "control":
        c = rng.choice(["\x00", "\x01", "\x07", "\x1b", "\x7f"])
        i = rng.randrange(len(lines))
        lines[i] = lines[i] + c
        return "\n".join(lines), f"control character {c!r} at the end of line {i + 1}", (r"malformed TOML",)
    if choice == "unterminated_table":
        lines.append("[[leg]")
        return "\n".join(lines), "unterminated [[leg] header", (r"malformed TOML",)
    lines.insert(1, 'bad = "\\q"')
    return "\n".join(lines), "invalid escape \\q", (r"malformed TOML",)


def gen_file_case(rng: random.Random) -> FileCase:
    """One bad mechanism file: a mutation of a random valid base (or a garbage file)."""
    base = rng.choice(sorted(BASES))
    doc = copy.deepcopy(BASES[base])
    family = rng.choices(
        ["unknown_key", "delete", "wrong_type", "nonfinite", "nonpositive", "out_of_range", "geometry", "malformed",
         "empty", "binary", "deep", "bigint_literal"],
        weights=[14, 10, 16, 10, 10, 10, 12, 12, 2, 3, 1, 1])[0]
    if family == "unknown_key":
        detail, needles = mutate_unknown_key(rng, doc)
    elif family == "delete":
        detail, needles = mutate_delete_required(rng, doc, base)
    elif family == "wrong_type":
        detail, needles = mutate_wrong_type(rng, doc)
    elif family == "nonfinite":
        detail, needles = mutate_nonfinite(rng, doc)
    elif family == "nonpositive":
        detail, needles = mutate_nonpositive(rng, doc)
    elif family == "out_of_range":
        detail, needles = mutate_out_of_range(rng, doc, base)
    elif family == "geometry":
        detail, needles = mutate_geometry(rng, doc, base)
    elif family == "malformed":
        text, detail, needles = _text_mutation(rng, to_toml(doc))
        return FileCase(family, detail, text.encode("utf-8"), needles, base)
    elif family == "empty":
        text = rng.choice(["", "\n", "   \n\t\n", "# just a comment\n", "\ufeff", "name = \"only a name\"\n"])
        return FileCase(family, f"content {text!r}", text.encode("utf-8"), (r"(^|: )platform: missing",), base)
    elif family == "binary":
        n = rng.randrange(1, 600)
        raw = bytearray(rng.getrandbits(8) for _ in range(n))
        raw.insert(rng.randrange(len(raw) + 1), 0xFF)  # never valid UTF-8
        if rng.random() < 0.3:  # a valid file in UTF-16
            raw = bytearray(to_toml(doc).encode("utf-16"))
        return FileCase(family, f"{len(raw)} random/UTF-16 bytes", bytes(raw), (r"not a UTF-8 text file",), base)
    elif family == "deep":
        n = rng.choice([2000, 10000, 100000])
        text = to_toml(doc) + "deep = " + "[" * n + "]" * n + "\n"
        return FileCase(family, f"array nested {n} deep", text.encode(), (r"malformed TOML",), base)
    else:  # bigint_literal: more digits than Python converts
        n = rng.choice([4301, 5000, 20000])
        text = to_toml(doc).replace("angle = 0.0", "angle = " + "7" * n, 1)
        if text == to_toml(doc):
            text = to_toml(doc) + "\n[limits]\nmax_strain = " + "7" * n + "\n" if "limits" not in doc else \
                to_toml(doc).replace("max_strain = ", "max_strain = " + "7" * n + "#", 1)
        return FileCase(family, f"an integer literal with {n} digits", text.encode(), (r"malformed TOML",), base)
    return FileCase(family, detail, to_toml(doc).encode("utf-8"), needles, base)


def loader_problems(path: Path, case: FileCase) -> list[str]:
    try:
        m = load_mechanism(path)
    except MechanismError as exc:
        msg = str(exc)
        probs = []
        if not isinstance(exc, ValueError):
            probs.append("MechanismError is not a ValueError")
        if not msg.startswith(f"{path}: "):
            probs.append(f"message does not start with the file name: {msg!r}")
        if "\n" in msg or "Traceback" in msg:
            probs.append(f"message is not one line: {msg!r}")
        if "invalid mechanism description" in msg:
            probs.append(f"catch-all message (an unhandled exception inside the loader): {msg!r}")
        for n in case.needles:
            if not re.search(n, msg):
                probs.append(f"message does not match {n!r}: {msg!r}")
        return probs
    except BaseException:  # noqa: BLE001
        return ["not a MechanismError:\n" + traceback.format_exc()[-1500:]]
    return [f"loaded without error: {m.name!r} ({m.kind})"]


CLI_FOR_FILE = [
    ["show", "{f}"],
    ["ik", "{f}", "--pose", "0", "0", "0"],
    ["fk", "{f}", "--inputs", "0.1", "0.1", "0.1", "--json"],
    ["path", "{f}", "--from", "0", "0", "0", "--to", "0.01", "0", "0", "--steps", "2"],
    ["show", "{f}", "--plot", "{plot}"],
]


def check_file_cases(tmp_path: Path, n: int, seed: int, cli_every: int = 1) -> dict[str, Any]:
    rng = random.Random(seed)
    failures: list[str] = []
    kinds: dict[str, int] = {}
    n_cli = 0
    t0 = time.perf_counter()
    for k in range(n):
        case = gen_file_case(rng)
        kinds[case.kind] = kinds.get(case.kind, 0) + 1
        path = tmp_path / f"bad_{k:05d}.toml"
        path.write_bytes(case.content)
        probs = loader_problems(path, case)
        if probs:
            failures.append(f"case {k}: loader: {probs}\n{case.describe()}")
            continue
        if k % cli_every == 0:
            n_cli += 1
            tmpl = rng.choice(CLI_FOR_FILE)
            argv = [a.format(f=str(path), plot=str(tmp_path / "never.png")) for a in tmpl]
            r = run_cli(argv)
            probs = bad_input_problems(r, (_esc(str(path)) + ": ",) + case.needles)
            if probs:
                failures.append(f"case {k}: CLI {argv}: {probs}\n{case.describe()}")
        path.unlink()
    assert not (tmp_path / "never.png").exists()
    return {"n": n, "n_cli": n_cli, "kinds": dict(sorted(kinds.items())), "failures": failures,
            "seconds": time.perf_counter() - t0}


def test_base_documents_are_valid_and_round_trip(tmp_path):
    """The generator's starting points load, and the TOML writer reproduces the example files."""
    for name, doc in BASES.items():
        p = tmp_path / f"{name}.toml"
        p.write_text(to_toml(doc), encoding="utf-8")
        m = load_mechanism(p)
        if (EXAMPLES / f"{name}.toml").exists():
            assert m == load_mechanism(EXAMPLES / f"{name}.toml")


def test_generator_is_deterministic_and_varied():
    assert gen_file_case(random.Random(7)).content == gen_file_case(random.Random(7)).content
    rng1, rng2 = random.Random(11), random.Random(11)
    c1 = [gen_file_case(rng1) for _ in range(200)]
    c2 = [gen_file_case(rng2) for _ in range(200)]
    assert [c.content for c in c1] == [c.content for c in c2]
    assert len({c.content for c in c1}) > 150
    assert len({c.kind for c in c1}) >= 10


def test_bad_files_default(tmp_path):
    res = check_file_cases(tmp_path, N_FILES_DEFAULT, SEED)
    record("bad files (default)", f"{res['n']} files, {res['n_cli']} also through the CLI, "
                                  f"{len(res['failures'])} failures, {res['seconds']:.1f} s; {res['kinds']}")
    assert not res["failures"], f"{len(res['failures'])} failures:\n\n" + "\n\n".join(res["failures"][:8])


@pytest.mark.slow
def test_bad_files_slow(tmp_path):
    res = check_file_cases(tmp_path, N_FILES_SLOW, SEED + 1)
    record("bad files (slow)", f"{res['n']} files, {res['n_cli']} also through the CLI, "
                               f"{len(res['failures'])} failures, {res['seconds']:.1f} s; {res['kinds']}")
    assert not res["failures"], f"{len(res['failures'])} failures:\n\n" + "\n\n".join(res["failures"][:8])


# --------------------------------------------------------------------------------------
# fixed loader cases: paths, sizes, encodings, and good files that must stay good
# --------------------------------------------------------------------------------------
def test_unreadable_paths(tmp_path):
    d = tmp_path / "adir.toml"
    d.mkdir()
    f = tmp_path / "afile"
    f.write_text("x")
    cases = [
        (tmp_path / "nope.toml", r"nope\.toml: file not found"),
        (d, r"adir\.toml: is a directory"),
        (f / "x.toml", r"x\.toml: (cannot read file|file not found)"),
        (str(tmp_path / "a\0b.toml"), r"NUL"),
        ("", r"empty file name"),
    ]
    for p, needle in cases:
        with pytest.raises(MechanismError) as info:
            load_mechanism(p)
        msg = str(info.value)
        assert re.search(needle, msg), msg
        assert "\n" not in msg


def test_oversized_and_endless_files(tmp_path):
    from flexkin.mechanism.loader import MAX_FILE_BYTES

    big = tmp_path / "big.toml"
    big.write_bytes(b"# padding\n" * (MAX_FILE_BYTES // 10 + 10))
    with pytest.raises(MechanismError, match=r"big\.toml: file too large"):
        load_mechanism(big)
    if os.path.exists("/dev/zero"):  # an endless stream must not be read to the end
        t0 = time.perf_counter()
        with pytest.raises(MechanismError, match=r"/dev/zero: (file too large|not a UTF-8|malformed)"):
            load_mechanism("/dev/zero")
        assert time.perf_counter() - t0 < 10
    if os.path.exists("/dev/null"):
        with pytest.raises(MechanismError, match=r"/dev/null: platform: missing"):
            load_mechanism("/dev/null")


@pytest.mark.parametrize("variant", ["crlf", "bom", "reordered", "comments", "tabs", "int_values"])
def test_harmless_variants_still_load(tmp_path, variant):
    """Controls: formatting changes that are NOT mistakes must not be rejected."""
    text = (EXAMPLES / "mixed_legs.toml").read_text(encoding="utf-8")
    want = load_mechanism(EXAMPLES / "mixed_legs.toml")
    if variant == "crlf":
        data = text.replace("\n", "\r\n").encode()
    elif variant == "bom":
        data = b"\xef\xbb\xbf" + text.encode()
    elif variant == "reordered":
        doc = tomllib.loads(text)
        doc = {k: doc[k] for k in reversed(list(doc))}
        data = to_toml(doc).encode()
    elif variant == "comments":
        data = ("# header\n\n" + text.replace("\n", "   # trailing comment\n", 3) + "\n# end\n").encode()
    elif variant == "tabs":
        data = text.replace(" = ", "\t=\t").encode()
    else:  # integers where floats are expected
        doc = tomllib.loads(text)
        doc["leg"][1]["range"] = [60, 240]
        doc["load"]["moment"] = 0
        doc["load"]["force"] = [0, -0.05]
        data = to_toml(doc).encode()
    p = tmp_path / f"{variant}.toml"
    p.write_bytes(data)
    m = load_mechanism(p)
    if variant != "int_values":
        assert m == want
    else:
        assert m.load == (0.0, -0.05, 0.0)


def test_unknown_keys_are_always_errors_with_a_hint(tmp_path):
    """Every table rejects unknown keys (no silent ignoring, no mere warnings) and suggests the
    allowed key for each single-edit misspelling (deletion, insertion, substitution,
    transposition, case change)."""
    import warnings

    doc0 = BASES["prototype_loaded"]
    n = 0
    for kind, allowed in ALLOWED.items():
        for key in allowed:
            variants = {key.swapcase(), key[1:] or key + "x", key + "s", key[:-1] + "x" if len(key) > 1 else "Ex",
                        (key[1] + key[0] + key[2:]) if len(key) > 1 and key[0] != key[1] else key + "_"}
            for new in sorted(v for v in variants if v not in allowed and v):
                doc = copy.deepcopy(doc0)
                table = {"": doc, "rod": doc["rod"], "leg": doc["leg"][1], "platform": doc["platform"],
                         "load": doc["load"], "limits": doc["limits"]}[kind]
                table[new] = table.pop(key) if key in table else 1.0
                p = tmp_path / "k.toml"
                p.write_text(to_toml(doc), encoding="utf-8")
                with warnings.catch_warnings():
                    warnings.simplefilter("error")  # a warning instead of an error fails here
                    with pytest.raises(MechanismError) as info:
                        load_mechanism(p)
                msg = str(info.value)
                prefix = {"": "", "leg": "leg[2]."}.get(kind, kind + ".")
                assert f"{prefix}{key_text(new)}: unknown key" in msg, msg
                dmin = min(osa(new.lower(), a.lower()) for a in allowed)
                ok = [a for a in allowed if osa(new.lower(), a.lower()) == dmin]
                assert re.search(r"did you mean '(" + "|".join(map(re.escape, ok)) + r")'\?", msg), (new, msg)
                n += 1
    assert n >= 40


# ======================================================================================
# bad command lines
# ======================================================================================
# option -> number of values, per subcommand (SPEC §4 and cli.py's parser)
NUMERIC = {
    "rod": {"--length": 1, "--EI": 1, "--E": 1, "--radius": 1, "--tip": 2, "--clamp-angle": 1, "--tip-y": 1,
            "--x-range": 2},
    "ik": {"--pose": 3, "--load": 3},
    "fk": {"--inputs": 3, "--load": 3},
    "path": {"--from": 3, "--to": 3, "--load": 3},
    "show": {},
}
POSITIVE = {"--length", "--EI", "--E", "--radius"}
INT_OPTS = {"ik": ["--max-mode"], "fk": ["--max-mode"], "rod": ["--max-mode"], "path": ["--max-mode", "--steps",
                                                                                        "--solution"], "show": []}
ALL_OPTIONS = {
    "show": ["--plot", "--help"],
    "rod": ["--length", "--EI", "--E", "--radius", "--tip", "--clamp-angle", "--max-mode", "--sweep", "--tip-y",
            "--x-range", "--points", "--json", "--plot", "--help"],
    "ik": ["--pose", "--load", "--max-mode", "--json", "--plot", "--stable-only", "--feasible-only", "--curves",
           "--help"],
    "fk": ["--inputs", "--load", "--max-mode", "--json", "--plot", "--stable-only", "--feasible-only", "--help"],
    "path": ["--from", "--to", "--steps", "--solution", "--load", "--max-mode", "--json", "--plot", "--help"],
}
JUNK_NUMBERS = ["abc", "", " ", "nan", "NaN", "+nan", "inf", "+inf", "Infinity", "1e999", "-1e999", "1e400", "1,5",
                "0x10", "1e", ".", "1.2.3", "one", "None", "true", "½", "1/2", "0.5m", "5e-", "e5", "1 2", "--",
                "-nan", "-inf", "-x", "\x00", "１e９９９"]
JUNK_INTS = ["0", "7", "1e9", "-1", "abc", "2.5", "", "99999999999999999999", "nan", "inf", "1e0", "0x2", "two",
             "-0", "+7", " 9 ", "3.0", "1_000_000"]


def _templates() -> list[tuple[str, list[str]]]:
    return [
        ("show", ["show", RFR]),
        ("rod", ["rod", "--length", "1", "--EI", "1", "--tip", "0.6", "0.3"]),
        ("rod", ["rod", "--length", "1", "--E", "2e9", "--radius", "1e-3", "--tip", "0.6", "0.3", "--json"]),
        ("ik", ["ik", RFR, "--pose", "0.05", "0.02", "20"]),
        ("ik", ["ik", PROTO, "--pose", "0", "0", "90", "--load", "0", "0", "0", "--max-mode", "1", "--json"]),
        ("fk", ["fk", PROTO, "--inputs", "0.025", "0.025", "0.025"]),
        ("fk", ["fk", MIXED, "--inputs", "0.02", "90", "0.8", "--json"]),
        ("path", ["path", PROTO, "--from", "0", "0", "90", "--to", "0", "0", "100", "--steps", "4"]),
        ("path", ["path", RFR, "--from", "0", "0", "0", "--to", "0.01", "0", "0", "--solution", "1", "--json"]),
    ]


@dataclass
class ArgvCase:
    kind: str
    argv: list[str]
    needles: tuple[str, ...]
    detail: str = ""


def _value_positions(argv: list[str], opt: str, n: int) -> list[int]:
    i = argv.index(opt)
    return list(range(i + 1, i + 1 + n))


def _is_prefix_of_option(tok: str, sub: str) -> bool:
    opts = ALL_OPTIONS.get(sub, []) + (["--version", "--help"] if sub == "" else [])
    return any(o.startswith(tok) for o in opts)


def gen_argv_case(rng: random.Random, files: dict[str, str]) -> ArgvCase:
    sub, argv = rng.choice(_templates())
    argv = list(argv)
    family = rng.choices(["drop", "count", "junk_number", "junk_int", "nonpositive", "unknown_option", "command",
                          "file", "rod_semantics", "length_input", "explicit_arg"],
                         weights=[10, 12, 20, 10, 6, 14, 4, 10, 5, 3, 3])[0]
    opts = [o for o in NUMERIC[sub] if o in argv]
    if family == "drop":
        choices = [o for o in opts if o in ("--pose", "--inputs", "--from", "--to", "--length", "--tip")]
        if sub != "rod":
            choices.append("mechanism")
        if sub == "rod" and "--EI" in argv:
            choices.append("--EI")
        what = rng.choice(choices)
        if what == "mechanism":
            del argv[1]
            return ArgvCase(family, argv, (r"required: .*mechanism",), "dropped the mechanism file")
        i = argv.index(what)
        n = {"--EI": 1, "--length": 1, "--tip": 2}.get(what, 3)
        del argv[i:i + 1 + n]
        needle = {"--EI": r"stiffness"}.get(what, _esc(what))
        return ArgvCase(family, argv, (needle,), f"dropped {what}")
    if family == "count" and opts:
        opt = rng.choice(opts)
        n = NUMERIC[sub][opt]
        pos = _value_positions(argv, opt, n)
        k = rng.choice([j for j in range(0, n + 2) if j != n])
        if k < n:
            del argv[pos[k]:pos[-1] + 1]
            if rng.random() < 0.5:  # followed directly by another option
                other = rng.choice([o for o in ALL_OPTIONS[sub] if o not in (opt, "--help")])
                if other in ("--json", "--sweep", "--stable-only", "--feasible-only"):
                    argv.insert(pos[0] if k == 0 else pos[k - 1] + 1, other)
            return ArgvCase(family, argv, (_esc(opt),), f"{opt} with {k} value(s)")
        argv.insert(pos[-1] + 1, "7.25")
        return ArgvCase(family, argv, (r"unrecognized arguments: .*7\.25",), f"{opt} with {k} values")
    if family in ("junk_number", "count") and opts:
        opt = rng.choice(opts)
        p = rng.choice(_value_positions(argv, opt, NUMERIC[sub][opt]))
        argv[p] = rng.choice(JUNK_NUMBERS)
        return ArgvCase("junk_number", argv, (_esc(opt),), f"{opt} value {argv[p]!r}")
    if family == "junk_int" and INT_OPTS[sub]:
        opt = rng.choice(INT_OPTS[sub])
        val = rng.choice(JUNK_INTS)
        if opt == "--solution" and val in ("0", "7", "+7", " 9 ", "-0"):
            val = "-1"
        if opt == "--steps" and val in ("7", "+7", " 9 "):
            val = "0"
        if opt == "--max-mode" and val in (" 9 ",):
            val = "9"
        if opt in argv:
            argv[argv.index(opt) + 1] = val
        else:
            argv += [opt, val]
        return ArgvCase(family, argv, (_esc(opt),), f"{opt} {val!r}")
    if family == "nonpositive" and sub == "rod":
        opt = rng.choice([o for o in POSITIVE if o in argv])
        argv[argv.index(opt) + 1] = val = rng.choice(["0", "-1", "-0.0", "0.0", "-1e-300", "-5"])
        return ArgvCase(family, argv, (_esc(opt),), f"{opt} {val}")
    if family == "unknown_option":
        tok = rng.choice(["--bogus", "--pose-x", "-x", "--JSON", "---pose", "-p", "--maxmode", "--max_mode",
                          "--no-json", "--inputz", "-P", "-j", "--platform", "--Pose", "--stable", "--loads",
                          "-5x", "--" + "".join(rng.choice("qwzkv") for _ in range(rng.randrange(3, 9)))])
        if _is_prefix_of_option(tok, sub):
            tok = "--zz" + tok.lstrip("-")
        pos = rng.randrange(1, len(argv) + 1)
        # never split an option from its values
        while pos < len(argv) and not argv[pos].startswith("--") and pos > 1:
            pos += 1
        argv.insert(pos, tok)
        return ArgvCase(family, argv, (r"(unrecognized arguments|ambiguous option|unknown|invalid).*" + _esc(tok),),
                        f"unknown option {tok!r}")
    if family == "command":
        tok = rng.choice(["IK", "ikk", "solve", "", "show_", "fk2", "Rod", "-", "path/", "workspaces"])
        argv = [tok] + argv[1:]
        return ArgvCase(family, argv, (r"invalid choice: " + _esc(repr(tok)),), f"command {tok!r}")
    if family == "file" and sub != "rod":
        kind = rng.choice(["missing", "dir", "bad", "binary", "empty"])
        f = files[kind]
        argv[1] = f
        needle = {"missing": r"file not found", "dir": r"is a directory", "bad": r"platform\.attach",
                  "binary": r"not a UTF-8", "empty": r"platform: missing"}[kind]
        return ArgvCase(family, argv, (_esc(f) + ": ", needle), f"{kind} mechanism file")
    if family == "rod_semantics":
        c = rng.choice(["both", "E_only", "radius_only", "points", "x_range", "tip_y", "no_tip"])
        base = ["rod", "--length", "1", "--tip", "0.6", "0.3"]
        if c == "both":
            return ArgvCase(family, base + ["--EI", "1", "--E", "2e9", "--radius", "1e-3"], (r"either",), c)
        if c == "E_only":
            return ArgvCase(family, base + ["--E", "2e9"], (r"stiffness",), c)
        if c == "radius_only":
            return ArgvCase(family, base + ["--radius", "1e-3"], (r"stiffness",), c)
        if c == "points":
            v = rng.choice(["1", "0", "-3", "10001", "abc", "2.5", "1e3"])
            return ArgvCase(family, ["rod", "--sweep", "--points", v], (r"--points",), c)
        if c == "x_range":
            return ArgvCase(family, ["rod", "--sweep", "--x-range", "0.5"], (r"--x-range",), c)
        if c == "tip_y":
            return ArgvCase(family, ["rod", "--sweep", "--tip-y", rng.choice(["nan", "inf", "x"])], (r"--tip-y",), c)
        return ArgvCase(family, ["rod", "--length", "1", "--EI", "1"], (r"--tip",), c)
    if family == "length_input":
        i = rng.randrange(3)
        u = ["0.5", "0.5", "0.5"]
        u[i] = rng.choice(["0", "-0.5", "-1e-9", "0.0", "-0"])
        return ArgvCase(family, ["fk", LEN, "--inputs", *u], (rf"(input {i + 1}|--inputs)",), f"length input {u}")
    if family == "explicit_arg":
        flag = rng.choice([o for o in ("--json", "--sweep", "--stable-only", "--feasible-only") if o in ALL_OPTIONS[sub]]
                          or ["--help"])
        if flag == "--help":
            return gen_argv_case(rng, files)
        argv.append(f"{flag}={rng.choice(['yes', '1', 'true', ''])}")
        return ArgvCase(family, argv, (_esc(flag),), f"{flag}=value")
    return gen_argv_case(rng, files)


@pytest.fixture(scope="module")
def bad_paths(tmp_path_factory) -> dict[str, str]:
    d = tmp_path_factory.mktemp("argv_files")
    (d / "a_directory.toml").mkdir()
    (d / "bad.toml").write_text(to_toml({**BASES["unit_3rfr"], "platform": {"attach": [[0, 0], [0, 0], [1, 1]]}}))
    (d / "binary.toml").write_bytes(bytes(range(256)))
    (d / "empty.toml").write_bytes(b"")
    return {"missing": str(d / "missing.toml"), "dir": str(d / "a_directory.toml"), "bad": str(d / "bad.toml"),
            "binary": str(d / "binary.toml"), "empty": str(d / "empty.toml")}


def check_argv_cases(n: int, seed: int, files: dict[str, str]) -> dict[str, Any]:
    rng = random.Random(seed)
    failures, known = [], {}
    kinds: dict[str, int] = {}
    t0 = time.perf_counter()
    slowest = (0.0, None)
    for k in range(n):
        case = gen_argv_case(rng, files)
        kinds[case.kind] = kinds.get(case.kind, 0) + 1
        r = run_cli(case.argv)
        if r.seconds > slowest[0]:
            slowest = (r.seconds, case.argv)
        probs = bad_input_problems(r, case.needles)
        if probs:
            kb = known_bug(case.argv)
            if kb:
                known[kb] = known.get(kb, 0) + 1
            else:
                failures.append(f"case {k} [{case.kind}: {case.detail}] argv={case.argv!r}: {probs}")
    return {"n": n, "kinds": dict(sorted(kinds.items())), "failures": failures, "known": known,
            "seconds": time.perf_counter() - t0, "slowest": slowest}


def test_argv_generator_is_deterministic(bad_paths):
    a = [gen_argv_case(random.Random(3), bad_paths).argv for _ in range(3)]
    rng1, rng2 = random.Random(5), random.Random(5)
    assert [gen_argv_case(rng1, bad_paths).argv for _ in range(300)] == \
           [gen_argv_case(rng2, bad_paths).argv for _ in range(300)]
    assert a[0] == a[1] == a[2]


def test_bad_argv_default(bad_paths):
    res = check_argv_cases(N_ARGV_DEFAULT, SEED, bad_paths)
    record("bad argv (default)", f"{res['n']} command lines, {len(res['failures'])} failures, known bugs "
                                 f"{res['known']}, {res['seconds']:.1f} s (slowest {res['slowest'][0]:.2f} s); "
                                 f"{res['kinds']}")
    assert not res["failures"], f"{len(res['failures'])} failures:\n" + "\n".join(res["failures"][:10])


@pytest.mark.slow
def test_bad_argv_slow(bad_paths):
    res = check_argv_cases(N_ARGV_SLOW, SEED + 1, bad_paths)
    record("bad argv (slow)", f"{res['n']} command lines, {len(res['failures'])} failures, known bugs "
                              f"{res['known']}, {res['seconds']:.1f} s (slowest {res['slowest'][0]:.2f} s); "
                              f"{res['kinds']}")
    assert not res["failures"], f"{len(res['failures'])} failures:\n" + "\n".join(res["failures"][:10])


# --------------------------------------------------------------------------------------
# fixed command-line cases (the brief's list, one by one)
# --------------------------------------------------------------------------------------
FIXED_ARGV = [
    ([], r"required: command"),
    (["--bogus"], r"(--bogus|required: command)"),
    (["show"], r"required: mechanism"),
    (["ik", RFR, "--pose", "0", "0"], r"--pose"),
    (["ik", RFR, "--pose", "0", "0", "nan"], r"--pose.*finite"),
    (["ik", RFR, "--pose", "0", "0", "0", "--max-mode", "0"], r"--max-mode"),
    (["ik", RFR, "--pose", "0", "0", "0", "--max-mode", "7"], r"--max-mode"),
    (["ik", RFR, "--pose", "0", "0", "0", "--max-mode", "1e9"], r"--max-mode"),
    (["ik", RFR, "--pose", "0", "0", "0", "--max-mode", "-1"], r"--max-mode"),
    (["fk", RFR, "--inputs", "0", "0", "0", "--max-mode", "0"], r"--max-mode"),
    (["rod", "--length", "1", "--EI", "1", "--tip", "0.5", "0.1", "--max-mode", "7"], r"--max-mode"),
    (["path", RFR, "--from", "0", "0", "0", "--to", "0", "0", "1", "--max-mode", "1e9"], r"--max-mode"),
    (["fk", RFR, "--inputs", "0", "0", "0", "--load", "1", "2"], r"--load"),
    (["fk", RFR], r"--inputs"),
    (["path", RFR, "--to", "0", "0", "1"], r"--from"),
    (["path", RFR, "--from", "0", "0", "0", "--to", "0", "0", "1", "--steps", "0"], r"--steps"),
    (["path", RFR, "--from", "0", "0", "0", "--to", "0", "0", "1", "--steps", "100001"], r"--steps"),
    (["path", RFR, "--from", "0", "0", "0", "--to", "0", "0", "1", "--solution", "-1"], r"--solution"),
    (["rod", "--length", "1", "--EI", "0", "--tip", "0.5", "0.1"], r"--EI"),
    (["rod", "--length", "1", "--EI", "1", "--tip", "0.5"], r"--tip"),
    (["rod", "--length", "1", "--EI", "1", "--tip", "0.5", "nan"], r"--tip"),
    (["show", "/nonexistent_dir/m.toml"], r"/nonexistent_dir/m\.toml: file not found"),
    (["ik", str(EXAMPLES), "--pose", "0", "0", "0"], r"is a directory"),
    (["ik", "", "--pose", "0", "0", "0"], r"empty file name"),
    (["fk", LEN, "--inputs", "0", "1", "1"], r"(input 1|--inputs)"),
    (["path", RFR, "--from", "0.05", "0.02", "20", "--to", "0.05", "0.02", "21", "--steps", "1", "--solution",
      "100000"], r"solution"),
]


@pytest.mark.parametrize("argv, needle", FIXED_ARGV, ids=[" ".join(a)[:60] or "<empty>" for a, _ in FIXED_ARGV])
def test_fixed_bad_argv(argv, needle):
    r = run_cli(argv)
    assert not bad_input_problems(r, (needle,)), (bad_input_problems(r, (needle,)), r.err)


# --------------------------------------------------------------------------------------
# unwritable --plot / --curves paths
# --------------------------------------------------------------------------------------
def _plot_cases(tmp: Path) -> list[tuple[str, list[str], str, bool]]:
    """(id, argv, path that must be named, xfail?)"""
    afile = tmp / "afile"
    afile.write_text("x")
    adir = tmp / "adir"
    adir.mkdir(exist_ok=True)
    nodir = "/nonexistent_flexkin_dir/x.png"
    under_file = str(afile / "x.png")
    out = []
    for tag, target in (("nodir", nodir), ("under-file", under_file), ("proc", "/proc/flexkin_x.png")):
        out += [
            (f"show-{tag}", ["show", RFR, "--plot", target], target, False),
            (f"rod-{tag}", ["rod", "--length", "1", "--EI", "1", "--tip", "0.6", "0.3", "--plot", target], target, False),
        ]
    out += [
        ("ik-nodir", ["ik", RFR, "--pose", "0.05", "0.02", "20", "--plot", nodir], nodir, False),
        ("ik-curves-nodir", ["ik", RFR, "--pose", "0.05", "0.02", "20", "--curves", nodir], nodir, False),
        ("fk-nodir", ["fk", PROTO, "--inputs", "-3", "3", "0", "--plot", nodir], nodir, False),
        ("path-nodir", ["path", RFR, "--from", "0.05", "0.02", "20", "--to", "0.05", "0.02", "21", "--steps", "1",
                        "--plot", nodir], nodir, False),
        ("rod-sweep-nodir", ["rod", "--sweep", "--points", "3", "--plot", nodir], nodir, False),
        # a directory given as the figure file: matplotlib silently writes "<dir>.png" and the CLI
        # reports "figure written to <dir>" with exit 0
        ("show-directory", ["show", RFR, "--plot", str(adir)], str(adir), True),
        # an unknown extension: the message names the format but neither --plot nor the path
        ("show-bad-extension", ["show", RFR, "--plot", str(tmp / "x.xyz")], str(tmp / "x.xyz"), True),
    ]
    return out


_PLOT_IDS = [
    "show-nodir", "rod-nodir", "show-under-file", "rod-under-file", "show-proc", "rod-proc", "ik-nodir",
    "ik-curves-nodir", "fk-nodir", "path-nodir", "rod-sweep-nodir", "show-directory", "show-bad-extension"]
_PLOT_XFAIL: dict[str, str] = {}  # fixed: --plot is validated before any work


@pytest.mark.parametrize("case_id", [
    pytest.param(c, marks=pytest.mark.xfail(strict=True, reason=_PLOT_XFAIL[c])) if c in _PLOT_XFAIL else c
    for c in _PLOT_IDS])
def test_unwritable_plot_paths(tmp_path, case_id):
    cases = {c[0]: c for c in _plot_cases(tmp_path)}
    _, argv, target, _ = cases[case_id]
    r = run_cli(argv)
    # results may already be on stdout (computed before the figure), and an explanation of an
    # empty answer may precede the error: require the error line itself
    probs = bad_input_problems(r, (r"(" + _esc(target) + r"|--plot|--curves)",), stdout_empty=False, single=False)
    assert not probs, (probs, r.err)
    assert not any(Path(p).exists() for p in (target + ".png",)), "a figure was written next to the target"


# --------------------------------------------------------------------------------------
# extreme but valid input: answered or rejected cleanly, never a traceback
# --------------------------------------------------------------------------------------
def _big(rng, lo=-300, hi=300) -> str:
    """A number of random sign and magnitude 10**U(lo, hi); negative ones mostly in positional
    notation (argparse takes '-1e-3' for an option: known bug 'negative-exponent-values')."""
    import numpy as np

    x = rng.choice([1.0, -1.0]) * 10.0 ** rng.uniform(lo, hi)
    if x < 0 and rng.random() < 0.75:
        return np.format_float_positional(x, unique=True, trim="0")
    return repr(x)


def _extreme_file(rng: random.Random, tmp: Path) -> tuple[str, float]:
    """A valid example mechanism scaled to the edges of the supported ranges: (path, length scale)."""
    stem = rng.choice(["unit_3rfr", "unit_3pfr", "unit_3pfr_length", "mixed_legs"])
    doc = copy.deepcopy(BASES[stem])
    s = 10.0 ** rng.uniform(-11.0, 11.0)
    c = 10.0 ** rng.uniform(-29.0, 29.0)
    if "rod" in doc:
        for k in ("length", "radius"):
            if k in doc["rod"]:
                doc["rod"][k] *= s
        doc["rod"].pop("E", None)
        doc["rod"]["EI"] = c
    doc.pop("limits", None)
    doc.pop("load", None)
    for leg in doc["leg"]:
        leg["origin"] = [v * s for v in leg["origin"]]
        if "length" in leg:
            leg["length"] *= s
        leg.pop("radius", None)  # EI comes from [rod]
        leg.pop("E", None)
        if "range" in leg and leg["actuation"] != "revolute":
            leg["range"] = [v * s for v in leg["range"]]
    doc["platform"]["attach"] = [[x * s, y * s] for x, y in doc["platform"]["attach"]]
    path = tmp / f"extreme_{stem}_{rng.getrandbits(32):08x}.toml"
    path.write_text(to_toml(doc), encoding="utf-8")
    return str(path), s


def gen_extreme_case(rng: random.Random, tmp: Path | None = None) -> list[str]:
    kinds = ["rod", "rod", "rod_E", "ik_pose", "ik_load", "fk_far", "rod_sweep"] + (["file"] * 2 if tmp else [])
    kind = rng.choice(kinds)
    if kind == "file":  # a valid mechanism at the edges of the supported ranges: show (+ figure) and ik
        f, s = _extreme_file(rng, tmp)
        if rng.random() < 0.4:
            return ["show", f] + (["--plot", str(tmp / "extreme.png")] if rng.random() < 0.5 else [])
        return ["ik", f, "--pose", repr(0.05 * s), repr(0.02 * s), "20", "--max-mode", "1", "--json"]
    if kind == "rod":
        argv = ["rod", "--length", repr(10.0 ** rng.uniform(-15, 300)), "--EI", repr(10.0 ** rng.uniform(-300, 300)),
                "--tip", _big(rng, -300, 2), _big(rng, -300, 2)]
        if rng.random() < 0.5:
            argv += ["--clamp-angle", _big(rng, -10, 300)]
        if rng.random() < 0.5:
            argv += ["--max-mode", str(rng.randint(1, 6))]
        if rng.random() < 0.5:
            argv += ["--json"]
        return argv
    if kind == "rod_E":
        return ["rod", "--length", "1", "--E", repr(10.0 ** rng.uniform(-300, 300)), "--radius",
                repr(10.0 ** rng.uniform(-100, 100)), "--tip", "0.6", "0.3", "--json"]
    if kind == "rod_sweep":
        return ["rod", "--sweep", "--points", "3", "--length", repr(10.0 ** rng.uniform(-15, 15)),
                "--tip-y", _big(rng, -15, 15), "--x-range", _big(rng, -15, 15), _big(rng, -15, 15), "--json"]
    if kind == "ik_pose":  # far away (near the centre, IK of this mechanism takes up to ~20 s: not here)
        return ["ik", RFR, "--pose", _big(rng, 1, 300), _big(rng, -300, 300), _big(rng, -5, 300), "--json"]
    if kind == "ik_load":
        return ["ik", RFR, "--pose", "0.05", "0.02", "20", "--load", _big(rng), _big(rng), _big(rng), "--json"]
    return ["fk", PROTO, "--inputs", _big(rng, 1, 300), _big(rng, 1, 300), _big(rng, 1, 300), "--json"]


def extreme_problems(r: Run) -> list[str]:
    if r.exc is not None:
        return ["uncaught exception:\n" + r.exc[-1500:]]
    probs = []
    if r.rc not in (0, 2):
        probs.append(f"exit status {r.rc!r}")
    if "Traceback" in r.err:
        probs.append("traceback printed")
    if r.rc == 0 and "--json" in r.argv:
        try:
            json.loads(r.out, parse_constant=lambda c: (_ for _ in ()).throw(ValueError(c)))
        except ValueError as e:
            probs.append(f"stdout is not strict JSON: {e}")
    if r.rc == 2:
        msgs = r.messages
        if any(re.search(r"expected (\d+ arguments|one argument)", m) for m in msgs):
            probs.append(f"a valid number was refused as a missing value: {msgs}")
        named = [o for o in r.argv if o.startswith("--")] + [a for a in r.argv if a.endswith(".toml")]
        if len(msgs) != 1 or not any(o in msgs[0] for o in named):
            probs.append(f"rejected without naming an option or the file: {msgs}")
    return probs


def check_extreme_cases(n: int, seed: int, tmp: Path) -> dict[str, Any]:
    rng = random.Random(seed)
    failures, known, rcs = [], {}, {}
    t0 = time.perf_counter()
    for k in range(n):
        argv = gen_extreme_case(rng, tmp)
        r = run_cli(argv)
        rcs[str(r.rc)] = rcs.get(str(r.rc), 0) + 1
        probs = extreme_problems(r)
        if probs:
            kb = known_bug(argv)
            if kb:
                known[kb] = known.get(kb, 0) + 1
            else:
                failures.append(f"case {k} argv={argv!r}: {probs}")
    return {"n": n, "failures": failures, "known": known, "rcs": rcs, "seconds": time.perf_counter() - t0}


def test_extreme_values_default(tmp_path):
    res = check_extreme_cases(N_EXTREME_DEFAULT, SEED, tmp_path)
    record("extreme-but-valid argv (default)", f"{res['n']} command lines, exit codes {res['rcs']}, "
                                               f"{len(res['failures'])} failures, known bugs {res['known']}, "
                                               f"{res['seconds']:.1f} s")
    assert not res["failures"], "\n".join(res["failures"][:10])


@pytest.mark.slow
def test_extreme_values_slow(tmp_path):
    res = check_extreme_cases(N_EXTREME_SLOW, SEED + 1, tmp_path)
    record("extreme-but-valid argv (slow)", f"{res['n']} command lines, exit codes {res['rcs']}, "
                                            f"{len(res['failures'])} failures, known bugs {res['known']}, "
                                            f"{res['seconds']:.1f} s")
    assert not res["failures"], "\n".join(res["failures"][:10])


# --------------------------------------------------------------------------------------
# bugs found by this fuzzing and fixed in cli.py / the solvers: kept as regression tests
# --------------------------------------------------------------------------------------
@pytest.mark.parametrize("E, radius", [("1e300", "1e100"), ("1e261", "1e39"), ("1e-103", "1e-67")])
def test_fixed_bug_rod_EI_unrepresentable(E, radius):
    argv = ["rod", "--length", "1", "--E", E, "--radius", radius, "--tip", "0.5", "0.1"]
    r = run_cli(argv)
    assert not bad_input_problems(r, (r"--E|--radius",)), (r.exc, r.err)


@pytest.mark.parametrize("argv", [
    ["ik", RFR, "--pose", "0.05", "0.02", "20", "--load", "0", "-1e-3", "0"],
    ["rod", "--length", "1", "--EI", "1", "--tip", "0.6", "-3e-1"],
])
def test_fixed_bug_negative_exponent_values(argv):
    r = run_cli(argv)
    assert r.exc is None and r.rc == 0, r.err


def test_fixed_bug_rod_length_overflow():
    argv = ["rod", "--length", "1e200", "--EI", "1", "--tip", "0.5", "0.1"]
    r = run_cli(argv)
    assert r.exc is None and r.rc in (0, 2), r.exc[-300:]


@pytest.mark.parametrize("argv", [
    ["ik", LEN, "--pose", "0", "0", "0", "--max-mode", "1"],
    ["path", LEN, "--from", "0", "0", "0", "--to", "0.01", "0", "0", "--steps", "2", "--max-mode", "1"],
])
def test_fixed_bug_valid_input_reported_as_bad(argv):
    r = run_cli(argv)
    assert r.exc is None and r.rc == 0, (r.rc, r.err)


# ======================================================================================
# a handful of subprocess runs through the installed entry point
# ======================================================================================
def _entry_point() -> list[str]:
    exe = shutil.which("flexkin")
    if exe:
        return [exe]
    return [sys.executable, "-c", "import sys; from flexkin.cli import main; sys.exit(main())"]


SUBPROCESS_CASES = [
    (["ik", RFR, "--pose", "0", "0", "abc"], r"--pose"),
    (["fk", RFR, "--inputs", "0", "0", "0", "--max-mode", "7"], r"--max-mode"),
    (["rod", "--length", "-1", "--EI", "1", "--tip", "0.5", "0.1"], r"--length"),
    (["path", RFR, "--from", "0", "0", "0", "--to", "0", "0", "1", "--steps", "abc"], r"--steps"),
    (["show", "{bad}"], r"platform\.attach: .*coincide"),
    (["show", "{binary}"], r"not a UTF-8"),
]


@pytest.mark.parametrize("argv, needle", SUBPROCESS_CASES, ids=[a[0] + "-" + n[:12] for a, n in SUBPROCESS_CASES])
def test_subprocess(argv, needle, bad_paths):
    argv = [a.format(**bad_paths) for a in argv]
    p = subprocess.run(_entry_point() + argv, capture_output=True, text=True, timeout=120, cwd=str(ROOT))
    r = Run(argv, p.returncode, p.stdout, p.stderr, None, 0.0)
    assert p.returncode == 2, (p.returncode, p.stderr)
    assert not bad_input_problems(r, (needle,)), (bad_input_problems(r, (needle,)), p.stderr)
