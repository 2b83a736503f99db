"""Solvers on the one equation system: inverse and forward kinematics (global searches),
the Newton corrector, continuation, paths and workspaces."""
