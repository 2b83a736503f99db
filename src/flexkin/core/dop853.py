"""The Dormand–Prince 8(5,3) Runge–Kutta step (DOP853), compiled: flexkin's one ODE stepper.

Hairer, Nørsett & Wanner, *Solving Ordinary Differential Equations I* (2nd ed., 1993), §II.10,
code DOP853 (Dormand & Prince 1980; Prince & Dormand 1981): 12 stages, an 8th-order
propagating solution, and embedded 5th- and 3rd-order error estimators combined into one error
norm.  The coefficients below are those of Hairer's Fortran code (``dop853.f``, arrays ``a``,
``b``, ``c``, ``er`` and ``bhh``), to 16 significant digits; ``tests/test_dop853.py`` checks them
against order conditions and against :func:`scipy.integrate.solve_ivp` (``method="DOP853"``),
step by step.  Own code rather than scipy because the steps run inside compiled kernels (many
small systems: the rods of every solution), where a Python-level integrator is ~1000x slower.

A step from ``y`` over ``h`` (``h`` signed) for ``y' = f(y)``, with the kernel's own ``f``::

    f(y, K[0])                              # K[0] = f(y)
    for s in range(1, STAGES):
        stage_state(s, y, h, K, yt, n)      # yt = y + h sum_j A[s, j] K[j]
        f(yt, K[s])
    advance(y, h, K, y_new, n)              # 8th-order solution (y_new may be y)
    err = error_norm(y, y_new, h, K, rtol, atol, n)   # accept the step when err < 1

The systems here are autonomous, so ``C`` (the stage abscissae, ``C[s] = sum_j A[s, j]``) is
kept for completeness of the table only.  The step functions are inlined into the calling
kernel (numba ``inline="always"``): the Cosserat kernels step 45 variables at a time, and a
call per stage made the Cosserat refinement about 25 % slower.
"""

from __future__ import annotations

import math

import numpy as np

from .jit import njit

__all__ = ["STAGES", "A", "B", "C", "E3", "E5", "stage_state", "advance", "error_norm", "step_factor"]

STAGES = 12

A = np.array([
    [0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.05260015195876773, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.0197250569845379, 0.0591751709536137, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.02958758547680685, 0.0, 0.08876275643042054, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.2413651341592667, 0.0, -0.8845494793282861, 0.924834003261792, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.037037037037037035, 0.0, 0.0, 0.17082860872947386, 0.12546768756682242, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0,
     0.0],
    [0.037109375, 0.0, 0.0, 0.17025221101954405, 0.06021653898045596, -0.017578125, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.03709200011850479, 0.0, 0.0, 0.17038392571223998, 0.10726203044637328, -0.015319437748624402,
     0.008273789163814023, 0.0, 0.0, 0.0, 0.0, 0.0],
    [0.6241109587160757, 0.0, 0.0, -3.3608926294469414, -0.868219346841726, 27.59209969944671,
     20.154067550477894, -43.48988418106996, 0.0, 0.0, 0.0, 0.0],
    [0.47766253643826434, 0.0, 0.0, -2.4881146199716677, -0.590290826836843, 21.230051448181193,
     15.279233632882423, -33.28821096898486, -0.020331201708508627, 0.0, 0.0, 0.0],
    [-0.9371424300859873, 0.0, 0.0, 5.186372428844064, 1.0914373489967295, -8.149787010746927,
     -18.52006565999696, 22.739487099350505, 2.4936055526796523, -3.0467644718982196, 0.0, 0.0],
    [2.273310147516538, 0.0, 0.0, -10.53449546673725, -2.0008720582248625, -17.9589318631188, 27.94888452941996,
     -2.8589982771350235, -8.87285693353063, 12.360567175794303, 0.6433927460157636, 0.0],
])
B = np.array([0.054293734116568765, 0.0, 0.0, 0.0, 0.0, 4.450312892752409, 1.8915178993145003,
              -5.801203960010585, 0.3111643669578199, -0.1521609496625161, 0.20136540080403034,
              0.04471061572777259])
