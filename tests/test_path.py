"""Following an IK solution along a path: singularities and stability located against a 10x denser path,
d-mode changes followed, samples that are true equilibria (full IK contains them)."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest

import flexkin
from flexkin import follow_path

TH = np.radians(20.0)
START, END = np.array([0.0, 0.0, TH]), np.array([0.8, 0.0, TH])


@pytest.fixture(scope="module")
def unit_pfr(examples_dir):
    return flexkin.load_mechanism(examples_dir / "unit_3pfr.toml")


@pytest.fixture(scope="module")
def coarse(unit_pfr):
    return follow_path(unit_pfr, START, END, steps=20)


def test_branch_end_located_within_one_step_of_a_10x_denser_path(unit_pfr, coarse):
    fine = follow_path(unit_pfr, START, END, steps=200, solution=coarse.start_solution)
    assert not coarse.complete and not fine.complete
    end_c = [e for e in coarse.events if e.kind == "continuation_failed"][0]
    end_f = [e for e in fine.events if e.kind == "continuation_failed"][0]
    # the fine path places the end of the branch in (t_lo, t_hi] of width 1/200
    t_fine = end_f.t_hi
    assert end_c.t_lo - 1 / 20 <= t_fine <= end_c.t_hi + 1 / 20
    # the fine path also sees the instability right before the fold, the coarse one may not
    assert any(e.kind == "stability_lost" for e in fine.events) or fine.stable[-1]


def test_mode_change_is_followed_not_a_failure(coarse):
    changes = [e for e in coarse.events if e.kind == "mode_change"]
    assert changes, "this path changes the d-mode of rod 1 (111 -> 211)"
    assert all(e.t_hi < [f for f in coarse.events if f.kind == "continuation_failed"][0].t_lo for e in changes)
    assert {tuple(q) for q in coarse.modes} >= {(1, 1, 1), (2, 1, 1)}


def test_path_samples_are_ik_solutions(unit_pfr, coarse):
    """Every third sample: the full IK at that pose contains the followed inputs."""
    for j in range(0, len(coarse.t), 3):
        res = flexkin.ik(unit_pfr, coarse.poses[j])
        d = min(np.max(np.abs(np.array(s.inputs) - coarse.inputs[j])) for s in res.solutions)
        assert d < 1e-8


def test_fk_singularity_and_stability_loss_coincide_and_are_located(unit_pfr, coarse):
    """Just before the fold, det J_FK changes sign where stability is lost (paper §6: FK
    singularities are found by the instability that occurs simultaneously)."""
    # the branch folds at t ~ 0.8301 (previous test); det J_FK vanishes just before, at t ~ 0.8292
    a = START + 0.8250 * (END - START)
    b = START + 0.8298 * (END - START)
    sol = flexkin.ik(unit_pfr, a)
    near = follow_path(unit_pfr, START, a, steps=40, solution=coarse.start_solution)
    s0 = min(sol.solutions, key=lambda s: np.max(np.abs(np.array(s.inputs) - near.inputs[-1])))
    c = follow_path(unit_pfr, a, b, steps=10, solution=s0)
    f = follow_path(unit_pfr, a, b, steps=100, solution=s0)
    for r in (c, f):
        fk = [e for e in r.events if e.kind == "fk_singularity"]
        lost = [e for e in r.events if e.kind == "stability_lost"]
        assert len(fk) == 1 and len(lost) == 1
        assert (fk[0].t_lo, fk[0].t_hi) == (lost[0].t_lo, lost[0].t_hi)
    fine_t = [e for e in f.events if e.kind == "fk_singularity"][0].t_hi
    ce = [e for e in c.events if e.kind == "fk_singularity"][0]
    assert ce.t_lo - 0.1 <= fine_t <= ce.t_hi + 0.1


def test_path_bad_arguments(unit_pfr):
    with pytest.raises(ValueError, match="steps"):
        follow_path(unit_pfr, START, END, steps=0)
    with pytest.raises(ValueError, match="solution 10000 does not exist"):
        follow_path(unit_pfr, START, END, steps=5, solution=10_000)
    with pytest.raises(ValueError, match="start pose"):
        follow_path(unit_pfr, (0, np.nan, 0), END, steps=5)


def test_cli_path_json(examples_dir, tmp_path):
    out = subprocess.run([sys.executable, "-m", "flexkin.cli", "path", str(examples_dir / "unit_3pfr.toml"),
                          "--from", "0", "0", "20", "--to", "0.2", "0", "20", "--steps", "4", "--json",
                          "--plot", str(tmp_path / "p.png")], capture_output=True, text=True, timeout=300)
    assert out.returncode == 0, out.stderr
    d = json.loads(out.stdout)
    assert d["complete"] is True and len(d["points"]) == 5
    assert all(p["stable"] for p in d["points"])
    assert (tmp_path / "p.png").stat().st_size > 10_000
    bad = subprocess.run([sys.executable, "-m", "flexkin.cli", "path", str(examples_dir / "unit_3pfr.toml"),
                          "--from", "0", "0", "--to", "0.2", "0", "20"], capture_output=True, text=True, timeout=60)
    assert bad.returncode == 2 and "Traceback" not in bad.stderr


# ---- issue 18, defect 3: a stop reason follows from computed quantities ----------------------
def _rfr():
    from pathlib import Path

    return flexkin.load_mechanism(Path(__file__).resolve().parents[1] / "examples" / "unit_3rfr.toml")


def test_a_fold_is_called_an_ik_singularity_and_the_branch_really_ends_there():
    mech = _rfr()
    a, b = np.array([0.0, 0.0, TH]), np.array([0.3, 0.1, TH])
    r = follow_path(mech, a, b, steps=30)
    assert not r.complete and r.message.startswith("continuation stopped: IK singularity")
    t_end = float(r.t[-1])
    assert t_end < 1.0
    # independent: the full IK just beyond the stop has no solution continuing the branch
    u_last = r.inputs[-1]
    beyond = flexkin.ik(mech, (1 - (t_end + 0.03)) * a + (t_end + 0.03) * b)
    near = [s for s in beyond.solutions
            if np.max(np.abs(np.remainder(np.asarray(s.inputs) - u_last + np.pi, 2 * np.pi) - np.pi)) < 0.05]
    assert near == []


def test_a_corrector_failure_away_from_singularities_is_not_called_one(monkeypatch):
    import flexkin.solve.path as path_mod

    real = path_mod.continue_ik

    def failing_beyond_x(system, x, ch, pose, w):  # a corrector that gives up half-way: no fold there
        x1, c1, ok = real(system, x, ch, pose, w)
        return x1, c1, ok & (pose[:, 0] <= 0.15)

    monkeypatch.setattr(path_mod, "continue_ik", failing_beyond_x)
    r = follow_path(_rfr(), (0.0, 0.0, TH), (0.3, 0.1, TH), steps=30)
    assert not r.complete and r.t[-1] == pytest.approx(0.5)
    assert "corrector failed to converge at step size h =" in r.message
    assert "IK singularity" not in r.message and "no singularity detected" in r.message
    assert r.events[-1].kind == "continuation_failed"
