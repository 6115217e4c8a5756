"""Energy and work: T + Pi conserved without applied forces, and balanced against their work with them.

The works of the drive torque and the gas force per turn and per stroke (closedloop.studies.energy,
closedloop.slider_crank_gas_law), checked against sympy and quadrature; the balance (T + Pi)(t) - (T + Pi)(0) = W
along runs, with the works of closedloop.studies.energy, with the work integrated with the run
(simulate(work=True), closedloop.balance), and with a quadrature of the power written out here.
"""

import math

import numpy as np
import pytest
import sympy as sp
from scipy.integrate import quad

import closedloop.slider_crank_gas_law as gas_law
from closedloop import (Augmented, Baumgarte, InputError, Minimal, Orthogonal, consistent_initial_state,
                        simulate)
from closedloop.balance import energy_balance
from closedloop.slider_crank import (CASES, DEFAULT_READING, OMEGA, Reading, SliderCrankParameters,
                                     SliderCrankSystem, drive_torque, gas_force, get_reading, initial_state,
                                     slider_crank_system)
from closedloop.studies.energy import (crank_landscape, energy_balance_error, gas_outward_work, gas_work_per_cycle,
                                       non_conservative_work, torque_work_per_turn)

from .conftest import SWINGING

FORMULATIONS = [Augmented(), Baumgarte(5, 5), Orthogonal(5, 5), Minimal()]


# -- conservation without applied forces ---------------------------------------------------------
@pytest.mark.parametrize("formulation", FORMULATIONS, ids=lambda f: f.name)
@pytest.mark.parametrize("number", [1, 2])
def test_energy_is_conserved_without_torque_and_gas_force(conservative_slider_crank, formulation, number):
    system = conservative_slider_crank
    case = CASES[number]
    state = initial_state(system, case.phi0, case.dphi0)
    result = simulate(system, state, 20.0, formulation=formulation, method="DOP853", rtol=1e-11, atol=1e-11)
    energy = system.energy(result.s, result.sd)
    initial = system.energy(state.s, state.sd)
    assert abs(initial) > 100.0                      # a relative test needs a non-trivial energy
    assert np.max(np.abs(energy - initial)) / abs(initial) < 1e-8
    assert np.ptp(result.coordinate("phi")) > 1.0    # the mechanism really moved


@pytest.mark.parametrize("formulation", FORMULATIONS, ids=lambda f: f.name)
def test_a_new_mechanism_four_bar_linkage_conserves_energy_and_stays_closed(four_bar, formulation):
    """Grashof crank-rocker (l1 + l0 < l2 + l3): the crank turns fully; T + Pi constant, loop closed."""
    state = consistent_initial_state(four_bar, [0.5], [6.0], [1.0, 1.8])
    result = simulate(four_bar, state, 10.0, formulation=formulation, method="DOP853", rtol=1e-11, atol=1e-11)
    energy = four_bar.energy(result.s, result.sd)
    initial = four_bar.energy(state.s, state.sd)
    assert np.max(np.abs(energy - initial)) / abs(initial) < 1e-8
    assert result.max_constraint_error < 1e-7
    assert np.ptp(result.coordinate("theta1")) > 2 * np.pi      # the crank turned a full revolution


@pytest.mark.parametrize("formulation", [Minimal(), Baumgarte(5, 5)], ids=lambda f: f.name)
def test_unforced_four_bar_conserves_energy_on_a_swing(parallelogram, formulation):
    """The parallelogram below its change points: the minimal and the stabilised redundant runs both keep T + Pi."""
    start = consistent_initial_state(parallelogram, [SWINGING[0]], [SWINGING[1]], [0.0, SWINGING[0]])
    result = simulate(parallelogram, start, 5.0, formulation=formulation, method="DOP853", rtol=1e-11,
                      atol=1e-11, t_eval=np.linspace(0.0, 5.0, 501))
    energy = parallelogram.energy(result.s, result.sd)
    initial = parallelogram.energy(start.s, start.sd)
    assert abs(initial) > 10.0
    assert np.max(np.abs(energy - initial)) / abs(initial) < 1e-9


def test_conservative_system_does_no_work(conservative_slider_crank):
    state = initial_state(conservative_slider_crank, 1.0, 2.0)
    result = simulate(conservative_slider_crank, state, 5.0, method="DOP853", rtol=1e-11, atol=1e-11, work=True)
    assert np.all(result.work == 0.0)
    assert energy_balance(conservative_slider_crank, result).max_residual < 1e-7


# -- the works per turn and per stroke -----------------------------------------------------------
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


