"""Eigen 3.4's general real eigensolver ``Eigen::EigenSolver<Eigen::Matrix3f>``, replicated in float32.

PCL 1.13's RoPS builds its local reference frame with this solver, in float32, on a (nearly symmetric) 3 × 3
scatter matrix. Its eigenvectors are ~1e-6 away from the exact ones, and RoPS's bins are sensitive to 1e-6
changes of the frame: to give PCL's numbers the frame has to come out of the same float32 operations. No Python
library exposes that solver (NumPy and SciPy call LAPACK, with other algorithms), so it is written here from Eigen
3.4's headers (EigenSolver.h, RealSchur.h, HessenbergDecomposition.h, Householder.h, Jacobi.h), operation for
operation and in the same order, for the 3 × 3 case:

1. ``RealSchur::compute``: divide the matrix by its largest |coefficient|; Householder reduction to Hessenberg form
   (``HessenbergDecomposition``) and its Q; Francis double-shift QR steps with Eigen's shifts, deflation test
   (|T[i, i-1]| ≤ max(eps (|T[i-1, i-1]| + |T[i, i]|), eps² ‖T‖₁)), exceptional shifts at iterations 10 and 30,
   and 2 × 2 blocks split off by a Givens rotation when their eigenvalues are real; multiply T back by the scale.
2. ``EigenSolver::compute``: eigenvalues from the diagonal / 2 × 2 blocks of T; ``doComputeEigenvectors``: back
   substitution in T, then U times those vectors.
3. ``EigenSolver::eigenvectors``: each column divided by its norm, rows 0-1 the way Eigen's SSE2 packet division
   does it, row 2 as a scalar complex division.

Every product, sum and quotient is a single float32 operation, as Eigen's code does for 3 × 3 float matrices when
compiled for the x86-64 baseline (SSE2, no FMA), as Debian builds PCL; builds with FMA, AVX or NEON round
differently. Sums of three terms follow Eigen's reduction order: ``a + (b + c)`` for fixed-size vectors,
``(a + b) + c`` for dynamic-size segments. Complex divisions (complex eigenvalues only) follow libgcc's
``__divsc3`` (GCC ≥ 12): the textbook formula in float64, rounded to float32. Division by zero follows IEEE
(numba's numpy error model), as in C++. Checked bit for bit against the compiled Eigen and against PCL's own
``computeEigenVectors`` on recorded matrices (tests/features3d/test_eigen_f32.py).
"""

from __future__ import annotations

import math

import numba
import numpy as np

_F0 = np.float32(0.0)
_F1 = np.float32(1.0)
_HALF = np.float32(0.5)
_NEG0 = np.float32(-0.0)
_EPS = np.float32(np.finfo(np.float32).eps)
_FLT_MIN = np.float32(np.finfo(np.float32).tiny)  # std::numeric_limits<float>::min()
# Eigen's maximum number of QR iterations per row (RealSchur::m_maxIterationsPerRow).
_MAX_ITERATIONS_PER_ROW = 40


@numba.njit(cache=True, inline="always", error_model="numpy")
def _maxi(a, b):
    # numext::maxi is std::max: (a < b) ? b : a.
    return b if a < b else a


@numba.njit(cache=True, inline="always", error_model="numpy")
def _make_householder(c0, t0, t1, n_tail):
    """MatrixBase::makeHouseholder of (c0, t0[, t1]), n_tail = 1 or 2: (tau, beta, essential0, essential1)."""
    tail_sq = t0 * t0 if n_tail == 1 else t0 * t0 + t1 * t1
    if tail_sq <= _FLT_MIN:
        return _F0, c0, _F0, _F0
    beta = np.float32(math.sqrt(c0 * c0 + tail_sq))
    if c0 >= _F0:
        beta = -beta
    d = c0 - beta
    return (beta - c0) / beta, beta, t0 / d, t1 / d


@numba.njit(cache=True, error_model="numpy")
def _householder_left(m, r0, n_ess, c_lo, c_hi, e0, e1, tau):
    """applyHouseholderOnTheLeft: rows r0..r0+n_ess of m, columns c_lo..c_hi-1, v = (1, e0[, e1])."""
    if tau == _F0:
        return
    for j in range(c_lo, c_hi):
        tmp = e0 * m[r0 + 1, j]
        if n_ess == 2:
            tmp = tmp + e1 * m[r0 + 2, j]
        tmp = tmp + m[r0, j]
        m[r0, j] = m[r0, j] - tau * tmp
        m[r0 + 1, j] = m[r0 + 1, j] - tmp * (tau * e0)
        if n_ess == 2:
            m[r0 + 2, j] = m[r0 + 2, j] - tmp * (tau * e1)


