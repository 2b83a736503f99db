"""A canonical chart of all clamped rods, with point location in tip space (test-only seeding tool).

Used by ``ik_oracle`` and ``fk_oracle`` to seed their shooting for rods whose tip is CLAMPED to
the platform (tip position and tip tangent prescribed).  Independent of flexkin: plain RK4 of the
rod equations (paper Eqs. 5, 7) in the canonical frame.

Canonical rod: clamp at the origin with tangent along +x, unit length and EI.  It is fixed by its
(constant) tip force ``(ax, ay)`` (dimensionless, ``n L^2 / EI`` in the clamp frame) and its base
moment ``mt`` (``m0 L / EI``); its tip state is ``Q = (X, Y, Theta)`` (position, continuous tangent
angle = the turning of the rod) and its tip moment ``M`` (``m(L) L / EI``).  A rod of any leg is a
canonical rod rotated by its clamp angle, translated to its clamp and scaled by its length.

Chart: a grid over ``(xi, eta, s)`` with force ``(ax, ay) = rho (xi, eta)``, ``rho = |(xi, eta)|``
(so ``|n| L^2/EI = rho^2``; resolution in ``rho`` ~ resolution in Lambda = sqrt(R L^2/EI)) and base
moment ``mt = s (2 rho + max_turn + 2)``, ``s in [-1, 1]``: the first-integral bound ``2 rho`` of
inflectional rods plus room for non-inflectional rods whose tangent turns by up to ``max_turn``.
Every grid cube is cut into 6 tetrahedra (Kuhn); on a tetrahedron the chart is replaced by the
affine interpolant of its vertices, so a target tip state ``Q`` (taken modulo 2 pi in Theta: every
``Theta + 2 pi k`` in the chart's range is tried) lies in finitely many tetrahedra, each giving an
approximate rod (``ax, ay, mt``, tip moment) and its derivatives with respect to ``Q``.  The
tetrahedra are bucketed by their bounding boxes in a hierarchy of bucket sizes (as the pinned-rod
sheets of ``fk_oracle``).  Approximate by construction: only for seeding Newton.
"""

from __future__ import annotations

import numpy as np

try:  # numba (a flexkin dependency) makes the per-rod loops fast; numpy fallbacks otherwise
    from numba import njit
except ImportError:  # pragma: no cover
    njit = None

__all__ = ["ClampedChart", "bucket_hits", "bucket_spans", "chart", "rk4_rods", "rk4_step", "steps_for"]

_CACHE: dict = {}


# ======================================================================================
# RK4 of unit rods with per-rod step counts (numba), with the variational equations
# ======================================================================================
def steps_for(ax, ay, mt, n_min=64, n_max=1024, per_lambda=8.0, per_m=2.0):
    """Steps per unit rod: about ``per_lambda`` per unit of ``Lambda = sqrt(|(ax, ay)|)`` plus
    ``per_m`` per unit of the base moment ``|mt|`` (the curvature scale), clipped to [n_min, n_max]."""
    need = per_lambda * np.sqrt(np.hypot(ax, ay)) + per_m * np.abs(mt)
    return np.clip(np.ceil(need), n_min, n_max).astype(np.int64)


def _rk4_rods_py(ax, ay, mt, th0, steps, var):
    M = len(ax)
    Z = np.zeros((4, M))
    S = np.zeros((4, 4, M))
    ch = np.zeros(M, np.int64)
    for ns in np.unique(steps):
        k = np.flatnonzero(steps == ns)
        z = np.zeros((4, len(k)))
        z[2] = th0[k]
        z[3] = mt[k]
        Sk = np.zeros((4, 4, len(k)))
        Sk[2, 3] = 1.0
        Sk[3, 2] = 1.0
        a, b = ax[k], ay[k]
        h = 1.0 / ns
        ex = np.zeros((4, len(k))); ex[0] = 1.0
        ey = np.zeros((4, len(k))); ey[1] = 1.0

        def f(z, S):
            c, s = np.cos(z[2]), np.sin(z[2])
            dz = np.stack([c, s, z[3], a * s - b * c])
            dth = S[:, 2]
            dS = np.stack([-s * dth, c * dth, S[:, 3], (a * c + b * s) * dth + ex * s - ey * c], axis=1)
            return dz, dS

        last = np.sign(mt[k])
        cc = np.zeros(len(k), np.int64)
        for j in range(int(ns)):
            k1, l1 = f(z, Sk)
            k2, l2 = f(z + 0.5 * h * k1, Sk + 0.5 * h * l1)
            k3, l3 = f(z + 0.5 * h * k2, Sk + 0.5 * h * l2)
            k4, l4 = f(z + h * k3, Sk + h * l3)
            z = z + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)
            Sk = Sk + (h / 6.0) * (l1 + 2 * l2 + 2 * l3 + l4)
            if j < ns - 1:
                sg = np.sign(z[3])
                cc += (sg * last < 0)
                last = np.where(sg != 0, sg, last)
        Z[:, k] = z
        S[:, :, k] = Sk
        ch[k] = cc
    return Z, S, ch


