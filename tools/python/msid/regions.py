"""Exact finite-sample confidence regions of an msid FRF element (docs/statistics.md,
"Degrees of freedom and exact regions").

With v the reported variance of one element and n its complex degrees of freedom (the file's `dof`),

    |Ghat_ij - G_ij|^2 / v  ~  F(2, 2n)       (complex line)
    (Ghat_ij - G_ij)^2 / v  ~  F(1, n)        (DC line, "real": true)

so the `level` region is a disc of radius sqrt(v q) with q the `level` quantile of that F law:
for F(2, 2n) in closed form q = n ((1 - level)^(-1/n) - 1) (the 95% radius of statistics.md).
Without a dof (or an infinite one) the law is the Gaussian limit chi2_2 / 2 (q = -ln(1 - level)),
respectively chi2_1 — the asymptotic region, which under-covers with few periods.
"""
import math
from typing import Any, Optional

import numpy as np

ArrayLike = Any   # a number or what np.asarray takes


def f2_quantile(level: float, dof: Optional[ArrayLike]) -> np.ndarray:
    """`level` quantile of F(2, 2 dof) (dof may be an array; inf or None gives the chi2_2/2 limit)."""
    a = -math.log1p(-level)
    if dof is None:
        return np.asarray(a)
    n = np.asarray(dof, dtype=float)
    with np.errstate(over="ignore", invalid="ignore"):
        q = n * np.expm1(a / n)
    return np.where(np.isfinite(n), q, a)


def f1_quantile(level: float, dof: Optional[ArrayLike]) -> np.ndarray:
    """`level` quantile of F(1, dof) = t_dof((1 + level)/2)^2 (inf or None: chi2_1)."""
    from scipy import stats
    if dof is None:
        return np.asarray(stats.chi2.ppf(level, 1))
    n = np.asarray(dof, dtype=float)
    fin = np.isfinite(n)
    return np.where(fin, stats.f.ppf(level, 1, np.where(fin, n, 1.0)), stats.chi2.ppf(level, 1))


def radius(var: ArrayLike, dof: Optional[ArrayLike] = None, level: float = 0.95,
           real: ArrayLike = False) -> np.ndarray:
    """Radius of the `level` confidence disc (interval half-width for real lines) of elements with
    variance `var` and complex dof `dof` (arrays broadcast together)."""
    var = np.asarray(var, dtype=float)
    real = np.asarray(real, dtype=bool)
    q = np.broadcast_to(f2_quantile(level, dof), np.broadcast_shapes(var.shape, np.shape(f2_quantile(level, dof))))
    if np.any(real):
        q = np.where(real, f1_quantile(level, dof), q)
    return np.sqrt(np.maximum(var, 0.0) * q)


def normalised_residual(e: ArrayLike, var: ArrayLike) -> np.ndarray:
    """|e| / sqrt(var): a model's residual at a line in units of the FRF's standard deviation."""
    var = np.asarray(var, dtype=float)
    with np.errstate(divide="ignore", invalid="ignore"):
        return np.abs(e) / np.sqrt(var)
