"""Change points: where the path meets a configuration at which Phi_s loses rank.

At a change point (a bifurcation of the constraint manifold: a parallelogram four-bar with all its
links in line, say) two assembly branches meet.  Phi_s of (9) loses rank there, so lambda of (12) is
not determined, R of (20) and every null-space basis fail, and the motion past it is not decided by
Lagrange's equations with multipliers.  An integrator that steps over it lands on either branch, or
between them, and reports a smooth-looking motion with a small |f|: a silent wrong answer.

The check runs on every runner (solve_ivp, the compiled DOP853, naive switching) and every
formulation, minimal coordinates included, over the accepted steps in batches as the run goes
(:class:`closedloop.simulation.watch.PathWatch`), and, when a formulation fails inside a step,
over that step extrapolated to where it failed:

1. ``sigma_min(Phi_s)`` at every step end (the eigenvalues of the small Gram matrix
   ``Phi_s Phi_s^T``, for all step ends at once);
2. at each local minimum along the path (or a step end of the path's ends that is lower than
   its neighbour), the minimum is refined on the cubic Hermite interpolant of the positions
   (the step ends' s and s') over the two steps around it, by bounded minimisation;
3. where ``sigma_min < 0.1 sigma_max`` (:data:`REFINE_BELOW`) the Kantorovich number
   ``h = sigma_max e / sigma_min^2`` of (10.b) is formed with ``e`` the larger of |f| at the step
   end, |f| at the refined point of the interpolant (its own error) and ``eps (1 + |s|)``: the
   distance of the path to the constraint manifold, never below rounding.  ``h`` is the ratio of the
   distance to the nearest root of f = 0 to half the distance between the branches; above
   :data:`CHANGE_POINT_LIMIT` the run can not tell the branches apart: it has reached a change
   point, and stops with a :class:`~closedloop.errors.SingularConfigurationError` that names the
   time and the configuration.  No formulation of this library continues through a change point.

``simulate(..., branch_limit=math.inf)`` turns this check off together with the branch guard.
"""

from __future__ import annotations

import itertools
import math

import numpy as np

from .. import hermite
from ..errors import SingularConfigurationError
from ..loading import first_use


__all__ = ["singular_values", "find_change_point", "change_point_error", "branch_error", "meeting_point",
           "CHANGE_POINT_LIMIT", "REFINE_BELOW", "MEETING_TOLERANCE"]

#: Unit roundoff of float64: the smallest distance to the manifold a run can claim.
EPSILON = float(np.finfo(float).eps)

#: Kantorovich's own bound: above h = 1/2 Newton's iteration from the run's state is no longer
#: sure to reach one root, the distance to the manifold is as large as half the distance between
#: the branches, and the run can not tell which branch it is on.  (The guard at sign changes of
#: det Phi_z keeps the stricter BRANCH_LIMIT = 0.01; along the whole path 1/2 keeps runs that
#: resolve two near branches, such as Baumgarte at rtol 1e-9 with l2/l1 = 1 + 1e-8, and stops
#: every run through a change point, where h is 1e6 or more.)
CHANGE_POINT_LIMIT = 0.5

#: Local minima of sigma_min / sigma_max below this are refined on the interpolant; above it the
#: constraints are far from dependent and the step ends suffice.
REFINE_BELOW = 0.1


@first_use
def _optimize():
    """scipy.optimize's ``(brentq, minimize_scalar)``, imported on first use (it costs about 0.1 s)."""
    from scipy.optimize import brentq, minimize_scalar

    return brentq, minimize_scalar


def singular_values(jacobians):
    """``(sigma_min, sigma_max)`` of K matrices Phi_s of shape (r, n, K), from the eigenvalues of Phi Phi^T."""
    r = jacobians.shape[0]
    gram = np.einsum("ink,jnk->kij", jacobians, jacobians)
    if r == 1:
        largest = smallest = gram[:, 0, 0]
    elif r == 2:
        trace = gram[:, 0, 0] + gram[:, 1, 1]
        det = gram[:, 0, 0] * gram[:, 1, 1] - gram[:, 0, 1] * gram[:, 1, 0]
        largest = 0.5 * (trace + np.sqrt(np.maximum(trace * trace - 4.0 * det, 0.0)))
        # the small eigenvalue as det / largest keeps its relative accuracy where it is tiny
        smallest = np.where(largest > 0, np.maximum(det, 0.0) / np.where(largest > 0, largest, 1.0), 0.0)
    else:
        eigenvalues = np.linalg.eigvalsh(gram)
        largest, smallest = eigenvalues[:, -1], np.maximum(eigenvalues[:, 0], 0.0)
    return np.sqrt(smallest), np.sqrt(largest)


