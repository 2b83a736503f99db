"""docs/walkthrough.md is true: every command in its ``console`` blocks runs (from a scratch
directory holding a copy of the walkthrough's mechanism file) and prints the output shown there
(``…`` matches anything); the facts the prose states are checked from the JSON and the files."""

from __future__ import annotations

import csv
import json
import re
import shlex
import shutil
import tomllib
from pathlib import Path

import numpy as np
import pytest

from flexkin.cli import main

ROOT = Path(__file__).resolve().parents[1]
DOC = ROOT / "docs" / "walkthrough.md"
MECH = ROOT / "docs" / "spring_steel_3rfr.toml"
STUDY = ROOT / "docs" / "spring_steel_study.toml"


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
    shutil.copy(STUDY, d / STUDY.name)
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
    for verb in ("show", "ik", "fk", "path", "workspace", "refine", "study"):
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


def test_walkthrough_singularity_measures(capsys, monkeypatch, workdir):
    """Section 4: sing_fk changes sign where the stability margin does, and only there; sing_ik
    falls towards 0 at the fold; the numbers quoted; the same values for a copy scaled to 5 m
    rods with E / 2 (IK at the scaled start pose)."""
    path = json.loads(_run(capsys, monkeypatch, workdir, "flexkin path spring_steel_3rfr.toml --from 0.02 0.01 20 "
                                                           "--to 0.12 0.01 20 --steps 20 --solution 1 --json")[0])
    pts = path["points"]
    s_ik = np.array([p["jacobian"]["sing_ik"] for p in pts])
    s_fk = np.array([p["jacobian"]["sing_fk"] for p in pts])
    margin = np.array([p["stability_margin"] for p in pts])
    t = np.array([p["t"] for p in pts])
    flips = np.flatnonzero(np.sign(s_fk[1:]) != np.sign(s_fk[:-1]))
    assert list(flips) == list(np.flatnonzero(np.sign(margin[1:]) != np.sign(margin[:-1]))) == [7]
    assert (t[7], t[8]) == pytest.approx((0.35, 0.40))
    assert (s_ik[0], s_fk[0], s_ik[-1]) == pytest.approx((-0.049, -0.033, -0.0076), abs=5e-4)
    assert np.all(np.diff(np.abs(s_ik)) < 0) and np.all(np.sign(s_ik) == -1)
    end = next(e for e in path["events"] if e["kind"] == "continuation_failed")
    assert "sing_ik = 0.00067 at t = 0.7641" in end["detail"]
    import flexkin

    data = tomllib.loads((workdir / MECH.name).read_text())
    data["rod"] = dict(data["rod"], length=10 * data["rod"]["length"], radius=10 * data["rod"]["radius"],
                       E=0.5 * data["rod"]["E"])
    data["platform"] = {"attach": [[10 * x, 10 * y] for x, y in data["platform"]["attach"]]}
    data["leg"] = [dict(leg, origin=[10 * c for c in leg["origin"]]) for leg in data["leg"]]
    big = flexkin.ik(flexkin.mechanism_from_dict(data, source="x10"), (0.2, 0.1, np.radians(20)))
    s1 = big.solutions[0].jacobian
    assert (s1.sing_ik, s1.sing_fk) == pytest.approx((s_ik[0], s_fk[0]), rel=1e-6)


def test_walkthrough_study_facts(capsys, monkeypatch, workdir):
    """Section 8: equal stable areas, strain-limited areas that follow from the saved map of
    section 5 by the strain's proportionality to the radius, and the feasible region and disc."""
    if not (workdir / "study" / "results.csv").exists():  # when this test runs alone
        _run(capsys, monkeypatch, workdir, "flexkin study spring_steel_study.toml --out study --scheduler synchronous "
                                           "--no-figures")
    with open(workdir / "study" / "results.csv", newline="", encoding="utf-8") as fh:
        rows = list(csv.DictReader(fh))
    radius = [float(r["rod.radius"]) for r in rows]
    assert radius == pytest.approx([0.7e-3, 0.8e-3, 0.9e-3, 1.0e-3])
    if not (workdir / "workspace.npz").exists():
        _run(capsys, monkeypatch, workdir, "flexkin workspace spring_steel_3rfr.toml --theta 20 --seed 0.02 0.01 "
                                           "--step 0.01 --bounds -0.2 0.2 -0.2 0.2 --first-aspect --save workspace.npz")
    ws = np.load(workdir / "workspace.npz")
    reached = ws["map0_status"] == 1
    strain_1mm = ws["map0_strain"][reached]          # the walkthrough's 1 mm wire
    for r, rad in zip(rows, radius):
        assert float(r["workspace_area"]) == pytest.approx(278e-4)
        cells = int(np.count_nonzero(strain_1mm * (rad / 1e-3) <= 0.007))
        assert float(r["strain_limited_area"]) == pytest.approx(cells * 1e-4)
        assert float(r["feasible_area"]) == pytest.approx(50e-4)
        assert float(r["feasible_disc_radius"]) == pytest.approx(0.03)
        assert (float(r["feasible_disc_x"]), float(r["feasible_disc_y"])) == pytest.approx((0.0, 0.0), abs=1e-12)
        assert r["constraints"] == "ranges;strain"
    limited = [round(float(r["strain_limited_area"]) / 1e-4) for r in rows]
    assert limited == [278, 238, 168, 105]
