"""Output slots of the compiled rod kernels (:mod:`flexkin.rod.kernels`) and chart codes.

A kernel evaluates a unit rod (``L = EI = 1``, clamp at the origin, clamp tangent along +x)
into an array ``out[NQ]`` and its chart gradient ``grad[NQ, 3]``:

    X, Y   tip position              TH     tangent angle at the tip
    FX, FY force ON the tip BY the platform (local frame; the constant internal force)
    M0, ML bending moment EI theta' at the clamp and at the tip
    EN     bending energy (EI/2) int theta'^2 ds
    PHI    lambda L = sqrt(|force| L^2 / EI)

Positions scale with ``L``, forces with ``EI/L**2``, moments and energy with ``EI/L``.

Charts: pinned rods (two coordinates) in the unified or the seam chart; rods clamped at both
ends (three coordinates) in the wrench chart, or, when taut (their orbit passes close to the
saddle, where the wrench chart loses the digits of the tip), as windows of a librating or
rotating elastica orbit (:mod:`flexkin.rod.elastica`).  Every chart code ``>=``
:data:`CHART_WRENCH` is a clamped rod's.
"""

X, Y, TH, FX, FY, M0, ML, EN, PHI = range(9)
NQ = 9
CHART_UNIFIED, CHART_SEAM, CHART_WRENCH, CHART_LIB, CHART_ROT = 0, 1, 2, 3, 4
#: number of coordinates of each chart
CHART_DIM = (2, 2, 3, 3, 3)

__all__ = ["X", "Y", "TH", "FX", "FY", "M0", "ML", "EN", "PHI", "NQ", "CHART_UNIFIED", "CHART_SEAM",
           "CHART_WRENCH", "CHART_LIB", "CHART_ROT", "CHART_DIM"]
