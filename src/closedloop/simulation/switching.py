"""The switching rule, written once over K states: :func:`closedloop.simulate`, its compiled-DOP853
runner and the batch integrator (:mod:`~closedloop.simulation.batch`) all decide with these functions.

A switched force (:class:`closedloop.forces.SwitchedForce`) has switching functions h_i(t, s, s').
Each integration segment runs on one branch (``mode``) of every switch, so its right-hand side is
smooth; where h_i crosses zero the segment stops, and the branch is chosen from the rate of h_i
along the constrained motion (12) on either branch, ``off`` (switch i off) and ``on``:

- both rates > 0: the state leaves onto the "on" side (crossed, or turned back if it was there);
- both rates < 0: it leaves onto the "off" side;
- ``off > 0 > on``: both branches push the state onto the surface (Filippov sliding).  For a
  velocity-level switch that may stick (the slider-crank's gas force acts only while x_C' > 0)
  the **sticking rule** holds the mechanism at rest; any other switch is refused;
- otherwise (grazing, or both branches repel) the state keeps its branch and turns back.

Sticking rule
-------------
For a one-degree-of-freedom mechanism x_C' = 0 means the whole mechanism is at rest.  It is held
with s fixed and s' = 0 while the force needed to hold it lies between the two branches, that is
while the **release margin** ``min(off, -on)`` of the rates at rest stays > 0.  Release is at the
first zero of the margin (:func:`locate_release`), onto the side that the "off" rate then points
to.  A stuck state costs no right-hand-side evaluations, so no integration chatters there.
At rest, the margin depends on time only through the system's explicit forcing (the drive
torque's ripple): where that forcing is periodic with period P (:func:`forcing_period`), a
state not released within one period is never released, so a long run costs no more than P.

Stalls
------
A stop at a switch that makes no progress in time (less than :data:`MIN_PROGRESS` relative to
max(1, |t|)) counts as a stall; more than :data:`MAX_STALLS` stalls in a row is chattering, and
the run stops with an :class:`~closedloop.errors.IntegrationError`.
"""

from __future__ import annotations

import itertools

import numpy as np

from ..codecache import cached_code
from ..errors import IntegrationError
from ..fixed_step import rk4_step

__all__ = ["RATE_STEP", "SURFACE", "MIN_PROGRESS", "MAX_STALLS", "RELEASE_XTOL", "switching_rate", "decide",
           "on_surface", "on_chosen_side", "CHOSEN_SIDE", "release_margin", "side_after_release", "locate_release", "no_progress",
           "refuse_sliding", "chattering_error", "forcing_period", "RATE_FLOOR", "PROBE_TIME", "uninformative",
           "probe", "probe_rates", "choose_side", "state_scale"]

#: Forward-difference step of the rates dh/dt along the motion [s].
RATE_STEP = 1e-7
#: |h| at or below SURFACE x (1 + max|state|) counts as "on the surface" at the start of a run.
SURFACE = 1e-12
#: A stop closer than MIN_PROGRESS x max(1, |t|) seconds to the previous one makes no progress.
MIN_PROGRESS = 1e-12
#: Stops without progress in a row after which a state chatters.
MAX_STALLS = 50
#: Accuracy of a located release time [s].
RELEASE_XTOL = 1e-12
#: Rates of a switching function at or below RATE_FLOOR x (1 + max|state|) on both branches say
#: nothing: the contact is degenerate (a start at rest at a dead centre, where x_C' = 0 and x_C'' = 0
#: whatever the branch), and the branch is chosen by probing (see :func:`probe` and :data:`PROBE_TIME`).
RATE_FLOOR = 1e-10
#: How long each branch's own motion is followed from a degenerate contact [s]; its switching
#: value then plays the part of the rate in decide().  At a dead centre at rest x_C' grows like
#: t^3, so after 1e-3 s it is about 1e-9 of the speed scale: far above round-off.
PROBE_TIME = 1e-3
#: Runge-Kutta (4th order) steps of a probe.
PROBE_STEPS = 8


