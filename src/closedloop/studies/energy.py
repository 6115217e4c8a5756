"""Energy bookkeeping of the slider-crank: the works of the drive torque and of the gas force.

Multiplying (22) by s'^T removes the constraint forces (Phi_s s' = 0, (9)) and leaves
the power balance ``d(T + Pi)/dt = M(t) phi' + Q_x x_C'``, where ``Q_x = force_sign F``
is the gas force's generalised force on x_C (see :class:`~closedloop.slider_crank.GasForce`).
Integrated along a run::

    (T + Pi)(t) - (T + Pi)(0) = W_M(t) + W_F(t)

The gas force is not a potential force: it acts only while x_C' > 0.  On that
outward branch it depends on x_C alone, so it has a work function there,
:func:`gas_outward_work`, and ``W_F`` is a sum of its increments over the outward
pieces of the motion.  No quadrature of a kinked power is needed.  Where the slider
turns back only at the dead centres, where F = 0, the balance checks a simulation to
the tolerance of its integrator; a turn in mid-stroke, where F is not zero, adds the
error of its interpolated turning point, which falls with the square of the output
step (chapter 11).  (For any system, the work
can instead be integrated with the run: ``simulate(..., work=True)`` and
:func:`closedloop.balance.energy_balance`.  That check shares the run's
integration error; this one does not.)

The torque ``M(t) = M_bar + 0.01 sin(Omega t)`` depends on time only through its
ripple; ``W_M = M_bar (phi - phi_0) + W_ripple``, and ``|W_ripple|`` is at most
0.01 N m times the angle the crank has travelled.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from .. import hermite
from .. import slider_crank_gas_law as gas_law
from ..errors import InputError
from ..slider_crank import (DEFAULT_READING, OMEGA, SliderCrankParameters, SliderCrankSystem, drive_torque,
                           gas_force, get_reading, initial_state)
from ..validation import instance_of

__all__ = [
    "torque_work_per_turn",
    "gas_work_per_cycle",
    "gas_outward_work",
    "WorkHistory",
    "non_conservative_work",
    "energy_balance_error",
    "Landscape",
    "crank_landscape",
    "GAS_STROKE",
]

#: Where the printed gas law holds: the inner and outer dead centres of Table 1's slider [m].
GAS_STROKE = gas_law.STROKE


def torque_work_per_turn(reading=DEFAULT_READING):
    """Work of the drive torque per crank turn, ``2 pi`` times its mean over a ripple period [J].

    ``M(t) = M_bar + 0.01 sin(Omega t)`` depends on time, not on phi, so the
    work of one turn ``int M dphi`` depends on how the turn is timed.  Its mean
    part is ``2 pi M_bar``; the ripple adds at most ``2 pi 0.01`` J (its sign
    depends on the phase).  The mean is computed by quadrature of
    :func:`~closedloop.slider_crank.drive_torque` over one period ``2 pi/Omega``.

    Parameters
    ----------
    reading : str or Reading, optional
        How the printed numbers are read; default the paper's reproducing reading.

    Returns
    -------
    float
        About 260.4 J in the decimal readings.
    """
    from scipy.integrate import quad      # here only, as every scipy subpackage (tests/test_architecture.py)

    reading = get_reading(reading)
    period = 2.0 * math.pi / OMEGA
    mean = quad(lambda t: drive_torque(t, reading), 0.0, period)[0] / period
    return 2.0 * math.pi * mean


def gas_work_per_cycle(parameters=None, reading=DEFAULT_READING):
    """Work the gas force does on the mechanism over one slider cycle, ``oint Q_x dx_C`` [J].

    A cycle is an outward stroke from ``x_C = l2 - l1`` to ``l2 + l1`` (expansion:
    ``x_C' > 0``, the printed law F(x_C) acts) and an inward stroke back
    (compression: ``x_C' <= 0``, F = 0).  Only the outward branch contributes::

        oint Q_x dx_C = force_sign * int_{l2-l1}^{l2+l1} F(x, x' > 0) dx

    computed by quadrature (``scipy.integrate.quad``, split at x_C = 5 where the
    formula changes).  The law is zero outside [1.5, 5.5] m.

    Parameters
    ----------
    parameters : SliderCrankParameters, optional
        Fix the stroke; default Table 1 (exactly the law's range [1.5, 5.5] m).
        The crank must turn fully (``full_rotation``, l1 < l2), or the slider has no such cycle.
    reading : str or Reading, optional

    Returns
    -------
    float
        About -260.4 J in the paper's reading: the gas takes energy out.

    Raises
    ------
    InputError
        For parameters of a rocking crank (``full_rotation=False``).
    """
    from scipy.integrate import quad

    parameters = instance_of("parameters", SliderCrankParameters() if parameters is None else parameters,
                             SliderCrankParameters)
    if not parameters.full_rotation:                # l1 < l2 exactly when the crank turns fully
        raise InputError(f"parameters: a slider cycle from l2 - l1 to l2 + l1 needs a crank that turns fully "
                         f"(full_rotation=True, l1 < l2); got l1 = {parameters.l1:g} m, l2 = {parameters.l2:g} m")
    reading = get_reading(reading)
    inner, outer = parameters.l2 - parameters.l1, parameters.l2 + parameters.l1
    low, high = max(inner, GAS_STROKE[0]), min(outer, GAS_STROKE[1])
    if low >= high:
        return 0.0
    breaks = [gas_law.CHANGE_POINT] if low < gas_law.CHANGE_POINT < high else None
    work = quad(lambda x: gas_force(x, 1.0, reading), low, high, points=breaks)[0]
    return reading.force_sign * work


def gas_outward_work(x, reading=DEFAULT_READING):
    """Work of the gas force on the outward branch from x_C = 1.5 m to ``x`` [J], in closed form.

    With ``a, b, c`` = 282.857, 62.857, 110 (scaled by the reading)::

        for 1.5 <= x <= 5:
            U(x) = a ln((6 - x)/4.5) + b (x - 1.5)
        for 5 <= x <= 5.5:
            U(x) = U(5) - c (x - 5)
                   - c [cos(2 pi (x - 5.25)) - cos(-pi/2)] / (2 pi)

    times the reading's ``force_sign``; constant outside [1.5, 5.5], where F = 0.
    Both pieces are the integrals of the law of :mod:`closedloop.slider_crank_gas_law`,
    computed by sympy (:func:`closedloop.slider_crank_gas_law.outward_work_functions`).
    The work the gas does while the slider moves out from x_a to x_b is
    ``U(x_b) - U(x_a)``; moving in, it does none.

    Parameters
    ----------
    x : float or ndarray
    reading : str or Reading, optional
    """
    reading = get_reading(reading)
    inner_work, outer_work = gas_law.outward_work_functions()
    x = np.clip(np.asarray(x, dtype=float), *GAS_STROKE)
    change = gas_law.CHANGE_POINT
    value = (inner_work(np.minimum(x, change), *reading.gas_coefficients)
             + outer_work(np.maximum(x, change), *reading.gas_coefficients))
    value = reading.force_sign * value
    return value if value.ndim else float(value)


def _outward_increments(x, rate, step, work_function):
    """Work increments of a one-sided force between samples of a motion.

    ``x`` and its rate ``rate = dx/du`` are sampled at parameter values u with
    spacings ``step``.  Where the rate keeps its sign, the increment is the
    work function's change (rate > 0) or zero.  Where it changes sign, the
    turning point x* comes from the cubic Hermite interpolant through both
    samples and their rates.
    """
    x0, x1, v0, v1 = x[:-1], x[1:], rate[:-1] * step, rate[1:] * step
    increments = np.where((rate[:-1] > 0) & (rate[1:] > 0), work_function(x1) - work_function(x0), 0.0)
    for k in np.flatnonzero((rate[:-1] > 0) != (rate[1:] > 0)):
        x_turn = hermite.values(hermite.turning_point(x0[k], x1[k], v0[k], v1[k]), x0[k], x1[k], v0[k], v1[k])
        if rate[k] > 0:                       # out, then in: work up to the turning point
            increments[k] = work_function(x_turn) - work_function(x0[k])
        else:                                 # in, then out: work from the turning point
            increments[k] = work_function(x1[k]) - work_function(x_turn)
    return increments


@dataclass(frozen=True)
class WorkHistory:
    """Cumulative works of the non-conservative forces along a run, from its first output time.

    Attributes
    ----------
    t : ndarray, shape (N,)
    torque : ndarray, shape (N,)
        W_M(t) = int M(t) phi' dt [J].
    gas : ndarray, shape (N,)
        W_F(t) = int Q_x x_C' dt [J], <= 0 in the paper's reading.
    ripple : ndarray, shape (N,)
        The part of W_M done by the ripple 0.01 sin(Omega t) [J].
    """

    t: np.ndarray
    torque: np.ndarray
    gas: np.ndarray
    ripple: np.ndarray

    @property
    def total(self):
        """W_M + W_F [J]."""
        return self.torque + self.gas


def _values(system):
    return dict(zip(system.functions.parameters, system.parameter_values))


def non_conservative_work(system, result):
    """The works of the drive torque and of the gas force along a slider-crank run.

    ``W_M = M_bar (phi - phi_0) + int 0.01 sin(Omega t) phi' dt`` (the ripple part
    by the trapezoidal rule: it is 4000 times smaller than the mean part), and
    ``W_F`` exactly from :func:`gas_outward_work` over the outward pieces of the
    motion (turning points between output times from a cubic Hermite
    interpolant).  A turning point at a dead centre costs nothing (F = 0
    there); one in mid-stroke, where F is not zero, puts an error of F times the
    interpolant's error in x_C into ``W_F``, which falls with the square of the
    output step and may lie far above the integrator's tolerance (swinging
    cases, chapter 11): take dense outputs (``t_eval``) there, or compare with
    ``simulate(..., work=True)`` and :func:`closedloop.balance.energy_balance`.

    Parameters
    ----------
    system : SliderCrankSystem
        From :func:`~closedloop.slider_crank.slider_crank_system`; torque or gas
        switched off give zero works.
    result : SimulationResult
        A run of that system.

    Returns
    -------
    WorkHistory
    """
    from scipy.integrate import cumulative_trapezoid

    reading = instance_of("system", system, SliderCrankSystem).reading
    values = _values(system)
    t, phi, phi_dot = result.t, result.coordinate("phi"), result.velocity("phi")
    ripple_power = values["torque_ripple"] * np.sin(values["omega"] * t) * phi_dot
    ripple = cumulative_trapezoid(ripple_power, t, initial=0.0)
    torque = values["torque_mean"] * (phi - phi[0]) + ripple
    if system.force is None:
        gas = np.zeros_like(t)
    else:
        increments = _outward_increments(result.coordinate("x"), result.velocity("x"), np.diff(t),
                                         lambda x: gas_outward_work(x, reading))
        gas = np.concatenate(([0.0], np.cumsum(increments)))
    return WorkHistory(t=t, torque=torque, gas=gas, ripple=ripple)


def energy_balance_error(system, result, work=None):
    """``(T + Pi)(t) - (T + Pi)(0) - W_M(t) - W_F(t)`` along a run [J]: zero for an exact motion.

    Parameters
    ----------
    system, result
        As for :func:`non_conservative_work`.
    work : WorkHistory, optional
        Reuse works already computed.
    """
    work = non_conservative_work(system, result) if work is None else work
    energy = system.energy(result.s, result.sd)
    return energy - energy[0] - work.total


@dataclass(frozen=True)
class Landscape:
    """The crank's energy landscape on the paper's assembly branch.

    Attributes
    ----------
    phi : ndarray
        Crank angles [rad], increasing.
    potential : ndarray
        Pi(phi) with psi, x_C from (27)-(28) [J].
    tilted : ndarray
        V(phi) = Pi(phi) - M_bar phi [J]: the potential of gravity plus the mean torque.
    gas_loss : ndarray
        G(phi) = -W_F for a forward rotation from phi[0] to phi [J]: the slider moves
        out where dx_C/dphi > 0.
    slope : ndarray
        dx_C/dphi, the x_C row of R of (20).
    """

    phi: np.ndarray
    potential: np.ndarray
    tilted: np.ndarray
    gas_loss: np.ndarray
    slope: np.ndarray

    @property
    def barrier(self):
        """B = V + G, the barrier function of a forward rotation [J]."""
        return self.tilted + self.gas_loss


def crank_landscape(system, phi):
    """Pi, V = Pi - M_bar phi and the forward gas loss G along crank angles ``phi``.

    For a constant torque M_bar, ``T + V`` changes only by the gas work; the
    paper's torque adds a ripple whose work is at most 0.01 N m times the angle
    turned (see :func:`non_conservative_work`), so V is the landscape of the mean
    torque.

    Parameters
    ----------
    system : SliderCrankSystem
    phi : array_like
        Strictly increasing crank angles [rad].

    Returns
    -------
    Landscape
    """
    reading = instance_of("system", system, SliderCrankSystem).reading
    phi = np.asarray(phi, dtype=float)
    if phi.ndim != 1 or phi.size < 2 or np.any(np.diff(phi) <= 0):
        raise InputError("phi: must be a strictly increasing 1-d array of at least two angles")
    states = [initial_state(system, angle, 1.0) for angle in phi]    # s' = R at unit speed
    s = np.array([state.s for state in states]).T
    slope = np.array([state.sd[2] for state in states])
    _, potential = system.kinetic_and_potential_energy(s, np.zeros_like(s))
    tilted = potential - _values(system)["torque_mean"] * phi
    if system.force is None:
        gas_loss = np.zeros_like(phi)
    else:
        increments = _outward_increments(s[2], slope, np.diff(phi), lambda x: gas_outward_work(x, reading))
        gas_loss = -np.concatenate(([0.0], np.cumsum(increments)))
    return Landscape(phi=phi, potential=potential, tilted=tilted, gas_loss=gas_loss, slope=slope)
