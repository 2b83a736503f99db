"""Regenerate the cases of ``test_clamped_heavy_and_fold.py`` with the independent oracle (test-only).

Usage (from the repository root; a few minutes on the 2-core machine)::

    python tests/find_clamped_cases.py heavy   # the heavy-load case: counts and forces
    python tests/find_clamped_cases.py fold    # the near-fold pair: pose and both solutions
    python tests/find_clamped_cases.py own [FY ...]   # the own mechanism's heavy-load case

Nothing here calls flexkin's solvers: ``tests/ik_oracle.py`` (multi-start shooting, leg curves),
its own Newton on the 12 equations for the continuation, ``tests/stability_oracle.py``.

``fold``: the oracle's equilibria of ``examples/mixed_clamped.toml`` at (0.02, -0.05, 0.1 rad)
under its own load (SPEC §2's scope); the two closest in their inputs (a pair on the two sides of
a fold of the IK solution set at that pose) are continued together along -x (natural-parameter
continuation in the pose, tangent predictor from the oracle's Jacobian, Newton corrector, steps
halved on failure) until the continuation stalls: both are then within a few 1e-4 of the fold,
where they merge.  The pose is then moved back from the fold until the pair's inputs differ by
about ``TARGET`` (relative), both are polished by DOP853 and verified by re-integration, and
their stability is taken from the discretised-energy oracle.

``own``: the mechanism ``tests/data/own_clamped_heavy.toml`` was designed to share nothing with the
examples (every rod clamped, legs P-R-P, three different rods and tip angles, a scalene platform).
At the generic pose (0.04 m, -0.03 m, 7 deg) the oracle (the unit 3-PF's configuration) was run
under downward loads F_y = -400 N (15 equilibria in scope, all above 256 EI/L^2, max 953) and
-200 N (22 in scope, 19 above 256 EI/L^2, max 992: the case kept, with more equilibria and
forces still inside the oracle's 1000 EI/L^2).  This mode prints the counts for the loads given
(default: the test's) and every equilibrium in scope with its full-precision values (the source of
``OWN_KNOWN_MISS``: the equilibrium the tests found flexkin missing).
"""

from __future__ import annotations

import math
import os
import sys
import time
from pathlib import Path as _P

import numpy as np

sys.path.insert(0, os.path.dirname(__file__))
import ik_oracle as O  # noqa: E402
import stability_oracle as S  # noqa: E402

ROOT = _P(__file__).resolve().parents[1]
#: the pair's input distance aimed at (relative: revolute inputs in rad, others over L_ref)
TARGET = 5e-4


class ParamPath:
    """The oracle's 12 IK equations along a straight path ``p(t) = p0 + t d`` in (pose, load)."""

    def __init__(self, mech, p0, d):
        self.m, self.g = mech, O.Geom.of(mech)
        self.p0, self.d = np.asarray(p0, float), np.asarray(d, float)

    def p(self, t):
        return self.p0 + t * self.d

    def sys(self, t):
        p = self.p(t)
        return O._System(self.g, p[:3], p[3:])

    def newton(self, t, z0):
        z, rn, _ = O._newton(self.sys(t), np.atleast_2d(z0), n_iter=30, n_steps=600, tol=1e-12)
        return z[0], rn[0]

    def dzdt(self, t, z, e=1e-6):
        r0, J, _ = self.sys(t).eval(z[None], n_steps=600)
        r1, _ = self.sys(t + e).eval(z[None], n_steps=600, jac=False)
        return -np.linalg.solve(J[0], (r1[0] - r0[0]) / e)

    def follow(self, z, tmax, h0=0.002, hmin=1e-12):
        """Continue the solution z from t = 0 towards ``tmax`` (either sign); returns the t reached
        (== tmax unless the branch turns back: a fold) and the solution there."""
        sign, t, h = math.copysign(1.0, tmax), 0.0, h0
        while h > hmin and abs(t) < abs(tmax) - 1e-15:
            hh = min(h, abs(tmax) - abs(t))
            v = self.dzdt(t, z)
            zp = z + sign * hh * v
            zn, rn = self.newton(t + sign * hh, zp)
            if rn < 1e-10 and np.max(np.abs(zn - zp)) <= 0.2 * np.max(np.abs(hh * v)) + 1e-9:
                t, z, h = t + sign * hh, zn, min(1.5 * h, h0)
            else:
                h /= 2
        return t, z

    def build(self, t, z):
        sy = self.sys(t)
        zp, rn = O._polish(sy, z[None])
        return O._build_many(sy, zp, rn)[0]


def scaled_inputs_distance(g, a, b) -> float:
    d = (np.asarray(a.inputs, float) - np.asarray(b.inputs, float)) / g.u_scale()
    d = np.where([k == "revolute" for k in g.kind], np.angle(np.exp(1j * d)), d)
    return float(np.max(np.abs(d)))


