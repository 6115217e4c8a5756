"""How well conditioned the linear systems of (12) and (26) are at a state.

Masses that differ by many orders of magnitude make ``cond(M)`` and the
condition number of the augmented matrix of (12) huge.  Much of that is a
matter of units: scaling the rows and columns of the matrix (equilibration)
removes it, and an LU factorisation with partial pivoting is not misled by it.
What scaling cannot remove is a real spread of time scales in the motion,
which shows in the generalised mass ``R^T M R`` of the orthogonality theorem
(18)-(20) as it varies along the motion.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from .linalg import augmented_matrix, orthogonal_complement

__all__ = ["Conditioning", "conditioning", "augmented_matrix", "equilibration", "generalized_mass"]


def equilibration(M, Phi):
    """Symmetric scaling ``D`` that gives the matrix of (12) unit mass diagonal and unit constraint rows.

    ``d_s = 1/sqrt(diag M)`` for the coordinates, and for each constraint i
    ``d_i = 1/|Phi_i diag(d_s)|``.  ``D K D`` has the same solution up to the
    change of variables ``x = D y``.

    Returns
    -------
    ndarray, shape (n + r,)
        The diagonal of D.
    """
    d_s = 1.0 / np.sqrt(np.abs(np.diag(M)))
    d_lambda = 1.0 / np.linalg.norm(Phi * d_s, axis=1)
    return np.concatenate((d_s, d_lambda))


def generalized_mass(system, s):
    """``R^T M R`` of the orthogonality theorem (18)-(20): the mass matrix in the independent coordinates q."""
    M, _, _, Phi, _ = system.dynamics(0.0, np.asarray(s, dtype=float), np.zeros(system.n), None)
    R = orthogonal_complement(Phi, system.q_index, system.z_index)
    return R.T @ M @ R


@dataclass(frozen=True)
class Conditioning:
    """Condition numbers (2-norm) at one state.

    Attributes
    ----------
    mass : float
        cond(M).
    augmented : float
        cond of the matrix of (12).
    equilibrated : float
        cond of that matrix after the scaling of :func:`equilibration`.
    orthogonal : float
        cond of ``A = [R^T M; Phi_s]`` of (25).
    """

    mass: float
    augmented: float
    equilibrated: float
    orthogonal: float


def conditioning(system, s):
    """The :class:`Conditioning` of the linear systems of (12) and (26) at configuration s."""
    s = np.asarray(s, dtype=float)
    M, _, _, Phi, _ = system.dynamics(0.0, s, np.zeros(system.n), None)
    K = augmented_matrix(M, Phi)
    D = equilibration(M, Phi)
    R = orthogonal_complement(Phi, system.q_index, system.z_index)
    A = np.vstack((R.T @ M, Phi))
    return Conditioning(mass=float(np.linalg.cond(M)), augmented=float(np.linalg.cond(K)),
                        equilibrated=float(np.linalg.cond(D[:, None] * K * D[None, :])),
                        orthogonal=float(np.linalg.cond(A)))
