"""Command-line interface: SPEC §4 contract, exit codes, figures, clear errors."""

from __future__ import annotations

import json
import math
from pathlib import Path

import numpy as np
import pytest

from flexkin.cli import main

ROOT = Path(__file__).resolve().parents[1]
PROTO = str(ROOT / "examples" / "prototype_3pfr.toml")
RFR = str(ROOT / "examples" / "unit_3rfr.toml")


def run(capsys, *args):
    code = main(list(args))
    out, err = capsys.readouterr()
    return code, out, err


def test_show_prints_and_draws(capsys, tmp_path):
    png = tmp_path / "m.png"
    code, out, err = run(capsys, "show", PROTO, "--plot", str(png))
    assert code == 0
    assert "3-PFR prototype" in out and "prismatic" in out
    assert png.stat().st_size > 10_000


def test_rod_json_contract_and_forces_reproduce_tip(capsys):
    # independent check of the reported force and moment: integrate Eqs. (5)/(7)
    from scipy.integrate import solve_ivp

    code, out, _ = run(capsys, "rod", "--length", "1", "--EI", "2", "--tip", "0.6", "0.3", "--json")
    assert code == 0
    d = json.loads(out)
    assert d["solutions"], "expected equilibria"
    for s in d["solutions"]:
        assert set(s) >= {"mode", "k", "psi_deg", "tip_force", "base_moment", "energy"}
        fx, fy = s["tip_force"]

        def rhs(_, z):
            return [math.cos(z[2]), math.sin(z[2]), z[3] / 2.0, fx * math.sin(z[2]) - fy * math.cos(z[2])]

        z = solve_ivp(rhs, (0, 1), [0, 0, 0, s["base_moment"]], method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]
        if abs(s["k"]) < 1 - 1e-6:  # forward integration is ill-conditioned for tight loops
            assert math.hypot(z[0] - 0.6, z[1] - 0.3) < 1e-7


def test_rod_sweep_fig19(capsys, tmp_path):
    png = tmp_path / "fig19.png"
    code, out, err = run(capsys, "rod", "--sweep", "--points", "8", "--json", "--plot", str(png))
    assert code == 0
    d = json.loads(out)
    assert d["tip_y"] == -0.2125
    assert d["x"][0] == pytest.approx(0.86) and d["x"][-1] == pytest.approx(0.51)
    # the least-energy branch (S-shaped, d-mode 2) spans the whole sweep
    full = [b for b in d["branches"] if len(b["x"]) == 8]
    assert any(set(b["mode"]) == {2.0} for b in full)
    assert png.stat().st_size > 10_000


def test_ik_table2_json(capsys, tmp_path):
    png, curves = tmp_path / "ik.png", tmp_path / "fig7.png"
    code, out, err = run(capsys, "ik", PROTO, "--pose", "0", "0", "120", "--json", "--plot", str(png),
                         "--curves", str(curves))
    assert code == 0
    d = json.loads(out)
    assert d["problem"] == "ik" and d["max_mode"] == 2 and d["load"] == [0, 0, 0]
    assert d["pose"] == [0, 0, pytest.approx(120)]
    s111 = [s for s in d["solutions"] if s["modes"] == [1, 1, 1]]
    # Table 2, theta = 120 deg: rho = 0.058 m for all three legs (theory column)
    assert any(np.allclose(s["inputs"], 0.058, atol=1e-3) for s in s111)
    for s in d["solutions"]:
        assert s["pose"][2] == pytest.approx(120)
        assert len(s["rods"]) == 3 and s["residual"] <= 1e-10
    assert png.stat().st_size > 10_000 and curves.stat().st_size > 10_000


def test_ik_revolute_inputs_in_degrees(capsys):
    code, out, _ = run(capsys, "ik", RFR, "--pose", "0.05", "0.02", "20", "--json")
    d = json.loads(out)
    import flexkin

    res = flexkin.ik(flexkin.load_mechanism(RFR), (0.05, 0.02, math.radians(20)))
    assert len(d["solutions"]) == len(res) == 8
    for s, r in zip(d["solutions"], res.solutions):
        assert s["inputs"] == pytest.approx([math.degrees(u) for u in r.inputs])


