"""What a batch of the batch integrator may ask for: its step, its length, its work.

Each check refuses, before any integration, a request the fixed-step scheme of
:mod:`~closedloop.simulation.batch` cannot answer well or in reasonable time, naming the
parameter and the value that would pass.
"""

from __future__ import annotations

import math

import numpy as np

from ..errors import InputError
from ..validation import positive_number
from . import switching as rule

__all__ = ["DEFAULT_STEP", "MAX_ANGLE_PER_STEP", "MAX_CELL_STEPS", "MAX_STEPS", "check_span", "check_work",
           "check_step", "step_bound"]

#: Step of the fixed-step scheme [s]; its choice is measured in the book's basin chapter.
DEFAULT_STEP = 0.02
#: The largest angle the fastest rate of a batch may turn in one step [rad] (see :func:`check_step`):
#: the book's convergence study (chapter 12) starts at 0.08 s, 0.5 rad of the slider-crank's forcing.
MAX_ANGLE_PER_STEP = 0.6
#: The most cell-steps (cells x t_end / step) a batch may ask for, over all its parts: 1e9 would take hours.
MAX_CELL_STEPS = 1e9
#: Most steps of one batch (t_end / step); a step of a batch costs about a millisecond.
MAX_STEPS = 100_000


def _shown(value, up):
    """``value`` in 3 significant digits, rounded up (a lower bound) or down (an upper bound), so that the number
    a message advises passes the check that it advises for."""
    text = float(f"{value:.3g}")
    if (text < value) if up else (text > value):
        unit = 10.0 ** (math.floor(math.log10(abs(value))) - 2)
        text = float(f"{text + unit if up else text - unit:.3g}")
    return f"{text:g}"


def check_span(t_end, step, longest=math.inf):
    """Refuse a t_end and step whose run needs more than :data:`MAX_STEPS` steps, or a step beyond t_end.

    Parameters
    ----------
    t_end, step : float
        The run's length and step [s].
    longest : float, optional
        The longest step that resolves the batch (:func:`step_bound`): where even it
        needs more than MAX_STEPS steps, only a shorter t_end helps, and the message says so.

    Raises
    ------
    InputError
    """
    t_end = positive_number("t_end", t_end, unit="s")
    step = positive_number("step", step, unit="s")
    if step > t_end:
        raise InputError(f"step: must be <= t_end = {t_end:g} s, got {step:g} s")
    if t_end / step > MAX_STEPS:
        if t_end / MAX_STEPS > longest:
            raise InputError(f"t_end: {t_end:g} s would take more than {MAX_STEPS:g} steps (about 1 ms each), even of "
                             f"the longest step that resolves this map, {_shown(longest, up=False)} s; give a t_end "
                             f"<= {_shown(MAX_STEPS * step * (1 - 1e-9), up=False)} s (with this step of {step:g} s), "
                             f"or <= {_shown(MAX_STEPS * float(_shown(longest, up=False)) * (1 - 1e-9), up=False)} s "
                             f"with a step of {_shown(longest, up=False)} s")
        raise InputError(f"step: t_end/step would be {t_end / step:.3g} steps, more than {MAX_STEPS:g} (about 1 ms "
                         f"each); give a step >= {_shown(t_end / MAX_STEPS, up=True)} s or a shorter t_end, got "
                         f"{step:g} s")


def check_work(cells, t_end, step):
    """Refuse a batch of more than :data:`MAX_CELL_STEPS` cell-steps (all its cells, however it is split).

    Raises
    ------
    InputError
    """
    work = cells * t_end / step
    if work > MAX_CELL_STEPS:
        raise InputError(f"t_end: {cells} cells x t_end / step = {work:.3g} cell-steps, more than the "
                         f"{MAX_CELL_STEPS:.0e} a map may take (hours of CPU); use fewer cells, a shorter "
                         "t_end or a larger step")


def check_step(system, step, rates):
    """Refuse a step too coarse for the motion: the fastest rate of the batch times the step.

    The rates are the cells' starting speeds |q0'| and the forcing's 2 pi / P (P its period,
    read off the model by :func:`~closedloop.simulation.switching.forcing_period`; none for an
    autonomous system, and 2 pi rad/s when the period is unknown).  Their largest, times the
    step, must stay below :data:`MAX_ANGLE_PER_STEP`.

    Raises
    ------
    InputError
    """
    fastest, source, _ = step_bound(system, rates)
    if fastest * step > MAX_ANGLE_PER_STEP:
        raise InputError(
            f"step: {step:g} s can not resolve this map: its fastest rate is {fastest:.3g} rad/s ({source}), "
            f"so the step must be <= {MAX_ANGLE_PER_STEP / fastest:.3g} s (at most {MAX_ANGLE_PER_STEP:g} rad "
            "per step)")


def step_bound(system, rates):
    """``(fastest rate, which one it is, the longest step that resolves it)`` of a batch (see :func:`check_step`)."""
    period = rule.forcing_period(system)
    forcing = 0.0 if period == 0.0 else 2.0 * math.pi / (period if period else 1.0)
    fastest = max(float(np.max(np.abs(rates), initial=0.0)), forcing)
    source = "the forcing's 2 pi / period" if forcing >= fastest else "the largest starting speed |dphi0|"
    return fastest, source, (MAX_ANGLE_PER_STEP / fastest if fastest > 0 else math.inf)
