"""MuJoCo's dense BLAS and Cholesky routines, in MuJoCo's order of operations.

``mju_dot`` sums the first multiple of 4 products in four interleaved partial sums (its AVX
path), ``(s0 + s2) + (s1 + s3)``, then adds the rest as one group; ``mju_cholFactor``,
``mju_cholSolve``, ``mju_mulMatMatT`` and ``mju_mulMatTVec`` are built on it. Repeating that order
makes the compiled controller's results bit-identical to calling MuJoCo.

The routines the tick calls are inlined into their callers (:func:`langenv.kernels.inline`): a
call of a few dozen flops costs as much as its arithmetic, and a caller that passes constant
sizes (the UR5's 6 x 6 least squares) gets them unrolled. Inlining moves no operation.
"""

from __future__ import annotations

import numpy as np

from langenv.kernels import inline, kernel

__all__ = [
    "chol_factor",
    "chol_solve",
    "dot",
    "mul_mat_mat_t",
    "mul_mat_t_vec",
    "mul_mat_vec",
    "sqr_mat_t",
]


@inline
def dot(a: np.ndarray, ia: int, b: np.ndarray, ib: int, n: int) -> float:
    """``mju_dot(a + ia, b + ib, n)`` on flat arrays."""
    res = 0.0
    i = 0
    if n >= 4:
        s0 = a[ia] * b[ib]
        s1 = a[ia + 1] * b[ib + 1]
        s2 = a[ia + 2] * b[ib + 2]
        s3 = a[ia + 3] * b[ib + 3]
        i = 4
        while i <= n - 4:
            s0 = s0 + a[ia + i] * b[ib + i]
            s1 = s1 + a[ia + i + 1] * b[ib + i + 1]
            s2 = s2 + a[ia + i + 2] * b[ib + i + 2]
            s3 = s3 + a[ia + i + 3] * b[ib + i + 3]
            i += 4
        res = (s0 + s2) + (s1 + s3)
    left = n - i
    if left == 3:
        res += a[ia + i] * b[ib + i] + a[ia + i + 1] * b[ib + i + 1] + a[ia + i + 2] * b[ib + i + 2]
    elif left == 2:
        res += a[ia + i] * b[ib + i] + a[ia + i + 1] * b[ib + i + 1]
    elif left == 1:
        res += a[ia + i] * b[ib + i]
    return res


@kernel
def mul_mat_mat_t(
    res: np.ndarray, m1: np.ndarray, m2: np.ndarray, r1: int, c1: int, r2: int
) -> None:
    """``mju_mulMatMatT``: ``res (r1, r2) = m1 (r1, c1) @ m2 (r2, c1).T`` on flat arrays."""
    for i in range(r1):
        for j in range(r2):
            res[i * r2 + j] = dot(m1, i * c1, m2, j * c1, c1)


@inline
def sqr_mat_t(res: np.ndarray, mat: np.ndarray, r: int, c: int) -> None:
    """``mju_mulMatMatT(res, mat, mat, r, c, r)``: ``res (r, r) = mat (r, c) @ mat.T``, one
    :func:`dot` per entry of the lower triangle, mirrored: entry ``(j, i)``'s dot multiplies the
    same pairs in the same order as ``(i, j)``'s (each product's factors swapped, which IEEE
    multiplication does not see), so ``res`` is bit for bit :func:`mul_mat_mat_t`'s."""
    for i in range(r):
        for j in range(i + 1):
            v = dot(mat, i * c, mat, j * c, c)
            res[i * r + j] = v
            res[j * r + i] = v


@inline
def mul_mat_vec(res: np.ndarray, mat: np.ndarray, vec: np.ndarray, nr: int, nc: int) -> None:
    """``mju_mulMatVec``: ``res (nr,) = mat (nr, nc) @ vec (nc,)``, one :func:`dot` per row."""
    for r in range(nr):
        res[r] = dot(mat, r * nc, vec, 0, nc)


@inline
def mul_mat_t_vec(res: np.ndarray, mat: np.ndarray, vec: np.ndarray, nr: int, nc: int) -> None:
    """``mju_mulMatTVec``: ``res (nc,) = mat (nr, nc).T @ vec (nr,)``, zero entries skipped."""
    for j in range(nc):
        res[j] = 0.0
    for r in range(nr):
        v = vec[r]
        if v != 0.0:
            for j in range(nc):
                res[j] += mat[r * nc + j] * v


@inline
def chol_factor(mat: np.ndarray, n: int, mindiag: float) -> int:
    """``mju_cholFactor``: in-place ``mat = L L'`` (flat, row-major); returns the rank."""
    rank = n
    for j in range(n):
        tmp = mat[j * (n + 1)]
        if j:
            tmp -= dot(mat, j * n, mat, j * n, j)
        deficient = tmp < mindiag
        if deficient:
            tmp = mindiag
            rank -= 1
        mat[j * (n + 1)] = np.sqrt(tmp)
        if deficient:
            for i in range(j + 1, n):
                mat[i * n + j] = 0.0
        else:
            tmp = 1.0 / mat[j * (n + 1)]
            for i in range(j + 1, n):
                mat[i * n + j] = (mat[i * n + j] - dot(mat, i * n, mat, j * n, j)) * tmp
    return rank


@inline
def chol_solve(res: np.ndarray, mat: np.ndarray, vec: np.ndarray, n: int) -> None:
    """``mju_cholSolve`` (MuJoCo 4): ``res = (L L')^-1 vec``, ``mat`` from :func:`chol_factor`."""
    for i in range(n):
        res[i] = vec[i]
    for i in range(n):
        if i:
            res[i] -= dot(mat, i * n, res, 0, i)
        res[i] /= mat[i * (n + 1)]
    for j in range(n - 1, -1, -1):  # backward, column by column (MuJoCo 4's order)
        res[j] /= mat[j * (n + 1)]
        rj = res[j]
        for i in range(j):
            res[i] -= mat[j * n + i] * rj
