"""Workspaces by wave propagation (paper §6, Fig. 17): every cell a verified stable equilibrium,
C3 symmetry, IK boundaries confirmed by a 10x finer continuation, save/load, CLI."""

from __future__ import annotations

import json
import os
import sys
from types import SimpleNamespace

import numpy as np
import pytest

import flexkin
from flexkin import follow_path
from flexkin.analysis.stability import mechanism_stability
from flexkin.solve.workspace import REACHED, load_workspace, workspace

sys.path.insert(0, os.path.dirname(__file__))
from ik_oracle import verify_many  # noqa: E402

try:
    from oracles import REPORT  # type: ignore
except ImportError:  # pragma: no cover
    REPORT = {}

TH = np.radians(20.0)


@pytest.fixture(scope="module")
def rfr(examples_dir):
    return flexkin.load_mechanism(examples_dir / "unit_3rfr.toml")


@pytest.fixture(scope="module")
def rfr_ws(rfr):
    return workspace(rfr, TH, step=0.03, bounds=(-0.6, 0.6, -0.6, 0.6), all_aspects=False)


def _cells(ws, mp, mask):
    jj, ii = np.nonzero(mask)
    return [(j, i) for j, i in zip(jj, ii)]


def test_every_sampled_cell_is_a_verified_stable_equilibrium(rfr, rfr_ws):
    mp = rfr_ws.maps[0]
    cells = _cells(rfr_ws, mp, mp.reached)
    assert len(cells) > 100
    rng = np.random.default_rng(7)
    pick = [cells[k] for k in rng.choice(len(cells), 25, replace=False)]
    sols = [rfr_ws.solution(rfr, 0, j, i) for j, i in pick]
    checks = verify_many(rfr, sols, load=np.zeros(3))
    assert max(c["tip_error"] for c in checks) < 1e-8
    assert max(c["eq_force"] for c in checks) < 1e-9 and max(c["eq_moment"] for c in checks) < 1e-9
    assert all(s.stable for s in sols)
    # and the full IK at those poses contains them (they are true IK solutions)
    for (j, i), s in list(zip(pick, sols))[:5]:
        res = flexkin.ik(rfr, s.pose)
        assert min(np.max(np.abs(np.array(t.inputs) - np.array(s.inputs))) for t in res.solutions) < 1e-8


def test_fig17_character_bounded_with_both_boundary_kinds(rfr_ws):
    """A bounded region (not touching the grid edge) with IK-singularity boundaries and
    FK-singularity / instability boundaries."""
    mp = rfr_ws.maps[0]
    r = mp.reached
    assert not (r[0].any() or r[-1].any() or r[:, 0].any() or r[:, -1].any())
    assert mp.boundary_ik.sum() >= 5 and mp.boundary_fk.sum() >= 5
    REPORT["workspace unit 3-RFR theta=20 (step 0.03)"] = (
        f"{mp.area_cells} cells, IK boundary {int(mp.boundary_ik.sum())}, FK/instability boundary "
        f"{int(mp.boundary_fk.sum())}, unresolved {int(mp.boundary_seam.sum())}, {rfr_ws.elapsed:.1f} s")


def test_ik_boundary_confirmed_by_a_10x_finer_continuation(rfr, rfr_ws):
    mp = rfr_ws.maps[0]
    X, Y = rfr_ws.x, rfr_ws.y
    cells = _cells(rfr_ws, mp, mp.boundary_ik)
    rng = np.random.default_rng(3)
    tried = confirmed = 0
    for k in rng.permutation(len(cells))[:8]:
        j, i = cells[k]
        for dj, di in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            jj, ii = j + dj, i + di
            if mp.status[jj, ii] == REACHED:
                continue
            if mp.status[jj, ii] != 3:  # only continuation failures (status FAILED)
                continue
            start = np.array([X[i], Y[j], rfr_ws.theta])
            end = np.array([X[ii], Y[jj], rfr_ws.theta])
            sol = rfr_ws.solution(rfr, 0, j, i)
            path = follow_path(rfr, start, end, steps=10, solution=sol)
            tried += 1
            lost = (not path.complete) or any(e.kind == "ik_singularity" for e in path.events)
            confirmed += lost
            break
    assert tried >= 4
    assert confirmed == tried


def test_c3_symmetric_workspace(examples_dir):
    """unit 3-PFR: the mechanism is C3-symmetric, so the region of its C3-symmetric seed
    solution at theta is mapped onto itself by a 120 deg rotation (to within one cell)."""
    mech = flexkin.load_mechanism(examples_dir / "unit_3pfr.toml")
    res = flexkin.ik(mech, (0.0, 0.0, TH))
    sym = [s for s in res.solutions if s.stable and np.ptp(s.inputs) < 1e-9]
    assert sym
    ws = workspace(mech, TH, seed=sym[0], step=0.03, bounds=(-0.9, 0.9, -0.9, 0.9))
    mp = ws.maps[0]
    jj, ii = np.nonzero(mp.reached)
    pts = np.stack([ws.x[ii], ws.y[jj]], -1)
    c, s = np.cos(2 * np.pi / 3), np.sin(2 * np.pi / 3)
    rot = pts @ np.array([[c, s], [-s, c]])
    d = np.min(np.linalg.norm(rot[:, None, :] - pts[None, :, :], axis=2), axis=1)
    frac = np.mean(d <= 1.5 * ws.step)
    REPORT["workspace C3 symmetry unit 3-PFR"] = f"{len(pts)} cells, {frac:.4f} within 1.5 cells after 120 deg"
    assert len(pts) > 200
    assert frac >= 0.98


def test_save_and_load_round_trip(rfr_ws, tmp_path):
    f = tmp_path / "ws.npz"
    rfr_ws.save(str(f))
    back = load_workspace(str(f))
    assert back.theta == rfr_ws.theta and np.array_equal(back.x, rfr_ws.x)
    for a, b in zip(back.maps, rfr_ws.maps):
        assert np.array_equal(a.status, b.status) and np.array_equal(a.inputs, b.inputs)
        assert np.array_equal(a.boundary_ik, b.boundary_ik) and a.seeds == b.seeds


def test_workspace_bad_arguments(rfr):
    with pytest.raises(ValueError, match="bounds"):
        workspace(rfr, TH, bounds=(1, 0, 0, 1))
    with pytest.raises(ValueError, match="step"):
        workspace(rfr, TH, step=-1.0)
    with pytest.raises(ValueError, match="outside the bounds"):
        workspace(rfr, TH, seed=(5.0, 5.0), bounds=(-0.5, 0.5, -0.5, 0.5))


def test_cli_workspace_json_and_plot(examples_dir, tmp_path):
    from flexkin.cli import main

    out = tmp_path / "w.png"
    import contextlib
    import io

    buf = io.StringIO()
    with contextlib.redirect_stdout(buf), contextlib.redirect_stderr(io.StringIO()):
        rc = main(["workspace", str(examples_dir / "unit_3rfr.toml"), "--theta", "20", "--step", "0.05",
                   "--bounds", "-0.6", "0.6", "-0.6", "0.6", "--first-aspect", "--json", "--plot", str(out)])
    assert rc == 0
    d = json.loads(buf.getvalue())
    asp = d["workspaces"][0]["aspects"][0]
    assert asp["cells"] > 20 and asp["modes"]
    assert out.stat().st_size > 10_000