if njit is not None:
    @njit(cache=True, fastmath=False)
    def _rk4_rods_nb(ax, ay, mt, th0, steps, var):  # pragma: no cover - compiled
        M = ax.shape[0]
        Z = np.zeros((4, M))
        S = np.zeros((4, 4, M))
        ch = np.zeros(M, np.int64)
        y = np.zeros(20)
        k = np.zeros((4, 20))
        t = np.zeros(20)
        nv = 20 if var else 4
        for r in range(M):
            a = ax[r]
            b = ay[r]
            ns = steps[r]
            h = 1.0 / ns
            for q in range(20):
                y[q] = 0.0
            y[2] = th0[r]
            y[3] = mt[r]
            # S[p, s] stored at 4 + 4 p + s: d state s / d param p; params (ax, ay, mt, th0)
            y[4 + 4 * 2 + 3] = 1.0
            y[4 + 4 * 3 + 2] = 1.0
            last = np.sign(mt[r])
            cc = 0
            for j in range(ns):
                for stage in range(4):
                    if stage == 0:
                        for q in range(nv):
                            t[q] = y[q]
                    elif stage == 3:
                        for q in range(nv):
                            t[q] = y[q] + h * k[2, q]
                    else:
                        for q in range(nv):
                            t[q] = y[q] + 0.5 * h * k[stage - 1, q]
                    c = np.cos(t[2])
                    s = np.sin(t[2])
                    k[stage, 0] = c
                    k[stage, 1] = s
                    k[stage, 2] = t[3]
                    k[stage, 3] = a * s - b * c
                    if var:
                        g = a * c + b * s
                        for p in range(4):
                            o = 4 + 4 * p
                            dth = t[o + 2]
                            k[stage, o + 0] = -s * dth
                            k[stage, o + 1] = c * dth
                            k[stage, o + 2] = t[o + 3]
                            extra = 0.0
                            if p == 0:
                                extra = s
                            elif p == 1:
                                extra = -c
                            k[stage, o + 3] = g * dth + extra
                for q in range(nv):
                    y[q] += (h / 6.0) * (k[0, q] + 2.0 * k[1, q] + 2.0 * k[2, q] + k[3, q])
                if j < ns - 1:
                    sg = np.sign(y[3])
                    if sg * last < 0:
                        cc += 1
                    if sg != 0:
                        last = sg
            for q in range(4):
                Z[q, r] = y[q]
            if var:
                for p in range(4):
                    for q in range(4):
                        S[p, q, r] = y[4 + 4 * p + q]
            ch[r] = cc
        return Z, S, ch


def rk4_rods(ax, ay, mt, th0, steps, var=True):
    """Unit rods (L = EI = 1): dimensionless force ``(ax, ay)``, base moment ``mt``, clamp angle
    ``th0``, integrated by RK4 with ``steps`` (per rod) steps.  Returns the tip states Z (4, M)
    = (x, y, theta, m), the sensitivities S (4 params (ax, ay, mt, th0), 4 states, M) (zeros if
    not ``var``) and the number of sign changes of the moment at the interior RK4 nodes (M,)."""
    ax, ay, mt, th0 = (np.ascontiguousarray(np.asarray(v, float).ravel()) for v in (ax, ay, mt, th0))
    steps = np.ascontiguousarray(np.broadcast_to(np.asarray(steps, np.int64), ax.shape))
    if njit is not None:
        return _rk4_rods_nb(ax, ay, mt, th0, steps, bool(var))
    return _rk4_rods_py(ax, ay, mt, th0, steps, var)  # pragma: no cover