@numba.njit(cache=True, error_model="numpy")
def _householder_right(m, c0, n_ess, r_lo, r_hi, e0, e1, tau):
    """applyHouseholderOnTheRight: columns c0..c0+n_ess of m, rows r_lo..r_hi-1, v = (1, e0[, e1])."""
    if tau == _F0:
        return
    for i in range(r_lo, r_hi):
        tmp = m[i, c0 + 1] * e0
        if n_ess == 2:
            tmp = tmp + m[i, c0 + 2] * e1
        tmp = tmp + m[i, c0]
        m[i, c0] = m[i, c0] - tau * tmp
        t = tau * tmp
        m[i, c0 + 1] = m[i, c0 + 1] - e0 * t
        if n_ess == 2:
            m[i, c0 + 2] = m[i, c0 + 2] - e1 * t


@numba.njit(cache=True, inline="always", error_model="numpy")
def _make_givens(p, q):
    """JacobiRotation::makeGivens(p, q) for real scalars: (c, s)."""
    if q == _F0:
        return (-_F1 if p < _F0 else _F1), _F0
    if p == _F0:
        return _F0, (_F1 if q < _F0 else -_F1)
    if abs(p) > abs(q):
        t = q / p
        u = np.float32(math.sqrt(_F1 + t * t))
        if p < _F0:
            u = -u
        c = _F1 / u
        return c, -t * c
    t = p / q
    u = np.float32(math.sqrt(_F1 + t * t))
    if q < _F0:
        u = -u
    s = -_F1 / u
    return -t * s, s


@numba.njit(cache=True, error_model="numpy")
def _rotate_rows(m, p, q, c_lo, c, s):
    """m.rightCols(..).applyOnTheLeft(p, q, J(c, s).adjoint()): rows p, q from column c_lo on."""
    if c == _F1 and s == _F0:
        return
    for j in range(c_lo, m.shape[1]):
        x = m[p, j]
        y = m[q, j]
        m[p, j] = c * x + (-s) * y
        m[q, j] = s * x + c * y


@numba.njit(cache=True, error_model="numpy")
def _rotate_cols(m, p, q, r_hi, c, s):
    """m.topRows(r_hi).applyOnTheRight(p, q, J(c, s)): columns p, q of rows 0..r_hi-1."""
    if c == _F1 and s == _F0:
        return
    for i in range(r_hi):
        x = m[i, p]
        y = m[i, q]
        m[i, p] = c * x + (-s) * y
        m[i, q] = s * x + c * y


