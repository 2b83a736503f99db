"""Inverse kinematics of mechanisms with CLAMPED legs by tracing every leg's solution curve (test-only).

Used by ``ik_oracle.oracle_ik`` when some leg's rod is welded to the platform.  Nothing here
calls flexkin: the rods are integrated by ``clamped_chart.rk4_rods`` (RK4 + variational
equations) and ``ik_oracle.integrate_batch`` (DOP853), always in the multiple-shooting form of
``ms_shooting`` (K segments per rod), which stays well conditioned for taut rods.

For a fixed pose, leg i's rods that satisfy the rod's own equations (tip at B_i; clamped: tip
tangent theta_P + tip_angle, pinned: zero tip moment) form 1-D curves in (rod unknowns, input u)
(the paper's geometric-condition sets, §4.1).  The IK solutions are the triples of curve points
whose platform wrenches balance the load.  Method:

1. seeds: the input range is cut into slices; at every slice the canonical chart of clamped rods
   (``clamped_chart``; random rods for pinned legs) gives approximate rods, Newton-solved exactly
   with the input frozen;
2. curves: from seeds not yet covered, every curve is traced both ways by pseudo-arclength
   continuation (through the folds of the curve in u) until it leaves the search box (d-mode,
   turning up to max_turn + TURN_MARGIN, force, input range) or closes;
3. triples of curve points nearly in equilibrium are found by ``ik_oracle._triple_starts``
   (wrench balance linearised along the curves);
4. each triple is solved by a Newton iteration on the 3 platform equations in which every rod
   moves along its own curve (:func:`curve_newton`): rods never leave their branch;
5. all candidates (also from ``oracle_ik``'s random starts) are refined on the full
   multiple-shooting system (RK4), polished with DOP853 segments (rtol 1e-13) and built with
   densely sampled DOP853 segments (d-mode, tip moment, turning).
"""

from __future__ import annotations

import numpy as np
from ik_oracle import (
    OracleRod,
    OracleSolution,
    _dedupe_rows,
    _key,
    _mode_ambiguous,
    _System,
    _triple_starts,
    _triple_z,
    _wrap,
    count_inflections,
    elastica_k,
    integrate_batch,
)
from ms_shooting import LegMS, MSSystem

__all__ = ["TURN_MARGIN", "leg_samples", "curve_newton", "solve_clamped", "build_ms"]

#: the search box admits clamped rods turning by up to max_turn + TURN_MARGIN (rad): a margin for
#: candidates that converge inside the bound; the returned solutions obey |turning| <= max_turn
TURN_MARGIN = 0.5


# ======================================================================================
# seeds
# ======================================================================================
def leg_slices(sys: _System, i: int, n_u: int, L_max_factor=3.0):
    """Input grid of leg i: prismatic, the clamp positions within reach of B_i (|B_i - A| <= L);
    revolute, the full circle; length, free lengths from |B_i - origin| to ``L_max_factor`` times
    that.  Returns u (n_u,) SI (empty when B_i is out of reach)."""
    g = sys.g
    d = sys.B[i] - g.origin[i]
    k = g.kind[i]
    if k == "prismatic":
        e = np.array([np.cos(g.angle[i]), np.sin(g.angle[i])])
        proj = float(d @ e)
        h = abs(float(-e[1] * d[0] + e[0] * d[1]))
        if h >= g.length[i]:
            return np.zeros(0)
        half = np.sqrt(g.length[i] ** 2 - h * h)
        return np.linspace(proj - half, proj + half, n_u)
    if k == "revolute":
        return -np.pi + 2 * np.pi * (np.arange(n_u) + 0.5) / n_u
    r = float(np.hypot(*d))
    return np.linspace(r * 1.0005, L_max_factor * r, n_u)


