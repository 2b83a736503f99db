"""Forward kinematics of mechanisms with CLAMPED legs (test-only; used by ``fk_oracle.fk_multistart``).

Nothing here calls flexkin.  With the inputs fixed every clamp is fixed; for a platform pose p,
rod i's solutions (tip at B_i(p); clamped: tip tangent theta_P + tip_angle, pinned: zero tip
moment) are finitely many (per d-mode and turning bound), and as p varies they form sheets over
the 3-D pose space.  The FK solutions are the poses where one rod of every leg balances the load.

Method (the analogue of ``fk_oracle``'s pose-grid starts, with exact rods):

1. poses: a jittered grid of the reach region (``fk_oracle.pose_grid``) plus random poses;
2. at every pose every rod's solutions: approximate rods from the canonical chart of clamped rods
   (``clamped_chart``; for a pinned rod from ``fk_oracle``'s triangulated chart sheet), each
   solved exactly by multiple-shooting Newton with the pose frozen (``ms_shooting.RodFK``);
3. every combination of one rod per leg at a pose: its wrench balance is linearised in the pose
   (exact derivatives, the rods following the pose); a combination whose predicted pose
   correction is within ``s_max`` grid steps is a start (one per cluster of equal predictions);
4. each start is solved by Newton on the 3 platform equations in the pose with every rod slaved
   to the pose (re-solved from its tangent prediction at every step, so it never leaves its
   sheet) (:func:`pose_newton`);
5. candidates are refined on the full multiple-shooting FK system (K segments, RK4), polished with
   DOP853 segments (rtol 1e-13) and built/verified with densely sampled DOP853 segments.
"""

from __future__ import annotations

import numpy as np
from clamped_chart import chart
from ik_oracle import Geom, _dedupe_rows, _mode_ambiguous, _wrap, count_inflections, elastica_k, integrate_batch
from leg_curves import TURN_MARGIN
from ms_shooting import MSSystem, RodFK, solve_batch

__all__ = ["fk_clamped", "pose_newton", "rods_at_poses"]


def _rod_newton(rod: RodFK, Xr, pose, n_iter=20, tol=1e-10, blow=5e3):
    """Damped Newton on one rod's rows with the pose frozen.  Returns Xr, ok."""
    g, i = rod.g, rod.i
    Xr = np.array(Xr, float)
    M = len(Xr)
    ok = np.zeros(M, bool)
    active = np.ones(M, bool)
    fs = g.F_ref * rod.L**2 / g.EI[i]
    for it in range(n_iter + 1):
        idx = np.flatnonzero(active)
        if not idx.size:
            break
        o = rod.eval(Xr[idx], pose[idx])
        rn = np.max(np.abs(o["R"]), axis=1)
        done = rn < tol
        ok[idx[done]] = True
        if it == n_iter:
            break
        step = solve_batch(o["Jr"], -o["R"])
        good = np.all(np.isfinite(step), axis=1)
        step[~good] = 0.0
        Rd = np.hypot(Xr[idx, 0], Xr[idx, 1]) * fs
        lim = np.hypot(step[:, 0], step[:, 1]) * fs / (0.5 * Rd + 3.0)
        if rod.K > 1:
            lim = np.maximum(lim, np.max(np.abs(step[:, 3 + 4 * np.arange(rod.K - 1) + 2]), axis=1) / 0.5)
        step *= (1.0 / np.maximum(lim, 1.0))[:, None]
        upd = ~done & good
        Xr[idx[upd]] += step[upd]
        active[idx[done | ~good | (Rd > blow)]] = False
    return Xr, ok


def _rod_state(rod: RodFK, Xr, pose):
    """Wrench W (M, 3), its total derivative w.r.t. the pose with the rod following (M, 3, 3),
    dXr/dpose (M, nr, 3) and the evaluation dict."""
    o = rod.eval(Xr, pose)
    W, dWx, dWp = rod.wrench(Xr, o)
    dX = -solve_batch(o["Jr"], o["Jp"])
    return W, dWp + np.einsum("nkr,nrp->nkp", dWx, dX), dX, o


