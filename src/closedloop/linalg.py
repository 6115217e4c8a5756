"""Linear algebra of constrained systems, written once: small and batched solves, the augmented
matrix of (12), the orthogonal complement R of (20) and a null-space basis of Phi_s.

Every formulation, the kinematics and the basin map solve their small systems here, so a
singular matrix is refused with one message wherever it is met.
"""

from __future__ import annotations

import math

import numpy as np

from .errors import InputError, SingularConfigurationError, at_time
from .loading import first_use
from .validation import one_of

__all__ = ["augmented_matrix", "solve_augmented", "solve_small", "solve_dense", "solve_many", "condition_number",
           "orthogonal_complement", "orthogonal_complement_many", "partition_condition", "partition_determinant",
           "null_space_basis", "SINGULAR_TOLERANCE", "CONDITION_LIMIT", "RANK_LIMIT", "NULL_SPACE_BASES", "NEAR_RANK_LOSS",
           "NEARLY_SINGULAR"]


def augmented_matrix(M, Phi):
    """``[[M, Phi_s^T], [Phi_s, 0]]``, the matrix of (12) and (16).

    Parameters
    ----------
    M : ndarray, shape (n, n)
        The mass matrix.
    Phi : ndarray, shape (r, n)
        The constraint Jacobian Phi_s.

    Returns
    -------
    ndarray, shape (n + r, n + r)
    """
    n, r = M.shape[0], Phi.shape[0]
    K = np.zeros((n + r, n + r))
    K[:n, :n] = M
    K[:n, n:] = Phi.T
    K[n:, :n] = Phi
    return K


def solve_augmented(M, Phi, p1, p2, t=None):
    """Solve ``[[M, Phi^T], [Phi, 0]] [s''; lambda] = [p1; p2]`` (12), (16)."""
    n = M.shape[0]
    K = augmented_matrix(M, Phi)
    try:
        x = solve_dense(K, np.concatenate((p1, p2)))
    except np.linalg.LinAlgError:
        if not np.all(np.isfinite(K)):
            raise SingularConfigurationError(
                f"the augmented matrix of (12) is not finite{at_time(t)}: the state it was formed at is not "
                "(a step whose stage overflowed, or a force that returned NaN before it)") from None
        raise SingularConfigurationError(
            f"the augmented matrix of (12) is singular{at_time(t)}: the constraints are dependent "
            "(cond(Phi_s) = inf: assembly branches meet, a change point) and no formulation of this library "
            "passes it; end the run before it, or change the geometry"
        ) from None
    return x[:n], x[n:]


@first_use
def _gesv():
    """LAPACK's ``dgesv`` (LU with partial pivoting, then the two triangular solves), from scipy.linalg,
    imported on first use (not with this module: scipy.linalg costs about 0.2 s to import)."""
    from scipy.linalg.lapack import dgesv

    return dgesv


@first_use
def _qr():
    """scipy.linalg's QR factorisation, imported on first use (scipy.linalg costs about 0.2 s to import)."""
    from scipy.linalg import qr

    return qr


def solve_dense(A, b):
    """Solve ``A x = b`` for a square real A (n >= 3) by LAPACK's ``dgesv``, the routine numpy.linalg.solve
    calls too: the same LU with partial pivoting, without numpy's checks and dispatch, which cost most of
    a small solve such as the augmented matrix of (12) at every right-hand side.

    Raises ``numpy.linalg.LinAlgError`` for an exactly singular A (a zero pivot), like numpy.
    """
    lu, pivots, x, info = _gesv()(A, b)
    if info > 0:
        raise np.linalg.LinAlgError("Singular matrix")
    if info < 0:                            # an argument LAPACK refused: a bug here, never the data
        raise ValueError(f"dgesv: argument {-info} is invalid")
    return x


#: |det| / |A|_F^2 at or below which a 2 x 2 matrix counts as singular (cond(A) >~ 1/this).
SINGULAR_TOLERANCE = 1e-14


