"""The works of the drive torque and the gas force (closedloop.studies.energy), checked independently."""

import math

import numpy as np
import pytest
import sympy as sp

from closedloop import Baumgarte, Minimal, simulate
from closedloop.studies.energy import (_outward_increments, crank_landscape, energy_balance_error, gas_outward_work,
                               gas_work_per_cycle, non_conservative_work, torque_work_per_turn)
from closedloop.slider_crank import CASES, SliderCrankParameters, gas_force, initial_state, slider_crank_system


def printed_gas_work(low, high, scale=1):
    """int F dx of the printed law over [low, high] within [1.5, 5.5], by sympy, exactly."""
    x = sp.symbols("x")
    a, b, c = (sp.Rational(282857, 1000) * scale, sp.Rational(62857, 1000) * scale, 110 * scale)
    low, high = sp.nsimplify(low), sp.nsimplify(high)
    inner = sp.integrate(-a / (6 - x) + b, (x, low, sp.Min(high, 5)))
    outer = sp.integrate(-c * (1 - sp.sin(2 * sp.pi * (x - sp.Rational(21, 4)))), (x, sp.Max(low, 5), high)) \
        if high > 5 else 0
    return float(inner + outer)


def test_torque_work_per_turn_is_two_pi_times_the_mean_torque():
    assert torque_work_per_turn() == pytest.approx(2 * math.pi * 41.45, rel=1e-12)
    assert torque_work_per_turn("thousands-opposing") == pytest.approx(2 * math.pi * 41450.0, rel=1e-12)
    assert torque_work_per_turn() == pytest.approx(260.438, abs=1e-3)            # NOTES.md: 260.4 J


def test_gas_work_per_cycle_matches_sympy_integral_of_the_printed_law():
    exact = printed_gas_work(1.5, 5.5)
    closed = -282.857 * math.log(4.5) + 3.5 * 62.857 - 110.0 / 2        # the sin term integrates to 0
    assert exact == pytest.approx(closed, rel=1e-12)
    assert gas_work_per_cycle() == pytest.approx(exact, rel=1e-10)       # quadrature, opposing: +F
    assert gas_work_per_cycle() == pytest.approx(-260.439, abs=1e-3)     # NOTES.md: 260.4 J
    assert gas_work_per_cycle(reading="decimal-as-printed") == pytest.approx(-exact, rel=1e-10)
    assert gas_work_per_cycle(reading="thousands-opposing") == pytest.approx(1000 * exact, rel=1e-10)
    # a shorter crank strokes over [2.5, 4.5] only, inside the first formula
    short = SliderCrankParameters(l1=1.0)
    assert gas_work_per_cycle(short) == pytest.approx(printed_gas_work(2.5, 4.5), rel=1e-10)


def test_gas_outward_work_is_an_antiderivative_of_the_gas_force():
    x = np.array([1.6, 2.0, 3.3, 4.9, 5.1, 5.3, 5.45])
    h = 1e-6
    slope = (gas_outward_work(x + h) - gas_outward_work(x - h)) / (2 * h)
    assert np.allclose(slope, gas_force(x, 1.0), rtol=1e-6, atol=1e-6)
    assert gas_outward_work(1.5) == pytest.approx(0.0, abs=1e-12)
    assert gas_outward_work(5.0) == pytest.approx(printed_gas_work(1.5, 5.0), rel=1e-12)
    assert gas_outward_work(5.5) == pytest.approx(gas_work_per_cycle(), rel=1e-10)
    assert gas_outward_work(7.0) == gas_outward_work(5.5)                 # no force beyond the stroke


def test_one_sided_work_through_turning_points_between_samples():
    """x = sin u, work function w(x) = x: the outward pieces add up to exactly 2 per period."""
    u = np.linspace(0.0, 2 * np.pi, 23)               # no sample at the turning points pi/2, 3pi/2
    increments = _outward_increments(np.sin(u), np.cos(u), np.diff(u), lambda x: x)
    assert increments.sum() == pytest.approx(2.0, abs=2e-3)
    assert np.all(increments >= 0)


@pytest.fixture(scope="module")
def slider_crank():
    return slider_crank_system()


@pytest.mark.parametrize("number", [1, 2])
def test_energy_balance_along_a_run_to_the_integrator_tolerance(slider_crank, number):
    """(T + Pi)(t) - (T + Pi)(0) = W_M + W_F: the residual follows the integrator's tolerance."""
    case = CASES[number]
    state = initial_state(slider_crank, case.phi0, case.dphi0)
    t = np.linspace(0.0, 20.0, 4001)
    errors = {}
    for rtol in (1e-5, 1e-11):
        result = simulate(slider_crank, state, 20.0, formulation=Minimal(), method="DOP853",
                          rtol=rtol, atol=rtol, t_eval=t)
        work = non_conservative_work(slider_crank, result)
        errors[rtol] = np.max(np.abs(energy_balance_error(slider_crank, result, work)))
    assert errors[1e-11] < 3e-5                       # joules, against works of hundreds of joules
    assert np.max(np.abs(work.gas)) > 400.0 and np.max(np.abs(work.torque)) > 70.0
    assert errors[1e-5] > 3 * errors[1e-11]           # a loose integration shows in the balance


def test_one_turn_of_a_rotating_run_balances_torque_and_gas(slider_crank):
    """Case 4 rotates: over a crank turn from phi = 3 pi the torque and gas works are each ~260.4 J."""
    case = CASES[4]
    t = np.linspace(0.0, 20.0, 8001)
    result = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 20.0,
                      formulation=Baumgarte(5, 5), method="DOP853", rtol=1e-10, atol=1e-10, t_eval=t)
    work = non_conservative_work(slider_crank, result)
    phi = result.coordinate("phi")
    turn = [np.interp(angle, phi, work.torque) for angle in (3 * np.pi, 5 * np.pi)]
    gas = [np.interp(angle, phi, work.gas) for angle in (3 * np.pi, 5 * np.pi)]
    assert turn[1] - turn[0] == pytest.approx(torque_work_per_turn(), abs=2 * np.pi * 0.01)
    assert gas[1] - gas[0] == pytest.approx(gas_work_per_cycle(), abs=1e-4)


def test_crank_landscape_amplitude_tilt_and_gas_loss(slider_crank):
    p = slider_crank.parameters
    phi = np.linspace(np.pi, 3 * np.pi, 1441)
    land = crank_landscape(slider_crank, phi)
    amplitude = (p.m1 * p.a1 + p.m2 * p.l1 * (1 - p.a2 / p.l2)) * p.g        # Pi on the branch, closed form
    assert np.ptp(land.potential) / 2 == pytest.approx(amplitude, rel=1e-5)
    assert land.tilted[-1] - land.tilted[0] == pytest.approx(-2 * np.pi * 41.45, rel=1e-10)
    assert land.gas_loss[-1] == pytest.approx(-gas_work_per_cycle(), rel=1e-8)
    outward = (phi > np.pi + 1e-9) & (phi < 2 * np.pi - 1e-9)           # x_C grows from pi to 2 pi
    assert np.all(land.slope[outward] > 0) and np.all(land.slope[~outward] <= 1e-12)