def test_unreachable_pose_is_an_answer(capsys):
    code, out, err = run(capsys, "ik", PROTO, "--pose", "5", "5", "0", "--json")
    assert code == 0
    assert json.loads(out)["solutions"] == []
    assert err.strip() and "Traceback" not in err


def test_fk_cannot_assemble_is_an_answer(capsys):
    code, out, err = run(capsys, "fk", PROTO, "--inputs", "-3", "3", "0", "--json")
    assert code == 0
    d = json.loads(out)
    assert d["solutions"] == [] and d["problem"] == "fk"
    assert "assemble" in err


@pytest.mark.parametrize("args, fragment", [
    (("ik", PROTO, "--pose", "0", "0"), "--pose"),
    (("ik", PROTO, "--pose", "0", "0", "abc"), "--pose"),
    (("ik", PROTO, "--pose", "0", "0", "nan"), "finite"),
    (("ik", PROTO, "--pose", "0", "0", "90", "--max-mode", "0"), "--max-mode"),
    (("ik", PROTO, "--pose", "0", "0", "90", "--max-mode", "99"), "--max-mode"),
    (("ik", PROTO, "--pose", "0", "0", "90", "--bogus"), "--bogus"),
    (("ik", "/nonexistent/file.toml", "--pose", "0", "0", "90"), "file.toml"),
    (("rod", "--length", "1", "--tip", "0.5", "0.1"), "stiffness"),
    (("rod", "--length", "-1", "--EI", "1", "--tip", "0.5", "0.1"), "--length"),
    (("rod", "--length", "1", "--EI", "1", "--E", "2", "--radius", "1", "--tip", "0.5", "0.1"), "either"),
    (("fk", PROTO, "--inputs", "0", "0"), "--inputs"),
    (("frobnicate",), "invalid choice"),
])
def test_bad_arguments_exit_2_with_one_clear_message(capsys, args, fragment):
    code, out, err = run(capsys, *args)
    assert code == 2
    assert fragment in err
    assert "Traceback" not in err and out == ""


# ---- issue 14: one rod clamped at both ends ------------------------------------------------
def test_rod_clamped_tip_lists_tip_moments_that_the_rod_equations_confirm(capsys, tmp_path):
    from scipy.integrate import solve_ivp

    png = tmp_path / "rod.png"
    code, out, err = run(capsys, "rod", "--length", "1", "--EI", "2", "--tip", "0.6", "0.3", "--tip-angle", "30",
                         "--json", "--plot", str(png))
    assert code == 0 and png.stat().st_size > 10_000 and str(png) in err
    d = json.loads(out)
    assert d["joint"] == "clamped" and d["tip_angle_deg"] == pytest.approx(30)
    assert d["solutions"]
    for s in d["solutions"]:
        assert "tip_moment" in s
        fx, fy = s["tip_force"]

        def rhs(_, z):
            return [math.cos(z[2]), math.sin(z[2]), z[3] / 2.0, fx * math.sin(z[2]) - fy * math.cos(z[2])]

        z = solve_ivp(rhs, (0, 1), [0, 0, 0, s["base_moment"]], method="DOP853", rtol=1e-12, atol=1e-12).y[:, -1]
        assert math.hypot(z[0] - 0.6, z[1] - 0.3) < 1e-6
        assert abs(math.remainder(z[2] - math.radians(30), 2 * math.pi)) < 1e-6   # clamped tangent
        assert z[3] == pytest.approx(s["tip_moment"], abs=1e-5)                # EI theta'(L)
    code, out, err = run(capsys, "rod", "--length", "1", "--EI", "2", "--tip", "0.6", "0.3", "--tip-angle", "30")
    assert code == 0 and "mL [N m]" in out and "clamped at 30 deg" in out


def test_rod_tip_angle_with_sweep_is_refused(capsys):
    code, out, err = run(capsys, "rod", "--sweep", "--tip-angle", "10", "--points", "3")
    assert code == 2 and "--tip-angle" in err