def chart_seeds(sys: _System, i: int, u, max_mode, max_turn, R_max):
    """Approximate rods of clamped leg i at the inputs u (SI) from the canonical chart of clamped
    rods.  Returns (slice index, scaled q (n, 3))."""
    from clamped_chart import chart

    g = sys.g
    ch = chart(rho_max=float(np.sqrt(R_max)), max_turn=float(max_turn), mode_cap=max_mode + 1)
    A, al, L = g.clamp(i, np.asarray(u, float))
    A, al, L = np.asarray(A, float).reshape(-1, 2), np.asarray(al, float).reshape(-1), np.asarray(L, float).reshape(-1)
    d = (sys.B[i][None] - A) / L[:, None]
    c, s_ = np.cos(al), np.sin(al)
    Q = np.stack([c * d[:, 0] + s_ * d[:, 1], -s_ * d[:, 0] + c * d[:, 1], _wrap(sys.tip_th[i] - al)], 1)
    qi, tr, w, _sh = ch.locate(Q, max_mode=max_mode)
    if not len(qi):
        return np.zeros(0, np.int64), np.zeros((0, 3))
    p, _M, _md, _dP, _dM = ch.interp(tr, w)
    cq, sq, Lq = c[qi], s_[qi], L[qi]
    fx = (cq * p[:, 0] - sq * p[:, 1]) * g.EI[i] / Lq**2
    fy = (sq * p[:, 0] + cq * p[:, 1]) * g.EI[i] / Lq**2
    m0 = p[:, 2] * g.EI[i] / Lq
    return qi, np.stack([fx / g.F_ref, fy / g.F_ref, m0 / (g.F_ref * g.L_ref)], 1)


def random_seeds(sys: _System, i, u, R_range, per_slice, rng):
    """Random rods (force log-uniform, base moment inside the first-integral bound) at every slice."""
    g = sys.g
    jj = np.repeat(np.arange(len(u)), per_slice)
    Rd = np.exp(rng.uniform(np.log(R_range[0]), np.log(R_range[1]), len(jj)))
    ang = rng.uniform(0, 2 * np.pi, len(jj))
    L = g.length[i] if g.kind[i] != "length" else u[jj]
    f = Rd * g.EI[i] / L**2 / g.F_ref
    q = np.column_stack([f * np.cos(ang), f * np.sin(ang),
                         2 * np.sqrt(Rd) * rng.uniform(-1, 1, len(jj)) * g.EI[i] / L / (g.F_ref * g.L_ref)])
    return jj, q


def dedupe_slices(jj, q, tol=1e-6):
    """Indices of unique (slice, q) pairs (inf-norm of q / (1 + |q|) within ``tol`` at one slice)."""
    from scipy.spatial import cKDTree

    if not len(jj):
        return np.zeros(0, np.int64)
    X = np.column_stack([jj * 1e3, q / (1.0 + np.abs(q))])
    pairs = cKDTree(X).query_pairs(tol, p=np.inf, output_type="ndarray")
    drop = np.zeros(len(jj), bool)
    if len(pairs):
        for a, b in pairs[np.lexsort((pairs[:, 1], pairs[:, 0]))]:
            if not drop[a]:
                drop[b] = True
    return np.flatnonzero(~drop)


# ======================================================================================
# one leg: Newton at a frozen input, curve metric, tangent, pseudo-arclength steps
# ======================================================================================
def leg_newton(leg: LegMS, x, n_iter=20, tol=1e-10, blow=5e3):
    """Damped Newton on the leg's rows with its input frozen.  Returns x, ok."""
    g, i = leg.g, leg.i
    x = np.array(x, float)
    M = len(x)
    ok = np.zeros(M, bool)
    active = np.ones(M, bool)
    for it in range(n_iter + 1):
        idx = np.flatnonzero(active)
        if not idx.size:
            break
        o = leg.eval(x[idx])
        rn = np.max(np.abs(o["R"]), axis=1)
        done = rn < tol
        ok[idx[done]] = True
        if it == n_iter:
            break
        with np.errstate(all="ignore"):
            try:
                step = -np.linalg.solve(o["Jr"], o["R"][..., None])[..., 0]
            except np.linalg.LinAlgError:
                step = np.full(o["R"].shape, np.nan)
                for k in range(len(idx)):
                    try:
                        step[k] = -np.linalg.solve(o["Jr"][k], o["R"][k])
                    except np.linalg.LinAlgError:
                        pass
        good = np.all(np.isfinite(step), axis=1)
        step[~good] = 0.0
        fs = g.F_ref * o["L"] ** 2 / g.EI[i]
        Rd = np.hypot(x[idx, 0], x[idx, 1]) * fs
        lim = np.hypot(step[:, 0], step[:, 1]) * fs / (0.5 * Rd + 3.0)
        if leg.K > 1:
            lim = np.maximum(lim, np.max(np.abs(step[:, 3 + 4 * np.arange(leg.K - 1) + 2]), axis=1) / 0.5)
        else:
            mtd = np.abs(step[:, 2]) * g.F_ref * g.L_ref * o["L"] / g.EI[i]
            lim = np.maximum(lim, mtd / (0.5 * np.sqrt(Rd) + 1.0 + 0.25 * np.abs(x[idx, 2])))
        step *= (1.0 / np.maximum(lim, 1.0))[:, None]
        upd = ~done & good
        xi = x[idx]
        xi[upd, :-1] += step[upd]
        x[idx] = xi
        active[idx[done | ~good | (Rd > blow)]] = False
    return x, ok


