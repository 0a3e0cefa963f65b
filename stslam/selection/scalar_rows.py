"""The filter bank's rows on Python floats, for temporal order 1 and the paper's three models (SPEC 2, 3, 4).

:class:`stslam.selection.bank.FilterBank` steps rows of motion state x = [q, q̇] with
F = [[1, δt], [0, 1]] and the scalar isotropic update (d = 1). Its stacked F P Fᵀ + Q is one
numpy product; what follows it, per row, is written out here once, for the bank's step and for
its rerun of a window's tail, with the floating-point operations of the BLAS products it
replaces (products by 0 or 1 where the kernel fuses a multiply-add, sums accumulated from +0;
the bank's module docstring), so both give the bits of :meth:`ModelFilter.step`.
"""

from __future__ import annotations

import numpy as np

from stslam.articulation.models import PrismaticModel, RevoluteModel, StaticModel


def _floats_static(structure):
    return (tuple(structure.p0.tolist()),)


def _floats_prismatic(structure):
    return tuple(structure.p0.tolist()), tuple(structure.direction.tolist())


def _floats_revolute(structure):
    x0, y0 = structure.centre_xy.tolist()
    return (x0, y0, float(structure.radius), tuple(structure.v1.tolist()), tuple(structure.v2.tolist()),
            tuple(structure.p0.tolist()))


def _scalar_static(c, q):
    """_point_static on Python floats: P0 + l·1, [1, 1, 1]."""
    (p0,) = c
    return (p0[0] + q * 1.0, p0[1] + q * 1.0, p0[2] + q * 1.0), (1.0, 1.0, 1.0)


def _scalar_prismatic(c, q):
    """_point_prismatic on Python floats: P0 + l·n̂, n̂."""
    p0, d = c
    return (p0[0] + q * d[0], p0[1] + q * d[1], p0[2] + q * d[2]), d


def _scalar_revolute(c, q):
    """_point_revolute on Python floats (cos φ and sin φ from numpy, as there)."""
    x0, y0, r, v1, v2, p0 = c
    cos, sin = float(np.cos(q)), float(np.sin(q))
    a, b = x0 + r * cos, y0 + r * sin
    z = (a * v1[0] + b * v2[0] + p0[0], a * v1[1] + b * v2[1] + p0[1], a * v1[2] + b * v2[2] + p0[2])
    return z, (r * (-sin * v1[0] + cos * v2[0]), r * (-sin * v1[1] + cos * v2[1]), r * (-sin * v1[2] + cos * v2[2]))


SCALAR_KERNELS = {StaticModel: (_floats_static, _scalar_static), PrismaticModel: (_floats_prismatic, _scalar_prismatic),
                  RevoluteModel: (_floats_revolute, _scalar_revolute)}


def predict_row(x, A, h: float, z, point, constant, white=None) -> tuple:
    """One row's prediction and innovation terms.

    ``x`` = (x0, x1), ``A`` = F P Fᵀ + Q as ((a00, a01), (a10, a11)), ``h`` = δt, ``z`` = (z0, z1, z2),
    ``point`` and ``constant`` the row's kernel and structure floats (:data:`SCALAR_KERNELS`),
    ``white`` the rows of L⁻¹ of the point's covariance (or None). Returns
    (x⁻0, x⁻1, P⁻ (4 floats), y, ∂f/∂q, j·j, j·y, y·y), the last three on the whitened y and j.
    """
    (a00, a01), (a10, a11) = A
    Pp = (0.5 * (a00 + a00), 0.5 * (a01 + a10), 0.5 * (a10 + a01), 0.5 * (a11 + a11))  # symmetrised
    x0, x1 = x
    xp0, xp1 = x0 + (h * x1 + 0.0), 0.0 * x0 + (x1 + 0.0)  # F x
    q = (0.0 + xp0) + 0.0 * xp1  # [1, 0] x⁻
    (zp0, zp1, zp2), jv = point(constant, q)
    y = raw_y = (z[0] - zp0, z[1] - zp1, z[2] - zp2)
    raw_j = jv
    if white is not None:  # y ← L⁻¹ y, j ← L⁻¹ ∂f/∂q, so S = a j jᵀ + ρC becomes a j jᵀ + ρI (SPEC 4)
        l0, l1, l2 = white
        y = (l0[0] * y[0], l1[0] * y[0] + l1[1] * y[1], l2[0] * y[0] + l2[1] * y[1] + l2[2] * y[2])
        jv = (l0[0] * jv[0], l1[0] * jv[0] + l1[1] * jv[1], l2[0] * jv[0] + l2[1] * jv[1] + l2[2] * jv[2])
    jj = ((0.0 + jv[0] * jv[0]) + jv[1] * jv[1]) + jv[2] * jv[2]
    jy = ((0.0 + jv[0] * y[0]) + jv[1] * y[1]) + jv[2] * y[2]
    yy = ((0.0 + y[0] * y[0]) + y[1] * y[1]) + y[2] * y[2]
    return xp0, xp1, Pp, raw_y, raw_j, jj, jy, yy


def update_row(xp0: float, xp1: float, Pp, jj: float, jy: float, r: float, m: float) -> tuple:
    """One row's isotropic update (d = 1, M = ρ + P⁻00 j·j): the new x (2 floats) and P ((2, 2) nested)."""
    p00, p01, p10, p11 = Pp
    x = (xp0 + p00 * (jy / m), xp1 + p10 * (jy / m))  # K y, K = p0 jᵀ/M
    i00, i10 = 1.0 - p00 * (jj / m), 0.0 - p10 * (jj / m)  # I − K H
    b00, b01 = (i00 * p00 + 0.0) + 0.0 * p10, (i00 * p01 + 0.0) + 0.0 * p11  # (I − KH) P⁻
    b10, b11 = p10 + (i10 * p00 + 0.0), p11 + (i10 * p01 + 0.0)
    c = r * jj / (m * m)  # Joseph form: (I − KH) P⁻ (I − KH)ᵀ + c p₀p₀ᵀ
    n00 = ((b00 * i00 + 0.0) + 0.0 * b01) + c * (p00 * p00)
    n01 = (b01 + (b00 * i10 + 0.0)) + c * (p00 * p10)
    n10 = ((b10 * i00 + 0.0) + 0.0 * b11) + c * (p10 * p00)
    n11 = (b11 + (b10 * i10 + 0.0)) + c * (p10 * p10)
    return x, ((0.5 * (n00 + n00), 0.5 * (n01 + n10)), (0.5 * (n10 + n01), 0.5 * (n11 + n11)))
