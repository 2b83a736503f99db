"""Import paths of earlier releases (issue 27, item 10): a script written against flexkin 0.1
(``import flexkin.kinematics``, ``from flexkin.workspace import workspace``) still runs, each old
path warning once with a FutureWarning that names the new one, at the script's import line."""

from __future__ import annotations

import json
import subprocess
import sys
from pathlib import Path

import pytest

from flexkin._moved import MOVED, PACKAGES, REMOVED_IN

ROOT = Path(__file__).resolve().parents[1]


def _run(code: str) -> dict:
    """Run ``code`` in a fresh interpreter; it prints one JSON object last."""
    out = subprocess.run([sys.executable, "-W", "error::DeprecationWarning", "-c", code], capture_output=True,
                         text=True, timeout=600, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    return json.loads(out.stdout.strip().splitlines()[-1])


PROLOGUE = """
import json, warnings
warnings.simplefilter("always")
def caught(stmt):
    with warnings.catch_warnings(record=True) as w:
        warnings.simplefilter("always")
        exec(stmt, globals())
    return [(x.category.__name__, str(x.message), x.filename) for x in w]
"""


def test_a_flexkin_0_1_script_runs_and_is_told_the_new_paths():
    d = _run(PROLOGUE + """
w1 = caught("import flexkin.kinematics")
w2 = caught("from flexkin.kinematics import ik, fk, KinematicsResult, Solution")
import flexkin, flexkin.solve.ik, flexkin.results
same = [ik is flexkin.ik, fk is flexkin.fk, KinematicsResult is flexkin.results.KinematicsResult,
        Solution is flexkin.results.Solution]
w3 = caught("from flexkin.kinematics.stability import mechanism_stability")
import flexkin.analysis.stability as st
same.append(mechanism_stability is st.mechanism_stability)
w4 = caught("import flexkin.kinematics.ik as old_ik")
same.append(old_ik is flexkin.solve.ik)
print(json.dumps({"w": [w1, w2, w3, w4], "same": same}))
""")
    assert all(d["same"])
    w1, w2, w3, w4 = d["w"]
    assert len(w1) == 1 and w1[0][0] == "FutureWarning" and "(fk, ik, KinematicsResult, Solution) are in flexkin" in w1[0][1]
    assert w2 == []  # warned once, at the first import
    assert len(w3) == 1 and "flexkin.analysis.stability" in w3[0][1] and REMOVED_IN in w3[0][1]
    assert len(w4) == 1 and "flexkin.solve.ik" in w4[0][1]
    assert all(x[2] == "<string>" for x in w1 + w3 + w4)  # points at the script, not at importlib


def test_old_workspace_module_and_the_workspace_function_both_work():
    d = _run(PROLOGUE + """
import numpy as np, flexkin
w = caught("from flexkin.workspace import workspace as ws_fn, Workspace")
import flexkin.solve.workspace as new
m = flexkin.load_mechanism("examples/unit_3rfr.toml")
ws = flexkin.workspace(m, np.radians(20), step=0.1, bounds=(-0.6, 0.6, -0.6, 0.6), all_aspects=False)
print(json.dumps({"w": w, "fn": ws_fn is new.workspace, "cls": Workspace is new.Workspace,
                  "call": type(ws).__name__, "cells": ws.maps[0].area_cells}))
""")
    assert d["fn"] and d["cls"] and d["call"] == "Workspace" and d["cells"] > 10
    assert len(d["w"]) == 1 and "flexkin.solve.workspace" in d["w"][0][1]


@pytest.mark.parametrize("old", sorted(set(MOVED) - {"flexkin.workspace"}))  # that one: in a subprocess above
def test_every_moved_module_is_its_new_module(old):
    import importlib
    import warnings

    new = importlib.import_module(MOVED[old][0])
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", FutureWarning)
        assert importlib.import_module(old) is new


def test_the_changelog_lists_every_moved_path():
    text = (ROOT / "CHANGELOG.md").read_text()
    for old in list(MOVED) + list(PACKAGES):
        assert f"`{old}`" in text, old


def test_the_rod_solver_names_of_flexkin_rod_warn_and_are_the_new_ones():
    """``flexkin.rod.solve_rod`` and ``RodInverseResult`` moved to :mod:`flexkin.solve.rod_inverse`
    (issue 29: the rod package is the closed form only); the old names warn until REMOVED_IN."""
    import flexkin
    import flexkin.rod

    for name in ("solve_rod", "RodInverseResult"):
        with pytest.warns(FutureWarning, match=f"flexkin.rod.{name} moved to flexkin.solve.rod_inverse") as rec:
            old = getattr(flexkin.rod, name)
        assert old is getattr(flexkin, name)
        assert f"removed in flexkin {REMOVED_IN}" in str(rec[0].message)
    with pytest.raises(AttributeError):
        flexkin.rod.no_such_name