def _hermite(t, t0, t1, s0, s1, v0, v1):
    """Positions on the cubic Hermite interpolant over [t0, t1] at time t."""
    step = t1 - t0
    return hermite.values((t - t0) / step, s0, s1, step * v0, step * v1)


def maximal_minors(jacobian):
    """The r x r minors of one Phi_s (r x n), in a fixed order of the column sets.

    They are the Pluecker coordinates of its row space: all vanish exactly where Phi_s
    loses rank, and along a path that crosses such a point the vector of them passes
    through zero and comes out reversed (det Phi_z, the one the branch guard watches,
    is one of them, and can touch zero without changing sign while the others do).
    """
    r, n = jacobian.shape
    return np.array([np.linalg.det(jacobian[:, list(columns)]) for columns in itertools.combinations(range(n), r)])


def _refine(system, times, s, sd, k, beyond=None):
    """The smallest sigma_min(Phi_s) on the steps next to step end k: ``(t, sigma_min, sigma_max, s)``.

    On each step the minimum is sought twice: where the minors of Phi_s reverse (a root of
    their projection on the minors at the step's start, found by brentq to rounding, which
    is where a path through a change point meets it), and by bounded minimisation of
    sigma_min (a path that passes near one).  With ``beyond`` (a time past the last step
    end, where the run failed) the last step's interpolant is also followed, extrapolated,
    up to that time.
    """
    brentq, minimize_scalar = _optimize()

    last = times.size - 1
    pieces = [(a, times[a], times[a + 1]) for a in (k - 1, k) if 0 <= a < last and times[a + 1] > times[a]]
    if beyond is not None and k == last and last >= 1 and beyond > times[last] > times[last - 1]:
        pieces.append((last - 1, times[last], beyond))
    best = None
    for a, start, end in pieces:
        def position(t, a=a):
            return _hermite(t, times[a], times[a + 1], s[:, a], s[:, a + 1], sd[:, a], sd[:, a + 1])

        def sigma_min(t):
            return singular_values(system.jacobian(position(t))[:, :, None])[0][0]

        candidates = [minimize_scalar(sigma_min, bounds=(start, end), method="bounded",
                                      options={"xatol": 1e-12 * max(1.0, abs(end))}).x]
        first = maximal_minors(system.jacobian(position(start)))

        def reversal(t):
            return float(first @ maximal_minors(system.jacobian(position(t))))

        if reversal(start) > 0 > reversal(end):
            candidates.append(brentq(reversal, start, end, xtol=1e-15, rtol=4 * EPSILON))
        for t in candidates:
            low, high = (float(v[0]) for v in singular_values(system.jacobian(position(t))[:, :, None]))
            if best is None or low < best[1]:
                best = (float(t), low, high, position(t))
    return best


def _dips(times, ratio):
    """How low ``sigma_min / sigma_max`` may dip between each step end and its two neighbours (K - 2,).

    Through a change point sigma_min falls linearly to zero and rises again, a V: coarse steps
    whose ends all keep it above REFINE_BELOW sigma_max (a compiled DOP853 step of 0.18 s across the
    fold of a parallelogram) still show the dip through their neighbours.  The estimate is the
    bottom of the V through the three points whose arms have the slope of the steeper side (its
    mirror through the other outer point): lower than a smooth minimum, so it only ever asks for a
    refinement.  inf where the middle point is no minimum.
    """
    t0, t1, t2 = times[:-2], times[1:-1], times[2:]
    r0, r1, r2 = ratio[:-2], ratio[1:-1], ratio[2:]
    with np.errstate(divide="ignore", invalid="ignore"):
        left, right = (r1 - r0) / (t1 - t0), (r2 - r1) / (t2 - t1)
        # the left arm through 0 and 1, the right one through 2 with the opposite slope; and the mirror
        at = (r2 - r1 + left * (t1 + t2)) / (2.0 * left)
        bottom_left = r1 + left * (at - t1)
        at_right = (r0 - r1 + right * (t1 + t0)) / (2.0 * right)
        bottom_right = r1 + right * (at_right - t1)
    minimum = (r1 <= r0) & (r1 <= r2) & (t1 > t0) & (t2 > t1)
    bottoms = np.where(np.isfinite(bottom_left) & (bottom_left <= r1), bottom_left, np.inf)
    bottoms = np.minimum(bottoms, np.where(np.isfinite(bottom_right) & (bottom_right <= r1), bottom_right, np.inf))
    return np.where(minimum, np.maximum(bottoms, 0.0), np.inf)