def _in_box(rod: RodFK, o, Xr, R_max, max_mode, max_turn):
    g = rod.g
    Rd = np.hypot(Xr[:, 0], Xr[:, 1]) * g.F_ref * rod.L**2 / g.EI[rod.i]
    return (o["changes"] + 1 <= max_mode + 1) & (np.abs(o["turning"]) <= max_turn + TURN_MARGIN) & (Rd <= 1.5 * R_max)


def _approx_rods(fsys, sheets, rod: RodFK, poses, max_mode, max_turn, R_max):
    """Approximate rods of ``rod`` at the poses: (pose index, scaled q (n, 3))."""
    g, i = rod.g, rod.i
    arm = rod.arm(poses)
    B = poses[:, :2] + arm
    if g.clamped[i]:
        ch = chart(rho_max=float(np.sqrt(R_max)), max_turn=float(max_turn), mode_cap=max_mode + 1, max_span=2.0)
        c, s = np.cos(rod.al), np.sin(rod.al)
        d = (B - rod.A) / rod.L
        Q = np.stack([c * d[:, 0] + s * d[:, 1], -s * d[:, 0] + c * d[:, 1],
                      _wrap(poses[:, 2] + g.tip_angle[i] - rod.al)], 1)
        qi, tr, w, _sh = ch.locate(Q, max_mode=max_mode)
        p, *_ = ch.interp(tr, w)
        fx = (c * p[:, 0] - s * p[:, 1]) * g.EI[i] / rod.L**2
        fy = (s * p[:, 0] + c * p[:, 1]) * g.EI[i] / rod.L**2
        m0 = p[:, 2] * g.EI[i] / rod.L
    else:
        sh = sheets[i]
        qi, tr, a, b = sh.locate(B)
        T = sh.tri[tr]
        w = np.stack([1 - a - b, a, b], 1)
        f = np.einsum("nk,nkc->nc", w, sh.F[T])
        fx, fy = f[:, 0], f[:, 1]
        m0 = np.einsum("nk,nk->n", w, sh.W0[T]) * g.EI[i] / rod.L
    return qi, np.stack([fx / g.F_ref, fy / g.F_ref, m0 / (g.F_ref * g.L_ref)], 1)


def rods_at_poses(fsys, sheets, rod: RodFK, poses, max_mode, max_turn, R_max):
    """Exact solutions of ``rod`` at every pose: (pose index, Xr) (chart seeds, Newton with the pose
    frozen, inside the search box, de-duplicated per pose)."""
    from leg_curves import dedupe_slices

    qi, q = _approx_rods(fsys, sheets, rod, poses, max_mode, max_turn, R_max)
    if not len(qi):
        return qi, np.zeros((0, rod.nr))
    sel = dedupe_slices(qi, q, tol=0.02)
    qi, q = qi[sel], q[sel]
    Xr, ok = _rod_newton(rod, rod.expand(q), poses[qi])
    qi, Xr = qi[ok], Xr[ok]
    if len(qi):
        o = rod.eval(Xr, poses[qi], jac=False)
        inb = _in_box(rod, o, Xr, R_max, max_mode, max_turn)
        qi, Xr = qi[inb], Xr[inb]
    sel = dedupe_slices(qi, Xr[:, :3])
    return qi[sel], Xr[sel]


