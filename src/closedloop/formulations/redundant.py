"""The formulations in redundant coordinates, whose state is ``y = [s, s']``.

- :class:`Augmented`: the augmented system (12), no stabilisation;
- :class:`Baumgarte`: (16)-(17), the constraint error obeys (15);
- :class:`Orthogonal`: the ODE (24)-(26), lambda removed with R of (20);
- :class:`NullSpace`: (24)-(26) with R replaced by a basis of the null space
  of Phi_s that needs no fixed partition (SVD, or partitioning with pivoting),
  so it passes the dead positions where Phi_z of (20) is singular.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from ..errors import InputError
from ..linalg import NULL_SPACE_BASES, null_space_basis, orthogonal_complement, solve_augmented, solve_dense
from ..validation import finite_number, one_of, positive_number
from .base import Formulation

__all__ = ["Augmented", "Baumgarte", "Orthogonal", "NullSpace", "baumgarte_from_step", "baumgarte_p2", "GAIN_LIMIT"]


#: The largest Baumgarte gain alpha or beta [1/s].  The constraint error of (15) then decays within
#: 1/GAIN_LIMIT = 1 us, and every method takes steps about that short: RK45 needs 85 000 steps for
#: 0.5 s at 1e5, Radau more than 1e5 steps for 0.03 s at 1e6, so one second at this limit already
#: needs MAX_STEPS = 1e6 steps.  Far above it the terms of (17) overflow (beta^2 = inf at 1.4e154:
#: NaN accelerations at the start, on which solve_ivp's step selection never ends).
GAIN_LIMIT = 1e6


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
    step = positive_number("step", step, unit="s")
    if math.sqrt(2.0) / step > GAIN_LIMIT:
        raise InputError(f"step: must be >= {math.sqrt(2.0) / GAIN_LIMIT:.3g} s, so that beta = sqrt(2)/step stays "
                         f"<= {GAIN_LIMIT:g} 1/s (GAIN_LIMIT), got {step:g}")
    return Baumgarte(alpha=1.0 / step, beta=math.sqrt(2.0) / step)



@dataclass(frozen=True)
class Augmented(Formulation):
    """The augmented system (12) with ``p2 = -Phi_s' s'`` (11): no stabilisation.

    The constraint error is not fed back, so f and f' drift (13).
    """

    name = "augmented"

    def accelerations(self, system, t, s, sd, mode=None):
        """s'' from (12)."""
        M, p1, _, Phi, gamma = system.dynamics(t, s, sd, mode)
        return solve_augmented(M, Phi, p1, -gamma, t)[0]



@dataclass(frozen=True)
class _Stabilised(Formulation):
    """The Baumgarte gains alpha, beta >= 0 of (15), shared by (17) and (25)."""

    alpha: float = 5.0
    beta: float = 5.0

    def __post_init__(self):
        for name in ("alpha", "beta"):
            value = finite_number(name, getattr(self, name), minimum=0.0)
            if value > GAIN_LIMIT:
                raise InputError(f"{name}: must be <= {GAIN_LIMIT:g} 1/s, got {value:g} (the paper's range is 1 to "
                                 "20; above the limit a run needs more than 1e6 steps per second)")

    @property
    def gains(self):
        return (self.alpha, self.beta)



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
        M, p1, constraint_values, Phi, gamma = system.dynamics(t, s, sd, mode)
        p2 = baumgarte_p2(Phi, gamma, constraint_values, sd, self.alpha, self.beta)
        return solve_augmented(M, Phi, p1, p2, t)[0]



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
    guards_partition = True       # R of (20) is refused where |Phi_s| |Phi_z^-1| > CONDITION_LIMIT

    def accelerations(self, system, t, s, sd, mode=None):
        """s'' from (26)."""
        M, p1, constraint_values, Phi, gamma = system.dynamics(t, s, sd, mode)
        R = orthogonal_complement(Phi, system.q_index, system.z_index, t)
        p2 = baumgarte_p2(Phi, gamma, constraint_values, sd,
                          self.alpha, self.beta)                   # (17)
        A = np.vstack((R.T @ M, Phi))                              # (25)
        p = np.concatenate((R.T @ p1, p2))                         # (25)
        return solve_dense(A, p)                                   # (26)



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
        one_of("basis", self.basis, NULL_SPACE_BASES)

    def accelerations(self, system, t, s, sd, mode=None):
        """s'' from (26) with N in place of R."""
        M, p1, constraint_values, Phi, gamma = system.dynamics(t, s, sd, mode)
        N = null_space_basis(Phi, self.basis, t)
        p2 = baumgarte_p2(Phi, gamma, constraint_values, sd,
                          self.alpha, self.beta)                   # (17)
        A = np.vstack((N.T @ M, Phi))                              # (25)
        p = np.concatenate((N.T @ p1, p2))                         # (25)
        return solve_dense(A, p)                                   # (26)