def test_torque_work_per_turn_balances_gas_work_per_stroke():
    """41.45 * 2 pi = 260.4 J per revolution against 260.4 J per outward stroke (Haug's data),
    by quadrature of the laws themselves."""
    stroke = quad(lambda x: -gas_force(x, 1.0), 1.5, 5.5, points=[5.0], epsabs=1e-12)[0]
    turn = quad(lambda t: drive_torque(t), 0.0, 1.0)[0] * 2 * math.pi   # mean torque (ripple integrates out)
    assert stroke == pytest.approx(260.44, abs=0.01)
    assert turn == pytest.approx(260.44, abs=0.01)


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


def test_the_outward_work_is_the_integral_of_the_law():
    inner_work, outer_work = gas_law.outward_work_functions()
    coefficients = gas_law.PRINTED_COEFFICIENTS
    # a ln((6 - x)/4.5) + b (x - 1.5) at x = 5: 282.857 ln(1/4.5) + 62.857 * 3.5
    assert inner_work(5.0, *coefficients) == pytest.approx(282.857 * math.log(1 / 4.5) + 62.857 * 3.5, rel=1e-14)
    # -110 (x - 5) - 110 [cos 2 pi (x - 5.25) - cos(-pi/2)]/(2 pi) at x = 5.5: -55 - 110 cos(pi/2)/(2 pi) = -55
    assert outer_work(5.5, *coefficients) == pytest.approx(-55.0, rel=1e-12)
    # a whole outward stroke in the paper's reading (force_sign = +1): about -260.44 J
    whole_stroke = 282.857 * math.log(1 / 4.5) + 62.857 * 3.5 - 55.0
    assert gas_outward_work(5.5) - gas_outward_work(1.5) == pytest.approx(whole_stroke, rel=1e-13)
    assert whole_stroke == pytest.approx(-260.4393, abs=1e-4)


class ConstantGas(Reading):
    """A reading whose gas law is F = +1 N on x_C in [1.5, 5] (coefficients a, b, c = 0, 1, 0)."""

    @property
    def gas_coefficients(self):
        return (0.0, 1.0, 0.0)


class Samples:
    """Samples of the motion x_C = 3.5 + sin t, crank at rest, as non_conservative_work reads a run."""

    def __init__(self, t):
        self.t = t

    def coordinate(self, name):
        return 3.5 + np.sin(self.t) if name == "x" else np.zeros_like(self.t)

    def velocity(self, name):
        return np.cos(self.t) if name == "x" else np.zeros_like(self.t)


def test_one_sided_work_through_turning_points_between_samples():
    """x = 3.5 + sin u, work function w(x) = x - 1.5: the outward pieces add up to exactly 2 per period."""
    system = slider_crank_system(reading=ConstantGas("constant", 1.0, +1, "F = 1 N"), torque=False)
    assert gas_outward_work([2.5, 4.5], system.reading) == pytest.approx([1.0, 3.0], rel=1e-14)
    u = np.linspace(0.0, 2 * np.pi, 23)               # no sample at the turning points pi/2, 3pi/2
    work = non_conservative_work(system, Samples(u))
    increments = np.diff(work.gas)
    assert increments.sum() == pytest.approx(2.0, abs=2e-3)
    assert np.all(increments >= 0)


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


# -- the balance along runs ----------------------------------------------------------------------
def studies_balance_error(system, result):
    """max |(T + Pi)(t) - (T + Pi)(0) - W_M - W_F| with the works of closedloop.studies.energy, and the works."""
    work = non_conservative_work(system, result)
    return np.max(np.abs(energy_balance_error(system, result, work))), work