def pose_lattice(fsys, h_xy, n_theta, rng):
    """A regular pose grid (random offset) over the reach region: spacing ``h_xy L_ref`` in x, y and
    2 pi / n_theta in theta.  Returns the poses (M, 3) and their integer grid indices (M, 3)."""
    from fk_oracle import _in_reach, _reach_box

    g = fsys.g
    h = h_xy * g.L_ref
    ht = 2 * np.pi / n_theta
    off = rng.uniform(size=3)
    th = -np.pi + ht * (np.arange(n_theta) + off[2])
    lo, hi = _reach_box(fsys, th)
    ok = np.all(hi > lo, axis=1)
    if not np.any(ok):
        return np.zeros((0, 3)), np.zeros((0, 3), np.int64)
    x0 = np.floor(lo[ok, 0].min() / h) - 1
    y0 = np.floor(lo[ok, 1].min() / h) - 1
    nx = int(np.ceil(hi[ok, 0].max() / h) - x0) + 2
    ny = int(np.ceil(hi[ok, 1].max() / h) - y0) + 2
    I, J, T = np.meshgrid(np.arange(nx), np.arange(ny), np.arange(n_theta), indexing="ij")
    idx = np.stack([I.ravel(), J.ravel(), T.ravel()], 1)
    poses = np.column_stack([(x0 + idx[:, 0] + off[0]) * h, (y0 + idx[:, 1] + off[1]) * h, th[idx[:, 2]]])
    keep = _in_reach(fsys, poses)
    return poses[keep], idx[keep]


def propagate(rods_i: RodFK, poses, idx, n_theta, qi, Xr, R_max, max_mode, max_turn, max_sweeps=60, info=None):
    """Flood-fill rod solutions over the pose lattice: every solution at a node is continued to the
    6 neighbouring nodes (tangent predictor dXr/dpose, Newton corrector with the pose frozen) until
    no new solution appears.  Returns (node index, Xr) of all solutions."""
    from leg_curves import dedupe_slices
    from scipy.spatial import cKDTree

    if not len(qi):
        return qi, Xr
    key = {tuple(k): n for n, k in enumerate(idx)}
    nbr = np.full((len(idx), 6), -1, np.int64)
    for n, (a, b, c) in enumerate(idx):
        for d, (da, db, dc) in enumerate(((1, 0, 0), (-1, 0, 0), (0, 1, 0), (0, -1, 0), (0, 0, 1), (0, 0, -1))):
            nbr[n, d] = key.get((a + da, b + db, (c + dc) % n_theta), -1)
    frontier = np.arange(len(qi))
    sweeps = 0
    while len(frontier) and sweeps < max_sweeps:
        sweeps += 1
        _W, _J, dX, _o = _rod_state(rods_i, Xr[frontier], poses[qi[frontier]])
        fin = np.all(np.isfinite(dX).reshape(len(frontier), -1), axis=1)
        src = np.repeat(frontier[fin], 6)
        dst = nbr[qi[src], np.tile(np.arange(6), int(np.count_nonzero(fin)))]
        ok = dst >= 0
        src, dst = src[ok], dst[ok]
        if not len(src):
            break
        dp = poses[dst] - poses[qi[src]]
        dp[:, 2] = _wrap(dp[:, 2])
        k_src = np.searchsorted(frontier[fin], src)
        xp = Xr[src] + np.einsum("nrp,np->nr", dX[fin][k_src], dp)
        # skip predictions that land on known solutions of the target node
        tree = cKDTree(np.column_stack([qi * 1e3, Xr[:, :3] / (1.0 + np.abs(Xr[:, :3]))]))
        d, _ = tree.query(np.column_stack([dst * 1e3, xp[:, :3] / (1.0 + np.abs(xp[:, :3]))]), k=1, p=np.inf)
        new = d > 0.05
        src, dst, xp = src[new], dst[new], xp[new]
        if not len(src):
            break
        xn, okn = _rod_newton(rods_i, xp, poses[dst], n_iter=10)
        xn, dst = xn[okn], dst[okn]
        if len(dst):
            o = rods_i.eval(xn, poses[dst], jac=False)
            inb = _in_box(rods_i, o, xn, R_max, max_mode, max_turn)
            xn, dst = xn[inb], dst[inb]
        if not len(dst):
            break
        all_q = np.concatenate([qi, dst])
        all_X = np.concatenate([Xr, xn])
        sel = dedupe_slices(all_q, all_X[:, :3])
        fresh = sel[sel >= len(qi)]
        if not len(fresh):
            break
        frontier = np.arange(len(qi), len(qi) + len(fresh))
        qi = np.concatenate([qi, all_q[fresh]])
        Xr = np.concatenate([Xr, all_X[fresh]])
    if info is not None:
        info.setdefault("propagation_sweeps", []).append(sweeps)
    return qi, Xr


