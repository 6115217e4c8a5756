"""Kinematic singularities: where Phi_z and Phi_s lose rank, what fails there, and the remedy.

Dead positions (Phi_z singular, Phi_s of full rank) of a rocking slider-crank and a rocking
four-bar, which the null-space formulation passes; near a bifurcation of the slider-crank
(l2 -> l1), a clear error. The change points of a parallelogram four-bar, where Phi_s itself
loses rank, are in test_change_points.py.
"""

import math

import numpy as np
import pytest
import sympy as sp

from closedloop import (Augmented, Baumgarte, ClosedForm, InitialState, InputError, Minimal, NullSpace, Orthogonal,
                        SingularConfigurationError, System, consistent_initial_state, derive, formulation_from_name,
                        null_space_basis, simulate)
from closedloop.four_bar import four_bar_model
from closedloop.linalg import solve_dense, solve_small
from closedloop.model import condition_number
from closedloop.slider_crank import SliderCrankParameters, initial_state, slider_crank_model, slider_crank_system

from .conftest import PARALLELOGRAM

ROCKING = SliderCrankParameters(l2=1.5, a2=0.75, full_rotation=False)      # l2/l1 = 0.75


@pytest.fixture(scope="module")
def rocking():
    """l2 < l1, no torque, no gas force: a conservative crank that rocks through dead positions."""
    return slider_crank_system(ROCKING, torque=False, gas=False)


def test_det_phi_z_is_minus_l2_cos_psi():
    """(20) needs Phi_z = d(f1, f2)/d(psi, x_C) invertible: det = -l2 cos psi, zero with the rod upright."""
    d = derive(slider_crank_model())
    model = d.model
    Phi_z = d.jacobian[:, list(model.dependent_index)]
    l2, psi = sp.Symbol("l2"), sp.Symbol("psi")
    assert sp.simplify(Phi_z.det() + l2 * sp.cos(psi)) == 0


def test_condition_number_closed_form_matches_numpy():
    rng = np.random.default_rng(7)
    for _ in range(200):
        A = rng.normal(size=(2, 2)) * 10.0 ** rng.uniform(-3, 3)
        assert condition_number(A) == pytest.approx(np.linalg.cond(A), rel=1e-8)
    assert condition_number(np.array([[1.0, 2.0], [2.0, 4.0]])) == math.inf


def test_solve_dense_solves_as_numpy_does_and_refuses_a_singular_matrix():
    """solve_dense calls LAPACK's dgesv directly (numpy.linalg.solve's routine, without its overhead): the
    same solutions to round-off, for a vector and for a matrix of right-hand sides, and the same error."""
    rng = np.random.default_rng(11)
    for size in (3, 5, 8):
        A = rng.normal(size=(size, size)) + size * np.eye(size)
        for b in (rng.normal(size=size), rng.normal(size=(size, 2))):
            x = solve_dense(A, b)
            assert x.shape == b.shape
            np.testing.assert_allclose(x, np.linalg.solve(A, b), rtol=1e-12, atol=1e-14)
            np.testing.assert_allclose(A @ x, b, rtol=1e-12, atol=1e-12)
    singular = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0], [0.0, 1.0, 1.0]])
    with pytest.raises(np.linalg.LinAlgError, match="Singular matrix"):
        solve_dense(singular, np.ones(3))


def test_solve_small_two_by_two_is_cramers_rule_and_refuses_round_off_singular_matrices():
    rng = np.random.default_rng(13)
    for _ in range(200):
        A = rng.normal(size=(2, 2)) * 10.0 ** rng.uniform(-3, 3)
        b = rng.normal(size=2)
        det = A[0, 0] * A[1, 1] - A[0, 1] * A[1, 0]
        expected = np.array([A[1, 1] * b[0] - A[0, 1] * b[1], A[0, 0] * b[1] - A[1, 0] * b[0]]) / det
        assert np.array_equal(solve_small(A, b), expected)                  # the same IEEE operations
        B = rng.normal(size=(2, 3))
        np.testing.assert_allclose(A @ solve_small(A, B), B, rtol=1e-9, atol=1e-9 * np.abs(B).max())
    for singular in (np.array([[1.0, 2.0], [2.0, 4.0]]), np.array([[1.0, 1.0], [1.0, 1.0 + 2.3e-16]]),
                     np.array([[np.nan, 1.0], [1.0, 1.0]])):
        with pytest.raises(np.linalg.LinAlgError):
            solve_small(singular, np.ones(2))