def solve_small(A, b):
    """Solve ``A x = b`` for a square A; closed form for 1 x 1 and 2 x 2.

    numpy's solver costs a few microseconds of overhead per call, more than the
    arithmetic of a 2 x 2 system: the minimal formulation makes several such
    solves per right-hand-side evaluation.  Raises ``numpy.linalg.LinAlgError``
    for a singular A, like numpy, and also for a 2 x 2 A that is singular to
    working precision (``|det A|`` at most ``SINGULAR_TOLERANCE`` times the squared
    Frobenius norm of A, i.e. cond(A) of order 1e14 or more), whose solution is
    round-off only: at a change point of a linkage, rounding leaves such a
    determinant of about 1e-16 instead of 0.
    """
    size = A.shape[0]
    if size == 1:
        a = A[0, 0]
        if a == 0.0 or not np.isfinite(a):
            raise np.linalg.LinAlgError("Singular matrix")
        return b / a
    if size == 2:                          # on Python floats: the same IEEE arithmetic as numpy's scalars
        (a, c), (d, e) = A.tolist()
        det = a * e - c * d
        if not math.isfinite(det) or abs(det) <= SINGULAR_TOLERANCE * (a * a + c * c + d * d + e * e):
            raise np.linalg.LinAlgError("Singular matrix")
        if b.ndim == 1:
            b0, b1 = b.tolist()
            return np.array([(e * b0 - c * b1) / det, (a * b1 - d * b0) / det])
        return np.array([e * b[0] - c * b[1], a * b[1] - d * b[0]]) / det
    return solve_dense(A, b)


#: cond(Phi_s) above which a message says that Phi_s nearly loses rank, two assembly branches coming close (below
#: it, a large Kantorovich number comes from a large |f|: a drift, at a well-conditioned configuration).
NEAR_RANK_LOSS = 100.0
#: cond(Phi_s), or |Phi_s| |Phi_z^-1| of a partition, above which a message about a run that could not go on names
#: that matrix as nearly singular there.
NEARLY_SINGULAR = 1e3

#: |Phi_s| |Phi_z^-1| (:func:`partition_condition`) above which R of (20) is refused: a state is then
#: within 1e-10 of a dead position, relative to the constraints' own scale, and what R gives there keeps
#: fewer than about 16 - log10(1e10) = 6 significant digits, fewer than any tolerance in this book.
CONDITION_LIMIT = 1e10


def _top_and_det(a, c, d, e):
    """``(sigma_max^2, |det A|)`` of ``A = [[a, c], [d, e]]`` in closed form: sigma_1^2 + sigma_2^2 = |A|_F^2
    and sigma_1 sigma_2 = |det A|, so sigma_min = |det A| / sigma_max."""
    det = abs(a * e - c * d)
    frobenius2 = a * a + c * c + d * d + e * e
    return 0.5 * (frobenius2 + math.sqrt(max(frobenius2 * frobenius2 - 4.0 * det * det, 0.0))), det


def condition_number(A):
    """The 2-norm condition number sigma_max / sigma_min of a matrix (``inf`` if singular).

    Closed form for 1 x 1 and 2 x 2 matrices (cheap enough to check at every
    right-hand-side evaluation), singular values otherwise.
    """
    A = np.asarray(A, dtype=float)
    if A.shape == (1, 1):
        return 1.0 if A[0, 0] != 0.0 else math.inf
    if A.shape == (2, 2):                  # on Python floats, summed in numpy's order: the same numbers
        top, det = _top_and_det(*A.ravel().tolist())
        return math.inf if det == 0.0 else top / det          # sigma_max / sigma_min = sigma_max^2 / |det A|
    singular_values = np.linalg.svd(A, compute_uv=False)
    return math.inf if singular_values[-1] == 0.0 else float(singular_values[0] / singular_values[-1])


def partition_determinant(Phi, z_index):
    """det Phi_z, the determinant of the columns z of Phi_s in the partition s = (q, z) of (20).

    R of (20) exists where it is not zero, and its sign tells the two assembly
    branches of a partition apart: a change of sign along a motion is a dead
    position of the independent coordinates q.

    Parameters
    ----------
    Phi : ndarray, shape (r, n) or (r, n, K)
        Phi_s at one configuration, or at K configurations along the last axis.
    z_index : sequence of int
        The r dependent coordinates.

    Returns
    -------
    float or ndarray, shape (K,)
        det Phi_z (closed form for r <= 2, LU otherwise).
    """
    Phi = np.asarray(Phi, dtype=float)
    if Phi.ndim == 2:
        return float(partition_determinant(Phi[:, :, None], z_index)[0])
    Phi_z = Phi[:, list(z_index), :]
    r = Phi_z.shape[0]
    if r == 1:
        return Phi_z[0, 0].copy()
    if r == 2:
        return Phi_z[0, 0] * Phi_z[1, 1] - Phi_z[0, 1] * Phi_z[1, 0]
    return np.linalg.det(np.moveaxis(Phi_z, 2, 0))


