"""Minimal coordinates by coordinate partitioning: an ODE in the independent coordinates q alone."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from ..errors import ConvergenceError, SingularConfigurationError, at_time
from ..kinematics import solve_dependent
from ..linalg import condition_number, orthogonal_complement, solve_small
from .base import Formulation

__all__ = ["Minimal", "CONTINUATION_PIECES", "CONTINUATION_STEP"]


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
    configuration where Phi_z is singular (a dead position of q): there it
    raises :class:`~closedloop.errors.SingularConfigurationError`, as it does
    when Newton's solution jumps to another assembly branch (det Phi_z changes
    sign).  :class:`NullSpace` passes such configurations.
    """

    name = "minimal"
    guards_branch = True          # it stops where Newton's z would change branch
    guards_partition = True       # R of (20) is refused where det Phi_z = 0

    def state_names(self, system):
        return [name for k, name in enumerate(super().state_names(system))
                if k % system.n in set(system.q_index.tolist())]

    def pack(self, system, s, sd):
        return np.concatenate((s[system.q_index], sd[system.q_index]))

    def unpacker(self, system):
        """A function ``y -> (s, s')`` that solves f(q, z) = 0 for z by Newton.

        It keeps the last solution (local to one integration segment): Newton
        starts from the first-order prediction ``z + R_z (q - q_last)``, and a
        call at the same y as the last one (an event function evaluated where
        the right-hand side just was) costs nothing.
        """
        f, qi, zi = system.f, system.q_index, system.z_index
        last = {"y": None, "s": None, "R": None, "side": None}

        def solve(q, s_from, R_from, t):
            guess = s_from[zi] if R_from is None else s_from[zi] + R_from[zi] @ (q - s_from[qi])
            s, Phi = solve_dependent(system, q, guess, t, return_jacobian=True)
            return s, Phi, np.sign(np.linalg.det(Phi[:, zi]))

        def solve_on_branch(q, t):
            # One Newton solve from the first-order prediction.  A long step (a fast crank) can
            # carry that prediction into the basin of another assembly branch although Phi_z is
            # well conditioned all the way; then follow q from the last solution in small steps
            # (continuation).  A real dead position of q is crossed by every path, so the caller's
            # branch check still catches it.
            try:
                found = solve(q, last["s"], last["R"], t)
                if found[2] == last["side"]:
                    return found
            except (ConvergenceError, SingularConfigurationError):
                if last["R"] is None:
                    raise
                found = None
            for pieces in CONTINUATION_PIECES:
                try:
                    found = follow(q, pieces, t)
                except (ConvergenceError, SingularConfigurationError):
                    continue
                if found[2] == last["side"]:
                    return found
            if found is None:
                return solve(q, last["s"], last["R"], t)  # raises the direct solve's error
            return found

        def follow(q, pieces, t):
            s_now, R_now = last["s"], last["R"]
            for k in range(pieces):
                q_k = s_now[qi] + (q - s_now[qi]) / (pieces - k)
                s_now, Phi, side = solve(q_k, s_now, R_now, t)
                R_now = orthogonal_complement(Phi, qi, zi, t)
            return s_now, Phi, side

        def unpack(y, t=None):
            s, R = unpack_with_R(y, t)
            return s, R @ y[f:]

        def unpack_with_R(y, t=None):
            if last["y"] is not None and np.array_equal(y, last["y"]):
                return last["s"], last["R"]
            try:
                s, Phi, side = solve_on_branch(y[:f], t)
            except (ConvergenceError, SingularConfigurationError) as error:
                raise SingularConfigurationError(
                    f"minimal coordinates failed{at_time(t)}: {error} [cond(Phi_z) was "
                    f"{condition_number(system.jacobian(last['s'])[:, zi]):.3g} at the last solved state]; "
                    "q can not pass a dead position of this partition: use the NullSpace formulation"
                ) from None
            R = orthogonal_complement(Phi, qi, zi, t)
            if side != last["side"]:
                condition = condition_number(system.jacobian(last["s"])[:, zi])
                moved = np.abs(y[:f] - last["s"][qi]).max()
                if moved / CONTINUATION_PIECES[-1] <= CONTINUATION_STEP:
                    why = ("so the path met a dead position of q, or Newton's z jumped to another branch near one; "
                           "q alone can not pass it: use the NullSpace formulation (near a bifurcation, also "
                           "tighten rtol and atol)")
                else:
                    why = (f"but a step moved q by {moved:.3g}, too far for Newton to follow z even in "
                           f"{CONTINUATION_PIECES[-1]} pieces, so the motion is too fast for the step; give a "
                           "max_step, or use a formulation that does not solve for z (Orthogonal, NullSpace)")
                raise SingularConfigurationError(
                    f"minimal coordinates left their assembly branch{at_time(t)}: det(Phi_z) changed sign "
                    f"(cond(Phi_z) was {condition:.3g} at the last state on the branch), {why}"
                )
            last.update(y=y.copy(), s=s, R=R)
            return s, R

        def seed(s_start):
            s_start = np.array(s_start, dtype=float)
            last.update(y=None, s=s_start, R=None,
                        side=np.sign(np.linalg.det(system.jacobian(s_start)[:, zi])))

        unpack.seed = seed
        unpack.with_R = unpack_with_R
        return unpack

    def make_rhs(self, system, mode, unpack):
        f = system.f

        def rhs(t, y):
            s, R = unpack.with_R(y, t)
            qd = y[f:]
            return np.concatenate((qd, self._qdd(system, t, s, R @ qd, mode, R)[0]))

        return rhs

    def _qdd(self, system, t, s, sd, mode, R=None):
        M, p1, _, Phi, gamma = system.dynamics(t, s, sd, mode)
        zi = system.z_index
        if R is None:
            R = orthogonal_complement(Phi, system.q_index, zi, t)
        c = np.zeros(system.n)
        c[zi] = solve_small(Phi[:, zi], -gamma)
        qdd = solve_small(R.T @ M @ R, R.T @ (p1 - M @ c))
        return qdd, R, c

    def accelerations(self, system, t, s, sd, mode=None):
        """s'' = R q'' + c at a consistent state."""
        qdd, R, c = self._qdd(system, t, s, sd, mode)
        return R @ qdd + c


#: Numbers of equal pieces Minimal's Newton continuation tries, in turn, when a single Newton solve
#: from the prediction lands on another assembly branch (see Minimal.unpacker).
CONTINUATION_PIECES = (8, 64)
#: Longest piece of q (radians or metres) on which the continuation's Newton solve is trusted: a
#: change of branch on shorter pieces is a dead position of q; on longer ones, a step too long.
CONTINUATION_STEP = 0.05
