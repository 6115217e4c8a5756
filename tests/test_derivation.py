"""The sympy derivation reproduces the paper's equations of motion (29)-(31), term by term."""

import sympy as sp

from closedloop import derive
from closedloop.slider_crank import slider_crank_model

phi, psi, x = sp.symbols("phi psi x")
dphi, dpsi, dx = sp.symbols("dphi dpsi dx")
ddphi, ddpsi, ddx = sp.symbols("ddphi ddpsi ddx")
lam1, lam2 = sp.symbols("lambda1 lambda2")
l1, a1, m1, I1, l2, a2, m2, I2, m3, g = sp.symbols("l1 a1 m1 I1 l2 a2 m2 I2 m3 g")
torque_mean, ripple, omega, t = sp.symbols("torque_mean torque_ripple omega t")
M_drive = torque_mean + ripple * sp.sin(omega * t)       # the paper's M(t); the gas force is numeric


def printed_equations(corrected):
    """(29)-(31) typed from the paper as LHS - RHS, with F = 0 (the gas force is a separate callable).

    With ``corrected`` the right side of (29) is the one the derivation gives,
    ``M + lambda1 l1 sin q1 - lambda2 l1 cos q1``, instead of the print's
    ``M + lambda1 sin q1 + lambda2 l1 cos q1``.
    """
    rhs29 = (M_drive + lam1 * l1 * sp.sin(phi) - lam2 * l1 * sp.cos(phi) if corrected
             else M_drive + lam1 * sp.sin(phi) + lam2 * l1 * sp.cos(phi))
    eq29 = ((I1 + m1 * a1**2 + m2 * l1**2) * ddphi - m2 * l1 * a2 * ddpsi * sp.cos(phi - psi)
            - m2 * l1 * a2 * dpsi**2 * sp.sin(phi - psi) + (m1 * a1 + m2 * l1) * g * sp.cos(phi)) - rhs29
    eq30 = (-m2 * l1 * a2 * ddphi * sp.cos(phi - psi) + (I2 + m2 * a2**2) * ddpsi
            + m2 * l1 * a2 * dphi**2 * sp.sin(phi - psi) - m2 * g * a2 * sp.cos(psi)) \
        - (-lam1 * l2 * sp.sin(psi) + lam2 * l2 * sp.cos(psi))
    eq31 = m3 * ddx - (0 + lam1)
    return [eq29, eq30, eq31]


def derived_equations():
    return list(derive(slider_crank_model()).equations_of_motion([ddphi, ddpsi, ddx], [lam1, lam2]))


def test_equations_30_and_31_match_the_print_term_by_term():
    derived, printed = derived_equations(), printed_equations(corrected=False)
    for k in (1, 2):
        assert sp.expand(derived[k] - printed[k]) == 0, f"equation ({30 + k - 1}) differs"


def test_equation_29_matches_once_its_multiplier_terms_are_corrected():
    derived = derived_equations()
    assert sp.expand(derived[0] - printed_equations(corrected=True)[0]) == 0


def test_the_printed_equation_29_differs_only_in_its_multiplier_terms():
    difference = sp.expand(derived_equations()[0] - printed_equations(corrected=False)[0])
    assert difference != 0
    # Only lambda terms differ: the print has lambda1 sin q1 + lambda2 l1 cos q1.
    assert difference.free_symbols <= {lam1, lam2, l1, phi}
    assert sp.simplify(difference - (-(l1 - 1) * lam1 * sp.sin(phi) + 2 * lam2 * l1 * sp.cos(phi))) == 0
    assert sp.expand(difference.subs({lam1: 0, lam2: 0})) == 0


def test_mass_matrix_is_the_papers_kinetic_energy():
    M = derive(slider_crank_model()).mass_matrix
    expected = sp.Matrix([
        [I1 + m1 * a1**2 + m2 * l1**2, -m2 * l1 * a2 * sp.cos(phi - psi), 0],
        [-m2 * l1 * a2 * sp.cos(phi - psi), I2 + m2 * a2**2, 0],
        [0, 0, m3],
    ])
    assert sp.simplify(M - expected) == sp.zeros(3, 3)


def test_jacobian_and_its_rate_term_are_those_of_27_28():
    d = derive(slider_crank_model())
    expected_Phi = sp.Matrix([[-l1 * sp.sin(phi), l2 * sp.sin(psi), -1],
                              [l1 * sp.cos(phi), -l2 * sp.cos(psi), 0]])
    assert sp.simplify(d.jacobian - expected_Phi) == sp.zeros(2, 3)
    # Phi_s' s' by hand: differentiate each row of Phi_s s' once more in time
    expected_gamma = sp.Matrix([-l1 * sp.cos(phi) * dphi**2 + l2 * sp.cos(psi) * dpsi**2,
                                -l1 * sp.sin(phi) * dphi**2 + l2 * sp.sin(psi) * dpsi**2])
    assert sp.simplify(d.jacobian_rate_product - expected_gamma) == sp.zeros(2, 1)


def test_derivation_runs_once_per_model():
    """A second system on the same model reuses its generated functions (a cache hit, no new miss),
    and binding a system calls no derivation at all: a System needs the numeric functions only."""
    from closedloop.model import model_functions
    from closedloop.slider_crank import slider_crank_system

    slider_crank_system()
    before, derived = model_functions.cache_info(), derive.cache_info()
    second = slider_crank_system(reading="thousands-opposing")
    after = model_functions.cache_info()
    assert (after.misses, after.hits) == (before.misses, before.hits + 1)
    assert derive.cache_info() == derived
    assert second.derived is derive(slider_crank_model())        # on demand, the one derivation of the model
