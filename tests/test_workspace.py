"""Workspaces by wave propagation (paper §6, Fig. 17): every cell a verified stable equilibrium,
C3 symmetry, IK boundaries confirmed by a 10x finer continuation, save/load, CLI."""

from __future__ import annotations

import json
import os
import sys

import numpy as np
import pytest

import flexkin
from flexkin import follow_path
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


# ---- constrained workspaces, grid edge, stability along the wave, metrics (issues 13, 15, 18) ----
def _mech_2pl(radius=0.01, max_strain=0.03):
    """A 2P+L design (legs 1-2 prismatic, leg 3 pushes its rod out of a fixed guide) with
    narrow strokes, a rod radius and a strain limit, so that a workspace crosses all three."""
    d = {"name": "2P+L test", "rod": {"length": 1.0, "EI": 1.0, "radius": radius},
         "platform": {"attach": [[-0.21650635094610965, -0.125], [0.21650635094610965, -0.125], [0.0, 0.25]]},
         "leg": [{"actuation": "prismatic", "origin": [-0.8660254037844386, -0.5], "angle": 0.0, "range": [-0.5, 0.1]},
                 {"actuation": "prismatic", "origin": [0.8660254037844386, -0.5], "angle": 120.0, "range": [-0.5, 0.1]},
                 {"actuation": "length", "origin": [0.0, 1.0], "angle": 270.0, "range": [0.5, 1.1]}],
         "limits": {"max_strain": max_strain}}
    return flexkin.mechanism_from_dict(d)


TH15 = np.radians(15.0)
BOX = (-0.64, 0.64, -0.64, 0.64)


@pytest.fixture(scope="module")
def pl_pair():
    mech = _mech_2pl()
    free = workspace(mech, TH15, step=0.04, bounds=BOX, all_aspects=False)
    cons = workspace(mech, TH15, step=0.04, bounds=BOX, all_aspects=False, constrained=True)
    return mech, free, cons


def _independent_violations(mech, sol):
    """Range and strain verdicts of one solution by explicit comparisons and the feasibility module."""
    bad_range = any(not (lo - 1e-12 <= u <= hi + 1e-12) for u, (lo, hi) in
                    zip(sol.inputs, [leg.range for leg in mech.legs]))
    strain = max(float(np.max(np.abs(r.curvature(2001)))) * mech.legs[i].rod.radius for i, r in enumerate(sol.rods))
    return bad_range, strain


def test_unconstrained_map_marks_the_infeasible_cells(pl_pair):
    """Without constraints every stable cell is reached, and its violations agree with an
    independent check: explicit range comparisons and the strain from dense curvature samples."""
    mech, free, _ = pl_pair
    mp = free.maps[0]
    r = mp.reached
    bad = r & (mp.violations != 0)
    assert r.sum() > 100 and 0.1 < bad.sum() / r.sum() < 0.95  # a real mix: the old maps reported all of them
    rng = np.random.default_rng(11)
    jj, ii = np.nonzero(r)
    for k in rng.choice(len(jj), 20, replace=False):
        sol = free.solution(mech, 0, jj[k], ii[k])
        bad_range, strain = _independent_violations(mech, sol)
        assert bool(mp.violations[jj[k], ii[k]] & 1) == bad_range
        assert mp.strain[jj[k], ii[k]] == pytest.approx(strain, rel=1e-5)
        if abs(strain - mech.max_strain) > 1e-4:
            assert bool(mp.violations[jj[k], ii[k]] & 2) == (strain > mech.max_strain)
    # feasible cells next to infeasible ones are the infeasible boundary
    assert mp.boundary_infeasible.sum() > 0
    assert not np.any(mp.boundary_infeasible & (mp.violations != 0))
    assert "constraints not applied" in free.summary() and "ranges, strain" in free.region


def test_constrained_wave_stops_at_infeasible_cells(pl_pair):
    mech, free, cons = pl_pair
    mp, mf = cons.maps[0], free.maps[0]
    r = mp.reached
    assert r.sum() > 20
    assert np.all(mp.violations[r] == 0)               # only feasible cells are reached ...
    assert np.all(mf.reached[r])                       # ... all of them reached without constraints too
    assert r.sum() < mf.reached.sum()
    assert mp.boundary_infeasible.sum() > 0 and np.any(mp.status == 5)
    for (j, i) in zip(*np.nonzero(mp.status == 5)):   # refused cells carry the reason
        assert mp.violations[j, i] != 0
    # every input of every reached cell in range (the old maps: only a fraction)
    for k, leg in enumerate(mech.legs):
        lo, hi = leg.range
        u = mp.inputs[..., k][r]
        assert np.all((u >= lo - 1e-12) & (u <= hi + 1e-12))
    assert "feasible only" in cons.region and "feasible only" in cons.summary()
    met = cons.metrics()
    assert met["region"] == cons.region and met["feasible_area"] == pytest.approx(met["workspace_area"])