def test_case_2_balances_its_energy_against_the_work_of_torque_and_gas(slider_crank):
    """Case 2 over 20 s, DOP853: (T + Pi)(t) - (T + Pi)(0) = W_M + W_F, three ways.

    With the exact works of closedloop.studies.energy the residual follows the integrator's
    tolerance; with the work integrated with the run (closedloop.balance) it is small for minimal
    coordinates and for Baumgarte; with a trapezoidal quadrature of the power M phi' + F x_C' of
    the printed laws it is small against works of hundreds of joules.
    """
    state = initial_state(slider_crank, CASES[2].phi0, CASES[2].dphi0)
    t = np.linspace(0.0, 20.0, 40001)
    tight = simulate(slider_crank, state, 20.0, formulation=Minimal(), method="DOP853", rtol=1e-11, atol=1e-11,
                     t_eval=t, work=True)
    # 1. the works of closedloop.studies.energy
    tight_error, work = studies_balance_error(slider_crank, tight)
    assert tight_error < 3e-5                          # joules, against works of hundreds of joules
    assert np.max(np.abs(work.gas)) > 400.0 and np.max(np.abs(work.torque)) > 70.0
    loose = simulate(slider_crank, state, 20.0, formulation=Minimal(), method="DOP853", rtol=1e-5, atol=1e-5,
                     t_eval=np.linspace(0.0, 20.0, 4001))
    assert studies_balance_error(slider_crank, loose)[0] > 3 * tight_error   # a loose integration shows
    # 2. the work integrated with the run
    baumgarte = simulate(slider_crank, state, 20.0, formulation=Baumgarte(5, 5), method="DOP853", rtol=1e-11,
                         atol=1e-11, work=True)
    for result in (tight, baumgarte):
        balance = energy_balance(slider_crank, result)
        assert np.max(np.abs(balance.work)) > 100.0           # the gas force removed real energy
        assert balance.max_residual < 1e-6
        assert len(result.switch_events) > 5                  # ... across many switches
    # 3. a trapezoidal quadrature of the power, independent of the library's works
    phi_dot, x, x_dot = tight.velocity("phi"), tight.coordinate("x"), tight.velocity("x")
    power = drive_torque(t) * phi_dot + (+1) * gas_force(x, x_dot) * x_dot   # paper's reading: +F
    quadrature = np.concatenate(([0.0], np.cumsum(0.5 * (power[1:] + power[:-1]) * np.diff(t))))
    energy = slider_crank.energy(tight.s, tight.sd)
    # trapezoidal quadrature of a power with kinks at the switches: 1e-3 J out of ~1000 J of work
    assert np.max(np.abs(energy - energy[0] - quadrature)) < 2e-3
    assert np.max(np.abs(quadrature)) > 100.0


def test_case_1_energy_balance_follows_the_integrator_tolerance(slider_crank):
    """(T + Pi)(t) - (T + Pi)(0) = W_M + W_F along case 1: the residual follows the integrator's tolerance."""
    state = initial_state(slider_crank, CASES[1].phi0, CASES[1].dphi0)
    t = np.linspace(0.0, 20.0, 4001)
    errors = {}
    for rtol in (1e-5, 1e-11):
        result = simulate(slider_crank, state, 20.0, formulation=Minimal(), method="DOP853",
                          rtol=rtol, atol=rtol, t_eval=t)
        errors[rtol], work = studies_balance_error(slider_crank, result)
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


def test_work_of_a_constant_torque_is_torque_times_angle():
    """Ripple off, gas force off: W(t) = M (phi(t) - phi(0)) exactly."""
    parameters = SliderCrankParameters()
    values = parameters.as_dict()
    values.update(torque_mean=41.45, torque_ripple=0.0, omega=OMEGA)
    system = SliderCrankSystem(parameters, get_reading(DEFAULT_READING), values, None)
    state = initial_state(system, CASES[2].phi0, CASES[2].dphi0)
    result = simulate(system, state, 10.0, formulation=Baumgarte(), method="DOP853", rtol=1e-10, atol=1e-10,
                      t_eval=np.linspace(0, 10, 101), work=True)
    angle = result.coordinate("phi") - state.s[0]
    assert np.max(np.abs(angle)) > 2 * math.pi
    assert np.max(np.abs(result.work - 41.45 * angle)) < 1e-7


def test_work_is_constant_while_stuck(slider_crank):
    state = initial_state(slider_crank, CASES[3].phi0, CASES[3].dphi0)
    result = simulate(slider_crank, state, 32.0, method="DOP853", rtol=1e-10, atol=1e-10, work=True)
    start, end = result.sticking_intervals[0]
    held = (result.t >= start) & (result.t <= end)
    assert held.sum() >= 2 and np.ptp(result.work[held]) == 0.0
    assert energy_balance(slider_crank, result).max_residual < 1e-6


def test_energy_balance_needs_the_work(slider_crank):
    result = simulate(slider_crank, initial_state(slider_crank, 1.0, 1.0), 0.1)
    with pytest.raises(InputError, match="work=True"):
        energy_balance(slider_crank, result)


def test_a_gas_cycle_needs_a_crank_that_turns_fully():
    """With l1 >= l2 the slider never runs from l2 - l1 to l2 + l1 (on the branch near phi = 0 with
    l1 = 3.5, l2 = 2 it stays within [2.9, 5.5] m); the work of such a "cycle" was returned as -260.4 J."""
    rocking = SliderCrankParameters(l1=3.5, l2=2.0, full_rotation=False)
    with pytest.raises(InputError,
                       match=r"^parameters: a slider cycle .* \(full_rotation=True, l1 < l2\); got l1 = 3.5 m, l2 = 2 m"):
        gas_work_per_cycle(rocking)
    assert gas_work_per_cycle(SliderCrankParameters(l1=1.0, l2=4.0)) < 0.0     # a full turn, a shorter stroke