def weights(x, du_ref, frac=0.15):
    """Curve metric on a leg's unknowns (M, 4K): a unit step changes the tip force by ``frac``
    (relative, + frac F_ref), the base moment by ``frac`` (+ frac F_ref L_ref) or the scaled input
    by ``du_ref``; the node states carry no weight (they follow)."""
    M, n = x.shape
    c = np.zeros((M, n))
    qF = np.hypot(x[:, 0], x[:, 1])
    c[:, 0] = c[:, 1] = 1.0 / (frac * (1.0 + qF))
    c[:, 2] = 1.0 / (frac * (1.0 + np.abs(x[:, 2])))
    c[:, -1] = 1.0 / du_ref
    return c


def tangent(J, c, prev=None):
    """Unit tangent (weighted metric ``c``) of the curve with Jacobian J (M, n-1, n): the null
    vector, from a complete QR factorisation of J^T; oriented along ``prev`` if given."""
    with np.errstate(all="ignore"):
        Q, _ = np.linalg.qr(np.transpose(J, (0, 2, 1)), mode="complete")
        t = Q[:, :, -1]
        t = t / np.linalg.norm(t * c, axis=1)[:, None]
    if prev is not None:
        flip = np.sum(t * prev * c * c, axis=1) < 0
        t = np.where(flip[:, None], -t, t)
    return t


def state(leg: LegMS, x, du_ref, prev=None):
    """The leg at x: evaluation dict, scaled platform wrench W (M, 3), unit tangent t (M, 4K) and
    dW/dsigma (M, 3) along it."""
    o = leg.eval(x)
    W, dWdx = leg.wrench(x, o)
    t = tangent(o["J"], weights(x, du_ref), prev)
    return o, W, t, np.einsum("nkj,nj->nk", dWdx, t)


def move(leg: LegMS, x, t, ds, du_ref, n_iter=8, tol=1e-11):
    """Pseudo-arclength step: predictor x + t ds, corrector Newton on the leg's rows plus the
    hyperplane through the predictor normal to t (weighted metric).  Returns x, ok."""
    xp = x + t * ds[:, None]
    c = weights(x, du_ref)
    nv = c * c * t
    xn = xp.copy()
    ok = np.zeros(len(x), bool)
    active = np.ones(len(x), bool)
    for it in range(n_iter + 1):
        idx = np.flatnonzero(active)
        if not idx.size:
            break
        o = leg.eval(xn[idx])
        h = np.sum(nv[idx] * (xn[idx] - xp[idx]), axis=1)
        rn = np.max(np.abs(o["R"]), axis=1)
        done = rn < tol
        ok[idx[done]] = True
        if it == n_iter:
            break
        J = np.concatenate([o["J"], nv[idx][:, None, :]], axis=1)
        F = np.column_stack([o["R"], h])
        with np.errstate(all="ignore"):
            try:
                stp = -np.linalg.solve(J, F[..., None])[..., 0]
            except np.linalg.LinAlgError:
                stp = np.full(F.shape, np.nan)
                for k in range(len(idx)):
                    try:
                        stp[k] = -np.linalg.solve(J[k], F[k])
                    except np.linalg.LinAlgError:
                        pass
        bad = ~np.all(np.isfinite(stp), axis=1) | (np.max(np.abs(stp * c[idx]), axis=1) > 2.0)
        if leg.K > 1:
            bad |= np.max(np.abs(stp[:, 3 + 4 * np.arange(leg.K - 1) + 2]), axis=1) > 1.0
        upd = ~done & ~bad
        xn[idx[upd]] += stp[upd]
        active[idx[done | bad]] = False
    return xn, ok