def partition_condition(Phi, z_index):
    """``|Phi_s| |Phi_z^-1|`` in the 2-norm: how near Phi_z is to singular, against the whole Phi_s.

    cond(Phi_z) = |Phi_z| |Phi_z^-1| alone misses a Phi_z that is small as a whole: a 1 x 1
    Phi_z has condition 1 unless it is exactly 0, and so has ``1e-17 I``; there R of (20) is
    huge and the state lies within rounding of a dead position.  Measured against Phi_s this is
    at least cond(Phi_z), and the two agree where Phi_z carries Phi_s's scale (for the
    slider-crank they differ by less than a factor 2).  ``inf`` where Phi_z is singular or any
    entry is not finite.  Closed forms for r <= 2 (cheap enough for every right-hand side),
    singular values otherwise.
    """
    Phi = np.asarray(Phi, dtype=float)
    return _partition_condition(Phi, Phi[:, z_index])


def _partition_condition(Phi, Phi_z):
    """:func:`partition_condition` with Phi_z taken out of the float array Phi by the caller."""
    r = Phi_z.shape[0]
    if r == 1:
        smallest = abs(float(Phi_z[0, 0]))
        largest = math.sqrt(sum(v * v for v in Phi[0].tolist()))
    elif r == 2:
        top, det = _top_and_det(*Phi_z.ravel().tolist())
        smallest = det / math.sqrt(top) if top > 0.0 else 0.0
        first, second = Phi.tolist()       # the larger eigenvalue of the 2 x 2 Gram matrix Phi_s Phi_s^T
        g11, g22 = sum(v * v for v in first), sum(v * v for v in second)
        g12 = sum(u * v for u, v in zip(first, second))
        largest = math.sqrt(0.5 * (g11 + g22) + math.sqrt(0.25 * (g11 - g22) ** 2 + g12 * g12))
    else:
        if not np.all(np.isfinite(Phi)):
            return math.inf
        smallest = float(np.linalg.svd(Phi_z, compute_uv=False)[-1])
        largest = float(np.linalg.norm(Phi, 2))
    value = largest / smallest if smallest > 0.0 else math.inf
    return value if math.isfinite(value) else math.inf       # NaN entries: inf, refused as singular


def orthogonal_complement(Phi, q_index, z_index, t=None):
    """R of (20) from Phi_s, in the order of s; see :meth:`System.orthogonal_complement`.

    Raises :class:`~closedloop.errors.SingularConfigurationError` when
    :func:`partition_condition` exceeds :data:`CONDITION_LIMIT` (or Phi_z is not finite).
    """
    Phi_q, Phi_z = Phi[:, q_index], Phi[:, z_index]
    condition = _partition_condition(Phi, Phi_z)
    if condition > CONDITION_LIMIT:
        raise SingularConfigurationError(
            f"Phi_z is singular{at_time(t)}: |Phi_s| |Phi_z^-1| = {condition:.3g} > {CONDITION_LIMIT:.0e}, so R of "
            "(20) does not exist at this configuration (a dead position of the independent coordinates); "
            "use the NullSpace formulation, which needs no partition"
        )
    X = solve_small(Phi_z, Phi_q)
    R = np.empty((Phi.shape[1], len(q_index)))
    R[q_index] = np.eye(len(q_index))
    R[z_index] = -X
    return R


def solve_many(A, b):
    """Solve ``A[:, :, j] x[:, j] = b[:, j]`` for every j; A of shape (m, m, K), b of shape (m, K)."""
    m = A.shape[0]
    if m == 1:
        det = A[0, 0]
        bad = det == 0.0
        x = b / np.where(bad, 1.0, det)
    elif m == 2:
        det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
        bad = det == 0.0
        det = np.where(bad, 1.0, det)
        x = np.array([A[1, 1] * b[0] - A[0, 1] * b[1], A[0, 0] * b[1] - A[1, 0] * b[0]]) / det
    else:
        A_stack = np.moveaxis(A, -1, 0)
        bad = np.linalg.det(A_stack) == 0.0
        x = np.linalg.solve(np.where(bad[:, None, None], np.eye(m), A_stack), b.T[:, :, None])[:, :, 0].T
    if np.any(bad):
        raise SingularConfigurationError(
            "Phi_z is singular at some cells of the batch: R of (20) does not exist there"
        )
    return x