def find_change_point(system, times, s, sd, failed_at=None, limit=None, evaluated=None, open_start=False,
                      open_end=False, accept=None):
    """The first change point along a path given at its step ends, or None.

    Parameters
    ----------
    system : System
    times : ndarray, shape (K,)
        Step ends (increasing), the segment's start first.
    s, sd : ndarray, shape (n, K)
        Positions and velocities there.
    limit : float, optional
        The bound on the Kantorovich number (default :data:`CHANGE_POINT_LIMIT`).
    evaluated : tuple, optional
        ``system.constraints_and_jacobian_many(s)``, when the caller has it.
    failed_at : float, optional
        Where the run failed after its last step end (the formulation could not
        go on): the path is then also followed, extrapolated, up to that time.
    open_start, open_end : bool, optional
        The path goes on before its first (after its last) step end, which is then
        not taken for a minimum on the strength of one neighbour: a batch of a run's
        step ends, checked as the run goes, whose ends the next batch holds too.
    accept : callable, optional
        ``accept(found) -> bool``: a point found is returned only if this is true,
        else the search goes on along the path.

    Returns
    -------
    None, or ``(t, s, sigma_min, sigma_max, kantorovich, distance)`` where the path can not tell two
    branches apart: a change point, or a place where two branches pass near each other and the path's
    distance to the constraints reached half their gap (:func:`branch_error` tells which).
    """
    limit = CHANGE_POINT_LIMIT if limit is None else limit
    if times.size < 2:
        return None
    residuals, jacobians = system.constraints_and_jacobian_many(s) if evaluated is None else evaluated
    smallest, largest = singular_values(jacobians)
    error = np.maximum(np.sqrt(np.sum(residuals * residuals, axis=0)),
                       EPSILON * (1.0 + np.max(np.abs(s), axis=0)))
    lower_left = np.concatenate(([not open_start], smallest[1:] <= smallest[:-1]))
    lower_right = np.concatenate((smallest[:-1] <= smallest[1:], [not open_end]))
    # a minimum where Phi_s is well conditioned is passed over below, unrefined: only the others are looked at
    low_enough = smallest < REFINE_BELOW * largest
    low_enough[1:-1] |= _dips(times, smallest / np.where(largest > 0, largest, 1.0)) < REFINE_BELOW
    if failed_at is not None:
        low_enough[-1] = True
    minima = np.flatnonzero(lower_left & lower_right & low_enough)
    for k in minima:
        t, low, high, position = float(times[k]), float(smallest[k]), float(largest[k]), s[:, k]
        if low_enough[k]:                         # low at the step end, dipping between its neighbours, or failed
            refined = _refine(system, times, s, sd, k, failed_at)
            if refined is not None:               # None: no step of positive length beside step end k
                t, low, high, position = refined
        if low >= REFINE_BELOW * high:
            continue     # Phi_s well conditioned: a large |f| here is drift, not a change point
        # |f| on the interpolant measures how far the interpolated path is from the manifold, so
        # a refined minimum that only reflects the interpolation's own error is not trusted
        distance = max(float(error[k]), float(np.linalg.norm(system.constraints(position))))
        kantorovich = math.inf if low == 0.0 else high * distance / (low * low)
        if kantorovich > limit and (accept is None or accept((t, position, low, high, kantorovich, distance))):
            return t, position, low, high, kantorovich, distance
    return None


#: A point where f(s) = 0 and Phi_s loses rank to within this much (relative to 1 + |s|, and to sigma_max(Phi_s)):
#: the branches meet there.  Where they only come near (a length off by a relative 1e-8 from a parallelogram's,
#: say), the least-squares residual stays at the size of that defect.
MEETING_TOLERANCE = 1e-12


@first_use
def _least_squares():
    """scipy.optimize's least_squares, imported on first use."""
    from scipy.optimize import least_squares

    return least_squares


