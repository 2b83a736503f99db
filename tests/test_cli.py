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