def in_box(leg: LegMS, o, x, u_box, R_max, max_mode, max_turn):
    """Points inside the search box: d-mode (RK4) <= max_mode + 1, |turning| <= max_turn + TURN_MARGIN,
    R L^2/EI <= 1.5 R_max, the scaled input within ``u_box`` (None: periodic)."""
    g = leg.g
    Rd = np.hypot(x[:, 0], x[:, 1]) * g.F_ref * o["L"] ** 2 / g.EI[leg.i]
    ok = (o["changes"] + 1 <= max_mode + 1) & (np.abs(o["turning"]) <= max_turn + TURN_MARGIN) & (Rd <= 1.5 * R_max)
    if u_box is not None:
        ok &= (x[:, -1] >= u_box[0]) & (x[:, -1] <= u_box[1])
    return ok


def trace(leg: LegMS, x, du_ref, u_box, R_max, max_mode, max_turn, max_steps=400):
    """Trace the leg's curve from the points x (exact) both ways (unit nominal steps, halved on
    failure down to 1/64, grown after successes) until it leaves the search box, closes on its
    start, or after ``max_steps``.  Returns the traced points (incl. the starts) and a tracer id per
    point."""
    M = len(x)
    X = np.concatenate([x, x])
    start = X.copy()
    o0 = leg.eval(x)
    t0 = tangent(o0["J"], weights(x, du_ref))
    T = np.concatenate([t0, -t0])
    ds = np.ones(2 * M)
    steps = np.zeros(2 * M, np.int64)
    alive = np.all(np.isfinite(T), axis=1)
    tid = np.arange(2 * M) % M
    out_x, out_id = [x], [np.arange(M)]
    while np.any(alive):
        idx = np.flatnonzero(alive)
        xn, ok = move(leg, X[idx], T[idx], ds[idx], du_ref)
        fail = idx[~ok]
        ds[fail] *= 0.5
        alive[fail[ds[fail] < 1.0 / 64]] = False
        k = idx[ok]
        if not k.size:
            continue
        xn = xn[ok]
        o = leg.eval(xn)
        inb = in_box(leg, o, xn, u_box, R_max, max_mode, max_turn)
        c = weights(xn, du_ref)
        tn = tangent(o["J"], c, T[k])
        fin = np.all(np.isfinite(tn), axis=1)
        keep = inb & fin
        X[k] = xn
        T[k] = np.where(fin[:, None], tn, T[k])
        ds[k] = np.minimum(ds[k] * 1.5, 1.0)
        steps[k] += 1
        out_x.append(xn[keep]); out_id.append(tid[k][keep])
        closed = (steps[k] >= 4) & (np.max(np.abs((xn - start[k]) * c), axis=1) < 0.7)
        alive[k[~keep | closed | (steps[k] >= max_steps)]] = False
    return np.concatenate(out_x), np.concatenate(out_id)