C = np.array([0.0, 0.05260015195876773, 0.0789002279381516, 0.1183503419072274, 0.2816496580927726,
              0.3333333333333333, 0.25, 0.3076923076923077, 0.6512820512820513, 0.6, 0.8571428571428571, 1.0])
#: 5th-order error estimator (Hairer's ``er``): ``sum_j E5[j] K[j]``
E5 = np.array([0.01312004499419488, 0.0, 0.0, 0.0, 0.0, -1.2251564463762044, -0.4957589496572502,
               1.6643771824549864, -0.35032884874997366, 0.3341791187130175, 0.08192320648511571,
               -0.022355307863886294])
#: 3rd-order error estimator: ``B`` minus Hairer's ``bhh`` (at stages 1, 9 and 12)
E3 = B.copy()
E3[0] -= 0.244094488188976377952755905512
E3[8] -= 0.733846688281611857341361741547
E3[11] -= 0.0220588235294117647058823529412
for _a in (A, B, C, E3, E5):
    _a.setflags(write=False)

#: step-size control (Hairer II.4 with the 8th-order exponent)
SAFETY = 0.9
MIN_FACTOR = 0.2
MAX_FACTOR = 10.0


@njit(cache=True, inline="always")
def stage_state(s, y, h, K, yt, n) -> None:
    """``yt[:n] = y[:n] + h sum_{j<s} A[s, j] K[j, :n]``: the state at which stage ``s`` evaluates
    the right-hand side (``K[:s]`` hold the earlier stages; ``yt`` must not be ``y``)."""
    for i in range(n):
        yt[i] = 0.0
    for j in range(s):  # stage-outer: the inner loop runs along a row of K (vectorised)
        a = A[s, j]
        if a != 0.0:
            for i in range(n):
                yt[i] += a * K[j, i]
    for i in range(n):
        yt[i] = y[i] + h * yt[i]


@njit(cache=True, inline="always")
def advance(y, h, K, out, n) -> None:
    """The 8th-order solution ``out[:n] = y[:n] + h sum_j B[j] K[j, :n]`` (``out`` may be ``y``)."""
    for i in range(n):
        out[i] = y[i]
    for j in range(STAGES):  # stage-outer, as in stage_state
        b = B[j]
        if b != 0.0:
            hb = h * b
            for i in range(n):
                out[i] += hb * K[j, i]


@njit(cache=True, inline="always")
def error_norm(y, y_new, h, K, rtol, atol, n) -> float:
    """Hairer's DOP853 error norm of the step ``y -> y_new`` over ``h`` (accept when < 1), with
    the componentwise scale ``atol + rtol max(|y|, |y_new|)``."""
    e5 = 0.0
    e3 = 0.0
    for i in range(n):
        a5 = 0.0
        a3 = 0.0
        for j in range(STAGES):
            a5 += E5[j] * K[j, i]
            a3 += E3[j] * K[j, i]
        sc = atol + rtol * max(abs(y[i]), abs(y_new[i]))
        e5 += (a5 / sc) ** 2
        e3 += (a3 / sc) ** 2
    if e5 == 0.0 and e3 == 0.0:
        return 0.0
    return abs(h) * e5 / math.sqrt((e5 + 0.01 * e3) * n)


@njit(cache=True)
def step_factor(err, rejected_before) -> float:
    """Factor of the next step size after a step with error norm ``err``: at most 1 after a
    rejected step (when ``err < 1`` follows a rejection) or when ``err >= 1``."""
    if err >= 1.0:
        return max(MIN_FACTOR, SAFETY * err ** (-1.0 / 8.0))
    f = MAX_FACTOR if err == 0.0 else min(MAX_FACTOR, SAFETY * err ** (-1.0 / 8.0))
    return min(1.0, f) if rejected_before else f
