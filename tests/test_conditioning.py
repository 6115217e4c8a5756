"""Masses spread over 1e-6 ... 1e6 kg: condition numbers, and how accurate the solves of (12) and (26) stay."""

import mpmath
import numpy as np
import pytest

from closedloop import Augmented, Minimal, Orthogonal
from closedloop.conditioning import augmented_matrix, conditioning, equilibration, generalized_mass
from closedloop.slider_crank import SliderCrankParameters, initial_state, slider_crank_system

SPREADS = [(1e6, 1e-6, 1e-6), (1e-6, 1e6, 1e-6), (1e-6, 1e-6, 1e6), (1e6, 1e6, 1e-6)]


def _system(m1, m2, m3):
    return slider_crank_system(SliderCrankParameters(m1=m1, I1=2.25 * m1, m2=m2, I2=m2, m3=m3))


def _exact_solution(K, b):
    mpmath.mp.dps = 40
    return np.array([float(v) for v in mpmath.lu_solve(mpmath.matrix(K.tolist()), mpmath.matrix(b.tolist()))])


@pytest.mark.parametrize("masses", SPREADS)
def test_scaling_not_physics_makes_the_augmented_matrix_ill_conditioned(masses):
    system = _system(*masses)
    state = initial_state(system, 2.0, 3.0)
    numbers = conditioning(system, state.s)
    assert numbers.mass > 1e10 or numbers.augmented > 1e10
    assert numbers.equilibrated < 100                       # equilibration removes it
    M, p1, f, Phi, gamma = system.dynamics(0.0, state.s, state.sd)
    exact = _exact_solution(augmented_matrix(M, Phi), np.concatenate((p1, -gamma)))
    for formulation in (Augmented(), Orthogonal(0, 0), Minimal()):
        accelerations = formulation.accelerations(system, 0.0, state.s, state.sd)
        assert np.max(np.abs(accelerations - exact[:3]) / np.abs(exact[:3])) < 1e-9


def test_equilibration_gives_unit_diagonal_and_unit_rows():
    system = _system(1e6, 1e-6, 1e-6)
    state = initial_state(system, 2.0, 0.0)
    M, _, _, Phi, _ = system.dynamics(0.0, state.s, state.sd)
    D = equilibration(M, Phi)
    K = D[:, None] * augmented_matrix(M, Phi) * D[None, :]
    assert np.allclose(np.diag(K)[:3], 1.0)
    assert np.allclose(np.linalg.norm(K[3:, :3], axis=1), 1.0)


def test_generalized_mass_is_twice_the_kinetic_energy_at_unit_crank_speed():
    """R^T M R against 2 T at phi' = 1, with psi', x_C' from finite differences of the assembly."""
    system = _system(1e-6, 1e-6, 1e6)
    for phi in (0.3, 2.0, 3.1):
        s = initial_state(system, phi, 0.0).s
        h = 1e-6
        sd = (initial_state(system, phi + h, 0.0).s - initial_state(system, phi - h, 0.0).s) / (2 * h)
        T, _ = system.kinetic_and_potential_energy(s, sd)
        assert generalized_mass(system, s)[0, 0] == pytest.approx(2 * T, rel=1e-6)
