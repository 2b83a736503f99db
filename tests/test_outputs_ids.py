"""One id convention everywhere, and what ``show`` and the IK table tell (issue 27, item 9): the
workspace's seed solutions and refined solutions carry the 1-based ids of ``flexkin ik``;
``show`` names each leg's platform joint and a clamped joint's tip angle; ``ik --feasibility``
without ``--json`` adds a feasibility column to the table."""

from __future__ import annotations

import json

import numpy as np
import pytest

import flexkin
from flexkin.cli import main
from flexkin.solve.workspace import load_workspace


def _run(capsys, *args):
    capsys.readouterr()
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    assert code == 0, err
    return out, err


def test_workspace_seed_ids_are_the_ik_ids(capsys, tmp_path, examples_dir):
    """Every aspect's seeds, in the summary, the JSON and the saved file, are ids of the IK
    solutions at the seed pose whose inputs the map holds at the seed cell."""
    mech_file = examples_dir / "unit_3rfr.toml"
    npz = tmp_path / "ws.npz"
    args = ["workspace", mech_file, "--theta", "20", "--seed", "0.05", "0.02", "--step", "0.1", "--bounds", "-0.6",
            "0.6", "-0.6", "0.6", "--save", npz, "-q"]
    out, _ = _run(capsys, *args)
    ws = load_workspace(str(npz))
    with np.load(npz) as d:
        assert "map0_seed_ids" in d and "map0_seeds" not in d
        assert tuple(d["map0_seed_ids"]) == ws.maps[0].seeds
    mech = flexkin.load_mechanism(mech_file)
    res = flexkin.ik(mech, (ws.seed[0], ws.seed[1], np.radians(20)))
    by_id = {s.id: s for s in res.solutions}
    j = int(np.argmin(np.abs(ws.y - ws.seed[1])))
    i = int(np.argmin(np.abs(ws.x - ws.seed[0])))
    for mp in ws.maps:
        inputs = mp.inputs[j, i]
        assert any(np.allclose(np.array(by_id[k].inputs), inputs, atol=1e-8) for k in mp.seeds), mp.seeds
        assert f"seed solutions {', '.join(map(str, mp.seeds))}" in out
        assert all(by_id[k].stable for k in mp.seeds)
    js, _ = _run(capsys, *(args[:-3] + ["--json", "-q"]))
    assert [a["seeds"] for a in json.loads(js)["workspaces"][0]["aspects"]] == [list(mp.seeds) for mp in ws.maps]


def test_a_workspace_file_of_flexkin_0_2_reads_with_ids(tmp_path, examples_dir):
    """Files written before stored 0-based indices as ``map{k}_seeds``: they read back as ids."""
    ws = flexkin.workspace(flexkin.load_mechanism(examples_dir / "unit_3rfr.toml"), np.radians(20), step=0.1,
                           bounds=(-0.6, 0.6, -0.6, 0.6), seed=(0.05, 0.02), all_aspects=False)
    ws.save(str(tmp_path / "new.npz"))
    with np.load(tmp_path / "new.npz") as d:
        old = {k: d[k] for k in d.files if not k.endswith("_seed_ids")}
        old.update({f"map{k}_seeds": d[f"map{k}_seed_ids"] - 1 for k in range(int(d["n_maps"]))})
    np.savez(tmp_path / "old.npz", **old)
    assert load_workspace(str(tmp_path / "old.npz")).maps[0].seeds == ws.maps[0].seeds


def test_refine_json_carries_the_kirchhoff_ids(capsys, examples_dir):
    """``refine --json`` has the IK ids (``id``; no 0-based ``index``), also after a filter."""
    spring = examples_dir.parent / "docs" / "spring_steel_3rfr.toml"
    out, _ = _run(capsys, "refine", spring, "--pose", "0.02", "0.01", "20", "--json", "-q")
    d = json.loads(out)
    assert [s["id"] for s in d["solutions"]] == list(range(1, len(d["solutions"]) + 1))
    assert all("index" not in s for s in d["solutions"] + d["born"])
    assert all(s["merged_with"] is None or s["merged_with"] >= 1 for s in d["solutions"])
    res = flexkin.ik(flexkin.load_mechanism(spring), (0.02, 0.01, np.radians(20)))
    for s, k in zip(d["solutions"], res.solutions):
        assert s["kirchhoff_inputs"] == pytest.approx(k.inputs_display(), abs=1e-9)
        assert s["kirchhoff_modes"] == list(k.modes)


def test_refined_solution_index_is_deprecated(examples_dir):
    from flexkin.cosserat import params_for_mechanism, refine

    spring = flexkin.load_mechanism(examples_dir.parent / "docs" / "spring_steel_3rfr.toml")
    res = flexkin.ik(spring, (0.02, 0.01, np.radians(20))).select(stable_only=True)
    keep = [s for s in res.solutions if s.id in (2, 5)]
    r = refine(spring, keep, params=params_for_mechanism(spring), problem="ik", stability=False,
               born_search=False)
    assert [s.id for s in r.solutions] == [2, 5]
    with pytest.warns(FutureWarning, match=r"use \.id"):
        assert r.solutions[1].index == 1


def test_show_names_the_joint_and_the_tip_angle(capsys, examples_dir):
    out, _ = _run(capsys, "show", examples_dir / "mixed_clamped.toml")
    head = next(line for line in out.splitlines() if "actuation" in line)
    assert "joint" in head and "tip angle [deg]" in head
    rows = {line.split()[0]: line.split() for line in out.splitlines()
            if line.strip()[:1].isdigit() and len(line.split()) > 8}
    mech = flexkin.load_mechanism(examples_dir / "mixed_clamped.toml")
    for i, leg in enumerate(mech.legs):
        row = rows[str(i + 1)]
        assert row[-2] == leg.joint
        if leg.joint == "clamped":
            assert float(row[-1]) == pytest.approx(np.degrees(leg.tip_angle), abs=1e-4)
        else:
            assert row[-1] == "-"


def test_ik_feasibility_without_json_is_a_column_of_the_table(capsys):
    from pathlib import Path

    spring = Path(__file__).resolve().parents[1] / "docs" / "spring_steel_3rfr.toml"
    out, _ = _run(capsys, "ik", spring, "--pose", "0.02", "0.01", "20", "--feasibility")
    lines = out.splitlines()
    head = next(line for line in lines if line.lstrip().startswith("#"))
    assert "feasible" in head and "reasons" in head
    mech = flexkin.load_mechanism(spring)
    res = flexkin.ik(mech, (0.02, 0.01, np.radians(20)))
    feas = {s.id: f for s, f in zip(res.solutions, res.feasibility())}
    rows = [line for line in lines if line[:3].strip().isdigit()]
    assert len(rows) == len(feas) == 8
    for row in rows:
        f = feas[int(row[:3])]
        assert row.split()[11] == ("yes" if f.feasible else "no")
        for reason in f.reasons:
            assert reason in row
    plain, _ = _run(capsys, "ik", spring, "--pose", "0.02", "0.01", "20")
    assert "feasible" not in plain