@numba.njit(cache=True, error_model="numpy")
def _real_schur(a, t, u):
    """RealSchur<Matrix3f>::compute(a) with U: writes T into t and U into u; False when QR did not converge."""
    n = 3
    scale = _F0
    for i in range(n):
        for j in range(n):
            scale = _maxi(scale, abs(a[i, j]))
    u[:] = _F0
    for i in range(n):
        u[i, i] = _F1
    if scale < _FLT_MIN:
        t[:] = _F0
        return True
    for i in range(n):
        for j in range(n):
            t[i, j] = a[i, j] / scale

    # HessenbergDecomposition: one reflector, for column 0 (column 1's has tau = 0: identity in 3 × 3).
    tau, beta, e0, _e1 = _make_householder(t[1, 0], t[2, 0], _F0, 1)
    t[1, 0] = beta
    t[2, 0] = _F0  # matrixH() zeroes what lies below the subdiagonal (the stored reflector)
    _householder_left(t, 1, 1, 1, 3, e0, _F0, tau)
    _householder_right(t, 1, 1, 0, 3, e0, _F0, tau)
    # Q: that reflector applied to the identity (HouseholderSequence::evalTo, bottom-right 2 × 2 corner).
    _householder_left(u, 1, 1, 1, 3, e0, _F0, tau)

    # computeFromHessenberg
    max_iters = _MAX_ITERATIONS_PER_ROW * n
    norm = _F0
    for j in range(n):
        col = abs(t[0, j])
        for i in range(1, min(n, j + 2)):
            col = col + abs(t[i, j])
        norm += col
    consider_zero = _maxi(norm * (_EPS * _EPS), _FLT_MIN)
    iu = n - 1
    it = 0
    total_it = 0
    exshift = _F0
    if norm != _F0:
        while iu >= 0:
            # findSmallSubdiagEntry
            il = iu
            while il > 0:
                s = abs(t[il - 1, il - 1]) + abs(t[il, il])
                s = _maxi(s * _EPS, consider_zero)
                if abs(t[il, il - 1]) <= s:
                    break
                il -= 1
            if il == iu:  # one root found
                t[iu, iu] = t[iu, iu] + exshift
                if iu > 0:
                    t[iu, iu - 1] = _F0
                iu -= 1
                it = 0
            elif il == iu - 1:  # two roots found: splitOffTwoRows
                p = _HALF * (t[iu - 1, iu - 1] - t[iu, iu])
                q = p * p + t[iu, iu - 1] * t[iu - 1, iu]
                t[iu, iu] += exshift
                t[iu - 1, iu - 1] += exshift
                if q >= _F0:
                    z = np.float32(math.sqrt(abs(q)))
                    if p >= _F0:
                        c, s = _make_givens(p + z, t[iu, iu - 1])
                    else:
                        c, s = _make_givens(p - z, t[iu, iu - 1])
                    _rotate_rows(t, iu - 1, iu, iu - 1, c, s)
                    _rotate_cols(t, iu - 1, iu, iu + 1, c, s)
                    t[iu, iu - 1] = _F0
                    _rotate_cols(u, iu - 1, iu, n, c, s)
                if iu > 1:
                    t[iu - 1, iu - 2] = _F0
                iu -= 2
                it = 0
            else:
                # No subdiagonal is negligible: in 3 × 3 the active window is the whole matrix (il = 0, iu = 2),
                # so Eigen's QR step starts at row 0 (initFrancisQRStep's im = 0) and has one 3-reflector.
                # computeShift
                x = t[2, 2]
                y = t[1, 1]
                w = t[2, 1] * t[1, 2]
                if it == 10:  # Wilkinson's ad hoc shift
                    exshift += x
                    for i in range(n):
                        t[i, i] -= x
                    s = abs(t[2, 1]) + abs(t[1, 0])
                    x = np.float32(0.75) * s
                    y = np.float32(0.75) * s
                    w = np.float32(-0.4375) * s * s
                if (
                    it == 30
                ):  # MATLAB's ad hoc shift (never reached in our tests: 3 × 3 converges sooner)
                    s = (y - x) / np.float32(2.0)
                    s = s * s + w
                    if s > _F0:
                        s = np.float32(math.sqrt(s))
                        if y < x:
                            s = -s
                        s = s + (y - x) / np.float32(2.0)
                        s = x - w / s
                        exshift += s
                        for i in range(n):
                            t[i, i] -= s
                        x = np.float32(0.964)
                        y = np.float32(0.964)
                        w = np.float32(0.964)
                it += 1
                total_it += 1
                if total_it > max_iters:
                    break
                # initFrancisQRStep: first column of (T - s1)(T - s2), scaled
                tmm = t[0, 0]
                r = x - tmm
                s = y - tmm
                v0 = (r * s - w) / t[1, 0] + t[0, 1]
                v1 = t[1, 1] - tmm - r - s
                v2 = t[2, 1]
                # performFrancisQRStep
                tau, beta, e0, e1 = _make_householder(v0, v1, v2, 2)
                if beta != _F0:
                    _householder_left(t, 0, 2, 0, n, e0, e1, tau)
                    _householder_right(t, 0, 2, 0, n, e0, e1, tau)
                    _householder_right(u, 0, 2, 0, n, e0, e1, tau)
                tau, beta, e0, _e1 = _make_householder(t[1, 0], t[2, 0], _F0, 1)
                if beta != _F0:
                    t[1, 0] = beta
                    _householder_left(t, 1, 1, 1, n, e0, _F0, tau)
                    _householder_right(t, 1, 1, 0, n, e0, _F0, tau)
                    _householder_right(u, 1, 1, 0, n, e0, _F0, tau)
                t[2, 0] = _F0  # clean up pollution due to round-off errors
    if total_it > max_iters:
        return False
    for i in range(n):
        for j in range(n):
            t[i, j] *= scale
    return True