def leg_samples(sys: _System, i: int, R_range, max_mode, max_turn, K=4, n_u=121, batch=64, stats=None, seed=0):
    """Points of leg i's solution curves (see the module docstring), for ``ik_oracle._triple_starts``.

    Returns a dict: ``u`` (SI), ``n`` (world tip force), ``m0``, ``w`` (scaled platform wrench:
    force, moment ``(B_i - P) x n + m(L)``), ``T`` (dW per nominal step along the curve), ``sp``
    (|T|), ``cell`` (point rank along its tracer, 3 x tracer id: clusters of the triple search),
    ``dz`` (change of the scaled (q, u) per nominal step), ``x`` (the leg's multiple-shooting
    unknowns), ``du_ref`` (the curve metric's input unit)."""
    from scipy.spatial import cKDTree

    g = sys.g
    u = leg_slices(sys, i, n_u)
    keys = {"u": (), "n": (2,), "m0": (), "w": (3,), "sp": (), "T": (3,), "cell": (2,), "dz": (4,),
            "x": (4 * K,), "du_ref": ()}
    empty = {k: np.zeros((0,) + sh) for k, sh in keys.items()}
    if not len(u):
        return empty
    leg = LegMS(g, i, sys.pose, K=K)
    us = sys.us[i]
    du_ref = (u[-1] - u[0]) / 40.0 / us  # about 40 nominal steps across the input range
    periodic = g.kind[i] == "revolute"
    du = u[1] - u[0]
    u_box = None if periodic else ((u[0] - 0.5 * du) / us, (u[-1] + 0.5 * du) / us)
    R_max = R_range[1]
    if sys.cl[i]:
        jj, q = chart_seeds(sys, i, u, max_mode, max_turn, R_max)
    else:
        jj, q = random_seeds(sys, i, u, R_range, 24, np.random.default_rng(12345 + 17 * i + seed))
    n_seeds = len(jj)
    sel = dedupe_slices(jj, q, tol=0.02)  # near-identical seeds converge to the same rod
    jj, q = jj[sel], q[sel]
    x = leg.expand(q, u[jj] / us) if len(jj) else np.zeros((0, 4 * K))
    x, ok = leg_newton(leg, x)
    x, jj = x[ok], jj[ok]
    if len(x):
        inb = in_box(leg, leg.eval(x, jac=False), x, None, R_max, max_mode, max_turn)
        x, jj = x[inb], jj[inb]
    sel = dedupe_slices(jj, x[:, :3])
    x, jj = x[sel], jj[sel]
    covered = np.zeros(len(x), bool)
    TX, TI = [], []
    n_traced = rounds = 0
    while not np.all(covered):
        rounds += 1
        cand = np.flatnonzero(~covered)
        Y = x[cand] * weights(x[cand], du_ref)
        pick = []
        for k in range(len(cand)):  # seeds at least 3 nominal steps apart
            if len(pick) >= batch:
                break
            if not pick or np.min(np.max(np.abs(Y[pick] - Y[k]), axis=1)) > 3.0:
                pick.append(k)
        pk = cand[pick]
        tx, tid = trace(leg, x[pk], du_ref, u_box, R_max, max_mode, max_turn)
        TX.append(tx); TI.append(tid + n_traced)
        n_traced += len(pk)
        covered[pk] = True
        rest = np.flatnonzero(~covered)
        if len(rest):
            # covered: within 0.75 nominal steps of a traced point (traced points are at most one
            # step apart) with the same turning (distinct branches may come close in (q, u))
            tree = cKDTree(tx * weights(tx, du_ref))
            d, j = tree.query(x[rest] * weights(x[rest], du_ref), k=4, p=np.inf, distance_upper_bound=0.75)
            tt = leg.eval(tx, jac=False)["turning"]
            tr = leg.eval(x[rest], jac=False)["turning"]
            fin = np.isfinite(d)
            jj_ = np.where(fin, j, 0)
            same = fin & (np.abs(tt[jj_] - tr[:, None]) < 0.5)
            covered[rest[np.any(same, axis=1)]] = True
    if not TX:
        return empty
    tx, tid = np.concatenate(TX), np.concatenate(TI)
    if periodic:
        tx[:, -1] = np.angle(np.exp(1j * tx[:, -1] * us)) / us
    o, W, t, dW = state(leg, tx, du_ref)
    keep = in_box(leg, o, tx, None, R_max, max_mode, max_turn) & np.all(np.isfinite(dW), axis=1)
    if stats is not None:
        stats.setdefault("leg_curves", []).append({"leg": i, "seeds": n_seeds, "distinct_seeds": int(len(x)),
                                                   "tracers": n_traced, "rounds": rounds,
                                                   "points": int(np.count_nonzero(keep))})
    if not np.any(keep):
        return empty
    tx, tid, W, t, dW = tx[keep], tid[keep], W[keep], t[keep], dW[keep]
    order = np.lexsort((np.arange(len(tid)), tid))
    rank = np.empty(len(tid), np.int64)
    rank[order] = np.arange(len(tid)) - np.searchsorted(tid[order], tid[order], "left")
    return {"u": tx[:, -1] * us, "n": tx[:, :2] * g.F_ref, "m0": tx[:, 2] * g.F_ref * g.L_ref, "w": W,
            "sp": np.linalg.norm(dW, axis=1) + 1e-9, "T": dW, "cell": np.column_stack([rank, 3 * tid]),
            "dz": t[:, [0, 1, 2, -1]], "x": tx, "du_ref": np.full(len(tx), du_ref)}