def pose_newton(rods, Xr, pose, target, n_iter=20, tol=1e-9, max_step=(0.1, 0.1, 0.3)):
    """Newton on the 3 platform equations in the pose, every rod slaved to the pose.

    ``Xr`` (N, 3, nr) exact rods at the (physical) poses ``pose`` (N, 3).  Each iteration: every
    rod's wrench and its total pose derivative (:func:`_rod_state`), the pose step from the 3 x 3
    system (damped to ``max_step`` = (x / L_ref, y / L_ref, theta)), every rod moved by its tangent
    prediction and re-solved at the new pose (halving the step up to three times if a rod fails).
    Returns Xr, pose, the residual (inf-norm, scaled) and a success mask."""
    g = rods[0].g
    Xr = np.array(Xr, float)
    pose = np.array(pose, float)
    N = len(pose)
    alive = np.ones(N, bool)
    res = np.full(N, np.inf)
    ms = np.array(max_step, float) * np.array([g.L_ref, g.L_ref, 1.0])
    for it in range(n_iter + 1):
        idx = np.flatnonzero(alive)
        if not idx.size:
            break
        Ws, Js, dXs = [], [], []
        for i in range(3):
            W, J, dX, _ = _rod_state(rods[i], Xr[idx, i], pose[idx])
            Ws.append(W); Js.append(J); dXs.append(dX)
        F = Ws[0] + Ws[1] + Ws[2] - target
        rn = np.max(np.abs(F), axis=1)
        res[idx] = rn
        done = rn < tol
        alive[idx[done]] = False
        if it == n_iter:
            break
        step = solve_batch(Js[0] + Js[1] + Js[2], -F)
        ok = np.all(np.isfinite(step), axis=1)
        for dX in dXs:
            ok &= np.all(np.isfinite(dX).reshape(len(idx), -1), axis=1)
        alive[idx[~ok]] = False
        sel = ~done & ok
        idx, step = idx[sel], step[sel]
        dXs = [d[sel] for d in dXs]
        if not idx.size:
            continue
        step = step / np.maximum(np.max(np.abs(step) / ms, axis=1), 1.0)[:, None]
        todo = np.ones(len(idx), bool)
        for _half in range(4):
            k = np.flatnonzero(todo)
            if not k.size:
                break
            pn = pose[idx[k]] + step[k]
            xn = np.empty((len(k),) + Xr.shape[1:])
            good = np.ones(len(k), bool)
            for i in range(3):
                xp = Xr[idx[k], i] + np.einsum("nrp,np->nr", dXs[i][k], step[k])
                xn[:, i], okr = _rod_newton(rods[i], xp, pn, n_iter=8, tol=1e-11)
                good &= okr
            kk = k[good]
            Xr[idx[kk]] = xn[good]
            pose[idx[kk]] = pn[good]
            todo[kk] = False
            step[k[~good]] *= 0.5
        alive[idx[todo]] = False
    return Xr, pose, res, res < tol


