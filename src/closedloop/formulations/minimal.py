"""Minimal coordinates by coordinate partitioning: an ODE in the independent coordinates q alone."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConvergenceError, SingularConfigurationError, at_time
from ..kinematics import solve_dependent
from ..linalg import (NEAR_RANK_LOSS, NEARLY_SINGULAR, condition_number, orthogonal_complement, partition_condition,
                      partition_determinant, solve_many, solve_small)
from .base import Formulation

__all__ = ["Minimal", "MinimalUnpacker", "minimal_accelerations", "CONTINUATION_PIECES", "CONTINUATION_STEP"]


def minimal_accelerations(M, p1, Phi, gamma, R, z_index):
    """The minimal-coordinate ODE ``(R^T M R) q'' = R^T (p1 - M c)``, ``c_z = -Phi_z^{-1} Phi_s' s'``.

    With ``s' = R q'`` (20), ``s'' = R q'' + c`` where c of (10) has ``c_q = 0``;
    projecting (8) onto R (the orthogonality theorem (18)) removes lambda.
    Written once for :class:`Minimal` (one state) and the batch integrator
    (K states, :mod:`closedloop.simulation.batch_model`).

    Parameters
    ----------
    M, p1, Phi, gamma : ndarray
        M, p1, Phi_s and Phi_s' s' of (7)-(11): shapes (n, n), (n,), (r, n), (r,)
        at one state, or the same with a last axis of length K.
    R : ndarray, shape (n, f) or (n, f, K)
        R of (20).
    z_index : ndarray of int

    Returns
    -------
    qdd : ndarray, shape (f,) or (f, K)
    c : ndarray, shape (n,) or (n, K)

    Raises
    ------
    numpy.linalg.LinAlgError or SingularConfigurationError
        If Phi_z (or R^T M R) is singular.
    """
    batch = M.ndim == 3
    solve = solve_many if batch else solve_small
    c = np.zeros(p1.shape)
    c[z_index] = solve(Phi[:, z_index], -gamma)                       # from (10)
    if batch:                                                           # the same products, column by column
        reduced_mass = np.einsum("ilk,ijk,jmk->lmk", R, M, R)
        reduced_force = np.einsum("ilk,ik->lk", R, p1 - np.einsum("ijk,jk->ik", M, c))
    else:
        reduced_mass, reduced_force = R.T @ M @ R, R.T @ (p1 - M @ c)
    return solve(reduced_mass, reduced_force), c


@dataclass(frozen=True)
class Minimal(Formulation):
    """Minimal coordinates by coordinate partitioning: an ODE in q alone.

    At every evaluation z is solved from f(q, z) = 0 by Newton (warm-started
    from the previous evaluation), ``s' = R q'`` (20), and with
    ``s'' = R q'' + c``, ``c = [0; -Phi_z^{-1} Phi_s' s']`` from (10), the
    projection of (8) onto R (the orthogonality theorem (18)) gives::

        (R^T M R) q'' = R^T (p1 - M c)

    The constraints hold to Newton's tolerance at every point, so this is the
    accuracy reference for the other formulations.  It can not pass a
    configuration where Phi_z is singular (a dead position of q), where the
    branch z(q) ends and the mechanism goes on along the other one.  Where an
    evaluation lands there or beyond it raises
    :class:`~closedloop.errors.SingularConfigurationError` (|Phi_s| |Phi_z^-1| above
    :data:`~closedloop.linalg.CONDITION_LIMIT`, R^T M R singular, or Newton finds
    no z), as it does when Newton's solution jumps to another assembly branch
    (det Phi_z changes sign).  Where every evaluation stays short of it, the
    equation in q turns back on the same branch, a smooth motion of that
    equation and not of the mechanism; the run's watch locates that turning
    point on the step's interpolant, finds that the branch ends just beyond
    it, and stops there with the same error (:mod:`closedloop.simulation.watch`).
    Where q can reach a dead position use :class:`NullSpace`, which passes it.
    """

    name = "minimal"
    guards_branch = True          # it stops where Newton's z would change branch
    guards_partition = True       # R of (20) is refused where |Phi_s| |Phi_z^-1| > CONDITION_LIMIT

    def state_names(self, system):
        return [name for k, name in enumerate(super().state_names(system))
                if k % system.n in set(system.q_index.tolist())]

    def pack(self, system, s, sd):
        return np.concatenate((s[system.q_index], sd[system.q_index]))

    def unpacker(self, system):
        """A new :class:`MinimalUnpacker`: ``y -> (s, s')`` that solves f(q, z) = 0 for z by Newton."""
        return MinimalUnpacker(system)

    def make_rhs(self, system, mode, unpack):
        f = system.f

        def rhs(t, y):
            s, R = unpack.with_R(y, t)
            qd = y[f:]
            return np.concatenate((qd, self._qdd(system, t, s, R @ qd, mode, R)[0]))

        return rhs

    def _qdd(self, system, t, s, sd, mode, R=None):
        M, p1, _, Phi, gamma = system.dynamics(t, s, sd, mode)
        if R is None:
            R = orthogonal_complement(Phi, system.q_index, system.z_index, t)
        try:
            qdd, c = minimal_accelerations(M, p1, Phi, gamma, R, system.z_index)
        except np.linalg.LinAlgError:          # R^T M R singular to working precision: R is huge along one q
            raise SingularConfigurationError(
                f"the reduced mass R^T M R of the minimal coordinates is singular{at_time(t)} (|Phi_s| |Phi_z^-1| = "
                f"{partition_condition(Phi, system.z_index):.3g} at {np.array2string(s, precision=6)}): q is at a "
                "dead position of this partition, which q alone can not pass; use the NullSpace formulation"
            ) from None
        return qdd, R, c

    def accelerations(self, system, t, s, sd, mode=None):
        """s'' = R q'' + c at a consistent state."""
        qdd, R, c = self._qdd(system, t, s, sd, mode)
        return R @ qdd + c


class MinimalUnpacker:
    """``y -> (s, s')`` for minimal coordinates ``y = [q, q']``: z from f(q, z) = 0 (6) by Newton, s' = R q' (20).

    One per integration segment (rule 3 of :class:`~closedloop.formulations.base.Formulation`).
    It keeps the last solution: Newton starts from the first-order prediction
    ``z + R_z (q - q_last)``, and a call at the same y as the last one (an
    event function evaluated where the right-hand side just was) costs nothing.
    It stops with :class:`~closedloop.errors.SingularConfigurationError` where
    z would leave its assembly branch (det Phi_z changes sign).

    Parameters
    ----------
    system : System
    """

    def __init__(self, system):
        self.system = system
        self._last_y = None            # the last y unpacked, its s and R, and the branch's sign of det Phi_z
        self._last_s = None
        self._last_R = None
        self._side = None

    def __call__(self, y, t=None):
        """``(s, s')`` at ``y``; ``t`` is only for error messages."""
        s, R = self.with_R(y, t)
        return s, R @ y[self.system.f:]

    def seed(self, s_start):
        """Start a segment at the consistent coordinates ``s_start``: its branch is the one to keep."""
        s_start = np.array(s_start, dtype=float)
        self._last_y, self._last_s, self._last_R = None, s_start, None
        self._side = np.sign(partition_determinant(self.system.jacobian(s_start), self.system.z_index))

    def many(self, states, times):
        """``(s, s')`` as n x K arrays for K states (columns), in order along the path (warm-started)."""
        pairs = [self(states[:, k], times[k]) for k in range(states.shape[1])]
        return np.array([p[0] for p in pairs]).T, np.array([p[1] for p in pairs]).T

    def follow(self, q, t=None):
        """The coordinates s at the independent coordinates ``q`` on this unpacker's branch, followed from its last
        solution (by continuation where one Newton solve does not stay on the branch).

        Raises
        ------
        SingularConfigurationError
            Where the branch can not be followed to ``q``: it ends before (a dead
            position of q lies between), or Newton's z lands on another branch.
        """
        f = self.system.f
        return self.with_R(np.concatenate((np.asarray(q, dtype=float), np.zeros(f))), t)[0]

    def with_R(self, y, t=None):
        """``(s, R)`` at ``y``: the coordinates and R of (20) there (for the right-hand side)."""
        system = self.system
        f, qi, zi = system.f, system.q_index, system.z_index
        if self._last_y is not None and np.array_equal(y, self._last_y):
            return self._last_s, self._last_R
        try:
            s, Phi, side = self._solve_on_branch(y[:f], t)
        except (ConvergenceError, SingularConfigurationError) as error:
            raise SingularConfigurationError(
                f"minimal coordinates failed{at_time(t)}: {error} [|Phi_s| |Phi_z^-1| was "
                f"{partition_condition(system.jacobian(self._last_s), zi):.3g} at the last solved state]; "
                "q can not pass a dead position of this partition: use the NullSpace formulation"
            ) from None
        R = orthogonal_complement(Phi, qi, zi, t)
        if side != self._side:
            last = system.jacobian(self._last_s)
            condition = max(partition_condition(last, zi), partition_condition(Phi, zi))
            rank = max(condition_number(last), condition_number(Phi))
            moved = np.abs(y[:f] - self._last_s[qi]).max()
            if rank > NEAR_RANK_LOSS:
                why = (f"at a trial stage {moved:.3g} of q away, where the other assembly branch comes close to this "
                       f"one (cond(Phi_s) = {rank:.3g}: near a bifurcation, or at a change point); give a max_step, "
                       "so that the steps stay short where the branches are near")
            elif condition > NEARLY_SINGULAR:
                why = ("so the path met a dead position of q (Phi_z nearly singular), which q alone can not pass: "
                       "use the NullSpace formulation")
            elif moved / CONTINUATION_PIECES[-1] <= CONTINUATION_STEP:
                why = (f"but Phi_z is regular there, and so is Phi_s: Newton's z, at a trial stage {moved:.3g} of q "
                       "away, landed on another branch; give a max_step, or use a formulation that does not "
                       "solve for z (Orthogonal, NullSpace)")
            else:
                why = (f"but a step moved q by {moved:.3g}, too far for Newton to follow z even in "
                       f"{CONTINUATION_PIECES[-1]} pieces, so the motion is too fast for the step; give a "
                       "max_step, or use a formulation that does not solve for z (Orthogonal, NullSpace)")
            raise SingularConfigurationError(
                f"minimal coordinates left their assembly branch{at_time(t)}: det(Phi_z) changed sign "
                f"(|Phi_s| |Phi_z^-1| = {condition:.3g} at the last state on the branch or the one Newton found), "
                f"{why}"
            )
        self._last_y, self._last_s, self._last_R = y.copy(), s, R
        return s, R

    def _solve(self, q, s_from, R_from, t):
        """One Newton solve from the first-order prediction: ``(s, Phi, sign of det Phi_z, far)``.

        ``far``: Newton ended farther from the prediction than :data:`CONTINUATION_STEP` times
        1 + |z|.  From a prediction that far off, Newton can land on a solution of f(q, z) = 0
        with the same sign of det Phi_z but another turn of an angle (psi + 16 pi, seen when the
        extra stages of a dense output were evaluated at a segment's end, from a warm start 2 rad
        of q away), so such a solution is taken only where continuation can not reach q.
        """
        qi, zi = self.system.q_index, self.system.z_index
        guess = s_from[zi] if R_from is None else s_from[zi] + R_from[zi] @ (q - s_from[qi])
        s, Phi = solve_dependent(self.system, q, guess, t, return_jacobian=True)
        far = np.max(np.abs(s[zi] - guess)) > CONTINUATION_STEP * (1.0 + np.max(np.abs(guess)))
        return s, Phi, np.sign(partition_determinant(Phi, zi)), far

    def _solve_on_branch(self, q, t):
        """Newton from the prediction, else continuation in small steps of q, kept on the branch.

        A long step (a fast crank) can carry the prediction into the basin of
        another assembly branch although Phi_z is well conditioned all the way,
        or Newton can end far from the prediction; then q is followed from the
        last solution in small steps (continuation).  A real dead position of q
        is crossed by every path, so the branch check of :meth:`with_R` still
        catches it.  Where continuation does not reach q either (a trial stage
        of a step far out, which the step's error test then rejects), Newton's
        own solution on the branch's side is kept.
        """
        direct = found = None
        try:
            direct = found = self._solve(q, self._last_s, self._last_R, t)
            if direct[2] == self._side and not direct[3]:
                return direct[:3]
        except (ConvergenceError, SingularConfigurationError):
            if self._last_R is None:
                raise
        for pieces in CONTINUATION_PIECES:
            try:
                found = self._follow(q, pieces, t)
            except (ConvergenceError, SingularConfigurationError):
                continue
            if found[2] == self._side:
                return found
        if direct is not None and direct[2] == self._side:
            return direct[:3]
        if found is None:
            return self._solve(q, self._last_s, self._last_R, t)[:3]  # raises the direct solve's error
        return found[:3]

    def _follow(self, q, pieces, t):
        """Continuation: from the last solution to q in ``pieces`` equal steps of q."""
        qi, zi = self.system.q_index, self.system.z_index
        s_now, R_now = self._last_s, self._last_R
        for k in range(pieces):
            q_k = s_now[qi] + (q - s_now[qi]) / (pieces - k)
            s_now, Phi, side, far = self._solve(q_k, s_now, R_now, t)
            if far:
                raise ConvergenceError("continuation: Newton ended far from the prediction")
            R_now = orthogonal_complement(Phi, qi, zi, t)
        return s_now, Phi, side


#: Numbers of equal pieces Minimal's Newton continuation tries, in turn, when a single Newton solve
#: from the prediction lands on another assembly branch (see MinimalUnpacker).
CONTINUATION_PIECES = (8, 64, 512, 4096)
#: Longest piece of q (radians or metres) on which the continuation's Newton solve is trusted: a
#: change of branch on shorter pieces is a dead position of q; on longer ones, a step too long.
CONTINUATION_STEP = 0.05