def meeting_point(system, s):
    """Whether two assembly branches meet near ``s``: ``(point, gap)``.

    ``point`` is a point of f = 0 at which Phi_s loses rank, or None; ``gap`` estimates the distance
    between the two branches there (0 where they meet): ``2 sigma_min / sigma_max`` of Phi_s at a
    point of the constraints near ``s`` (Newton's minimum-norm projection), which is half the
    distance between the roots of f that Newton tells apart (the Kantorovich radius).

    Solves ``f(s) = 0``, ``Phi_s(s)^T u = 0``, ``|u| = 1`` in the least-squares sense
    (:func:`scipy.optimize.least_squares`, from ``s`` and the left singular vector u of
    sigma_min(Phi_s) there): at a change point the residual vanishes; where two branches
    only come near each other (a geometry close to a bifurcation) it stays at about the
    smallest singular value of Phi_s on the constraints there.  The point is taken only
    within the distance of ``s`` to the branches' estimated gap (``2 sigma_min / sigma_max``,
    at least 1e-3 (1 + |s|)).

    Returns
    -------
    point : ndarray, shape (n,), or None
    gap : float
    """
    s = np.asarray(s, dtype=float)
    r = system.r
    Phi = system.jacobian(s)
    U, sigma, _ = np.linalg.svd(Phi)
    scale = float(sigma[0]) if sigma[0] > 0 else 1.0

    def residual(x):
        point, u = x[:-r], x[-r:]
        f, J = system.constraints_and_jacobian(point)
        return np.concatenate((f, J.T @ u / scale, [u @ u - 1.0]))

    gap = _gap(system, s, sigma)
    try:
        found = _least_squares()(residual, np.concatenate((s, U[:, -1])), method="lm", xtol=1e-15, ftol=1e-15,
                                 gtol=1e-15, max_nfev=200 * (s.size + r))
    except (ValueError, ArithmeticError, np.linalg.LinAlgError):
        return None, gap
    point = found.x[:-r]
    if not np.all(np.isfinite(found.fun)):
        return None, gap
    reach = max(gap, 1e-3) * (1.0 + float(np.max(np.abs(s))))
    if np.max(np.abs(point - s)) <= reach and np.max(np.abs(found.fun)) <= MEETING_TOLERANCE * (
            1.0 + float(np.max(np.abs(s)))):
        return point, 0.0
    return None, gap


def _gap(system, s, sigma):
    """``2 sigma_min / sigma_max`` of Phi_s at Newton's projection of ``s`` onto f = 0 (at ``s``, where it fails)."""
    from ..formulations.projected import project_state

    try:
        on = project_state(system, s, np.zeros_like(s))[0]
        sigma = np.linalg.svd(system.jacobian(on), compute_uv=False)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError):
        pass
    return 2.0 * float(sigma[-1]) / float(sigma[0]) if sigma[0] > 0 else 0.0


def branch_error(t, position, low, high, distance, kantorovich, limit, system, method_name, names):
    """The SingularConfigurationError of a path that can not tell two assembly branches apart at ``position``.

    Where the branches meet near it (:func:`meeting_point`), a change point, which no
    formulation passes; else they only come near each other, and the path's distance to
    the constraints reached half the gap between them: the advice is a tighter tolerance.
    """
    where = ", ".join(f"{name} = {value:.6g}" for name, value in zip(names, position))
    condition = math.inf if low == 0.0 else high / low
    point, gap = (None, 0.0) if low == 0.0 else meeting_point(system, position)
    if low == 0.0 or point is not None:
        return SingularConfigurationError(
            f"the path reaches a change point at t = {t:.6g} s ({where}) with {method_name}: Phi_s loses rank "
            f"there (cond(Phi_s) = {condition:.3g}, Kantorovich number {kantorovich:.3g}), two assembly branches "
            "meet, and the motion past it is not determined by these equations; no formulation of this library "
            "passes a change point: end the run before it, or change the geometry"
        )
    return SingularConfigurationError(
        f"the path comes as near another assembly branch as its own at t = {t:.6g} s ({where}) with "
        f"{method_name}: the two branches pass within a distance of order {gap:.2g} of each other there "
        f"(cond(Phi_s) = {condition:.3g}; they do not meet, Phi_s keeps its rank on the constraints nearby), and "
        f"the path's drift off the constraints, {distance / low:.2g}, reached more than half of it (Kantorovich number "
        f"{kantorovich:.3g} > {limit:g}), so the run can no longer tell which branch it follows; tighten rtol "
        "and atol, so that the drift stays below that distance"
    )


def change_point_error(found, system, method_name):
    """The SingularConfigurationError for a point found by :func:`find_change_point` (see :func:`branch_error`)."""
    t, position, low, high, kantorovich, distance = found
    return branch_error(t, position, low, high, distance, kantorovich, CHANGE_POINT_LIMIT, system, method_name,
                        list(system.coordinate_names))
