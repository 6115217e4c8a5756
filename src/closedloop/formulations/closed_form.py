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
and no linear solve.

For an integration segment, where the branch (``mode``) of a switched force
and the gains are fixed, :func:`closed_form_rhs` goes one step further: when the
force can write itself as sympy expressions on that branch
(:meth:`closedloop.forces.SwitchedForce.expressions`), the force and the gains are
folded in as well, and the whole first-order right-hand side ``y' = [s', s'']``
is generated as one function of ``(t, y)``: one Python call per evaluation.

Every generated function is kept on disk (:mod:`closedloop.codecache`) under
the system's model and parameter values (and the branch, the gains and the
force's :meth:`~closedloop.forces.SwitchedForce.cache_key` where they are
folded in), so that a later run needs no sympy.

The closed form is exactly as singular as R of (20): where det Phi_z = 0 it
divides by zero and raises.  Near that point it loses digits as R does (about
cond(Phi_z) times the rounding) but does not check it, where
:class:`~closedloop.formulations.Orthogonal` refuses |Phi_s| |Phi_z^-1| above
:data:`~closedloop.linalg.CONDITION_LIMIT`.  In a run the branch guard (solve_ivp
methods and ode.dop853 alike, :mod:`closedloop.simulation.watch`) watches det
Phi_z's sign between steps.  Use :class:`closedloop.formulations.Augmented` or a null-space
formulation there.
"""

from __future__ import annotations

import math

from dataclasses import dataclass

import numpy as np

from ..codecache import cached_code
from ..errors import InputError, SingularConfigurationError, at_time
from .redundant import _Stabilised

__all__ = ["ClosedForm", "closed_form_accelerations", "closed_form_rhs", "MAX_CLOSED_FORM_SIZE"]

#: Largest r (for Phi_z) and f (for R^T M R) whose inverse is formed symbolically.
MAX_CLOSED_FORM_SIZE = 3


def _symbolic_inverse(matrix):
    """Adjugate over determinant, as sympy expressions (small square matrices only)."""
    import sympy as sp

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
    import sympy as sp

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
    cached = system.generated.get("closed_form")
    if cached is None:
        cached = system.generated["closed_form"] = _from_disk(system, "closed_form", (), _accelerations)
    return cached


def _accelerations(system):
    """closed_form_accelerations without the caches (sympy)."""
    import sympy as sp

    expressions, (Q, alpha, beta) = closed_form_expressions(system)
    model = system.model
    return sp.lambdify([model.time, list(model.coordinates), list(model.velocities), Q, alpha, beta],
                       expressions, modules="math", cse=True)


def _from_disk(system, kind, parts, generate):
    """``generate(system)`` through the disk cache (:mod:`closedloop.codecache`).

    Keyed on the system's model and parameter values and on ``parts``, which must
    name everything else the generated function depends on.
    """
    key = (system.model_identity, f"values {system.parameter_values.tolist()!r}", *parts)
    return cached_code(kind, key, lambda: {"function": generate(system)}, ("function",))["function"]


def _singular(t):
    return SingularConfigurationError(
        f"Phi_z is singular{at_time(t)} (det Phi_z = 0): the closed form of (26) divides "
        "by it; use Augmented or the NullSpace formulation through this configuration"
    )


def _generate_rhs(velocities, accelerations, time, coordinates):
    """Source and function ``rhs(t, y) -> list`` for ``y' = [s', s'']``, with ``y = [s, s']`` an array.

    The model's symbols are renamed (any sympy name is allowed in a model), common
    subexpressions are shared, and the state is read with ``y.tolist()``: the
    ``math`` functions are fastest on Python floats.
    """
    import sympy as sp
    from sympy.printing.pycode import PythonCodePrinter

    n = len(coordinates)
    names = [sp.Symbol(f"_y{i}") for i in range(2 * n)]
    rename = dict(zip(list(coordinates) + list(velocities), names))
    rename[time] = sp.Symbol("_t")
    expressions = [sp.sympify(e).xreplace(rename) for e in accelerations]
    replacements, reduced = sp.cse(expressions, symbols=sp.numbered_symbols("_c"))
    printer = PythonCodePrinter({"fully_qualified_modules": False})
    lines = ["def rhs(_t, y):", "    try:", f"        {', '.join(map(str, names))}, = y.tolist()"]
    lines += [f"        {symbol} = {printer.doprint(value)}" for symbol, value in replacements]
    lines.append(f"        return [{', '.join(map(str, names[n:]))}, {', '.join(map(printer.doprint, reduced))}]")
    lines += ["    except ZeroDivisionError:", "        raise _singular(_t) from None"]
    source = "\n".join(lines) + "\n"
    namespace = {name: getattr(math, name) for name in dir(math) if not name.startswith("_")}
    namespace["_singular"] = _singular
    exec(compile(source, "<closed form rhs>", "exec"), namespace)      # noqa: S102 (our own sympy output)
    rhs = namespace["rhs"]
    rhs.source = source
    return rhs


def closed_form_rhs(system, mode, alpha, beta):
    """The generated ``rhs(t, y) -> list`` of ``y' = [s', s'']`` on one branch of the force, or None.

    s'' is that of (26) with the gains ``alpha``, ``beta`` of (17) and the
    switched force on branch ``mode`` folded in as numbers and expressions, so
    that one call evaluates the whole right-hand side.  ``y`` is an array
    ``[s, s']`` of 2n floats.  Returns None when the system's force has no
    sympy form on that branch (:meth:`~closedloop.forces.SwitchedForce.expressions`);
    :class:`~closedloop.formulations.ClosedForm` then calls the force itself.
    Built once per system, branch and pair of gains, and kept on the system.

    Parameters
    ----------
    system : System
    mode : tuple of bool
    alpha, beta : float

    Returns
    -------
    callable or None

    Raises
    ------
    SingularConfigurationError
        When called where det Phi_z = 0.
    """
    by_mode = system.generated.setdefault("closed_form_rhs", {})
    key = (mode, float(alpha), float(beta))
    if key not in by_mode:
        force = "none" if system.force is None else system.force.cache_key(mode)
        if force is None:                   # a force without a key: its expressions cannot be kept on disk
            by_mode[key] = _folded_rhs(system, *key)
        else:                               # branches whose force has one key share one function
            by_key = system.generated.setdefault("closed_form_rhs_by_key", {})
            shared = (force, *key[1:])
            if shared not in by_key:
                by_key[shared] = _from_disk(system, "closed_form_rhs", (f"force, alpha, beta {shared!r}",),
                                            lambda system: _folded_rhs(system, *key))
            by_mode[key] = by_key[shared]
    return by_mode[key]


def _folded_rhs(system, mode, alpha, beta):
    """closed_form_rhs without the cache per branch (branches with the same force share a function)."""
    import sympy as sp

    model = system.model
    if system.force is None:
        force = [sp.Integer(0)] * system.n
    else:
        force = system.force.expressions(mode, model.time, list(model.coordinates), list(model.velocities))
        if force is None:
            return None
        force = [sp.sympify(v) for v in force]
    by_force = system.generated.setdefault("closed_form_rhs_by_force", {})
    key = (tuple(force), alpha, beta)
    if key not in by_force:
        accelerations, (Q, alpha_symbol, beta_symbol) = closed_form_expressions(system)
        values = dict(zip(Q, force))
        values.update({alpha_symbol: sp.Float(alpha), beta_symbol: sp.Float(beta)})
        by_force[key] = _generate_rhs(model.velocities, [e.xreplace(values) for e in accelerations], model.time,
                                      model.coordinates)
    return by_force[key]


@dataclass(frozen=True)
class ClosedForm(_Stabilised):
    """The ODE (26) with its linear algebra done once, symbolically.

    The same accelerations as :class:`Orthogonal` and :class:`Baumgarte` with
    the same gains (and as :class:`Augmented` with ``alpha = beta = 0``), from
    a function generated by :func:`closedloop.formulations.closed_form.closed_form_accelerations`:
    R of (20), Phi_z^{-1} and (R^T M R)^{-1} are eliminated in closed form and the
    parameter values folded in, so an evaluation assembles no matrix and solves
    no system.  Like R of (20) it needs a regular Phi_z.

    Parameters
    ----------
    alpha, beta : float, >= 0
        Baumgarte gains in p2~ of (17); 0 and 0 give the unstabilised (12).
    """

    name = "closed-form"
    guards_partition = True       # it divides by det Phi_z: exactly 0 raises (the run checks the sign)

    def switch_accelerations(self, system, mode):
        """s'' of (12) (alpha = beta = 0) from the generated closed form, or None without one."""
        rhs = closed_form_rhs(system, mode, 0.0, 0.0)
        if rhs is None:
            return None
        n = system.n

        def accelerations(t, s, sd):
            return np.array(rhs(t, np.concatenate((s, sd)))[n:])

        return accelerations

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