@pytest.mark.parametrize("basis", ["svd", "pivoted"])
def test_null_space_basis_spans_the_null_space_even_where_phi_z_is_singular(basis):
    l1, l2 = 2.0, 1.5
    phi = math.pi - math.asin(l2 / l1)          # dead position: psi = pi/2, cos psi = 0
    Phi = np.array([[-l1 * math.sin(phi), l2, -1.0], [l1 * math.cos(phi), 0.0, 0.0]])
    N = null_space_basis(Phi, basis)
    assert N.shape == (3, 1)
    assert np.max(np.abs(Phi @ N)) < 1e-14
    if basis == "svd":
        assert abs(np.linalg.norm(N) - 1.0) < 1e-14
    with pytest.raises(SingularConfigurationError, match=r"Phi_s lost rank at t = 1\.5 s: cond\(Phi_s\)"):
        null_space_basis(np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 6.0]]), basis, t=1.5)


def test_the_rocking_crank_is_an_explicit_documented_choice():
    with pytest.raises(InputError, match=r"^l1: must be < l2 = 1\.5 m.*full_rotation=False"):
        SliderCrankParameters(l2=1.5, a2=0.75)
    with pytest.raises(InputError, match=r"^l2: must be < l1 = 2 m with full_rotation=False.*bifurcation"):
        SliderCrankParameters(l2=2.0, full_rotation=False)
    with pytest.raises(InputError, match=r"^phi0: the mechanism does not assemble at phi0 = 1\.5"):
        initial_state(slider_crank_system(ROCKING), 1.5, 0.0)
    assert "full_rotation" not in ROCKING.as_dict()


@pytest.fixture(scope="module")
def through_dead_positions(rocking):
    state = initial_state(rocking, math.pi, 1.0)
    times = np.linspace(0.0, 8.0, 81)
    options = dict(method="DOP853", t_eval=times)
    remedy = simulate(rocking, state, 8.0, formulation=NullSpace(), rtol=1e-10, atol=1e-10, **options)
    reference = simulate(rocking, state, 8.0, formulation=Augmented(), rtol=1e-12, atol=1e-12, **options)
    return state, remedy, reference


def test_null_space_formulation_passes_the_dead_positions(rocking, through_dead_positions):
    state, remedy, reference = through_dead_positions
    assert remedy.max_constraint_error < 1e-8
    assert np.max(np.abs(remedy.s - reference.s)) < 1e-7
    energy = rocking.energy(remedy.s, remedy.sd)
    assert np.ptp(energy) < 1e-7 * np.max(np.abs(energy))
    # it went through them: the rod turned past upright, and phi reached its geometric limit there
    assert len(remedy.partition_singularities) >= 2
    assert np.ptp(remedy.coordinate("psi")) > math.pi
    limit = math.asin(ROCKING.l2 / ROCKING.l1)
    assert np.max(np.abs(remedy.coordinate("phi") - math.pi)) <= limit + 1e-9


def test_minimal_coordinates_fail_with_a_clear_error_at_the_first_dead_position(rocking, through_dead_positions):
    state, remedy, _ = through_dead_positions
    first = remedy.partition_singularities[0]
    with pytest.raises(SingularConfigurationError, match=r"at t = ([0-9.]+) s.*\|Phi_s\| \|Phi_z\^-1\|.*NullSpace") as error:
        simulate(rocking, state, 8.0, formulation=Minimal(), method="DOP853", rtol=1e-10, atol=1e-10)
    failed_at = float(error.value.args[0].split("at t = ")[1].split(" s")[0])
    assert abs(failed_at - first) < 1e-3
    assert "dead position of q" in str(error.value) and "too fast" not in str(error.value)


