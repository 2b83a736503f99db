"""Shared foundations: 2-D geometry, validation at the API boundary, the batched Newton
corrector and small dense linear algebra (compiled), and the on-disk cache."""