def _starts(rods, per_rod, poses, target, s_max, h, max_starts, info, chunk=1_000_000):
    """Combinations of one rod per leg at every pose whose linearised pose correction is within
    ``s_max`` grid steps ``h`` (x, y, theta); one per cluster of equal predictions (pose within
    half a grid step, rods' force and base moment within 5 %), best first.  Returns (pose index,
    (3,) row indices into per_rod, pose step)."""
    from fk_oracle import _combos
    from scipy.spatial import cKDTree

    npz = len(poses)
    states = []
    for i in range(3):
        qi, Xr = per_rod[i]
        order = np.argsort(qi, kind="stable")
        qi, Xr = qi[order], Xr[order]
        W, J, _dX, _ = _rod_state(rods[i], Xr, poses[qi]) if len(qi) else (np.zeros((0, 3)), np.zeros((0, 3, 3)),
                                                                         None, None)
        states.append((qi, order, W, J))
    cnts = [np.bincount(s_[0], minlength=npz) for s_ in states]
    info["fk_combinations"] = int(np.sum(cnts[0] * cnts[1] * cnts[2]))
    picks, scores, steps = [], [], []
    for Jx, sel in _combos(cnts, npz, chunk):
        F = states[0][2][sel[0]] + states[1][2][sel[1]] + states[2][2][sel[2]] - target
        Jt = states[0][3][sel[0]] + states[1][3][sel[1]] + states[2][3][sel[2]]
        dp = solve_batch(Jt, -F)
        sc = np.max(np.abs(dp) / h, axis=1)
        kp = np.flatnonzero(np.isfinite(sc) & (sc <= s_max))
        if not len(kp):
            continue
        picks.append(np.column_stack([Jx[kp]] + [states[i][1][sel[i][kp]] for i in range(3)]))
        scores.append(sc[kp])
        steps.append(dp[kp])
    if not picks:
        return np.zeros((0, 4), np.int64), np.zeros((0, 3))
    P, S, D = np.concatenate(picks), np.concatenate(scores), np.concatenate(steps)
    order = np.argsort(S, kind="stable")
    P, D = P[order], D[order]
    # clusters of equal predictions
    pred = poses[P[:, 0]] + D
    key = [pred / (0.5 * h)]
    for i in range(3):
        q = per_rod[i][1][P[:, 1 + i], :3]
        key.append(q / (0.05 * (1.0 + np.abs(q))))
    key = np.concatenate(key, axis=1)
    tree = cKDTree(key)
    taken = np.zeros(len(P), bool)
    keep = []
    for k in range(len(P)):
        if taken[k]:
            continue
        keep.append(k)
        taken[tree.query_ball_point(key[k], 1.0, p=np.inf)] = True
        if len(keep) >= max_starts:
            break
    keep = np.array(keep, np.int64)
    return P[keep], D[keep]


