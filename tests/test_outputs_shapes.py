"""Rod shapes out of the command line (``--shapes FILE.csv|FILE.npz`` on ik, fk and path) and the
path JSON with strain and feasibility per sample (issue 18, missing features)."""

from __future__ import annotations

import csv
import json
import math
from pathlib import Path

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import flexkin
from flexkin.cli import main

EX = Path(__file__).resolve().parents[1] / "examples"


def run(capsys, *args):
    code = main([str(a) for a in args])
    out, err = capsys.readouterr()
    return code, out, err


def _read_csv(path: Path) -> tuple[list[str], list[dict[str, str]]]:
    text = path.read_text(encoding="utf-8").splitlines()
    comments = [ln for ln in text if ln.startswith("#")]
    rows = list(csv.DictReader(ln for ln in text if not ln.startswith("#")))
    return comments, rows


def test_ik_shapes_csv_matches_the_json_ids_and_the_rod_equations(capsys, tmp_path):
    f = tmp_path / "shapes.csv"
    code, out, err = run(capsys, "ik", EX / "mixed_legs.toml", "--pose", "0", "0", "6", "--stable-only", "--json",
                         "--shapes", f)
    assert code == 0 and str(f) in err
    d = json.loads(out)
    ids = [s["id"] for s in d["solutions"]]
    comments, rows = _read_csv(f)
    assert any("theta_deg" in c and "DEGREES" in c for c in comments)
    assert list(rows[0]) == ["solution", "leg", "s_m", "x_m", "y_m", "theta_deg", "moment_Nm"]
    assert sorted({int(r["solution"]) for r in rows}) == sorted(ids)  # the same ids as the JSON (after filtering)
    mech = flexkin.load_mechanism(EX / "mixed_legs.toml")
    for sol in d["solutions"]:
        for leg in (1, 2, 3):
            r = [row for row in rows if int(row["solution"]) == sol["id"] and int(row["leg"]) == leg]
            s = np.array([float(x["s_m"]) for x in r])
            xy = np.array([[float(x["x_m"]), float(x["y_m"])] for x in r])
            th = np.radians([float(x["theta_deg"]) for x in r])
            m = np.array([float(x["moment_Nm"]) for x in r])
            assert s[0] == 0.0 and np.all(np.diff(s) > 0)
            # independent check: integrate the rod equations from the clamp with the JSON's forces
            rod = sol["rods"][leg - 1]
            EI = mech.legs[leg - 1].rod.EI
            fx, fy = rod["tip_force"]

            def rhs(_, z):
                return [math.cos(z[2]), math.sin(z[2]), z[3] / EI, fx * math.sin(z[2]) - fy * math.cos(z[2])]

            z = solve_ivp(rhs, (0, s[-1]), [xy[0, 0], xy[0, 1], th[0], rod["base_moment"]], t_eval=s,
                          rtol=1e-11, atol=1e-12, method="DOP853").y
            np.testing.assert_allclose(z[0], xy[:, 0], atol=1e-6)
            np.testing.assert_allclose(z[1], xy[:, 1], atol=1e-6)
            np.testing.assert_allclose(z[3], m, atol=1e-6 * max(1.0, np.abs(m).max()))
            # theta in degrees: the tangent of the sampled curve
            tang = np.arctan2(np.gradient(xy[:, 1], s), np.gradient(xy[:, 0], s))
            assert np.max(np.abs(np.angle(np.exp(1j * (tang[5:-5] - th[5:-5]))))) < 1e-2
            np.testing.assert_allclose(m[0], rod["base_moment"], rtol=1e-9, atol=1e-12)