def test_peak_curvature_of_cells_matches_dense_samples(rfr, rfr_ws):
    from flexkin.solve.workspace import cell_peak_curvature
    from flexkin.system import System

    mp = rfr_ws.maps[0]
    jj, ii = np.nonzero(mp.reached)
    sel = np.random.default_rng(5).choice(len(jj), 12, replace=False)
    system = System.from_mechanism(rfr)
    for k in sel:
        sol = rfr_ws.solution(rfr, 0, jj[k], ii[k])
        x = np.array(sol.x)[None]
        kc = cell_peak_curvature(system, rfr, x, np.array(sol.charts)[None])[0]
        dense = [float(np.max(np.abs(r.curvature(4001)))) for r in sol.rods]
        assert np.allclose(kc, dense, rtol=1e-5, atol=1e-9)


def test_region_cut_by_given_bounds_is_marked_and_default_bounds_grow():
    """unit 3-PFR at 20 deg: a box smaller than the region cuts it (grid-edge cells, message);
    with default bounds the grid grows until the region closes."""
    mech = flexkin.load_mechanism(os.path.join(os.path.dirname(__file__), "..", "examples", "unit_3pfr.toml"))
    cut = workspace(mech, TH, step=0.1, bounds=(-0.3, 0.3, -0.3, 0.3), all_aspects=False)
    mp = cut.maps[0]
    assert mp.cut_by_grid and mp.boundary_edge.sum() >= 5
    assert np.array_equal(mp.boundary_edge[1:-1, 1:-1], np.zeros((len(cut.y) - 2, len(cut.x) - 2), bool))
    assert "grid's edge" in cut.message and cut.metrics()["cut_by_grid"]
    small = workspace(mech, TH, step=0.1, bounds=(-0.3, 0.3, -0.3, 0.3), all_aspects=False, grow=3)
    assert small.grown >= 1
    sm = small.maps[0]
    assert not sm.cut_by_grid and not small.metrics()["cut_by_grid"]
    assert sm.area_cells > mp.area_cells
    # the grown grid contains the cut one, on the same lattice: the cut region is part of the closed one
    i = int(round((cut.x[0] - small.x[0]) / small.step))
    j = int(round((cut.y[0] - small.y[0]) / small.step))
    assert np.all(sm.reached[j:j + len(cut.y), i:i + len(cut.x)][mp.reached])


def test_stability_along_the_wave_equals_the_full_check(rfr, rfr_ws):
    """The closed-form verdict at every cell (the default) gives the same map as the margin of
    the discretised second variation carried along the wave to every cell
    (``stability="margins"``), every margin positive; margins filled in afterwards (layer by
    layer from the seed) equal the carried ones."""
    full = workspace(rfr, TH, step=0.03, bounds=(-0.6, 0.6, -0.6, 0.6), all_aspects=False, stability="margins")
    a, b = rfr_ws.maps[0], full.maps[0]
    assert np.array_equal(a.status, b.status)
    assert np.array_equal(a.boundary_fk, b.boundary_fk) and np.array_equal(a.boundary_ik, b.boundary_ik)
    assert np.all(np.isfinite(b.margin[b.reached])) and np.all(b.margin[b.reached] > 0)
    # margins filled in afterwards equal those of the full wave
    filled = rfr_ws.margins(rfr)[0]
    assert np.allclose(filled[a.reached], b.margin[b.reached], rtol=1e-9, atol=1e-12)
    with pytest.raises(ValueError, match="stability"):
        workspace(rfr, TH, stability="sometimes")


def test_metrics(rfr, rfr_ws):
    met = rfr_ws.metrics(rfr)
    h2 = rfr_ws.step ** 2
    assert met["aspect_areas"] == [m.area_cells * h2 for m in rfr_ws.maps]
    assert met["singularity_free_area"] == max(met["aspect_areas"])
    assert met["workspace_area"] == pytest.approx(rfr_ws.union().sum() * h2)
    sm = met["stability_margin"]
    assert 0 < sm["min"] <= sm["mean"] <= sm["max"]
    assert 0 < met["det_ik_ratio"] <= 1 and 0 < met["det_fk_ratio"] <= 1
    assert met["max_strain"] is None  # no radius: no strain
    json.dumps(met)


def _scaled(d, s):
    d = json.loads(json.dumps(d))
    d["rod"]["length"] *= s
    d["platform"]["attach"] = [[s * a for a in p] for p in d["platform"]["attach"]]
    for leg in d["leg"]:
        leg["origin"] = [s * a for a in leg["origin"]]
    return d