def _rk4_canonical(ax, ay, mt, n_steps):
    """Unit rods from the canonical clamp: tip (X, Y, Theta, M) and d-mode (1 + interior sign
    changes of the moment at the RK4 nodes)."""
    if njit is not None:
        Z, _S, ch = rk4_rods(ax, ay, mt, np.zeros(len(ax)), n_steps, var=False)
        return Z, 1 + ch
    M = len(ax)
    z = np.zeros((4, M))
    z[3] = mt
    h = 1.0 / n_steps

    def f(z):
        c, s = np.cos(z[2]), np.sin(z[2])
        return np.stack([c, s, z[3], ax * s - ay * c])

    changes = np.zeros(M, np.int64)
    last = np.sign(mt)
    for j in range(n_steps):
        z = rk4_step(f, z, h)
        if j < n_steps - 1:
            sg = np.sign(z[3])
            changes += (sg * last < 0)
            last = np.where(sg != 0, sg, last)
    return z, 1 + changes


def rk4_step(f, z, h):
    """One classical Runge-Kutta step of ``z' = f(z)`` (autonomous) with step ``h``."""
    k1 = f(z)
    k2 = f(z + 0.5 * h * k1)
    k3 = f(z + 0.5 * h * k2)
    k4 = f(z + h * k3)
    return z + (h / 6.0) * (k1 + 2 * k2 + 2 * k3 + k4)


def bucket_spans(lo, hi, origin, h, cap, last):
    """Buckets of size ``h`` (grid from ``origin``) overlapped by the boxes ``[lo, hi]`` (n, d):
    boxes overlapping at most ``cap`` buckets (all if ``last``) ``fits``; for each (box,
    bucket) pair, ``rep`` (box index among the fitting ones) and ``k`` (the bucket's running
    number within its box, row-major over ``span``); ``blo``, ``bhi``, ``span`` per box."""
    blo = np.floor((lo - origin) / h).astype(np.int64)
    bhi = np.floor((hi - origin) / h).astype(np.int64)
    span = bhi - blo + 1
    cnt = np.prod(span, axis=1)
    fits = np.ones(len(lo), bool) if last else cnt <= cap
    sm = np.flatnonzero(fits)
    c_sm = cnt[sm]
    rep = np.repeat(sm, c_sm)
    k = np.arange(len(rep)) - np.repeat(np.cumsum(c_sm) - c_sm, c_sm)
    return fits, rep, k, blo, bhi, span


def bucket_hits(qid, ok, bid, btri):
    """Entries of sorted buckets: for query bucket ids ``qid`` (where ``ok``), every entry of
    ``btri`` whose bucket id ``bid`` (sorted) equals it.  Returns (query index, entry)."""
    s0 = np.searchsorted(bid, qid, "left")
    s1 = np.searchsorted(bid, qid, "right")
    cnt = np.where(ok, s1 - s0, 0)
    qi = np.repeat(np.arange(len(qid)), cnt)
    pos = np.arange(len(qi)) - np.repeat(np.cumsum(cnt) - cnt, cnt) + np.repeat(s0, cnt)
    return qi, btri[pos]