@numba.njit(cache=True, inline="always", error_model="numpy")
def _cdiv(a, b, c, d):
    """(a + ib) / (c + id) as libgcc's __divsc3 (GCC >= 12): float64 arithmetic, rounded to float32."""
    aa = np.float64(a)
    bb = np.float64(b)
    cc = np.float64(c)
    dd = np.float64(d)
    den = cc * cc + dd * dd
    return np.float32((aa * cc + bb * dd) / den), np.float32((bb * cc - aa * dd) / den)


@numba.njit(cache=True, inline="always", error_model="numpy")
def _scale_down(a, b, c, row):
    """Element ``row`` of a complex 3-vector divided by the real c, as ``normalize()`` does it in Eigen 3.4.

    The division of the fixed-size column is vectorised two complex numbers at a time (SSE ``pdiv<Packet2cf>``:
    (a c) / (c c), each rounded to float32) for rows 0 and 1; row 2 is a scalar std::complex division.
    """
    if row < 2:
        # pmul(x, pconj(y)) / (|y|², |y|²) with y = (c, +0): the zero products keep their signs.
        cc = c * c + _F0
        return (a * c + (-(b * _NEG0))) / cc, (a * _NEG0 + b * c) / cc
    return _cdiv(a, b, c, _F0)


@numba.njit(cache=True, error_model="numpy")
def _row_dot(t, i, lo, hi, col):
    """m_matT.row(i).segment(lo, ..).dot(m_matT.col(col).segment(lo, ..)): dynamic size, left to right."""
    r = t[i, lo] * t[lo, col]
    for k in range(lo + 1, hi):
        r = r + t[i, k] * t[k, col]
    return r


@numba.njit(cache=True, error_model="numpy")
def _back_substitute(t, u, re, im):
    """EigenSolver::doComputeEigenvectors: overwrites t with the vectors of T, u with U times them."""
    size = 3
    norm = _F0
    for j in range(size):
        lo = max(j - 1, 0)
        row = abs(t[j, lo])
        for k in range(lo + 1, size):
            row = row + abs(t[j, k])
        norm += row
    if norm == _F0:
        return
    n = size - 1
    while n >= 0:
        p = re[n]
        q = im[n]
        if q == _F0:  # real vector
            lastr = _F0
            lastw = _F0
            l = n
            t[n, n] = _F1
            for i in range(n - 1, -1, -1):
                w = t[i, i] - p
                r = _row_dot(t, i, l, n + 1, n)
                if im[i] < _F0:
                    lastw = w
                    lastr = r
                else:
                    l = i
                    if im[i] == _F0:
                        if w != _F0:
                            t[i, n] = -r / w
                        else:
                            t[i, n] = -r / (_EPS * norm)
                    else:  # real equations of a 2 × 2 block
                        x = t[i, i + 1]
                        y = t[i + 1, i]
                        denom = (re[i] - p) * (re[i] - p) + im[i] * im[i]
                        tt = (x * lastr - lastw * r) / denom
                        t[i, n] = tt
                        if abs(x) > abs(lastw):
                            t[i + 1, n] = (-r - w * tt) / x
                        else:
                            t[i + 1, n] = (-lastr - y * tt) / lastw
                    tt = abs(t[i, n])  # overflow control
                    if (_EPS * tt) * tt > _F1:
                        for k in range(i, size):
                            t[k, n] /= tt
        elif q < _F0 and n > 0:  # complex vector (columns n-1, n)
            l = n - 1
            if abs(t[n, n - 1]) > abs(t[n - 1, n]):
                t[n - 1, n - 1] = q / t[n, n - 1]
                t[n - 1, n] = -(t[n, n] - p) / t[n, n - 1]
            else:
                t[n - 1, n - 1], t[n - 1, n] = _cdiv(_F0, -t[n - 1, n], t[n - 1, n - 1] - p, q)
            t[n, n - 1] = _F0
            t[n, n] = _F1
            # In 3 × 3 the other eigenvalue is real: Eigen's branches for a second complex pair never run.
            for i in range(n - 2, -1, -1):
                ra = _row_dot(t, i, l, n + 1, n - 1)
                sa = _row_dot(t, i, l, n + 1, n)
                w = t[i, i] - p
                l = i
                t[i, n - 1], t[i, n] = _cdiv(-ra, -sa, w, q)
                tt = _maxi(abs(t[i, n - 1]), abs(t[i, n]))  # overflow control
                if (_EPS * tt) * tt > _F1:
                    for k in range(i, size):
                        t[k, n - 1] /= tt
                        t[k, n] /= tt
            n -= 1
        n -= 1
    # back transformation: column j of U ← U[:, :j+1] · T[:j+1, j]
    tmp = np.empty(size, dtype=np.float32)
    for j in range(size - 1, -1, -1):
        for i in range(size):
            acc = u[i, 0] * t[0, j]
            for k in range(1, j + 1):
                acc = acc + u[i, k] * t[k, j]
            tmp[i] = acc
        for i in range(size):
            u[i, j] = tmp[i]


