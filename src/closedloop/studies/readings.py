"""The readings study: how each of the paper's four cases moves under each reading of its data.

The paper prints ``M = 41,450`` and the gas force with a Vietnamese decimal
comma, and its virtual work ``dA = M dq1 - F dq3`` leaves the sign of the gas
force loose; :data:`closedloop.slider_crank.READINGS` names the four readings.
This study simulates every case of section 4 under every reading (the table
in ``shared/paper/NOTES.md`` and chapter 6); the data it reads (Table 1, the
readings, the cases, the classifier) stay in :mod:`closedloop.slider_crank`.
"""

from __future__ import annotations

from dataclasses import dataclass

from ..formulations import Baumgarte
from ..simulation import simulate
from ..slider_crank import CASES, READINGS, classify_motion, get_case, initial_state, slider_crank_system

__all__ = ["ReadingOutcome", "reading_outcomes"]


@dataclass(frozen=True)
class ReadingOutcome:
    """How one case moves under one reading of the data (the table in NOTES.md)."""

    reading: str
    case: int
    motion: str
    stuck_at: float | None        # first time the slider sticks, if it does
    runaway_at: float | None      # time the crank speed passed the run-away limit, if it did
    final_speed: float            # phi' at the end of the run [rad/s]
    nfev: int


def reading_outcomes(t_end=20.0, formulation=None, method="LSODA", rtol=1e-8, atol=1e-8,
                     runaway_speed=100.0, readings=None, cases=None):
    """Simulate every case under every reading of the data.

    A run stops early once ``|phi'|`` exceeds ``runaway_speed`` (a crank
    spinning up without bound: at 100 rad/s the kinetic energy, 2.5e6 to
    3.7e6 J with the crank angle, is 3600 to 5400 times the 687 J swing of the
    potential energy over a turn), so the table stays quick to recompute.

    Parameters
    ----------
    t_end : float
    formulation, method, rtol, atol
        As for :func:`closedloop.simulate`; default Baumgarte(10, 10) with LSODA.
    runaway_speed : float
    readings, cases : iterables, optional
        Default: all of :data:`~closedloop.slider_crank.READINGS` and
        :data:`~closedloop.slider_crank.CASES`.

    Returns
    -------
    list of ReadingOutcome
    """
    formulation = Baumgarte(10.0, 10.0) if formulation is None else formulation
    rows = []
    for name in readings or READINGS:
        system = slider_crank_system(reading=name)
        for number in cases or CASES:
            case = get_case(number)
            result = simulate(system, initial_state(system, case.phi0, case.dphi0), t_end,
                              formulation=formulation, method=method, rtol=rtol, atol=atol,
                              stop_when=lambda t, s, sd: abs(sd[0]) - runaway_speed)
            stuck = result.sticking_intervals[0][0] if result.sticking_intervals else None
            rows.append(ReadingOutcome(name, number, classify_motion(result), stuck, result.stopped_at,
                                       float(result.sd[0, -1]), result.nfev))
    return rows
