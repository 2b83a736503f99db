"""docs/walkthrough.md is true: every command in its ``console`` blocks runs (from a scratch
directory holding a copy of the walkthrough's mechanism file) and prints the output shown there
(``…`` matches anything); the facts the prose states are checked from the JSON and the files."""

from __future__ import annotations

import csv
import json
import re
import shlex
import shutil
from pathlib import Path

import numpy as np
import pytest

from flexkin.cli import main

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "walkthrough.md"
MECH = ROOT / "docs" / "spring_steel_3rfr.toml"


def _blocks() -> list[tuple[list[str], list[str]]]:
    """(commands, expected lines) of every ``console`` block."""
    text = DOC.read_text(encoding="utf-8")
    out = []
    for body in re.findall(r"```console\n(.*?)```", text, flags=re.S):
        cmds, expect = [], []
        for ln in body.splitlines():
            if ln.startswith("$ "):
                cmds.append(ln[2:])
            elif ln.strip():
                expect.append(ln)
        out.append((cmds, expect))
    return out


BLOCKS = _blocks()


@pytest.fixture(scope="module")
def workdir(tmp_path_factory):
    d = tmp_path_factory.mktemp("walkthrough")
    shutil.copy(MECH, d / MECH.name)
    return d


def _pattern(line: str) -> re.Pattern:
    """The expected line as a regex: ``…`` matches anything, a run of spaces any whitespace."""
    rx = ".*".join(re.escape(p) for p in line.strip().split("…"))
    return re.compile(re.sub(r"(?:\\ )+", r"\\s+", rx) + r"\s*$")


def _run(capsys, monkeypatch, workdir, cmd: str) -> tuple[str, str]:
    monkeypatch.chdir(workdir)
    argv = shlex.split(cmd)
    assert argv[0] == "flexkin"
    code = main(argv[1:] + (["--quiet"] if argv[1] in ("ik", "fk", "path", "workspace", "refine") else []))
    out, err = capsys.readouterr()
    assert code == 0, (cmd, err)
    return out, err


def test_walkthrough_has_every_step():
    cmds = [c for block, _ in BLOCKS for c in block]
    verbs = [shlex.split(c)[1] for c in cmds]
    for verb in ("show", "ik", "fk", "path", "workspace", "refine"):
        assert verb in verbs, verb
    assert any("--feasible-only" in c and " ik " in f" {c} " for c in cmds)
    assert any("workspace" in c and "--constrained" in c for c in cmds)
    assert any("--shapes" in c for c in cmds)
    assert not (ROOT / "examples" / MECH.name).exists()  # not a bundled example


@pytest.mark.parametrize("k", range(len(BLOCKS)), ids=[shlex.split(b[0][0])[1] + f"-{k}" for k, b in enumerate(BLOCKS)])
def test_walkthrough_block_runs_and_prints_what_the_doc_shows(capsys, monkeypatch, workdir, k):
    cmds, expect = BLOCKS[k]
    lines: list[str] = []
    for cmd in cmds:
        out, err = _run(capsys, monkeypatch, workdir, cmd)
        lines += [ln.strip() for ln in (out + "\n" + err).splitlines()]
    for want in expect:
        pat = _pattern(want)
        assert any(pat.match(ln) for ln in lines), f"{want!r} not printed by {cmds}:\n" + "\n".join(lines[:40])


def test_walkthrough_facts(capsys, monkeypatch, workdir):
    """The numbers the prose quotes, from the JSON and the files."""
    ik = json.loads(_run(capsys, monkeypatch, workdir,
                         "flexkin ik spring_steel_3rfr.toml --pose 0.02 0.01 20 --json --feasibility")[0])
    sols = {s["id"]: s for s in ik["solutions"]}
    assert len(sols) == 8 and all(s["stable"] for s in sols.values())
    assert [i for i, s in sols.items() if s["feasible"]] == [1]
    f2 = sols[2]["feasibility"]
    assert f2["strains"][0] == pytest.approx(0.0072, abs=5e-5) and f2["strains"][2] == pytest.approx(0.0089, abs=5e-5)
    assert f2["inputs_out_of_range"] == [1, 3]
    assert sols[1]["feasibility"]["max_strain"] == pytest.approx(0.0059, abs=5e-5)
    path = json.loads(_run(capsys, monkeypatch, workdir, "flexkin path spring_steel_3rfr.toml --from 0.02 0.01 20 "
                                                           "--to 0.12 0.01 20 --steps 20 --solution 1 --json")[0])
    pts = path["points"]
    feasible_t = [p["t"] for p in pts if p["feasible"]]
    assert feasible_t == pytest.approx([0.0, 0.05, 0.1, 0.15, 0.2, 0.25])   # usable stroke: 25 mm
    lost = next(e for e in path["events"] if e["kind"] == "stability_lost")
    assert 0.35 <= lost["t_lo"] and lost["t_hi"] <= 0.40
    assert "L_ref = 0.5 m" in path["jacobian_units"]
    # the shape file of step 6: solution 1's rods, clamp at the pivots, theta in degrees
    _run(capsys, monkeypatch, workdir, "flexkin ik spring_steel_3rfr.toml --pose 0.02 0.01 20 --feasible-only "
                                       "--shapes shapes.csv")
    with open(workdir / "shapes.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(ln for ln in fh if not ln.startswith("#")))
    assert {r["solution"] for r in rows} == {"1"} and len(rows) == 3 * 101
    first = rows[0]
    assert float(first["theta_deg"]) == pytest.approx(sols[1]["inputs"][0], abs=1e-6)  # clamp angle = pivot angle
    assert (float(first["x_m"]), float(first["y_m"])) == pytest.approx((-0.4330127019, -0.25))
    if not (workdir / "workspace.npz").exists():  # when this test runs alone
        _run(capsys, monkeypatch, workdir, "flexkin workspace spring_steel_3rfr.toml --theta 20 --seed 0.02 0.01 "
                                           "--step 0.01 --bounds -0.2 0.2 -0.2 0.2 --first-aspect --save workspace.npz")
    ws = np.load(workdir / "workspace.npz")
    reached = ws["map0_status"] == 1
    assert int(reached.sum()) == 278
    # "only 50 of the 278 cells have all three pivots within their ranges", from the saved inputs
    # (independent of the workspace's own feasibility flags: the ranges compared modulo 360 deg)
    import flexkin

    mech = flexkin.load_mechanism(workdir / MECH.name)
    in_range = reached.copy()
    for i, leg in enumerate(mech.legs):
        lo, hi = leg.range
        in_range &= np.remainder(ws["map0_inputs"][..., i] - lo, 2 * np.pi) <= hi - lo  # angles mod 360 deg
    assert int(in_range.sum()) == 50
