"""The accelerations of (26) in closed form: one generated function per system.

The augmented system (12)/(16) and the orthogonality-theorem ODE (24)-(26)
have the same solution s'' wherever Phi_z is regular.  Written with R of (20),

    s'' = R q'' + c,     c_q = 0,   c_z = Phi_z^{-1} p2~               (17), (10)
    (R^T M R) q'' = R^T (p1 + Q - M c)                                   (18), (26)

with p2~ = -Phi_s' s' - 2 alpha Phi_s s' - beta^2 f of (17) (alpha = beta = 0
gives the unstabilised p2 of (11)) and Q the switched forces that are not sympy
expressions (the gas force).  Because Phi_z is r x r and R^T M R is f x f, both
small for the mechanisms of this book, the inverses are formed symbolically
(adjugate over determinant) once, the parameter values of the system are folded
in, common subexpressions are shared, and the result is generated as one
``math``-module function of floats.  At run time there is no matrix assembly
and no linear solve: for the slider-crank one call costs about 1.5 µs against
about 20 µs for assembling and solving (12) with numpy.

The closed form is exactly as singular as R of (20): where det Phi_z = 0 it
divides by zero.  Use :class:`closedloop.formulations.Augmented` or a null-space
formulation there.
"""

from __future__ import annotations

import sympy as sp

from .errors import InputError

__all__ = ["closed_form_accelerations", "MAX_CLOSED_FORM_SIZE"]

#: Largest r (for Phi_z) and f (for R^T M R) whose inverse is formed symbolically.
MAX_CLOSED_FORM_SIZE = 3


def _symbolic_inverse(matrix):
    """Adjugate over determinant, as sympy expressions (small square matrices only)."""
    if matrix.shape == (1, 1):
        return sp.Matrix([[1 / matrix[0, 0]]])
    return matrix.adjugate() / matrix.det(method="berkowitz")


def closed_form_expressions(system):
    """s'' of (26) in closed form, as sympy expressions.

    Parameters
    ----------
    system : System

    Returns
    -------
    accelerations : list of sympy.Expr
        One per coordinate, in terms of the model's time, coordinates and
        velocities, the gains ``alpha`` and ``beta``, and symbols ``Q0 ... Q{n-1}``
        for the switched generalised forces; the parameter values are folded in.
    symbols : tuple
        ``(Q, alpha, beta)``: the list of force symbols and the two gains.
    """
    derived, model = system.derived, system.model
    n, r, f = system.n, system.r, system.f
    if r > MAX_CLOSED_FORM_SIZE or f > MAX_CLOSED_FORM_SIZE:
        raise InputError(
            f"formulation: the closed form inverts Phi_z ({r} x {r}) and R^T M R ({f} x {f}) "
            f"symbolically, which is allowed up to {MAX_CLOSED_FORM_SIZE} x {MAX_CLOSED_FORM_SIZE}; "
            "use Orthogonal or Baumgarte for this model"
        )
    # Placeholders first: the elimination is done on symbols for the entries of
    # M, p1, f, Phi_s and Phi_s' s', which keeps the algebra small; the model's
    # expressions are substituted at the end and shared by cse when generated.
    M = sp.Matrix(n, n, lambda i, j: sp.Symbol(f"_M{min(i, j)}_{max(i, j)}"))
    Phi = sp.Matrix(r, n, lambda i, j: sp.Symbol(f"_P{i}_{j}"))
    p1 = sp.Matrix(n, 1, lambda i, _: sp.Symbol(f"_p{i}"))
    fv = sp.Matrix(r, 1, lambda i, _: sp.Symbol(f"_f{i}"))
    gamma = sp.Matrix(r, 1, lambda i, _: sp.Symbol(f"_g{i}"))
    Q = [sp.Symbol(f"Q{i}") for i in range(n)]
    alpha, beta = sp.symbols("alpha beta")
    sd = sp.Matrix(model.velocities)
    qi, zi = list(system.q_index), list(system.z_index)

    Phi_z_inverse = _symbolic_inverse(Phi[:, zi])
    R = sp.zeros(n, f)                                                     # (20)
    for k, i in enumerate(qi):
        R[i, k] = 1
    X = -Phi_z_inverse * Phi[:, qi]
    for k, i in enumerate(zi):
        R[i, :] = X[k, :]
    p2 = -gamma - 2 * alpha * (Phi * sd) - beta**2 * fv                   # (17)
    c = sp.zeros(n, 1)
    c_z = Phi_z_inverse * p2
    for k, i in enumerate(zi):
        c[i] = c_z[k]
    qdd = _symbolic_inverse(R.T * M * R) * (R.T * (p1 + sp.Matrix(Q) - M * c))   # (26)
    sdd = R * qdd + c

    values = dict(zip(model.parameters, (sp.Float(v) for v in system.parameter_values.tolist())))
    entries = {}
    for i in range(n):
        for j in range(n):
            entries[M[i, j]] = derived.mass_matrix[i, j]
        entries[p1[i]] = derived.p1[i]
    for i in range(r):
        entries[fv[i]] = derived.constraint_vector[i]
        entries[gamma[i]] = derived.jacobian_rate_product[i]
        for j in range(n):
            entries[Phi[i, j]] = derived.jacobian[i, j]
    entries = {k: sp.sympify(v).xreplace(values) for k, v in entries.items()}
    return [e.xreplace(entries) for e in sdd], (Q, alpha, beta)


def closed_form_accelerations(system):
    """The generated function ``accelerations(t, s, sd, Q, alpha, beta) -> list``.

    ``s``, ``sd`` and ``Q`` are lists of n floats (Q: the switched forces added
    to p1 of (7)); the result is s'' of (26) as a list.  The function is built
    once per :class:`~closedloop.model.System` and kept on it.

    Parameters
    ----------
    system : System

    Returns
    -------
    callable
    """
    cached = getattr(system, "_closed_form", None)
    if cached is not None:
        return cached
    expressions, (Q, alpha, beta) = closed_form_expressions(system)
    model = system.model
    function = sp.lambdify([model.time, list(model.coordinates), list(model.velocities), Q, alpha, beta],
                           expressions, modules="math", cse=True)
    system._closed_form = function
    return function