# ---- issue 18, defect 5: warnings are one line on stderr -------------------------------------
def test_implausible_file_warns_in_one_line_per_problem(capsys, tmp_path):
    text = Path(PROTO).read_text(encoding="utf-8").replace("radius = 1.5e-3", "radius = 1.0").replace("E = 68e9",
                                                                                                    "E = 68")
    f = tmp_path / "mm_for_m.toml"
    f.write_text(text, encoding="utf-8")
    code, out, err = run(capsys, "show", str(f))
    assert code == 0
    lines = [ln for ln in err.splitlines() if ln.strip()]
    assert len(lines) == 2, err
    assert all(ln.startswith("flexkin: warning: ") and str(f) in ln for ln in lines)
    assert "rod.radius" in lines[0] and "rod.E" in lines[1] and "E = 68 Pa" in lines[1]


def test_revolute_inputs_in_radians_warn(capsys):
    code, out, err = run(capsys, "fk", RFR, "--inputs", "1.5788", "-2.434", "-0.21", "--json", "--quiet")
    assert code == 0
    warn = [ln for ln in err.splitlines() if "warning" in ln]
    assert len(warn) == 1 and "--inputs" in warn[0] and "radians" in warn[0] and "90.46" in warn[0]
    json.loads(out)  # the answer is still given
    code, out, err = run(capsys, "fk", RFR, "--inputs", "90.46", "-139.47", "-12.03", "--json", "--quiet")
    assert "warning" not in err


# ---- issue 18, defect 1: revolute input ranges compare angles modulo 360 deg ----------------
def test_revolute_range_wraps_angles(capsys):
    from flexkin.mechanism import load_mechanism

    mech = load_mechanism(RFR)  # leg 2: range [60, 240] deg
    assert bool(mech.legs[1].in_range(math.radians(-139.467)))      # = 220.533 deg, inside
    assert not bool(mech.legs[1].in_range(math.radians(-60.0)))     # = 300 deg, outside
    code, out, err = run(capsys, "ik", RFR, "--pose", "0.05", "0.02", "20", "--feasible-only", "--json")
    assert code == 0
    sols = json.loads(out)["solutions"]
    assert sols, err  # before the fix: "none of the 8 equilibria is feasible"
    for s in sols:
        assert s["feasible"] and not s["feasibility"]["inputs_out_of_range"]
        u2 = s["inputs"][1] % 360.0
        assert 60.0 <= u2 <= 240.0


# ---- issue 18, defect 2 (CLI): the constrained workspace ----------------------------------------
def test_workspace_constrained_maps_only_cells_within_the_ranges(capsys, tmp_path):
    from flexkin.mechanism import load_mechanism

    mech_file = ROOT / "docs" / "spring_steel_3rfr.toml"
    args = ["workspace", str(mech_file), "--theta", "20", "--seed", "0.02", "0.01", "--step", "0.02",
            "--bounds", "-0.2", "0.2", "-0.2", "0.2", "--first-aspect", "--json", "--quiet"]
    code, out, _ = run(capsys, *args, "--save", str(tmp_path / "all.npz"))
    (free,) = json.loads(out)["workspaces"]
    code2, out2, err2 = run(capsys, *args, "--constrained", "--save", str(tmp_path / "c.npz"))
    (cons,) = json.loads(out2)["workspaces"]
    assert code == code2 == 0 and str(tmp_path / "c.npz") in err2
    assert not free["constrained"] and cons["constrained"] and "ranges" in cons["constraints"]
    a_free, a_cons = free["aspects"][0], cons["aspects"][0]
    assert 0 < a_cons["cells"] <= a_free["feasible_cells"] < a_free["cells"]
    assert a_cons["feasible_cells"] == a_cons["cells"] and a_cons["boundary_infeasible_cells"] > 0
    # independent: every mapped cell has its three pivots in range (angles modulo 360 deg)
    mech = load_mechanism(mech_file)
    ws = np.load(tmp_path / "c.npz")
    reached = ws["map0_status"] == 1
    assert int(reached.sum()) == a_cons["cells"]
    for i, leg in enumerate(mech.legs):
        lo, hi = leg.range
        assert np.all(np.remainder(ws["map0_inputs"][..., i][reached] - lo, 2 * np.pi) <= hi - lo + 1e-12)