def test_areas_scale_as_s_squared(examples_dir):
    """Every length x s (EI kept, no load): the equilibria are the scaled ones, so the same
    cells are reached on the scaled grid and every area is multiplied by s^2."""
    import tomllib

    d = tomllib.loads((examples_dir / "unit_3rfr.toml").read_text())
    s = 2.5
    ws = [workspace(flexkin.mechanism_from_dict(_scaled(d, f)), TH, step=0.05 * f,
                    bounds=tuple(f * b for b in (-0.6, 0.6, -0.6, 0.6)), all_aspects=False) for f in (1.0, s)]
    m0, m1 = (w.metrics() for w in ws)
    assert np.array_equal(ws[0].maps[0].status, ws[1].maps[0].status)
    assert m1["workspace_area"] == pytest.approx(s * s * m0["workspace_area"], rel=1e-12)
    assert m1["singularity_free_area"] == pytest.approx(s * s * m0["singularity_free_area"], rel=1e-12)


def test_c3_symmetry_of_the_symmetric_3rfr_union_and_dexterous_workspace():
    """symmetric_mechanism('revolute'): the union of all aspects at theta and the dexterous
    workspace over a C3-symmetric set of orientations map onto themselves under 120 deg."""
    from flexkin.mechanism import symmetric_mechanism
    from flexkin.solve.workspace import dexterous_workspace

    mech = symmetric_mechanism("revolute")
    box = (-0.6, 0.6, -0.6, 0.6)

    def c3_fraction(x, y, mask, h):
        jj, ii = np.nonzero(mask)
        pts = np.stack([x[ii], y[jj]], -1)
        c, s = np.cos(2 * np.pi / 3), np.sin(2 * np.pi / 3)
        rot = pts @ np.array([[c, s], [-s, c]])
        d = np.min(np.linalg.norm(rot[:, None, :] - pts[None, :, :], axis=2), axis=1)
        return len(pts), float(np.mean(d <= 1.5 * h))

    ws = workspace(mech, TH, step=0.04, bounds=box)
    n, frac = c3_fraction(ws.x, ws.y, ws.union(), ws.step)
    assert n > 100 and frac >= 0.97
    dx = dexterous_workspace(mech, TH + np.radians([-5.0, 0.0, 5.0]), step=0.04, bounds=box)
    single = [w.union().sum() for w in dx.workspaces]
    assert 0 < dx.mask.sum() <= min(single)
    assert dx.area == pytest.approx(dx.mask.sum() * dx.step ** 2)
    n, frac = c3_fraction(dx.x, dx.y, dx.mask, dx.step)
    assert frac >= 0.95
    # intersection by coordinates, cell by cell
    for w in dx.workspaces:
        jj, ii = np.nonzero(dx.mask)
        i = np.round((dx.x[ii] - w.x[0]) / w.step).astype(int)
        j = np.round((dx.y[jj] - w.y[0]) / w.step).astype(int)
        assert np.all(w.union()[j, i])


def test_merged_aspect_holds_the_region_of_every_seed_it_merges(pl_pair):
    """Seeds whose waves meet (same solution at a cell) are one aspect, and that aspect's map
    holds the cells of all of them: the first seed's own map is inside it (before, the merged
    map kept only the later seed's cells, stopped at the earlier region)."""
    mech, free, _ = pl_pair
    allw = workspace(mech, TH15, step=0.04, bounds=BOX)
    first = free.maps[0]
    mine = [mp for mp in allw.maps if first.seeds[0] in mp.seeds]
    assert len(mine) == 1
    assert np.all(mine[0].reached[first.reached])
    assert mine[0].area_cells >= first.area_cells
    assert sum(len(mp.seeds) for mp in allw.maps) == len({s for mp in allw.maps for s in mp.seeds})


def test_default_stability_rejects_unstable_cells_on_a_coarse_grid():
    """Regression: carrying stability by the sign of det A_FK over a coarse 0.1 m step admitted
    an unstable cell (margin -7.5) into the stable aspect of the unit 3-RFR with L = 1.1 m at
    10 deg; the default computes the second variation at every cell."""
    import math
    import tomllib
    from pathlib import Path

    from flexkin.mechanism import mechanism_from_dict

    d = tomllib.loads((Path(__file__).parents[1] / "examples" / "unit_3rfr.toml").read_text())
    d["rod"]["length"] = 1.1
    mech = mechanism_from_dict(d, source="unit_3rfr, L = 1.1")
    ws = workspace(mech, math.radians(10), step=0.1, all_aspects=False)
    margins = ws.margins(mech)[0][ws.maps[0].reached]
    assert margins.size > 10 and np.all(margins > 0)