class ClampedChart:
    """See the module docstring.  ``rho_max`` = sqrt of the largest dimensionless force,
    ``max_turn`` the turning to cover (rad), ``n_xy`` x ``n_xy`` x ``n_s`` grid, RK4 ``n_steps``."""

    def __init__(self, rho_max=17.5, max_turn=4 * np.pi, n_xy=49, n_s=97, n_steps=128, mode_cap=3,
                 theta_scale=2.0, bucket=0.06, cap=8, n_levels=10, max_span=np.inf):
        self.rho_max = float(rho_max)
        self.max_turn = float(max_turn)
        xi = np.linspace(-rho_max, rho_max, n_xy)
        s = np.linspace(-1.0, 1.0, n_s)
        XI, ET, S = np.meshgrid(xi, xi, s, indexing="ij")
        rho = np.hypot(XI, ET)
        ax, ay = (rho * XI).ravel(), (rho * ET).ravel()
        mt = (S * (2.0 * rho + max_turn + 2.0)).ravel()
        z, mode = _rk4_canonical(ax, ay, mt, n_steps)
        self.P = np.stack([ax, ay, mt], 1)  # (V, 3) rod parameters
        self.Q = np.stack([z[0], z[1], z[2]], 1)  # (V, 3) tip state
        self.Mt = z[3].copy()  # (V,) tip moment
        self.mode = mode
        self.shape = (n_xy, n_xy, n_s)
        # ---- Kuhn tetrahedra: 6 per cube, paths (0,0,0) -> (1,1,1) ---------------------------
        ni, nj, nk = self.shape
        I, J, K = np.meshgrid(np.arange(ni - 1), np.arange(nj - 1), np.arange(nk - 1), indexing="ij")
        I, J, K = I.ravel(), J.ravel(), K.ravel()
        rho_v = rho.ravel()

        def vid(a, b, c):
            return ((I + a) * nj + (J + b)) * nk + (K + c)

        tets = []
        cube = (I * (nj - 1) + J) * (nk - 1) + K
        cubes = []
        for perm in ((0, 1, 2), (0, 2, 1), (1, 0, 2), (1, 2, 0), (2, 0, 1), (2, 1, 0)):
            p = [0, 0, 0]
            verts = [vid(0, 0, 0)]
            for ax_ in perm:
                p[ax_] = 1
                verts.append(vid(*p))
            tets.append(np.stack(verts, 1))
            cubes.append(cube)
        T = np.concatenate(tets)
        cubes = np.concatenate(cubes)
        keep = np.max(rho_v[T], axis=1) <= rho_max * 1.0001
        # only what can matter: some vertex of d-mode <= mode_cap, some vertex turning <= max_turn + pi
        keep &= np.min(self.mode[T], axis=1) <= mode_cap
        keep &= np.min(np.abs(self.Q[T, 2]), axis=1) <= max_turn + np.pi
        keep &= np.all(np.isfinite(self.Q[T]).reshape(len(T), -1), axis=1)
        self.tet = T[keep]
        self.cube = cubes[keep]
        self.tet_mode = np.min(self.mode[self.tet], axis=1)
        # ---- affine maps per tetrahedron: dP/dQ, dM/dQ --------------------------------------
        V = self.Q[self.tet]  # (T, 4, 3)
        E = np.transpose(V[:, 1:] - V[:, :1], (0, 2, 1))  # (T, 3 coords, 3 edges)
        with np.errstate(all="ignore"):
            det = np.linalg.det(E)
        ok = np.isfinite(det) & (np.abs(det) > 1e-14)
        self.tet, self.cube, self.tet_mode, E = self.tet[ok], self.cube[ok], self.tet_mode[ok], E[ok]
        self.Einv = np.linalg.inv(E)  # barycentric (edge) coordinates of a point: Einv (q - v0)
        # ---- buckets ------------------------------------------------------------------------------
        self.scale = np.array([1.0, 1.0, 1.0 / theta_scale])  # Theta counts 1/theta_scale per unit
        Vs = self.Q[self.tet] * self.scale
        if np.isfinite(max_span):  # drop tetrahedra too large for a useful affine interpolant
            small = np.max(Vs.max(1) - Vs.min(1), axis=1) <= max_span
            self.tet, self.cube, self.tet_mode, self.Einv = (self.tet[small], self.cube[small], self.tet_mode[small],
                                                             self.Einv[small])
            Vs = Vs[small]
        lo, hi = Vs.min(1), Vs.max(1)
        self.origin = lo.min(0) - bucket
        th_t = self.Q[self.tet, 2]
        self.theta_range = (float(th_t.min()), float(th_t.max()))
        self.levels = []
        todo = np.arange(len(self.tet))
        for lev in range(n_levels):
            h = bucket * 2.0**lev
            fits, rep, k, blo, _, span = bucket_spans(lo[todo], hi[todo], self.origin, h, cap, lev == n_levels - 1)
            sy, sz = span[rep, 1], span[rep, 2]
            n1 = int(np.ceil((hi[:, 1].max() - self.origin[1]) / h)) + 2
            n2 = int(np.ceil((hi[:, 2].max() - self.origin[2]) / h)) + 2
            bx = blo[rep, 0] + k // (sy * sz)
            by = blo[rep, 1] + (k // sz) % sy
            bz = blo[rep, 2] + k % sz
            bid = (bx * n1 + by) * n2 + bz
            order = np.argsort(bid, kind="stable")
            self.levels.append((h, n1, n2, bid[order], todo[rep[order]]))
            todo = todo[~fits]
            if not len(todo):
                break

    # ------------------------------------------------------------------------------------------
    def locate(self, Q, max_mode=None, mod2pi=True, chunk=200000):
        """Tetrahedra containing the tip states ``Q`` (M, 3) (canonical frame; Theta modulo 2 pi
        if ``mod2pi``: every shift ``Theta + 2 pi k`` within the chart's range is tried).

        Returns (query index, tetrahedron, barycentric weights (n, 4), the Theta shift 2 pi k);
        only tetrahedra whose least vertex d-mode is <= ``max_mode`` + 1 (if given)."""
        Q = np.atleast_2d(np.asarray(Q, float))
        if mod2pi:
            lo_k = np.ceil((self.theta_range[0] - Q[:, 2]) / (2 * np.pi)).astype(np.int64)
            hi_k = np.floor((self.theta_range[1] - Q[:, 2]) / (2 * np.pi)).astype(np.int64)
            cnt = np.maximum(hi_k - lo_k + 1, 0)
            src = np.repeat(np.arange(len(Q)), cnt)
            kk = np.arange(len(src)) - np.repeat(np.cumsum(cnt) - cnt, cnt) + np.repeat(lo_k, cnt)
            shift = 2 * np.pi * kk
            Qx = Q[src].copy()
            Qx[:, 2] += shift
        else:
            src = np.arange(len(Q))
            shift = np.zeros(len(Q))
            Qx = Q
        out = ([], [], [], [])
        for c0 in range(0, len(Qx), chunk):
            qi, tr, w = self._locate(Qx[c0:c0 + chunk], max_mode)
            out[0].append(src[c0 + qi])
            out[1].append(tr)
            out[2].append(w)
            out[3].append(shift[c0 + qi])
        if not out[0]:
            return np.zeros(0, np.int64), np.zeros(0, np.int64), np.zeros((0, 4)), np.zeros(0)
        return tuple(np.concatenate(o) for o in out)

    def _locate(self, Q, max_mode):
        if njit is not None:
            mm = 1 << 40 if max_mode is None else int(max_mode) + 1
            levels = self.levels
            hs = np.array([lv[0] for lv in levels])
            n1s = np.array([lv[1] for lv in levels], np.int64)
            n2s = np.array([lv[2] for lv in levels], np.int64)
            if not hasattr(self, "_flat"):
                offs = np.cumsum([0] + [len(lv[3]) for lv in levels]).astype(np.int64)
                self._flat = (np.concatenate([lv[3] for lv in levels]), np.concatenate([lv[4] for lv in levels]),
                              offs, np.ascontiguousarray(self.Q[self.tet[:, 0]]))
            bid, btri, offs, V0 = self._flat
            Qc = np.ascontiguousarray(Q)
            qi, tr, w = _locate_nb(Qc, self.scale, self.origin, hs, n1s, n2s, bid, btri, offs, V0, self.Einv,
                                   self.tet_mode, mm)
            return qi, tr, w
        Qs = Q * self.scale
        QI, TR = [], []
        for h, n1, n2, bid, btri in self.levels:
            q = np.floor((Qs - self.origin) / h).astype(np.int64)
            ok = np.all(q >= 0, axis=1) & (q[:, 1] < n1) & (q[:, 2] < n2)
            qi, tr = bucket_hits((q[:, 0] * n1 + q[:, 1]) * n2 + q[:, 2], ok, bid, btri)
            QI.append(qi)
            TR.append(tr)
        qi, tr = np.concatenate(QI), np.concatenate(TR)
        if max_mode is not None:
            m = self.tet_mode[tr] <= max_mode + 1
            qi, tr = qi[m], tr[m]
        v0 = self.Q[self.tet[tr, 0]]
        lam = np.einsum("nij,nj->ni", self.Einv[tr], Q[qi] - v0)
        w = np.column_stack([1.0 - lam.sum(1), lam])
        inside = np.all(w >= -1e-12, axis=1)
        return qi[inside], tr[inside], w[inside]

    def interp(self, tr, w):
        """Interpolated rod parameters p = (ax, ay, mt) (n, 3), tip moment M (n,), d-mode estimate
        (n,), dp/dQ (n, 3, 3) and dM/dQ (n, 3) on the tetrahedra ``tr`` at weights ``w``."""
        T = self.tet[tr]
        Pv, Mv = self.P[T], self.Mt[T]  # (n, 4, 3), (n, 4)
        p = np.einsum("nk,nkc->nc", w, Pv)
        M = np.einsum("nk,nk->n", w, Mv)
        dP = np.transpose(Pv[:, 1:] - Pv[:, :1], (0, 2, 1))  # (n, 3 params, 3 edges)
        dM = Mv[:, 1:] - Mv[:, :1]  # (n, 3 edges)
        Ei = self.Einv[tr]  # d(edge coords)/dQ
        mode = self.mode[T[np.arange(len(T)), np.argmax(w, axis=1)]]
        return p, M, mode, dP @ Ei, np.einsum("ne,neq->nq", dM, Ei)


if njit is not None:
    @njit(cache=True)
    def _locate_nb(Q, scale, origin, hs, n1s, n2s, bid, btri, offs, V0, Einv, tet_mode, mm):  # pragma: no cover
        nq = Q.shape[0]
        cap = 16
        qi = np.empty(cap, np.int64)
        tr = np.empty(cap, np.int64)
        w = np.empty((cap, 4))
        n = 0
        for a in range(nq):
            for lev in range(hs.shape[0]):
                h = hs[lev]
                i0 = int(np.floor((Q[a, 0] * scale[0] - origin[0]) / h))
                i1 = int(np.floor((Q[a, 1] * scale[1] - origin[1]) / h))
                i2 = int(np.floor((Q[a, 2] * scale[2] - origin[2]) / h))
                if i0 < 0 or i1 < 0 or i2 < 0 or i1 >= n1s[lev] or i2 >= n2s[lev]:
                    continue
                key = (i0 * n1s[lev] + i1) * n2s[lev] + i2
                lo = offs[lev]
                hi = offs[lev + 1]
                s0 = lo + np.searchsorted(bid[lo:hi], key, "left")
                s1 = lo + np.searchsorted(bid[lo:hi], key, "right")
                for c in range(s0, s1):
                    t = btri[c]
                    if tet_mode[t] > mm:
                        continue
                    d0 = Q[a, 0] - V0[t, 0]
                    d1 = Q[a, 1] - V0[t, 1]
                    d2 = Q[a, 2] - V0[t, 2]
                    l0 = Einv[t, 0, 0] * d0 + Einv[t, 0, 1] * d1 + Einv[t, 0, 2] * d2
                    l1 = Einv[t, 1, 0] * d0 + Einv[t, 1, 1] * d1 + Einv[t, 1, 2] * d2
                    l2 = Einv[t, 2, 0] * d0 + Einv[t, 2, 1] * d1 + Einv[t, 2, 2] * d2
                    w0 = 1.0 - l0 - l1 - l2
                    if w0 >= -1e-12 and l0 >= -1e-12 and l1 >= -1e-12 and l2 >= -1e-12:
                        if n == cap:
                            cap *= 2
                            qi2 = np.empty(cap, np.int64)
                            tr2 = np.empty(cap, np.int64)
                            w2 = np.empty((cap, 4))
                            qi2[:n] = qi[:n]
                            tr2[:n] = tr[:n]
                            w2[:n] = w[:n]
                            qi, tr, w = qi2, tr2, w2
                        qi[n] = a
                        tr[n] = t
                        w[n, 0] = w0
                        w[n, 1] = l0
                        w[n, 2] = l1
                        w[n, 3] = l2
                        n += 1
        return qi[:n], tr[:n], w[:n]


def chart(rho_max=17.5, max_turn=4 * np.pi, n_xy=49, n_s=97, n_steps=128, mode_cap=3, max_span=np.inf) -> ClampedChart:
    """The cached chart for these parameters (built once per process)."""
    key = (round(float(rho_max), 6), round(float(max_turn), 6), int(n_xy), int(n_s), int(n_steps), int(mode_cap),
           float(max_span))
    if key not in _CACHE:
        _CACHE[key] = ClampedChart(rho_max, max_turn, n_xy, n_s, n_steps, mode_cap, max_span=max_span)
    return _CACHE[key]