def switching_rate(h, t, s, sd, sdd, h_now=None, s_ahead=None):
    """dh/dt along the motion: ``(h(t + e, s + e s', s' + e s'') - h(t, s, s')) / e``, e = RATE_STEP.

    Works for one state (s of shape (n,)) or K states (shape (n, K)) alike, as
    ``h`` does; ``h_now``, when given, is ``h(t, s, sd)``, and ``s_ahead``, when
    given, is ``s + e s'`` (the same for every branch's s'').
    """
    eps = RATE_STEP
    if h_now is None:
        h_now = h(t, s, sd)
    if s_ahead is None:
        s_ahead = s + eps * sd
    return (h(t + eps, s_ahead, sd + eps * sdd) - h_now) / eps


def decide(off, on, side):
    """The rule at states on a switching surface: ``(new side, sticks)``.

    Parameters
    ----------
    off, on : float or ndarray
        Rates of the switching function with the switch off and on.
    side : bool or ndarray of bool
        The branch the state is on.

    Returns
    -------
    new_side : bool or ndarray of bool
        True (on) where both rates are > 0, False where both are < 0, else ``side``.
    sticks : bool or ndarray of bool
        Where both branches push onto the surface (``off > 0 > on``); the caller
        applies the sticking rule there (``new_side`` is then ``side``).
    """
    if not any(isinstance(a, np.ndarray) for a in (off, on, side)):     # one state: no arrays (run.decide)
        sticks = bool(off > 0 and on < 0)
        if off > 0 and on > 0:
            return True, sticks
        if off < 0 and on < 0:
            return False, sticks
        return bool(side), sticks
    off, on = np.asarray(off), np.asarray(on)
    new_side = np.where((off > 0) & (on > 0), True, np.where((off < 0) & (on < 0), False, side))
    sticks = (off > 0) & (on < 0)
    if new_side.ndim == 0:
        return bool(new_side), bool(sticks)
    return new_side, sticks


def state_scale(s, sd):
    """``1 + max |s_k|, |s'_k|``: the size of a state, for the thresholds of the switching rule.

    One state (``s``, ``sd`` of shape (n,)) gives a float, NaN if the state holds one;
    K states (shape (n, K)) give an array of shape (K,).
    """
    if np.ndim(s) == 2:
        return 1.0 + np.abs(np.concatenate((s, sd))).max(axis=0)
    sizes = [abs(v) for v in s.tolist() + sd.tolist()]          # Python floats: a few entries, no numpy calls
    largest = max(sizes)
    return 1.0 + (np.nan if any(v != v for v in sizes) else largest)   # NaN as numpy's max gives it


def uninformative(off, on, scale):
    """Whether the rates on both branches vanish (to :data:`RATE_FLOOR` x ``scale``): probe instead.

    Floats give a bool; arrays (K states) an array of bool.
    """
    if any(isinstance(a, np.ndarray) for a in (off, on, scale)):
        return np.maximum(np.abs(off), np.abs(on)) <= RATE_FLOOR * scale
    return max(abs(float(off)), abs(float(on))) <= RATE_FLOOR * scale


def choose_side(off, on, side, scale, stalled, probed):
    """The branch of a switch at states on its surface, as :func:`decide` gives it: ``(new side, sticks)``.

    The rates ``off``, ``on`` decide, but where they vanish on both branches
    (:func:`uninformative`) or where the state stalled there (the segment the rates
    chose stopped at once), the probe's rates (:func:`probe_rates`) decide in their
    place.  :class:`~closedloop.simulation.run.Run` (one state) and the batch
    integrator (K states) both choose with this function.

    Parameters
    ----------
    off, on : float or ndarray, shape (K,)
        Rates of the switching function with the switch off and on.
    side : bool or ndarray of bool
        The branch each state is on.
    scale : float or ndarray
        :func:`state_scale` of each state.
    stalled : bool or ndarray of bool
    probed : callable
        ``probed(where) -> (off, on)``: the probe's rates at the states where the
        boolean ``where`` is True (one state: ``where`` is True).

    Returns
    -------
    new_side, sticks : bool or ndarray of bool
    """
    needs = stalled | uninformative(off, on, scale)
    if isinstance(needs, np.ndarray):
        if np.any(needs):
            off, on = np.array(off, dtype=float), np.array(on, dtype=float)
            off[needs], on[needs] = probed(needs)
    elif needs:
        off, on = probed(True)
    return decide(off, on, side)