def test_plain_r_refuses_a_dead_position_that_the_remedy_starts_from(rocking):
    l1, l2 = ROCKING.l1, ROCKING.l2
    phi = math.pi - math.asin(l2 / l1)
    omega = 1.0                                   # the rod turns; the crank is momentarily at rest
    state = InitialState([phi, math.pi / 2, l1 * math.cos(phi)], [0.0, omega, l2 * omega])
    with pytest.raises(SingularConfigurationError, match=r"at t = 0 s: \|Phi_s\| \|Phi_z\^-1\| = .* > 1e\+10.*NullSpace"):
        simulate(rocking, state, 1.0, formulation=Orthogonal(), method="DOP853")
    result = simulate(rocking, state, 1.0, formulation=NullSpace(basis="pivoted"), method="DOP853",
                      rtol=1e-10, atol=1e-10)
    assert result.max_constraint_error < 1e-8
    crank = result.coordinate("phi")                     # phi = pi - asin(l2/l1) is the crank's lower limit
    assert crank.min() >= phi - 1e-9 and crank[-1] > phi + 0.01


def test_the_remedy_is_available_by_name():
    assert formulation_from_name("nullspace", alpha=3.0) == NullSpace(alpha=3.0, beta=5.0)
    with pytest.raises(InputError, match=r"^basis: unknown 'lu'; choose one of svd, pivoted"):
        NullSpace(basis="lu")


@pytest.mark.parametrize("method", ["DOP853"])
def test_baumgarte_near_the_bifurcation_stops_with_a_clear_error_instead_of_changing_branch(method):
    """l2/l1 = 1 + 1e-8: the branches are about 3e-4 rad apart at phi = pi/2."""
    system = slider_crank_system(SliderCrankParameters(l2=2.0 * (1 + 1e-8), a2=1.0), torque=False, gas=False)
    state = initial_state(system, math.pi, 3.0)
    with pytest.raises(SingularConfigurationError, match=r"at t = [0-9.]+ s.*cond\(Phi_s\).*Kantorovich"):
        simulate(system, state, 3.0, formulation=Baumgarte(5, 5), method=method, rtol=1e-3, atol=1e-3)
    tight = simulate(system, state, 3.0, formulation=Baumgarte(5, 5), method=method, rtol=1e-9, atol=1e-9)
    assert np.max(np.cos(tight.coordinate("psi"))) < 0        # stayed on the paper's branch
    energy = system.energy(tight.s, tight.sd)
    assert np.ptp(energy) < 1e-4 * np.max(np.abs(energy))


def test_null_space_passes_the_dead_positions_of_a_rocking_four_bar_crank():
    """l0 = 3.2: not Grashof; the crank rocks, turning where coupler and rocker line up.

    There det Phi_z = 0 but Phi_s keeps its rank: a dead position of theta1, not a bifurcation.
    The crank's limit follows from the triangle O B D with |BD| = l2 + l3.
    """
    data = dict(PARALLELOGRAM, l0=3.2)
    rocking = System(four_bar_model(), data)
    start = consistent_initial_state(rocking, [np.pi / 2], [2.0], [0.0, np.pi / 2])
    t = np.linspace(0.0, 3.0, 3001)
    result = simulate(rocking, start, 3.0, formulation=NullSpace(5, 5), method="DOP853", rtol=1e-10,
                      atol=1e-10, t_eval=t)
    l0, l1, l2, l3 = (data[k] for k in ("l0", "l1", "l2", "l3"))
    limit = np.arccos((l0**2 + l1**2 - (l2 + l3) ** 2) / (2 * l0 * l1))
    crank = result.coordinate("theta1")
    assert len(result.partition_singularities) >= 3
    at_dead = np.interp(result.partition_singularities, t, np.abs(crank))
    assert np.max(np.abs(at_dead - limit)) < 1e-4
    assert np.max(np.abs(crank)) < limit + 1e-8
    assert result.max_constraint_error < 1e-8
    energy = rocking.energy(result.s, result.sd)
    assert np.max(np.abs(energy - energy[0])) < 1e-7 * abs(energy[0])
    with pytest.raises(SingularConfigurationError, match="use the NullSpace formulation"):
        simulate(rocking, start, 3.0, formulation=Minimal(), method="DOP853", rtol=1e-10, atol=1e-10)


