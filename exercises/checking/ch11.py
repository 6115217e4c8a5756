"""Checks for exercises/11-energy.md."""

import math
from functools import lru_cache

import numpy as np

from closedloop import Baumgarte, simulate
from closedloop.studies.energy import crank_landscape, energy_balance_error, gas_outward_work, non_conservative_work
from closedloop.slider_crank import CASES, TORQUE_RIPPLE, initial_state, slider_crank_system

from . import Check, another_letter, choice, make_check, numeric

#: Exercise 11.4: where the printed gas law changes formula [m].
LAW_CHANGE = 5.0
#: Exercise 11.6: the tolerances tried, and the bound on the balance's residual [J].
TOLERANCES, RESIDUAL_BOUND = (1e-4, 1e-5, 1e-6, 1e-7, 1e-8), 1e-3


def _run(number, rtol=1e-10):
    """The chapter's runs: case `number` over 20 s, Baumgarte(5, 5), DOP853, 4001 output points."""
    system = slider_crank_system()
    case = CASES[number]
    return simulate(system, initial_state(system, case.phi0, case.dphi0), 20.0, formulation=Baumgarte(5, 5),
                    method="DOP853", rtol=rtol, atol=rtol, t_eval=np.linspace(0.0, 20.0, 4001))


def _work_to_law_change():
    """U(5) of (11.b): the gas work while the slider moves out from 1.5 m to 5 m."""
    return gas_outward_work(LAW_CHANGE)


def _gas_work_case_3():
    return non_conservative_work(slider_crank_system(), _run(3)).gas[-1]


def _loosest_tolerance():
    """The largest rtol = atol of TOLERANCES at which case 4 keeps max |eps| of (11.e) below the bound."""
    system = slider_crank_system()
    passing = [rtol for rtol in TOLERANCES
               if np.abs(energy_balance_error(system, _run(4, rtol))).max() < RESIDUAL_BOUND]
    return max(passing)


def _barrier_tops(system, phi_end):
    """The tops of V = Pi - M_bar phi in (pi, phi_end], from the landscape, refined on a fine grid."""
    tops = []
    for turn in range(1, int(phi_end // (2 * math.pi)) + 1):
        window = np.linspace(2 * math.pi * turn, 2 * math.pi * turn + math.pi / 2, 401)
        land = crank_landscape(system, window)
        top = land.phi[np.argmax(land.tilted)]
        if top <= phi_end:
            tops.append(top)
    return np.array(tops)


@lru_cache(maxsize=None)
def _kinetic_energy_at_tops():
    """T of case 4 at each barrier top it passes, from E = T + V (smooth there) minus V(top)."""
    system = slider_crank_system()
    result = _run(4)
    phi = result.coordinate("phi")
    kinetic, _ = system.kinetic_and_potential_energy(result.s, result.sd)
    return np.interp(_barrier_tops(system, phi.max()), phi, kinetic)


def _first_top_kinetic_energy():
    return _kinetic_energy_at_tops()[0]


def _later_margins():
    """'b' if T at later tops differs from the first by no more than the ripple's work per turn."""
    kinetic = _kinetic_energy_at_tops()
    change = kinetic[1:] - kinetic[0]
    if np.all(np.abs(change) <= 2 * math.pi * TORQUE_RIPPLE * np.arange(1, kinetic.size)):
        return "b"
    return "a" if change[-1] > 0 else "c"


def _power_of_ten_off(expected):
    return expected * 10.0


CHECKS = {
    "11.4": Check("11.4", _work_to_law_change, numeric(1e-6, 0.0),
                  "integrate F = -a/(6 - x_C) + b from the inner dead centre x_C = 1.5 m to 5 m; the "
                  "logarithm's argument is the ratio of the distances 6 - x_C at the two ends. The gas "
                  "takes energy out, so the work is negative.",
                  lambda expected: -expected),
    # 1e-7: the page's linear turning points are 3.8e-8 off; leaving the turning points out is 2.3e-7
    # off, and summing every interval that starts outward 2.1e-6
    "11.5": Check("11.5", _gas_work_case_3, numeric(1e-7, 0.0),
                  "add U(x_C(t_k+1)) - U(x_C(t_k)) only over intervals where the slider moves out; where "
                  "x_C' changes sign, stop or start at the turning point. Use the run of case 3 at "
                  "rtol = 1e-10 over 20 s.",
                  lambda expected: expected * 1.5),
    "11.6": Check("11.6", _loosest_tolerance, numeric(1e-6, 0.0),
                  "run case 4 at each tolerance of the list with Baumgarte(5, 5), DOP853 and 4001 output "
                  "points, take max |energy_balance_error| of each, and give the largest rtol whose "
                  "residual stays below 1e-3 J.",
                  _power_of_ten_off),
    "11.7": Check("11.7", _first_top_kinetic_energy, numeric(1e-4, 0.0),
                  "the first top of V after phi0 = pi lies just before 5 pi/2, where V' = Pi' - M_bar = 0; "
                  "interpolate T of the run (system.kinetic_and_potential_energy) there, against phi.",
                  lambda expected: expected * 1.1),
    "11.8": Check("11.8", _later_margins, choice,
                  "compare T at the second and third tops with T at the first, and compare the changes "
                  "with the ripple's work per turn.",
                  another_letter()),
}

check = make_check(CHECKS)