def probe_rates(h, accelerations, t, s, sd, i):
    """The rates that stand in for ``(off, on)`` where the contact is degenerate: ``h_i`` after
    :data:`PROBE_TIME` of each branch's own motion (:func:`probe`), over :data:`PROBE_TIME`.

    Parameters
    ----------
    h : callable
        ``h(t, s, s')``, the switching values (shape (k,), or (k, K) for K states).
    accelerations : callable
        ``accelerations(side)`` gives the function ``s''(t, s, s')`` of (12) with switch i
        off (``side`` False) or on (True) and every other switch on its branch.
    t, s, sd : the states on the surface (one, or K as columns).
    i : int
        The switch.

    Returns
    -------
    off, on : float or ndarray
    """
    return tuple(probe(h, accelerations(side), t, s, sd)[i] / PROBE_TIME for side in (False, True))


def probe(h, accelerations, t, s, sd, duration=PROBE_TIME, steps=PROBE_STEPS):
    """The switching values ``h`` after following ``s'' = accelerations(t, s, s')`` for ``duration``.

    Classical Runge-Kutta with ``steps`` steps: where the first-order rates of a
    contact vanish on both branches, the sign of h after a short stretch of each
    branch's own motion says which way that motion leaves the surface, and
    ``h / duration`` takes the place of the rate in :func:`decide`.  One state
    (``s``, ``sd`` of shape (n,)) or K states (shape (n, K), ``t`` a float or (K,)).
    """
    step = duration / steps
    y = np.concatenate((s, sd))
    n = s.shape[0]

    def slope(time, state):
        return np.concatenate((state[n:], accelerations(time, state[:n], state[n:])))

    for k in range(steps):
        y = rk4_step(slope, t + k * step, y, step)
    return np.asarray(h(t + duration, y[:n], y[n:]))


#: What a switching value exactly zero at a segment's start counts as, on the side the rule chose for it
#: (see :func:`on_chosen_side`).
CHOSEN_SIDE = 1e-300


def on_chosen_side(value, side):
    """A switching value at the start of a segment, ``value``, with an exact zero moved onto the branch ``side``.

    A segment that starts on the surface h_i = 0 runs on the branch the rule chose
    there.  The event that watches h_i for the way back must not take the start
    itself for a crossing: with h_i(t0) = 0 a root finder bracketing a later crossing
    returns t0, where h_i is zero too, and every segment would stop where it began
    (a slider at rest just past a dead centre, which moves off the surface and comes
    back to it a moment later, stalled so).  An exact zero counts as
    :data:`CHOSEN_SIDE` on the chosen side: ``+`` on the "on" branch, ``-`` on the "off" one.
    The batch integrator locates its crossings from such a start the same way (arrays of
    values and sides).
    """
    if isinstance(value, np.ndarray):                  # K states, each on its own side
        return np.where(value == 0.0, np.where(side, CHOSEN_SIDE, -CHOSEN_SIDE), value)
    if value != 0.0:
        return value
    return CHOSEN_SIDE if side else -CHOSEN_SIDE


def on_surface(h, scale):
    """Where a switching value counts as zero at the start of a run (relative to ``scale``)."""
    return np.abs(h) <= SURFACE * scale


def release_margin(off, on):
    """``min(off, -on)``: > 0 while the holding force lies between the branches (held), else released."""
    return np.minimum(off, -on)


def side_after_release(off):
    """The branch a released state leaves on: "on" where the free motion rises onto it (off > 0)."""
    return off > 0