# ======================================================================================
# Newton along the curves
# ======================================================================================
def curve_newton(legs, X, du_ref, ds0=None, n_iter=15, tol=1e-9, max_ds=2.0, target=np.zeros(3)):
    """Newton on the three platform equations with every rod kept on its leg's curve.

    ``legs``: three :class:`LegMS`; ``X`` (N, 3, 4K) exact points of the three curves; ``du_ref``
    (3,) the curve metrics; ``ds0`` (N, 3) an optional first step (in nominal steps).  Each
    iteration computes every leg's wrench and its derivative along the curve (:func:`state`),
    solves the 3 x 3 system for the arclength steps (damped to ``max_ds``) and moves every rod along
    its curve (:func:`move`; the step is halved up to three times when a corrector fails).  Rods
    never leave their branch and folds of the curves in u are no obstacle.  Returns X, the
    equilibrium residual (inf-norm, scaled) and a success mask."""
    X = np.array(X, float)
    N = len(X)
    alive = np.ones(N, bool)
    res = np.full(N, np.inf)
    first = ds0 is not None
    for it in range(n_iter + 1):
        idx = np.flatnonzero(alive)
        if not idx.size:
            break
        Ws, dWs, ts = [], [], []
        for i in range(3):
            _o, W, t, dW = state(legs[i], X[idx, i], du_ref[i])
            Ws.append(W); dWs.append(dW); ts.append(t)
        F = Ws[0] + Ws[1] + Ws[2] - target
        rn = np.max(np.abs(F), axis=1)
        res[idx] = rn
        done = rn < tol
        alive[idx[done]] = False
        if it == n_iter:
            break
        if first:
            step = np.asarray(ds0, float)[idx]
            first = False
        else:
            with np.errstate(all="ignore"):
                try:
                    step = -np.linalg.solve(np.stack(dWs, -1), F[..., None])[..., 0]
                except np.linalg.LinAlgError:
                    step = np.full(F.shape, np.nan)
        ok = np.all(np.isfinite(step), axis=1)
        for t in ts:
            ok &= np.all(np.isfinite(t), axis=1)
        alive[idx[~ok]] = False
        sel = ~done & ok
        idx, step = idx[sel], step[sel]
        ts = [t[sel] for t in ts]
        if not idx.size:
            continue
        step = step / np.maximum(np.max(np.abs(step), axis=1) / max_ds, 1.0)[:, None]
        todo = np.ones(len(idx), bool)
        for _half in range(4):
            k = np.flatnonzero(todo)
            if not k.size:
                break
            xn = np.empty((len(k),) + X.shape[1:])
            good = np.ones(len(k), bool)
            for i in range(3):
                xn[:, i], okc = move(legs[i], X[idx[k], i], ts[i][k], step[k, i], du_ref[i])
                good &= okc
            kk = k[good]
            X[idx[kk]] = xn[good]
            todo[kk] = False
            step[k[~good]] *= 0.5
        alive[idx[todo]] = False
    return X, res, res < tol


def to_ms(msys: MSSystem, Xl):
    """Full multiple-shooting unknowns (N, 12 K) from the three legs' unknowns (N, 3, 4 K)."""
    return np.concatenate([Xl[:, 0, :-1], Xl[:, 1, :-1], Xl[:, 2, :-1], Xl[:, :, -1]], axis=1)


