"""Long runs of the slider-crank (chapter 9, study 3): drift and the energy balance (9.d) over 1000 s.

Case 2 keeps turning, so it is run for 1000 s with each formulation, with
``simulate(..., work=True)`` and :func:`closedloop.balance.energy_balance`:

    T(t) + Pi(t) - T(0) - Pi(0) = W(t) = integral_0^t tau . s' dt        (9.d)

and its crank angle is compared with a tighter minimal-coordinate run.  The five
runs take about a minute, too long for a page, so ``closedloop long-runs --json
FILE`` runs them once and writes what chapter 9 shows, with the provenance that
:func:`load_long_runs` and ``tests/test_long_runs_data.py`` check against the
library imported now (as chapter 8 does with ``book/data/benchmark.json``).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass

import numpy as np

from ..balance import energy_balance
from ..errors import InputError
from ..formulations import Augmented, Baumgarte, Minimal, Orthogonal
from ..simulation import simulate
from ..slider_crank import CASES, initial_state, slider_crank_system
from .provenance import provenance, read_with_provenance

__all__ = ["LongRunSettings", "DEFAULT_LONG_RUN_SETTINGS", "long_run_formulations", "run_long_runs",
           "load_long_runs"]


@dataclass(frozen=True)
class LongRunSettings:
    """What the long-run study runs.

    Attributes
    ----------
    case : int
        The paper's case (``CASES``) that gives the start.
    t_end : float
        Length of each run [s].
    samples : int
        Points of the output grid from 0 to ``t_end``.
    method : str
        Integration method of every run.
    rtol : float
        ``rtol = atol`` of the runs compared.
    reference_rtol : float
        ``rtol = atol`` of the minimal-coordinate run that the crank angles are compared with.
    phase_check_time : float
        The phase error is also reported over ``[0, phase_check_time]`` [s].
    """

    case: int = 2
    t_end: float = 1000.0
    samples: int = 2001
    method: str = "DOP853"
    rtol: float = 1e-8
    reference_rtol: float = 1e-11
    phase_check_time: float = 100.0

    def as_dict(self):
        """The settings as a JSON-ready dict."""
        return asdict(self)


#: The study that chapter 9 shows.
DEFAULT_LONG_RUN_SETTINGS = LongRunSettings()


def long_run_formulations():
    """The formulations compared, in the chapter's order: augmented, Baumgarte(5, 5), orthogonal(5, 5), minimal."""
    return (Augmented(), Baumgarte(5, 5), Orthogonal(5, 5), Minimal())


def _floats(values, digits=None):
    """Plain floats for JSON; ``digits`` significant digits (traces that are only drawn), or all."""
    values = np.asarray(values, dtype=float)
    if digits is None:
        return [float(v) for v in values]
    return [float(f"{v:.{digits}g}") for v in values]


#: Significant digits kept of the traces, which the chapter only draws (on log scales).
TRACE_DIGITS = 6


def run_long_runs(settings=DEFAULT_LONG_RUN_SETTINGS, progress=None):
    """Run the long-run study; a JSON-ready dict.

    Parameters
    ----------
    settings : LongRunSettings
    progress : callable or None
        Called with one line of text after each run.

    Returns
    -------
    dict
        The provenance (``closedloop_version``, ``source_fingerprint``,
        ``settings``, ``machine``), ``wall_s``, the grid ``t`` [s], the
        reference run's ``reference_n_steps``, and ``runs``: for each
        formulation name, the scalars of chapter 9's table
        (``max_constraint_error`` and ``final_constraint_error`` [m] of (32),
        ``max_balance_residual`` and ``work`` at ``t_end`` [J] of (9.d),
        ``n_steps``, ``cpu_s``, ``max_phase_error`` and ``early_phase_error``
        [rad], against the reference over the run and up to ``phase_check_time``)
        and two traces on the grid, to :data:`TRACE_DIGITS` significant digits:
        ``constraint_error`` |f| [m] and ``balance_residual`` Delta(T + Pi) - W [J].
    """
    if not isinstance(settings, LongRunSettings):
        raise InputError(f"settings: expected a LongRunSettings, got {type(settings).__name__}")
    wall = time.perf_counter()
    system = slider_crank_system()
    case = CASES[settings.case]
    state = initial_state(system, case.phi0, case.dphi0)
    grid = np.linspace(0.0, settings.t_end, settings.samples)
    common = dict(method=settings.method, t_eval=grid)
    reference = simulate(system, state, settings.t_end, formulation=Minimal(), rtol=settings.reference_rtol,
                         atol=settings.reference_rtol, **common)
    if progress is not None:
        progress(f"reference (minimal, rtol {settings.reference_rtol:.0e}): {reference.n_steps} steps")
    early = grid <= settings.phase_check_time
    runs = {}
    for formulation in long_run_formulations():
        result = simulate(system, state, settings.t_end, formulation=formulation, rtol=settings.rtol,
                          atol=settings.rtol, work=True, **common)
        balance = energy_balance(system, result)
        phase = np.abs(result.coordinate("phi") - reference.coordinate("phi"))
        runs[formulation.name] = {
            "max_constraint_error": float(result.max_constraint_error),
            "final_constraint_error": float(result.constraint_error[-1]),
            "max_balance_residual": balance.max_residual,
            "work": float(balance.work[-1]),
            "n_steps": int(result.n_steps),
            "cpu_s": float(result.cpu_time),
            "max_phase_error": float(phase.max()),
            "early_phase_error": float(phase[early].max()),
            "constraint_error": _floats(result.constraint_error, TRACE_DIGITS),
            "balance_residual": _floats(balance.residual, TRACE_DIGITS),
        }
        if progress is not None:
            progress(f"{formulation.name}: {result.n_steps} steps, {result.cpu_time:.1f} s CPU")
    data = provenance(settings)
    data.update(t=_floats(grid), reference_n_steps=int(reference.n_steps), runs=runs,
                wall_s=time.perf_counter() - wall)
    return data


def load_long_runs(path):
    """A study written by ``closedloop long-runs --json FILE``, checked for its parts.

    Returns the dict of :func:`run_long_runs` with its traces as arrays, and one
    more key, ``"current"``: True when its ``source_fingerprint`` is that of the
    library now imported.
    """
    data = read_with_provenance(path, ("t", "runs"), "long runs", "long-runs")
    data["t"] = np.asarray(data["t"])
    for run in data["runs"].values():
        for key in ("constraint_error", "balance_residual"):
            run[key] = np.asarray(run[key])
    return data