def locate_release(margin, t_held, t_free, margin_held, margin_free, xtol=RELEASE_XTOL):
    """The zero of the release margin between a held and a released time, for K states at once.

    Regula falsi with the Illinois modification on the bracket ``[t_held, t_free]``
    (margin > 0 at ``t_held``, <= 0 at ``t_free``), to ``xtol`` seconds.

    Parameters
    ----------
    margin : callable
        ``margin(t, index) -> ndarray``: the margins at times ``t`` (shape (k,)) of
        the states ``index`` (indices into the K states).
    t_held, t_free, margin_held, margin_free : ndarray, shape (K,)

    Returns
    -------
    ndarray, shape (K,)
    """
    lo, hi = np.array(t_held, dtype=float), np.array(t_free, dtype=float)
    m_lo, m_hi = np.array(margin_held, dtype=float), np.array(margin_free, dtype=float)
    side = np.zeros(lo.shape, dtype=int)            # the end kept twice in a row (Illinois)
    active = np.flatnonzero(hi - lo > xtol)
    for _ in range(100):
        if active.size == 0:
            break
        a, b, fa, fb = lo[active], hi[active], m_lo[active], m_hi[active]
        t = b - fb * (b - a) / (fb - fa)
        t = np.where((t > a) & (t < b), t, 0.5 * (a + b))
        m = margin(t, active)
        held = m > 0
        lo[active[held]], m_lo[active[held]] = t[held], m[held]
        hi[active[~held]], m_hi[active[~held]] = t[~held], m[~held]
        # Illinois: halve the value at the end that stayed, so that both ends move
        m_hi[active[held & (side[active] > 0)]] *= 0.5
        m_lo[active[~held & (side[active] < 0)]] *= 0.5
        side[active] = np.where(held, 1, -1)
        active = active[hi[active] - lo[active] > xtol]
    return hi


def no_progress(t_new, t_old):
    """Whether a stop at ``t_new`` made no progress since ``t_old`` (see Stalls)."""
    return t_new - t_old < MIN_PROGRESS * np.maximum(1.0, np.abs(t_old))


def refuse_sliding(t, name):
    """The error for a state that slides along a switch not declared able to stick."""
    return IntegrationError(
        f"at t = {float(np.max(t)):.6g} s the state slides along switch {name!r}, which is not declared "
        "able to stick; regularise the force or declare can_stick"
    )


def chattering_error(t, name, advice):
    """The error for a state that stalls on a switch more than MAX_STALLS times in a row."""
    return IntegrationError(
        f"the state chatters on switch {name!r} at t = {float(np.min(t)):.6g} s: more than {MAX_STALLS} stops in "
        f"a row without progress; {advice}"
    )


def forcing_period(system):
    """The period of the system's explicit dependence on time, for the sticking rule.

    Looks at the model's generalised forces and the switched force's expressions
    on every branch, with the parameter values in.  Returns 0.0 when none depends
    on time (an autonomous system), the period P > 0 when all are periodic in t
    with a common period, and None when that is not known (a force without a
    sympy form, or a forcing that is not periodic).  Computed once per system, with
    sympy; kept on disk (:mod:`closedloop.codecache`) under the model, the force's
    :meth:`~closedloop.forces.SwitchedForce.cache_key` and the parameter values,
    when the force has a key.
    """
    if "forcing_period" not in system.generated:
        force = system.force
        keys = () if force is None else tuple(
            force.cache_key(mode) for mode in itertools.product((False, True), repeat=len(force.switch_names)))
        if None not in keys:
            parts = (system.model_identity, f"force {keys!r}", f"values {system.parameter_values.tolist()!r}")
            period = cached_code("forcing_period", parts, lambda: {"period": _forcing_period(system)},
                                 ("period",))["period"]
        else:
            period = _forcing_period(system)
        system.generated["forcing_period"] = period
    return system.generated["forcing_period"]


def _forcing_period(system):
    import sympy as sp
    from sympy.calculus.util import periodicity

    model = system.model
    time = model.time
    values = dict(zip(model.parameters, system.parameter_values.tolist()))
    expressions = list(model.generalized_forces or ())
    force = system.force
    if force is not None:                  # a force without a sympy form gives None: its time is unknown
        for mode in itertools.product((False, True), repeat=len(force.switch_names)):
            branch = force.expressions(mode, time, list(model.coordinates), list(model.velocities))
            if branch is None:
                return None
            expressions += list(branch)
    timed = [e for e in (sp.sympify(e).xreplace(values) for e in expressions) if e.has(time)]
    if not timed:
        return 0.0
    periods = [periodicity(e, time) for e in timed]
    if any(p is None for p in periods):
        return None
    period = float(periods[0])
    if any(abs(float(p) - period) > 1e-12 * period for p in periods[1:]):
        return None                      # different periods: not worth a common multiple here
    return period