def fk_clamped(mech, inputs, load, max_mode=2, max_turn=None, K=4, grid=(0.08, 36), n_random=500, s_max=2.0,
               R_range=(0.05, 300.0), max_starts=50000, seed=0, return_all=False, stats=None, propagate_sweeps=60,
               chunk=500, min_poses=300):
    """All FK equilibria (d-modes <= max_mode, clamped |turning| <= max_turn, default 2 pi max_mode) of
    a mechanism with clamped legs; see the module docstring.  ``grid = (h_xy, n_theta)`` is the pose
    grid (spacing ``h_xy L_ref``, ``n_theta`` orientations), ``n_random`` random poses are added.
    Returns ``fk_oracle.FKOracleSolution`` items sorted by (modes, pose), each verified
    (``fk_oracle.verify_fk``, residual <= VERIFY_TOL), with the statistics in ``stats``."""
    import time

    from fk_oracle import FKSystem, _Sheet, chart_scan, sample_poses

    t0 = time.process_time()
    g = Geom.of(mech)
    load = np.asarray(mech.load if load is None else load, float)
    inputs = np.asarray(inputs, float).reshape(3)
    max_turn = 2 * np.pi * max_mode if max_turn is None else float(max_turn)
    fsys = FKSystem(g, inputs, load)
    rng = np.random.default_rng(seed)
    info: dict = {}
    rods = [RodFK(g, i, inputs, K) for i in range(3)]
    sheets = [None] * 3
    if not np.all(g.clamped):
        sc = chart_scan(40.0, 320, 480)
        sheets = [None if g.clamped[i] else _Sheet(fsys, i, sc, max_mode, 0.01 * g.L_ref) for i in range(3)]
    h_xy, n_th = grid
    poses, idx = pose_lattice(fsys, h_xy, n_th, rng)
    while len(poses) < min_poses and h_xy > 0.01:  # a small reach region: refine x, y
        h_xy *= 0.7
        poses, idx = pose_lattice(fsys, h_xy, n_th, rng)
    info["poses"] = len(poses)
    info["h_xy"] = round(h_xy, 4)
    per_rod = []
    for i in range(3):
        qi, Xr = rods_at_poses(fsys, sheets, rods[i], poses, max_mode, max_turn, R_range[1])
        if propagate_sweeps:
            qi, Xr = propagate(rods[i], poses, idx, n_th, qi, Xr, R_range[1], max_mode, max_turn,
                               max_sweeps=propagate_sweeps, info=info)
        per_rod.append((qi, Xr))
    if n_random:  # random poses, chart seeds only (no propagation)
        rp = sample_poses(fsys, n_random, rng)
        for i in range(3):
            qi, Xr = rods_at_poses(fsys, sheets, rods[i], rp, max_mode, max_turn, R_range[1])
            per_rod[i] = (np.concatenate([per_rod[i][0], qi + len(poses)]), np.concatenate([per_rod[i][1], Xr]))
        poses = np.concatenate([poses, rp])
    info["rods_per_pose"] = [round(len(p_[0]) / max(len(poses), 1), 2) for p_ in per_rod]
    target = np.array([load[0] / g.F_ref, load[1] / g.F_ref, load[2] / (g.F_ref * g.L_ref)])
    h = np.array([h_xy * g.L_ref, h_xy * g.L_ref, 2 * np.pi / n_th])
    P, D = _starts(rods, per_rod, poses, target, s_max, h, max_starts, info)
    info["fk_starts"] = len(P)
    info["cpu_seeding"] = round(time.process_time() - t0, 1)
    msys = MSSystem(g, "fk", inputs, load, K=K)
    sols = []
    if len(P):
        X = _solve_starts(rods, per_rod, poses, P, D, target, msys, info, h, chunk=chunk)
        sols = refine_build(mech, g, msys, X, inputs, load, max_mode, max_turn, return_all, info)
    info["unique"] = len(sols)
    info["cpu_total"] = round(time.process_time() - t0, 1)
    if stats is not None:
        stats.update(info)
    return sols


def _near_key(h, pose, q3):
    """Coordinates of (pose, rods) in which "close" (inf-norm <= 1) means "this start converges to
    that solution": the pose in units of two grid steps ``h`` (theta wrapped), every rod's force and
    base moment in units of 10 % (+ 0.1 in scaled units)."""
    cols = [pose[:, 0:1] / (2 * h[0]), pose[:, 1:2] / (2 * h[1]), _wrap(pose[:, 2:3]) / (2 * h[2])]
    for i in range(3):
        q = q3[:, i]
        cols.append(q / (0.1 * (1.0 + np.abs(q))))
    return np.concatenate(cols, axis=1)