def test_phi_z_is_measured_against_phi_s():
    """cond(Phi_z) misses a Phi_z small as a whole: a 1 x 1 one has condition 1 unless it is 0 (a Cartesian
    pendulum at y = 1e-17 gave accelerations off by 6), and so has 1e-17 I. |Phi_s| |Phi_z^-1| catches both,
    and equals the 2-norms' ratio computed by numpy."""
    from closedloop.linalg import orthogonal_complement, partition_condition

    with pytest.raises(SingularConfigurationError, match=r"\|Phi_s\| \|Phi_z\^-1\| = 1e\+17 > 1e\+10"):
        orthogonal_complement(np.array([[2.0, 2e-17]]), [0], [1])
    with pytest.raises(SingularConfigurationError, match=r"\|Phi_s\| \|Phi_z\^-1\| = 1\.41e\+17 > 1e\+10"):
        orthogonal_complement(np.array([[1.0, 1e-17, 0.0], [1.0, 0.0, 1e-17]]), [0], [1, 2])
    assert orthogonal_complement(np.array([[2.0, 1.0]]), [0], [1]).ravel().tolist() == [1.0, -2.0]
    rng = np.random.default_rng(7)
    for r, n in ((1, 2), (2, 3), (2, 4), (3, 5)):
        Phi = rng.normal(size=(r, n))
        z = list(range(n - r, n))
        exact = np.linalg.norm(Phi, 2) / np.linalg.svd(Phi[:, z], compute_uv=False)[-1]
        assert partition_condition(Phi, z) == pytest.approx(exact, rel=1e-12)


def test_a_phi_z_that_is_not_finite_is_refused_as_singular_not_by_numpy():
    from closedloop.linalg import orthogonal_complement

    with pytest.raises(SingularConfigurationError, match=r"\|Phi_s\| \|Phi_z\^-1\| = inf"):
        orthogonal_complement(np.array([[np.nan, 1.0, 0.5], [0.2, np.nan, 1.0]]), [0], [1, 2])


def test_null_space_basis_refuses_an_unknown_basis():
    from closedloop import InputError
    from closedloop.linalg import null_space_basis

    with pytest.raises(InputError, match=r"^basis: unknown 'bogus'; choose one of svd, pivoted$"):
        null_space_basis(np.array([[1.0, 2.0, 3.0]]), basis="bogus")          # it gave the pivoted basis


@pytest.mark.parametrize("formulation", [Orthogonal(), ClosedForm()], ids=lambda f: f.name)
def test_the_compiled_dop853_passes_the_dead_positions_with_the_branch_guard(rocking, through_dead_positions,
                                                                             formulation):
    """ode.dop853 has no dense output, and it refused every crossing of det Phi_z = 0 ("use a solve_ivp method");
    the crossing is now located on the quintic Hermite interpolant of the step's end states, and the branch
    guard checked there, as on solve_ivp: the same dead positions, to 1e-8 s, and the same motion."""
    state, _, reference = through_dead_positions
    times = reference.t
    tight = simulate(rocking, state, 8.0, formulation=NullSpace(), method="DOP853", rtol=1e-12, atol=1e-12)
    result = simulate(rocking, state, 8.0, formulation=formulation, method="ode.dop853", rtol=1e-10, atol=1e-10,
                      t_eval=times)
    assert len(result.partition_singularities) == len(tight.partition_singularities) >= 3
    assert np.max(np.abs(np.subtract(result.partition_singularities, tight.partition_singularities))) < 1e-8
    assert np.max(np.abs(result.s - reference.s)) < 1e-7