def heavy():
    import flexkin
    from test_clamped_heavy_and_fold import HEAVY_LOAD, HEAVY_MECHANISM, HEAVY_ORACLE, HEAVY_POSE
    from test_clamped_mechanism import _in_flexkin_scope, _oracle_winding

    m = flexkin.load_mechanism(ROOT / "examples" / HEAVY_MECHANISM)
    t0, c0 = time.time(), time.process_time()
    sols = O.oracle_ik(m, HEAVY_POSE, load=HEAVY_LOAD, **HEAVY_ORACLE)
    print(f"oracle: {len(sols)} in {time.time() - t0:.1f} s wall, {time.process_time() - c0:.1f} s CPU")
    ins = [s for s in sols if _in_flexkin_scope(s)]
    R = [max(r.R_dimless for r in s.rods) for s in ins]
    print(f"in scope {len(ins)}, above 256 EI/L^2 {sum(r > 256 for r in R)}, max R L^2/EI {max(R):.1f}, "
          f"extreme (|k| within 1e-7 of 1) {sum(s.extreme for s in ins)}")
    for s, r in zip(ins, R):
        print(s.mode_label, np.round(s.inputs, 6).tolist(), round(r, 1), [_oracle_winding(q) for q in s.rods])


def fold():
    import flexkin
    from test_clamped_mechanism import _in_flexkin_scope

    m = flexkin.load_mechanism(ROOT / "examples" / "mixed_clamped.toml")
    g = O.Geom.of(m)
    pose, load = np.array([0.02, -0.05, 0.1]), np.array(m.load, float)
    sols = [s for s in O.oracle_ik(m, pose, load=load, max_mode=3, max_turn=3 * math.pi, n_starts=300, seed=3)
            if _in_flexkin_scope(s)]
    pairs = sorted((scaled_inputs_distance(g, a, b), i, j) for i, a in enumerate(sols) for j, b in
                   enumerate(sols) if i < j)
    d0, i, j = pairs[0]
    A, B = sols[i], sols[j]
    print(f"{len(sols)} oracle solutions; closest pair {A.mode_label} {B.mode_label}, inputs {d0:.3g} apart")
    path = ParamPath(m, np.concatenate([pose, load]), [-1.0, 0, 0, 0, 0, 0])  # along -x
    ta, za = path.follow(A.z, 0.05)
    tb, zb = path.follow(B.z, 0.05)
    print(f"continuation along -x stalls at {ta:.7f} / {tb:.7f} m")
    tf = min(ta, tb)
    # back off from the fold: the pair's distance grows like sqrt(tf - t)
    back = 1e-6
    for _ in range(40):
        t = tf - back
        ta_, za_ = ParamPath(m, path.p(0.0), path.d).follow(A.z, t)
        tb_, zb_ = ParamPath(m, path.p(0.0), path.d).follow(B.z, t)
        a, b = path.build(t, za_), path.build(t, zb_)
        d = scaled_inputs_distance(g, a, b)
        if abs(d / TARGET - 1.0) < 0.1:
            break
        back *= (TARGET / max(d, 1e-12)) ** 2
    p = path.p(t)
    print(f"fold at x = {path.p(tf)[0]!r}; pair at t = {t!r}")
    print(f"pose {p[:3].tolist()}, load {p[3:].tolist()}: inputs {d:.3e} apart")
    for s in (a, b):
        v = O.verify_solution(m, s, p[3:], p[:3])
        np.set_printoptions(precision=17)
        st = S.solution_stability(m, s, p[3:])
        print(f"  {s.mode_label} inputs {s.inputs.tolist()}")
        print(f"    forces {s.forces.tolist()} base moments {[r.base_moment for r in s.rods]}")
        print(f"    max R L^2/EI {max(r.R_dimless for r in s.rods):.1f}, turnings {s.turnings}")
        print(f"    verify: tip {v['tip_error']:.1e} eq {max(v['eq_force'], v['eq_moment']):.1e}; stability "
              f"{st.stable} index {st.index} min_eig {st.min_eig:.4f} converged {st.converged}")


def own(*fys):
    import flexkin
    from test_clamped_heavy_and_fold import OWN_LOAD, OWN_MECHANISM, OWN_ORACLE, OWN_POSE
    from test_clamped_mechanism import _in_flexkin_scope, _oracle_winding

    m = flexkin.load_mechanism(OWN_MECHANISM)
    np.set_printoptions(precision=17)
    for fy in [float(v) for v in fys] or [OWN_LOAD[1]]:
        load = (OWN_LOAD[0], fy, OWN_LOAD[2])
        t0, c0 = time.time(), time.process_time()
        sols = O.oracle_ik(m, OWN_POSE, load=load, **OWN_ORACLE)
        print(f"load {load}: oracle {len(sols)} in {time.time() - t0:.1f} s wall, "
              f"{time.process_time() - c0:.1f} s CPU")
        ins = [s for s in sols if _in_flexkin_scope(s) and max(r.R_dimless for r in s.rods) <= 1000.0]
        R = [max(r.R_dimless for r in s.rods) for s in ins]
        print(f"in scope {len(ins)}, above 256 EI/L^2 {sum(r > 256 for r in R)}, max R L^2/EI {max(R, default=0):.1f}")
        for s in ins:
            print(s.mode_label, "windings", [_oracle_winding(q) for q in s.rods], "R L^2/EI",
                  [round(q.R_dimless, 1) for q in s.rods], "k", [q.k for q in s.rods])
            print("   inputs", s.inputs.tolist())
            print("   forces", s.forces.tolist())
            print("   base moments", [q.base_moment for q in s.rods], "tip moments", s.tip_moments.tolist())


if __name__ == "__main__":
    {"heavy": heavy, "fold": fold, "own": own}[sys.argv[1]](*sys.argv[2:])