def _solve_starts(rods, per_rod, poses, P, D, target, msys, info, h, chunk=500, near=1.0):
    """:func:`pose_newton` on the starts (best first) in chunks; a start whose lattice pose and rods
    are within ``near`` (:func:`_near_key`: two grid steps, 10 % of the rods' forces and base
    moments) of an already converged solution lies on that solution's sheets and is skipped.
    Returns the converged multiple-shooting unknowns."""
    from scipy.spatial import cKDTree

    found = []
    keys = np.zeros((0, 12))
    n_run = 0
    for c0 in range(0, len(P), chunk):
        Pc = P[c0:c0 + chunk]  # (pose_newton's first step is the linear prediction D itself)
        Xr = np.stack([per_rod[i][1][Pc[:, 1 + i]] for i in range(3)], 1)
        pose0 = poses[Pc[:, 0]]
        if len(keys):
            kz = _near_key(h, pose0, Xr[:, :, :3])  # the start's own node and rods
            d, _ = cKDTree(keys).query(kz, k=1, p=np.inf)
            # theta periodic: also compare with the key shifted by one turn
            sh = np.zeros(kz.shape[1])
            sh[2] = 2 * np.pi / (2 * h[2])
            d = np.minimum(d, np.minimum(cKDTree(keys).query(kz + sh, k=1, p=np.inf)[0],
                                         cKDTree(keys).query(kz - sh, k=1, p=np.inf)[0]))
            sel = d > near
            Xr, pose0 = Xr[sel], pose0[sel]
        if not len(Xr):
            continue
        n_run += len(Xr)
        Xr, pose, _res, ok = pose_newton(rods, Xr, pose0, target)
        if np.any(ok):
            found.append(np.concatenate([Xr[ok, 0], Xr[ok, 1], Xr[ok, 2], pose[ok] / msys.ps], axis=1))
            keys = np.concatenate([keys, _near_key(h, pose[ok], Xr[ok][:, :, :3])])
    info["fk_newton_runs"] = n_run
    info["fk_converged"] = int(sum(len(f) for f in found))
    return np.concatenate(found) if found else np.zeros((0, msys.n))


def _fk_key(msys: MSSystem, X):
    z = msys.reduce(X).copy()
    z[:, 11] = _wrap(z[:, 11])
    return z


def refine_build(mech, g: Geom, msys: MSSystem, X, inputs, load, max_mode, max_turn, return_all, info,
                 polish_tol=1e-9):
    """Refine (multiple-shooting Newton, RK4), de-duplicate, polish (DOP853 segments), build and
    verify FK candidates ``X`` (multiple-shooting unknowns)."""
    from fk_oracle import VERIFY_TOL, FKOracleRod, FKOracleSolution, verify_fk

    if not len(X):
        return []
    X = X[_dedupe_rows(_fk_key(msys, X), 1e-6)]
    fine = MSSystem(g, "fk", inputs, load, K=msys.K, n_min=64, per_lambda=16.0)
    X, rn, ch, turn = fine.newton(X, n_iter=10, tol=1e-11)
    good = (rn < 1e-7) & (return_all | (np.all(ch <= max_mode + 1, axis=1)
                                        & np.all(~g.clamped[None] | (np.abs(turn) <= max_turn + TURN_MARGIN), axis=1)))
    X = X[good]
    if not len(X):
        return []
    X = X[_dedupe_rows(_fk_key(msys, X), 1e-6)]
    Xp, rp = msys.polish(X)
    ok = rp <= polish_tol
    info["ms_polished"] = int(np.count_nonzero(ok))
    Xp, rp = Xp[ok], rp[ok]
    if not len(Xp):
        return []
    data = ms_rod_data(g, msys, Xp)
    checks = verify_fk(mech, inputs, load, data["pose"], data["forces"], data["tip_angles"], data["base_moments"],
                       tip_moments=data["tip_moments"])
    out = []
    for j, c in enumerate(checks):
        rods = []
        for i in range(3):
            kk = data["k"][j, i]
            kp = float(np.sqrt(abs(1.0 - kk * kk))) if kk <= 1 else float(np.sqrt(1.0 - 1.0 / (kk * kk)))
            rods.append(FKOracleRod(tip_force=data["forces"][j, i].copy(), base_moment=float(data["base_moments"][j, i]),
                                    tip_angle=float(data["tip_angles"][j, i]), clamp=data["A"][i].copy(),
                                    clamp_angle=float(data["al"][i]), length=float(data["L"][i]), EI=float(g.EI[i]),
                                    mode=int(data["modes"][j, i]), mode_ambiguous=bool(data["ambiguous"][j, i]),
                                    kprime=kp, R_dimless=float(data["R"][j, i]),
                                    tip_moment=float(data["tip_moments"][j, i]), turning=float(data["turning"][j, i]),
                                    joint=g.joint[i], k_value=float(kk) if g.clamped[i] else float("nan")))
        pose = data["pose"][j].copy()
        pose[2] = float(_wrap(pose[2]))
        s = FKOracleSolution(pose=pose, inputs=np.asarray(inputs, float).copy(), rods=tuple(rods),
                             residual=max(float(rp[j]), c["tip_shot"]), check=c, y=msys.reduce(Xp[j:j + 1])[0])
        extreme = s.extreme
        if s.residual > (1e-6 if extreme else VERIFY_TOL):
            info.setdefault("rejected", []).append((s.mode_label, s.pose.tolist(), s.residual))
            continue
        if return_all or (all(q <= max_mode for q in s.modes)
                          and all(abs(r.turning) <= max_turn for r in s.rods if r.joint == "clamped")):
            out.append(s)
    out.sort(key=lambda s: (s.modes, tuple(np.round(s.pose, 9))))
    return out


