"""Four ways to integrate Lagrange's equations with multipliers.

Each formulation is a small immutable object over the same :class:`~closedloop.model.System`:

- :class:`Augmented`: the augmented system (12), no stabilisation;
- :class:`Baumgarte`: (16)-(17), the constraint error obeys (15);
- :class:`Orthogonal`: the ODE (24)-(26), lambda removed with R of (20);
- :class:`Minimal`: coordinate partitioning, an ODE in q alone with z from
  Newton on f = 0 at every evaluation: the accuracy reference.

A formulation knows how to pack ``(s, s')`` into the integrator's state vector
``y``, how to unpack it, and how to build the right-hand side ``y' = F(t, y)``
on one smooth branch (``mode``) of the forces.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .errors import InputError
from .kinematics import solve_dependent
from .model import _orthogonal_complement, solve_augmented, solve_small

__all__ = [
    "Augmented",
    "Baumgarte",
    "Orthogonal",
    "Minimal",
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
    accuracy reference for the other formulations.
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
        last = {"y": None, "s": None, "R": None}

        def unpack(y, t=None):
            s, R = unpack_with_R(y, t)
            return s, R @ y[f:]

        def unpack_with_R(y, t=None):
            if last["y"] is not None and np.array_equal(y, last["y"]):
                return last["s"], last["R"]
            guess = last["s"][zi]
            if last["R"] is not None:
                guess = guess + last["R"][zi] @ (y[:f] - last["s"][qi])
            s, Phi = solve_dependent(system, y[:f], guess, t, return_jacobian=True)
            R = _orthogonal_complement(Phi, qi, zi, t)
            last.update(y=y.copy(), s=s, R=R)
            return s, R

        def seed(s_start):
            last.update(y=None, s=np.array(s_start, dtype=float), R=None)

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


FORMULATION_NAMES = ("augmented", "baumgarte", "orthogonal", "minimal", "projected")


def formulation_from_name(name, alpha=None, beta=None):
    """The formulation called ``name``, with Baumgarte gains where it takes them.

    Parameters
    ----------
    name : {"augmented", "baumgarte", "orthogonal", "minimal", "projected"}
    alpha, beta : float, optional
        Only for "baumgarte" and "orthogonal" (default 5 and 5, Baumgarte's choice).
    """
    if name not in FORMULATION_NAMES:
        raise InputError(f"formulation: unknown {name!r}; choose one of {', '.join(FORMULATION_NAMES)}")
    gains = {k: v for k, v in (("alpha", alpha), ("beta", beta)) if v is not None}
    if name in ("baumgarte", "orthogonal"):
        return {"baumgarte": Baumgarte, "orthogonal": Orthogonal}[name](**gains)
    if gains:
        raise InputError(
            f"alpha, beta: only the baumgarte and orthogonal formulations take gains, not {name!r}"
        )
    if name == "projected":
        from .projection import Projected      # projection.py builds on this module

        return Projected()
    return Augmented() if name == "augmented" else Minimal()