def curve_candidates(sys: _System, msys: MSSystem, R_range, max_mode, max_turn, max_starts, s_max, k_near, info,
                     pred_tol=0.02):
    """Candidates (multiple-shooting unknowns, RK4-converged) from the legs' curves: the triples of
    curve points nearly in equilibrium (``ik_oracle._triple_starts``, linear coefficients kept),
    merged when they predict the same solution (within ``pred_tol``, normalised), the best
    ``max_starts`` solved by :func:`curve_newton`."""
    from scipy.spatial import cKDTree

    g = sys.g
    K = msys.K
    samples = [leg_samples(sys, i, R_range, max_mode, max_turn, K=K, stats=info) for i in range(3)]
    info["leg_samples"] = [len(s_["u"]) for s_ in samples]
    # every other traced point is enough for the linearised matching (|s| <= s_max nominal steps)
    samples = [{k: v[s_["cell"][:, 0] % 2 == 0] for k, v in s_.items()} for s_ in samples]
    P, Ps = _triple_starts(sys, samples, 400000, k_near=max(k_near, 4), s_max=s_max, return_s=True)
    info["triple_clusters"] = len(P)
    if not len(P):
        return np.zeros((0, msys.n))
    zp = _triple_z(sys, samples, P, Ps)
    kz = zp / (1.0 + np.abs(zp))
    tree = cKDTree(kz)
    order = np.argsort(np.max(np.abs(Ps), axis=1), kind="stable")
    taken = np.zeros(len(P), bool)
    keep = []
    for k in order:
        if taken[k]:
            continue
        keep.append(k)
        taken[tree.query_ball_point(kz[k], pred_tol, p=np.inf)] = True
        if len(keep) >= max_starts:
            break
    keep = np.array(keep)
    info["curve_starts"] = len(keep)
    legs = [LegMS(g, i, sys.pose, K=K) for i in range(3)]
    Xl = np.stack([samples[i]["x"][P[keep, i]] for i in range(3)], 1)
    du_ref = np.array([samples[i]["du_ref"][0] for i in range(3)])
    target = np.array([sys.load[0] / g.F_ref, sys.load[1] / g.F_ref, sys.load[2] / (g.F_ref * g.L_ref)])
    Xl, _res, ok = curve_newton(legs, Xl, du_ref, ds0=np.clip(Ps[keep], -2.0, 2.0), target=target)
    info["curve_converged"] = int(np.count_nonzero(ok))
    return to_ms(msys, Xl[ok])


# ======================================================================================
# refine, polish, build
# ======================================================================================
def build_ms(sys: _System, msys: MSSystem, X, res, n_eval=1001) -> list[OracleSolution]:
    """Solutions from polished multiple-shooting unknowns: every segment integrated by DOP853 from
    its node (rtol 1e-13, ``n_eval`` samples per segment) for the d-mode (1 + sign changes of the
    moment strictly inside the rod), the tip moment, the turning and k."""
    X = np.atleast_2d(X)
    N = len(X)
    if not N:
        return []
    g, K = sys.g, msys.K
    Z = msys.reduce(X)
    n, u, A, al, L, ax, ay, mt = sys.rod_params(Z)
    out = []
    Ms = g.F_ref * g.L_ref
    per_rod = []
    for i in range(3):
        o = i * msys.nr
        ell = L[:, i] / K
        th0 = np.empty((N, K)); m_s = np.empty((N, K))
        th0[:, 0], m_s[:, 0] = al[:, i], X[:, o + 2] * Ms
        for j in range(1, K):
            b = o + 3 + 4 * (j - 1)
            th0[:, j], m_s[:, j] = X[:, b + 2], X[:, b + 3] * Ms
        EI = g.EI[i]
        sax = np.repeat(n[:, i, 0] * ell**2 / EI, K)
        say = np.repeat(n[:, i, 1] * ell**2 / EI, K)
        smt = (m_s * (ell[:, None] / EI)).ravel()
        y = integrate_batch(sax, say, smt, th0.ravel(), n_eval=n_eval).reshape(4, N, K, n_eval)
        ms = y[3] * (EI / ell)[:, None, None]  # (N, K, n_eval) physical moments
        ms_all = np.concatenate([ms[:, 0]] + [ms[:, j, 1:] for j in range(1, K)], axis=1)
        per_rod.append((ms_all, y[2, :, -1, -1], ms[:, -1, -1], y[2, :, -1, -1] - al[:, i]))
    for jn in range(N):
        rods = []
        for i in range(3):
            ms_all, thL, mL, turn = per_rod[i]
            cl = bool(sys.cl[i])
            if cl:
                kk = elastica_k(ax[jn, i], ay[jn, i], thL[jn], mL[jn] * L[jn, i] / g.EI[i])
            else:
                psi = np.arctan2(n[jn, i, 1], n[jn, i, 0])
                kk = abs(np.cos(0.5 * (thL[jn] - psi)))
            rods.append(OracleRod(tip_force=n[jn, i, :2].copy(), base_moment=float(n[jn, i, 2]),
                                  clamp=A[jn, i].copy(), clamp_angle=float(al[jn, i]), length=float(L[jn, i]),
                                  EI=float(g.EI[i]), mode=count_inflections(ms_all[jn]),
                                  mode_ambiguous=_mode_ambiguous(ms_all[jn], clamped=cl), k=float(kk),
                                  R_dimless=float(np.hypot(ax[jn, i], ay[jn, i])),
                                  tip_moment=float(mL[jn]) if cl else 0.0, turning=float(turn[jn]),
                                  tip_angle=float(thL[jn]), joint=g.joint[i]))
        out.append(OracleSolution(inputs=u[jn].copy(), rods=tuple(rods), residual=float(res[jn]), z=Z[jn].copy(),
                                  pose=sys.pose.copy()))
    return out