def ms_rod_data(g: Geom, msys: MSSystem, X, n_eval=1001):
    """Per solution and rod from polished multiple-shooting unknowns, with every segment integrated
    by DOP853 from its node: forces, base and tip moments, continuous tip angles, turning, d-modes
    (1 + sign changes of the moment strictly inside), boundary flags, k (first integral), R L^2/EI;
    and the poses, clamps."""
    X = np.atleast_2d(X)
    N, K = len(X), msys.K
    Fs, Ms = g.F_ref, g.F_ref * g.L_ref
    pose, u = msys.platform(X)
    A, al, L = msys.clamps(u)
    out = {k: np.zeros((N, 3)) for k in ("base_moments", "tip_moments", "tip_angles", "turning", "k", "R")}
    out["forces"] = np.zeros((N, 3, 2))
    out["modes"] = np.zeros((N, 3), np.int64)
    out["ambiguous"] = np.zeros((N, 3), bool)
    for i in range(3):
        o = i * msys.nr
        Li = L[:, i]
        ell = Li / K
        n = X[:, o:o + 2] * Fs
        th0 = np.empty((N, K)); m_s = np.empty((N, K))
        th0[:, 0], m_s[:, 0] = al[:, i], X[:, o + 2] * Ms
        for j in range(1, K):
            b = o + 3 + 4 * (j - 1)
            th0[:, j], m_s[:, j] = X[:, b + 2], X[:, b + 3] * Ms
        EI = g.EI[i]
        y = integrate_batch(np.repeat(n[:, 0] * ell**2 / EI, K), np.repeat(n[:, 1] * ell**2 / EI, K),
                            (m_s * (ell[:, None] / EI)).ravel(), th0.ravel(), n_eval=n_eval).reshape(4, N, K, n_eval)
        ms = y[3] * (EI / ell)[:, None, None]
        ms_all = np.concatenate([ms[:, 0]] + [ms[:, j, 1:] for j in range(1, K)], axis=1)
        thL, mL = y[2, :, -1, -1], ms[:, -1, -1]
        out["forces"][:, i] = n
        out["base_moments"][:, i] = m_s[:, 0]
        out["tip_moments"][:, i] = mL if g.clamped[i] else 0.0
        out["tip_angles"][:, i] = thL
        out["turning"][:, i] = thL - al[:, i]
        ax, ay = n[:, 0] * Li**2 / EI, n[:, 1] * Li**2 / EI
        out["R"][:, i] = np.hypot(ax, ay)
        for jn in range(N):
            out["modes"][jn, i] = count_inflections(ms_all[jn])
            out["ambiguous"][jn, i] = _mode_ambiguous(ms_all[jn], clamped=bool(g.clamped[i]))
            if g.clamped[i]:
                out["k"][jn, i] = elastica_k(ax[jn], ay[jn], thL[jn], mL[jn] * Li[jn] / EI)
            else:
                psi = np.arctan2(n[jn, 1], n[jn, 0])
                out["k"][jn, i] = abs(np.cos(0.5 * (thL[jn] - psi)))
    out["pose"] = pose
    out["A"], out["al"], out["L"] = A[0], al[0], L[0]
    return out