def orthogonal_complement_many(Phi, q_index, z_index):
    """R of (20) at K states at once: ``R[z] = -Phi_z^{-1} Phi_q``, ``R[q] = E``, in the order of s.

    Parameters
    ----------
    Phi : ndarray, shape (r, n, K)
        Phi_s of (9) at K states.
    q_index, z_index : ndarray of int
        Positions of q and z in s.

    Returns
    -------
    R : ndarray, shape (n, f, K)

    Raises
    ------
    SingularConfigurationError
        If Phi_z is singular at some state (see :func:`solve_many`).  Unlike
        :func:`orthogonal_complement`, no condition limit is applied.
    """
    Phi_z = Phi[:, z_index]
    R = np.zeros((Phi.shape[1], len(q_index), Phi.shape[2]))
    for column, coordinate in enumerate(q_index):
        R[coordinate, column] = 1.0
        R[z_index, column] = -solve_many(Phi_z, Phi[:, coordinate])
    return R


#: sigma_min(Phi_s) / sigma_max(Phi_s) below which Phi_s counts as rank deficient.
RANK_LIMIT = 1e-10
#: The ways :func:`null_space_basis` builds R: from the SVD, or by pivoted partitioning.
NULL_SPACE_BASES = ("svd", "pivoted")


def null_space_basis(Phi, basis="svd", t=None):
    """An n x f matrix N whose columns span the null space of Phi_s: Phi_s N = 0 (18).

    Any such N can replace R of (20) in (24)-(26): N = R T with T invertible,
    so ``N^T M s'' = N^T p1`` and ``R^T M s'' = R^T p1`` are the same equations.

    Parameters
    ----------
    Phi : ndarray, shape (r, n)
        Phi_s of (9).
    basis : {"svd", "pivoted"}
        ``"svd"``: the last f right singular vectors of Phi_s, an orthonormal
        basis.  ``"pivoted"``: coordinate partitioning with pivoting, R of (20)
        for the partition that QR with column pivoting finds best conditioned
        (its first r pivot columns become z) at this configuration.
    t : float, optional
        Time, only for error messages.

    Raises
    ------
    SingularConfigurationError
        If Phi_s itself loses rank (sigma_min / sigma_max < :data:`RANK_LIMIT`):
        the constraints are dependent, assembly branches meet there, and no
        choice of coordinates passes such a bifurcation.
    """
    try:
        Phi = np.asarray(Phi, dtype=float)
    except (TypeError, ValueError):
        raise InputError(f"Phi: expected a matrix of numbers (r x n), got {type(Phi).__name__}") from None
    if Phi.ndim != 2 or Phi.shape[0] >= Phi.shape[1] or not np.all(np.isfinite(Phi)):
        raise InputError(f"Phi: expected a finite matrix with fewer rows than columns (r x n, r < n), got "
                         f"{'shape ' + str(Phi.shape) if Phi.ndim != 2 or Phi.shape[0] >= Phi.shape[1] else 'non-finite entries'}")
    r, n = Phi.shape
    _, singular_values, Vt = np.linalg.svd(Phi)
    if singular_values[-1] < RANK_LIMIT * singular_values[0]:
        condition = math.inf if singular_values[-1] == 0 else singular_values[0] / singular_values[-1]
        raise SingularConfigurationError(
            f"Phi_s lost rank{at_time(t)}: cond(Phi_s) = {condition:.3g} > {1 / RANK_LIMIT:.0e}; the "
            "constraints are dependent (assembly branches meet, a bifurcation) and no choice of "
            "coordinates passes it; change the geometry or stop before it"
        )
    if basis == "svd":
        return Vt[r:].T
    if basis != "pivoted":
        one_of("basis", basis, NULL_SPACE_BASES)     # refuses it (NullSpace() checked its own already)
    pivots = _qr()(Phi, mode="r", pivoting=True)[1]
    return orthogonal_complement(Phi, np.sort(pivots[r:]), np.sort(pivots[:r]), t)