def solve_clamped(sys: _System, z_found, R_range, max_mode, max_turn, return_all, max_starts, s_max, k_near, info,
                  K=4, polish_tol=1e-9):
    """All IK solutions of a mechanism with clamped legs: the candidates ``z_found`` (12-unknown
    vectors, e.g. from random starts) and those of the legs' curves (:func:`curve_candidates`,
    unless ``max_starts`` is 0) are refined on the multiple-shooting system (K segments, RK4),
    de-duplicated, polished with DOP853 segments and kept when the tight residual is <=
    ``polish_tol``, every d-mode <= max_mode and every clamped |turning| <= max_turn (all if
    ``return_all``).  Returns :class:`ik_oracle.OracleSolution` items sorted by (modes, inputs)."""
    msys = MSSystem(sys.g, "ik", sys.pose, sys.load, K=K)
    parts = []
    if len(z_found):
        parts.append(msys.expand(np.asarray(z_found, float).reshape(-1, 12)))
    if max_starts:
        parts.append(curve_candidates(sys, msys, R_range, max_mode, max_turn, max_starts, s_max, k_near, info))
    X = np.concatenate(parts) if parts else np.zeros((0, msys.n))
    info["ms_candidates"] = len(X)
    if not len(X):
        return []
    Z = msys.reduce(X)
    keep = _dedupe_rows(_key(sys, Z), 1e-6)
    X = X[keep]
    fine = MSSystem(sys.g, "ik", sys.pose, sys.load, K=K, n_min=64, per_lambda=16.0)
    X, rn, ch, turn = fine.newton(X, n_iter=10, tol=1e-11)
    good = (rn < 1e-7) & (return_all | (np.all(ch <= max_mode + 1, axis=1)
                                        & np.all(~sys.cl[None] | (np.abs(turn) <= max_turn + TURN_MARGIN), axis=1)))
    X = X[good]
    if not len(X):
        return []
    X = X[_dedupe_rows(_key(sys, msys.reduce(X)), 1e-6)]
    Xp, rp = msys.polish(X)
    ok = rp <= polish_tol
    info["ms_polished"] = int(np.count_nonzero(ok))
    sols = []
    for s_ in build_ms(sys, msys, Xp[ok], rp[ok]):
        if return_all or (all(q <= max_mode for q in s_.modes)
                          and all(abs(r.turning) <= max_turn for r in s_.rods if r.joint == "clamped")):
            sols.append(s_)
    if sols:
        keys = np.array([_key(sys, s_.z) for s_ in sols]).reshape(-1, 12)
        sols = [sols[i] for i in _dedupe_rows(keys, 1e-7)]
    sols.sort(key=lambda s_: (s_.modes, tuple(np.round(s_.inputs, 9))))
    return sols
