"""The compiled pieces of the IK search and of the stability analysis against plain references.

* :func:`flexkin.solve.equilibrium.equilibrium_triples` (compiled subdivision of segment triples,
  Eq. 15) finds every segment triple of random polylines whose linear equations have a solution
  inside the segments: the reference is the brute-force solve of every triple;
* the banded second variation of :mod:`flexkin.analysis.second_variation` (Sylvester counts of
  the KKT system, shift-invert) gives the constrained eigenvalues of the dense pencil on an
  orthonormal null-space basis from :func:`scipy.linalg.null_space`, also when the
  constraints lose rank;
* the curve snapping of :mod:`flexkin.solve.pinned_curves` (Newton with the analytic gradient) lands on
  the level set of the closed-form tip (:func:`flexkin.rod.closed_form.tip_chart`).
"""

from __future__ import annotations

import itertools

import numpy as np
import pytest
from scipy.linalg import null_space

from flexkin.mechanism.actuators import COND_CIRCLE, COND_LINE
from flexkin.rod.closed_form import tip_chart
from flexkin.rod.kernels import CHART_UNIFIED
from flexkin.solve.pinned_curves import _snap
from flexkin.solve.equilibrium import equilibrium_triples


def _polyline(rng, n):
    """A random walk in 3-D wrench space: segments (n, 3) start and end points."""
    pts = np.cumsum(rng.normal(size=(n + 1, 3)) * 0.3, axis=0) + rng.normal(size=3)
    return pts[:-1], pts[1:]