@numba.njit(cache=True, error_model="numpy")
def eigen_solver_3x3(a: np.ndarray) -> tuple[bool, np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """``Eigen::EigenSolver<Matrix3f>(a)``: (ok, eigenvalues re, im, eigenvectors re, im), float32.

    a is a (3, 3) float32 array. Eigenvector j is column j, of unit norm, as ``eigenvectors()`` returns it;
    eigenvalues in Eigen's order (not sorted). ok is False (and the arrays NaN) where Eigen reports NoConvergence
    or NumericalIssue (as for most non-finite inputs).
    """
    t = np.empty((3, 3), dtype=np.float32)
    u = np.empty((3, 3), dtype=np.float32)
    re = np.full(3, np.nan, dtype=np.float32)
    im = np.full(3, np.nan, dtype=np.float32)
    vre = np.full((3, 3), np.nan, dtype=np.float32)
    vim = np.full((3, 3), np.nan, dtype=np.float32)
    if not _real_schur(a, t, u):
        return False, re, im, vre, vim
    # eigenvalues from the diagonal and the 2 × 2 blocks of T
    i = 0
    while i < 3:
        if i == 2 or t[i + 1, i] == _F0:
            re[i] = t[i, i]
            im[i] = _F0
            i += 1
        else:
            p = _HALF * (t[i, i] - t[i + 1, i + 1])
            t0 = t[i + 1, i]
            t1 = t[i, i + 1]
            maxval = _maxi(abs(p), _maxi(abs(t0), abs(t1)))
            t0 /= maxval
            t1 /= maxval
            p0 = p / maxval
            z = maxval * np.float32(math.sqrt(abs(p0 * p0 + t0 * t1)))
            re[i] = t[i + 1, i + 1] + p
            im[i] = z
            re[i + 1] = t[i + 1, i + 1] + p
            im[i + 1] = -z
            i += 2
    for i in range(3):
        if not (np.isfinite(re[i]) and np.isfinite(im[i])):
            re[:] = np.nan
            im[:] = np.nan
            return False, re, im, vre, vim
    _back_substitute(t, u, re, im)
    # eigenvectors(): real columns, or conjugate pairs (u_j ± i u_{j+1}), divided by their norm
    prec = np.float32(2.0) * _EPS
    j = 0
    while j < 3:
        if abs(im[j]) <= abs(re[j]) * prec or j == 2:
            sq = u[0, j] * u[0, j] + (u[1, j] * u[1, j] + u[2, j] * u[2, j])
            nrm = np.float32(math.sqrt(sq))
            for k in range(3):
                vre[k, j], vim[k, j] = (
                    _scale_down(u[k, j], _F0, nrm, k) if sq > _F0 else (u[k, j], _F0)
                )
            j += 1
        else:
            a0 = u[0, j] * u[0, j] + u[0, j + 1] * u[0, j + 1]
            a1 = u[1, j] * u[1, j] + u[1, j + 1] * u[1, j + 1]
            a2 = u[2, j] * u[2, j] + u[2, j + 1] * u[2, j + 1]
            sq = a0 + (a1 + a2)
            nrm = np.float32(math.sqrt(sq))
            for k in range(3):
                if sq > _F0:
                    vre[k, j], vim[k, j] = _scale_down(u[k, j], u[k, j + 1], nrm, k)
                    vre[k, j + 1], vim[k, j + 1] = _scale_down(u[k, j], -u[k, j + 1], nrm, k)
                else:
                    vre[k, j], vim[k, j] = u[k, j], u[k, j + 1]
                    vre[k, j + 1], vim[k, j + 1] = u[k, j], -u[k, j + 1]
            j += 2
    return True, re, im, vre, vim
