"""Four ways to integrate Lagrange's equations with multipliers.

Each formulation is a small immutable object over the same :class:`~closedloop.model.System`:

- :class:`Augmented`: the augmented system (12), no stabilisation;
- :class:`Baumgarte`: (16)-(17), the constraint error obeys (15);
- :class:`Orthogonal`: the ODE (24)-(26), lambda removed with R of (20);
- :class:`Minimal`: coordinate partitioning, an ODE in q alone with z from
  Newton on f = 0 at every evaluation: the accuracy reference;
- :class:`NullSpace`: (24)-(26) with R replaced by a basis of the null space
  of Phi_s that needs no fixed partition (SVD, or partitioning with pivoting),
  so it passes the dead positions where Phi_z of (20) is singular;
- :class:`ClosedForm`: the accelerations of (26) eliminated symbolically and
  generated as one function (:mod:`closedloop.closed_form`): the fast one.

A formulation knows how to pack ``(s, s')`` into the integrator's state vector
``y``, how to unpack it, and how to build the right-hand side ``y' = F(t, y)``
on one smooth branch (``mode``) of the forces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .closed_form import closed_form_accelerations, closed_form_rhs
from .errors import ConvergenceError, InputError, SingularConfigurationError, at_time
from .kinematics import solve_dependent
from .model import _orthogonal_complement, condition_number, solve_augmented, solve_small

__all__ = [
    "Augmented",
    "Baumgarte",
    "Orthogonal",
    "Minimal",
    "NullSpace",
    "ClosedForm",
    "null_space_basis",
    "RANK_LIMIT",
    "baumgarte_from_step",
    "baumgarte_p2",
    "formulation_from_name",
    "FORMULATION_NAMES",
]


def _check_gains(alpha, beta):
    for name, value in (("alpha", alpha), ("beta", beta)):
        if not (isinstance(value, (int, float, np.floating)) and math.isfinite(value) and value >= 0):
            raise InputError(f"{name}: must be a finite number >= 0, got {value!r}")


def baumgarte_from_step(step):
    """Baumgarte's rule of thumb ``alpha = 1/dt``, ``beta = sqrt(2)/dt`` (after (17)).

    Parameters
    ----------
    step : float
        The integration step dt, > 0.

    Returns
    -------
    Baumgarte
    """
    if not (isinstance(step, (int, float, np.floating)) and math.isfinite(step) and step > 0):
        raise InputError(f"step: must be a finite number > 0, got {step!r}")
    return Baumgarte(alpha=1.0 / step, beta=math.sqrt(2.0) / step)


class _RedundantFormulation:
    """Common part of the formulations whose state is ``y = [s, s']``."""

    def pack(self, system, s, sd):
        return np.concatenate((s, sd))

    def unpacker(self, system):
        n = system.n

        def unpack(y, t=None):
            return y[:n], y[n:]

        unpack.seed = lambda s_start: None
        return unpack

    def make_rhs(self, system, mode, unpack):
        n = system.n
        accelerations = self.accelerations

        def rhs(t, y):
            s, sd = y[:n], y[n:]
            return np.concatenate((sd, accelerations(system, t, s, sd, mode)))

        return rhs


@dataclass(frozen=True)
class Augmented(_RedundantFormulation):
    """The augmented system (12) with ``p2 = -Phi_s' s'`` (11): no stabilisation.

    The constraint error is not fed back, so f and f' drift (13).
    """

    name = "augmented"

    def accelerations(self, system, t, s, sd, mode=None):
        """s'' from (12)."""
        M, p1, f, Phi, gamma = system.dynamics(t, s, sd, mode)
        return solve_augmented(M, Phi, p1, -gamma, t)[0]


@dataclass(frozen=True)
class _Stabilised(_RedundantFormulation):
    """The Baumgarte gains alpha, beta >= 0 of (15), shared by (17) and (25)."""

    alpha: float = 5.0
    beta: float = 5.0

    def __post_init__(self):
        _check_gains(self.alpha, self.beta)


@dataclass(frozen=True)
class Baumgarte(_Stabilised):
    """Baumgarte's stabilisation (16)-(17).

    The constraint rows of (12) solve f'' + 2 alpha f' + beta^2 f = 0 (15)
    instead of f'' = 0 (14).  Baumgarte's own choice was alpha = beta = 5.

    Parameters
    ----------
    alpha, beta : float, >= 0
    """

    name = "baumgarte"

    def accelerations(self, system, t, s, sd, mode=None):
        """s'' from (16) with Baumgarte's p2~ of (17)."""
        M, p1, f, Phi, gamma = system.dynamics(t, s, sd, mode)
        return solve_augmented(M, Phi, p1, baumgarte_p2(Phi, gamma, f, sd, self.alpha, self.beta), t)[0]


def baumgarte_p2(Phi, gamma, f, sd, alpha, beta):
    """p2~ = -Phi_s' s' - 2 alpha Phi_s s' - beta^2 f (17)."""
    return -gamma - 2.0 * alpha * (Phi @ sd) - beta * beta * f


@dataclass(frozen=True)
class Orthogonal(_Stabilised):
    """The orthogonality-theorem ODE (24)-(26): ``A(s) s'' = p(s, s', t)``.

    ``A = [R^T M; Phi_s]`` and ``p = [R^T p1; p2~]`` (25), with R of (20) and
    Baumgarte's p2~ of (17); lambda never appears.

    Parameters
    ----------
    alpha, beta : float, >= 0
        Baumgarte gains in p2~.
    """

    name = "orthogonal"

    def accelerations(self, system, t, s, sd, mode=None):
        """s'' from (26)."""
        M, p1, f, Phi, gamma = system.dynamics(t, s, sd, mode)
        R = _orthogonal_complement(Phi, system.q_index, system.z_index, t)
        A = np.vstack((R.T @ M, Phi))                                       # (25)
        p = np.concatenate((R.T @ p1, baumgarte_p2(Phi, gamma, f, sd, self.alpha, self.beta)))
        return np.linalg.solve(A, p)                                         # (26)


@dataclass(frozen=True)
class Minimal:
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
                R_now = _orthogonal_complement(Phi, qi, zi, t)
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
            R = _orthogonal_complement(Phi, qi, zi, t)
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
            R = _orthogonal_complement(Phi, system.q_index, zi, t)
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

#: sigma_min(Phi_s) / sigma_max(Phi_s) below which Phi_s counts as rank deficient.
RANK_LIMIT = 1e-10
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
    from scipy.linalg import qr

    pivots = qr(Phi, mode="r", pivoting=True)[1]
    return _orthogonal_complement(Phi, np.sort(pivots[r:]), np.sort(pivots[:r]), t)


@dataclass(frozen=True)
class NullSpace(_Stabilised):
    """The orthogonality ODE (24)-(26) with a null-space basis that needs no fixed partition.

    ``A = [N^T M; Phi_s]``, ``p = [N^T p1; p2~]`` with N from
    :func:`null_space_basis` in place of R of (20), and Baumgarte's p2~ of (17)
    in the constraint rows.  N exists wherever Phi_s has full row rank, so
    this formulation carries a simulation through the dead positions where
    Phi_z (and so R of (20)) is singular.  :class:`Minimal` can not pass them;
    :class:`Orthogonal` passes them only because its steps happen not to land
    where R blows up, and it refuses a state on one.  It still stops, with a
    clear error, where Phi_s itself loses rank.

    Parameters
    ----------
    alpha, beta : float, >= 0
        Baumgarte gains in p2~, as for :class:`Orthogonal`.
    basis : {"svd", "pivoted"}
        How N is computed; see :func:`null_space_basis`.
    """

    basis: str = "svd"
    name = "nullspace"

    def __post_init__(self):
        super().__post_init__()
        if self.basis not in NULL_SPACE_BASES:
            raise InputError(f"basis: unknown {self.basis!r}; choose one of {', '.join(NULL_SPACE_BASES)}")

    def accelerations(self, system, t, s, sd, mode=None):
        """s'' from (26) with N in place of R."""
        M, p1, f, Phi, gamma = system.dynamics(t, s, sd, mode)
        N = null_space_basis(Phi, self.basis, t)
        A = np.vstack((N.T @ M, Phi))
        p = np.concatenate((N.T @ p1, baumgarte_p2(Phi, gamma, f, sd, self.alpha, self.beta)))
        return np.linalg.solve(A, p)


@dataclass(frozen=True)
class ClosedForm(_Stabilised):
    """The ODE (26) with its linear algebra done once, symbolically.

    The same accelerations as :class:`Orthogonal` and :class:`Baumgarte` with
    the same gains (and as :class:`Augmented` with ``alpha = beta = 0``), from
    a function generated by :func:`closedloop.closed_form.closed_form_accelerations`:
    R of (20), Phi_z^{-1} and (R^T M R)^{-1} are eliminated in closed form and the
    parameter values folded in, so an evaluation assembles no matrix and solves
    no system.  Like R of (20) it needs a regular Phi_z.

    Parameters
    ----------
    alpha, beta : float, >= 0
        Baumgarte gains in p2~ of (17); 0 and 0 give the unstabilised (12).
    """

    name = "closed form"

    def make_rhs(self, system, mode, unpack):
        folded = closed_form_rhs(system, mode, self.alpha, self.beta)     # force and gains folded in
        if folded is not None:
            return folded
        n = system.n
        accelerations = closed_form_accelerations(system)
        force = system.force
        alpha, beta = float(self.alpha), float(self.beta)
        no_force = [0.0] * n

        def rhs(t, y):
            values = y.tolist()
            s, sd = values[:n], values[n:]
            Q = no_force if force is None else force.components(t, s, sd, mode)
            try:
                return sd + accelerations(t, s, sd, Q, alpha, beta)
            except ZeroDivisionError:
                raise SingularConfigurationError(
                    f"Phi_z is singular{at_time(t)} (det Phi_z = 0): the closed form of (26) divides "
                    "by it; use Augmented or the NullSpace formulation through this configuration"
                ) from None

        return rhs

    def accelerations(self, system, t, s, sd, mode=None):
        """s'' of (26) from the generated closed form."""
        if system.force is not None and mode is None:
            mode = system.force.mode_at(t, s, sd)
        rhs = self.make_rhs(system, mode, None)
        return np.asarray(rhs(t, np.concatenate((s, sd)))[system.n:])


FORMULATION_NAMES = ("augmented", "baumgarte", "orthogonal", "minimal", "nullspace", "closed-form", "projected")


def formulation_from_name(name, alpha=None, beta=None):
    """The formulation called ``name``, with Baumgarte gains where it takes them.

    Parameters
    ----------
    name : {"augmented", "baumgarte", "orthogonal", "minimal", "nullspace", "closed-form", "projected"}
    alpha, beta : float, optional
        Only for "baumgarte", "orthogonal", "nullspace" and "closed-form" (default 5 and 5,
        Baumgarte's choice).
    """
    if name not in FORMULATION_NAMES:
        raise InputError(f"formulation: unknown {name!r}; choose one of {', '.join(FORMULATION_NAMES)}")
    gains = {k: v for k, v in (("alpha", alpha), ("beta", beta)) if v is not None}
    if name in ("baumgarte", "orthogonal", "nullspace", "closed-form"):
        return {"baumgarte": Baumgarte, "orthogonal": Orthogonal, "nullspace": NullSpace,
                "closed-form": ClosedForm}[name](**gains)
    if gains:
        raise InputError(
            "alpha, beta: only the baumgarte, orthogonal, nullspace and closed-form formulations take gains, "
            f"not {name!r}"
        )
    if name == "projected":
        from .projection import Projected      # projection.py builds on this module

        return Projected()
    return Augmented() if name == "augmented" else Minimal()