@pytest.mark.parametrize("seed", range(4))
def test_triples_equal_brute_force(seed):
    rng = np.random.default_rng(seed)
    p0s, p1s = zip(*[_polyline(rng, n) for n in (23, 17, 30)])
    target = sum(p[len(p) // 2] for p in p0s)  # a triple through the middle vertices solves it
    seg, s, complete = equilibrium_triples(list(p0s), list(p1s), target)
    assert complete
    found = {tuple(r) for r in seg}
    expected = set()
    for ijk in itertools.product(*(range(len(p)) for p in p0s)):
        M = np.stack([p1s[i][ijk[i]] - p0s[i][ijk[i]] for i in range(3)], -1)
        rhs = target - sum(p0s[i][ijk[i]] for i in range(3))
        sol = np.linalg.solve(M, rhs)
        if np.all((sol >= 0.0) & (sol <= 1.0)):
            expected.add(ijk)
            k = np.flatnonzero((seg == ijk).all(axis=1))[0]
            assert np.allclose(s[k], sol, atol=1e-9)
    assert expected and expected <= found
    # every reported triple solves Eq. (15) to within the leaf tolerance of its parameters
    for (a, b, c), t in zip(seg, s):
        w = sum(p0s[i][j] + t[i] * (p1s[i][j] - p0s[i][j]) for i, j in enumerate((a, b, c)))
        sc = 1.0 + max(np.abs(p1s[i][j] - p0s[i][j]).max() for i, j in enumerate((a, b, c)))
        assert np.max(np.abs(w - target)) <= 2.0 * sc


def test_triples_budget_reports_incomplete():
    rng = np.random.default_rng(7)
    p0s, p1s = zip(*[_polyline(rng, 64) for _ in range(3)])
    target = sum(p[10] for p in p0s)
    _, _, complete = equilibrium_triples(list(p0s), list(p1s), target, max_nodes=5)
    assert not complete


def _banded(rng, n, w, shift):
    """A random symmetric banded matrix (lower storage, half-bandwidth w) and its dense copy."""
    Ab = rng.normal(size=(w + 1, n))
    Ab[0] += shift
    A = np.zeros((n, n))
    for k in range(w + 1):
        for j in range(n - k):
            A[j + k, j] = A[j, j + k] = Ab[k, j]
    return Ab, A


@pytest.mark.parametrize("rank_loss", [False, True])
def test_sylvester_count_and_shift_invert_equal_dense_reference(rank_loss):
    """The banded KKT factorisation of :mod:`flexkin.analysis.second_variation` (three banded
    blocks, a 3-dof pose block, dense constraint rows with their pose coupling): the Sylvester
    count of eigenvalues below a shift (Eq. F3) and the shift-invert smallest eigenvalue equal
    the constrained eigenvalues of the dense pencil on the null space of the constraints
    (:func:`scipy.linalg.null_space`), also when constraint rows are dependent."""
    from scipy.linalg import eigh

    from flexkin.analysis.second_variation import _count, _independent_rows, _lowest, negative_eigenvalues

    rng = np.random.default_rng(11)
    w, ns = 4, np.array([20, 16, 24])
    nmax = ns.max()
    Kb = np.zeros((3, w + 1, nmax))
    Mb = np.zeros((3, w + 1, nmax))
    C = np.zeros((3, 3, nmax))
    T = np.zeros((3, 3, 3))
    mi = np.array([2, 3, 2])
    blocks_K, blocks_M = [], []
    for i in range(3):
        Kb[i, :, :ns[i]], Ki = _banded(rng, ns[i], w, 0.0)
        Mi_b, Mi = _banded(rng, ns[i], w, 0.0)
        Mi = Mi @ Mi.T + ns[i] * np.eye(ns[i])          # positive definite, then re-banded
        Mi = np.where(np.abs(np.subtract.outer(np.arange(ns[i]), np.arange(ns[i]))) <= w, Mi, 0.0)
        Mi += 10.0 * ns[i] * np.eye(ns[i])
        for k in range(w + 1):
            Mb[i, k, :ns[i] - k] = np.diagonal(Mi, -k)
        blocks_K.append(Ki)
        blocks_M.append(Mi)
        C[i, :mi[i], :ns[i]] = rng.normal(size=(mi[i], ns[i]))
        T[i, :mi[i]] = rng.normal(size=(mi[i], 3))
    if rank_loss:
        C[2, 1] = 0.0                                      # a vacuous row: no rod part ...
        T[2, 1] = 0.0                                      # ... and no pose part
    Pp = np.diag([0.0, 0.0, -0.7])
    n = ns.sum() + 3
    K = np.zeros((n, n))
    M = np.zeros((n, n))
    rows = []
    o = 0
    for i in range(3):
        K[o:o + ns[i], o:o + ns[i]] = blocks_K[i]
        M[o:o + ns[i], o:o + ns[i]] = blocks_M[i]
        for r in range(mi[i]):
            row = np.zeros(n)
            row[o:o + ns[i]] = C[i, r, :ns[i]]
            row[-3:] = T[i, r]
            rows.append(row)
        o += ns[i]
    K[-3:, -3:] = Pp
    M[-3:, -3:] = np.eye(3)
    Z = null_space(np.array(rows), rcond=1e-9)
    ref = eigh(Z.T @ K @ Z, Z.T @ M @ Z, eigvals_only=True)
    _independent_rows(C, C.copy(), T, mi, ns, 3, 3)
    assert mi.sum() == (6 if rank_loss else 7)
    for sigma in np.concatenate([ref[:6] - 1e-6, ref[:6] + 1e-6, [0.0, -50.0]]):
        assert _count(Kb, Mb, C, T, mi, ns, 3, 3, w, Pp, sigma) == np.sum(ref < sigma)
    vr = np.zeros((3, nmax))
    vp = np.zeros(3)
    mu, _ = _lowest(Kb, Mb, C, T, mi, ns, 3, 3, w, Pp, ref[0] - 10.0 * abs(ref[0]) - 10.0, vr, vp, False, -1, True)
    assert mu == pytest.approx(ref[0], rel=1e-10, abs=1e-10)
    # Bunch-Parlett inertia of symmetric indefinite matrices, with exact zeros on the diagonal
    for _ in range(20):
        A = rng.normal(size=(9, 9))
        A = A + A.T
        A[np.diag_indices(9)[0][:4], np.diag_indices(9)[1][:4]] = 0.0
        assert negative_eigenvalues(A, 9) == np.sum(np.linalg.eigvalsh(A) < 0)


@pytest.mark.parametrize("code, par", [(COND_LINE, (0.4, 0.0)), (COND_CIRCLE, (0.7, 0.3))])
def test_snap_lands_on_the_level_set(code, par):
    rng = np.random.default_rng(5)
    z = np.stack([rng.uniform(-2.0, 2.0, 200), rng.uniform(-3.5, 1.2, 200)], -1)
    d = rng.normal(size=(200, 2))
    if code == COND_LINE:
        out, tips = _snap(CHART_UNIFIED, code, np.array([*par, 0.0]), 0.0, z, d, iters=30, max_shift=1.0)
    else:  # the circle's regular form sign(k) sqrt(1 - |tip|) = +-sqrt(1 - r), one level per sign of k
        out, tips = np.empty_like(z), np.empty((len(z), 4))
        for sg in (1.0, -1.0):
            k = np.flatnonzero(np.sign(z[:, 0]) == sg)
            out[k], tips[k] = _snap(CHART_UNIFIED, code, np.array([*par, 0.0]), sg * np.sqrt(1.0 - par[0]), z[k],
                                    d[k], iters=30, max_shift=1.0)
    t = tip_chart(out[:, 0], out[:, 1])
    g = t.y - par[0] if code == COND_LINE else np.hypot(t.x, t.y) - par[0]
    moved = np.any(out != z, axis=1)
    assert moved.sum() > 40
    assert np.max(np.abs(g[moved])) < 1e-10
    # the points move along the normal of the given tangent only
    n = np.stack([-d[:, 1], d[:, 0]], -1)
    cross = (out - z)[:, 0] * n[:, 1] - (out - z)[:, 1] * n[:, 0]
    assert np.max(np.abs(cross)) < 1e-12
    # the returned tips are the closed-form tips of the returned points
    assert np.allclose(tips[:, 0], t.x, atol=1e-12) and np.allclose(tips[:, 1], t.y, atol=1e-12)


def _child_ik(theta: float) -> int:
    import flexkin
    from flexkin.mechanism import symmetric_mechanism

    return len(flexkin.ik(symmetric_mechanism("revolute"), (0.05, 0.02, theta)))


def test_fork_after_a_solve_is_safe(examples_dir):
    """A fork-based process pool works after the parent solved (no threading runtime that aborts
    on fork, such as GNU OpenMP behind numba's prange, may be started by the IK/stability kernels)."""
    import multiprocessing
    from concurrent.futures import ProcessPoolExecutor

    import flexkin
    from flexkin.mechanism import symmetric_mechanism

    proto = flexkin.load_mechanism(examples_dir / "prototype_3pfr.toml")
    assert len(flexkin.ik(proto, (0.0, 0.0, 0.5 * np.pi))) == 88  # many equilibria in one batch
    n = len(flexkin.ik(symmetric_mechanism("revolute"), (0.05, 0.02, 0.349)))
    with ProcessPoolExecutor(max_workers=1, mp_context=multiprocessing.get_context("fork")) as ex:
        assert list(ex.map(_child_ik, [0.349])) == [n]