def test_fk_shapes_npz(capsys, tmp_path):
    f = tmp_path / "fk.npz"
    code, out, err = run(capsys, "fk", EX / "prototype_3pfr.toml", "--inputs", "0.025", "0.025", "0.025",
                         "--stable-only", "--json", "--shapes", f)
    assert code == 0
    d = json.loads(out)
    z = np.load(f)
    assert list(z["solution"]) == [s["id"] for s in d["solutions"]]
    assert z["x_m"].shape == (len(d["solutions"]), 3, 101)
    np.testing.assert_allclose(z["pose"], [s["pose"] for s in d["solutions"]], atol=1e-12)
    assert str(z["input_units"][0]) == "m" and "DEGREES" in str(z["description"])
    # each rod ends at its platform point B_i
    mech = flexkin.load_mechanism(EX / "prototype_3pfr.toml")
    for a, s in enumerate(d["solutions"]):
        B = mech.platform.world((s["pose"][0], s["pose"][1], math.radians(s["pose"][2])))
        tips = np.stack([z["x_m"][a, :, -1], z["y_m"][a, :, -1]], -1)
        np.testing.assert_allclose(tips, B, atol=1e-9)


def test_path_shapes_and_json_with_strain_and_feasibility(capsys, tmp_path):
    f = tmp_path / "path.csv"
    code, out, err = run(capsys, "path", EX / "mixed_legs.toml", "--from", "0", "0", "6", "--to", "0.1", "0", "6",
                         "--steps", "10", "--json", "--shapes", f)
    assert code == 0
    d = json.loads(out)
    pts = d["points"]
    assert len(pts) == 11
    mech = flexkin.load_mechanism(EX / "mixed_legs.toml")  # max_strain 0.04, ranges on every leg
    for p in pts:
        assert set(p) >= {"feasible", "max_strain", "strains", "feasibility"}
        assert p["feasible"] == (not p["feasibility"]["reasons"])
        assert p["max_strain"] == pytest.approx(max(p["strains"]))
        # independent: the input-range part of the verdict from the inputs themselves
        u = [math.radians(v) if leg.actuation == "revolute" else v for v, leg in zip(p["inputs"], mech.legs)]
        out_of_range = [i + 1 for i, (leg, ui) in enumerate(zip(mech.legs, u)) if not leg.in_range(ui)]
        assert p["feasibility"]["inputs_out_of_range"] == out_of_range
    assert any(p["feasible"] for p in pts) and not all(p["feasible"] for p in pts)  # leg 2 leaves its range
    assert d["feasible_samples"] == sum(p["feasible"] for p in pts)
    comments, rows = _read_csv(f)
    assert list(rows[0]) == ["solution", "sample", "t", "leg", "s_m", "x_m", "y_m", "theta_deg", "moment_Nm"]
    assert sorted({int(r["sample"]) for r in rows}) == list(range(11))
    assert {int(r["solution"]) for r in rows} == {d["solution"]}
    # every exported rod ends at its platform point, also where the path runs in the seam chart
    for j, p in enumerate(pts):
        B = mech.platform.world((p["pose"][0], p["pose"][1], math.radians(p["pose"][2])))
        for leg in (1, 2, 3):
            last = [r for r in rows if int(r["sample"]) == j and int(r["leg"]) == leg][-1]
            assert math.hypot(float(last["x_m"]) - B[leg - 1][0], float(last["y_m"]) - B[leg - 1][1]) < 1e-8, (j, leg)
    # strain from the exported moments: radius * |M| / EI, as in the JSON
    for j in (0, 10):
        mmax = [max(abs(float(r["moment_Nm"])) for r in rows if int(r["sample"]) == j and int(r["leg"]) == leg)
                for leg in (1, 2, 3)]
        strain = [leg.rod.radius * mm / leg.rod.EI for leg, mm in zip(mech.legs, mmax)]
        np.testing.assert_allclose(strain, pts[j]["strains"], rtol=2e-2)


def test_shapes_file_type_checked_before_any_work(capsys, tmp_path):
    code, out, err = run(capsys, "ik", EX / "mixed_legs.toml", "--pose", "0", "0", "6", "--shapes", tmp_path / "s.txt")
    assert code == 2 and "--shapes" in err and ".csv" in err and out == ""
