"""The segment loop of one simulate() call: switches, sticking, and what every runner shares.

:class:`Run` holds what one call computes (outputs, counters, events) and no state survives
the call.  It steps from switch to switch: a **runner** integrates one segment on one branch
of the force (:mod:`~closedloop.simulation.solve_ivp_runner` or
:mod:`~closedloop.simulation.dop853_runner`), and the run decides the next branch with the
rule of :mod:`~closedloop.simulation.switching`.
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

from ..errors import IntegrationError, SingularConfigurationError
from ..validation import shown_array
from . import switching as rule
from . import watch
from .options import IMPLICIT_METHODS
from .result import Outputs, SwitchEvent
from .work import with_work, work_of

__all__ = ["Run", "SegmentEnd", "MAX_RELEASE_SAMPLES"]

#: Most checks of the holding force while one state is stuck (see Run._find_release): a check of the
#: slider-crank costs some 13 to 30 us (ClosedForm, Baumgarte), so 1e6 of them take under 40 s (1e7
#: took over six minutes).
MAX_RELEASE_SAMPLES = 1_000_000


class SegmentEnd(NamedTuple):
    """Where a segment stopped: at ``t_end`` (``event`` None), at switch ``event``, or at stop_when."""

    t: float
    s: np.ndarray | None
    sd: np.ndarray | None
    event: int | None


class Run:
    """The state of one simulate() call (see the module's notes)."""

    def __init__(self, system, formulation, options):
        self.system, self.formulation, self.options = system, formulation, options
        self.t_end = options.t_end
        self.force = system.force
        self.names = self.force.switch_names if self.force is not None else ()
        self.outputs = Outputs(options.t_eval)
        self.nfev = 0
        self.step_starts, self.step_sizes = [], []   # every accepted step: where it began, its size [s]
        self.t_reached = None             # time of the last accepted step
        self.last_step_size = 0.0         # carried from one compiled segment to the next
        self.steps_exhausted = False
        self.work_done = 0.0
        self.partition_singularities = []
        self.overflows = []               # (t, message) of the right-hand side's overflows in the current segment
        self.stopped_at = None
        self.switch_events, self.sticking_intervals = [], []
        self._fast_accelerations = {}     # the formulation's switch_accelerations per branch
        # Every accepted step end, checked as the run goes (change points, branch guard, dead positions).
        self.path = watch.PathWatch(system, formulation, options, self)

    # -- what every runner shares -------------------------------------------------
    def record_step(self, start, end):
        """An accepted step from ``start`` to ``end`` [s] (the compiled runner adds a segment's steps at once)."""
        self.step_starts.append(start)
        self.step_sizes.append(abs(end - start))

    def evaluations_left(self):
        return math.inf if self.options.max_nfev is None else self.options.max_nfev - self.nfev

    def budget_error(self, t):
        return IntegrationError(
            f"{self.options.method_name} used up max_nfev = {self.options.max_nfev} right-hand-side evaluations "
            f"at t = {t:.6g} s of {self.t_end:g} s; loosen rtol, or raise max_nfev"
        )

    def start_segment(self, s0, sd0, mode):
        """``(y0, unpack, rhs)`` of a segment on branch ``mode``, with the work state if asked for."""
        system, formulation = self.system, self.formulation
        y0 = formulation.pack(system, s0, sd0)
        unpack = formulation.unpacker(system)
        unpack.seed(s0)
        rhs = formulation.make_rhs(system, mode, unpack)
        if self.options.work:                       # one more state: W' = tau . s'
            y0, rhs, unpack = with_work(self.system, y0, rhs, unpack, mode, self.work_done)
        return y0, unpack, rhs

    def store_segment(self, t, y, s0, mode, t0):
        """Keep a segment's outputs, unpacked by a fresh unpacker that marches from the segment's start."""
        unpack = self.formulation.unpacker(self.system)
        unpack.seed(s0)
        self.outputs.add_segment(t, y, unpack, mode, t0, self.options.work)

    def end_of_segment(self, t_stop, y_stop, unpack, event):
        """The SegmentEnd of a segment stopped by ``event`` at ``(t_stop, y_stop)``, or at t_end."""
        if event is None:
            return SegmentEnd(self.t_end, None, None, None)
        if self.options.work:
            self.work_done = float(work_of(y_stop))
        s_end, sd_end = unpack(y_stop, t_stop)
        return SegmentEnd(t_stop, s_end, sd_end, event)

    def check_finite(self, t_out, y_out):
        if y_out.size == 0 or np.isfinite(y_out).all():     # most segments hold no output time
            return
        bad = ~np.all(np.isfinite(y_out), axis=0)
        k = int(np.argmax(bad))
        names = self.formulation.state_names(self.system)
        names = names + ["W"] * (y_out.shape[0] - len(names))
        which = [name for name, v in zip(names, y_out[:, k]) if not np.isfinite(v)]
        raise IntegrationError(
            f"the state became non-finite at t = {t_out[k]:.6g} s with {self.options.method_name} "
            f"({', '.join(which)} = {y_out[names.index(which[0]), k]}){self.path.force_clause_before(t_out[k])}; "
            f"{self.advice()}"
        )

    def force_clause(self, t, s, sd, mode=None):
        """``"; the force returned [nan ...] at t = ... s at a finite state ..."`` where the system's forces are not
        finite at ``(t, s, s')`` (a finite state), else ``""``: what a failed integration names as its cause."""
        s, sd = np.asarray(s, dtype=float), np.asarray(sd, dtype=float)
        if not (np.all(np.isfinite(s)) and np.all(np.isfinite(sd))):
            return ""
        try:
            with np.errstate(all="ignore"):
                tau = self.system.applied_forces(t, s, sd, mode)
        except Exception as error:
            return f"; the force raised {type(error).__name__} at t = {t:.6g} s: {error}"
        if np.all(np.isfinite(tau)):
            return ""
        return (f"; the force returned {shown_array(tau)} at t = {t:.6g} s, at a finite state (s = {shown_array(s)}, "
                f"s' = {shown_array(sd)}): a force must return finite numbers wherever the run goes")

    def overflow_error(self, error):
        """The IntegrationError for an arithmetic overflow (``error``) outside the integrator's steps."""
        t = 0.0 if self.t_reached is None else self.t_reached
        detail = error.args[-1] if error.args else type(error).__name__
        return IntegrationError(
            f"{self.options.method_name} failed after t = {t:.6g} s: an arithmetic overflow ({detail}), the "
            f"motion's speeds or accelerations are beyond the range of floating-point numbers; {self.advice()}")

    def advice(self):
        """What to try instead, for an integration that failed."""
        tries = []
        if self.options.method_name not in IMPLICIT_METHODS:
            tries.append("an implicit method (Radau, BDF or LSODA)")
        gains = self.formulation.gains
        if gains is not None and max(gains) > 20.0:
            tries.append(f"smaller Baumgarte gains than alpha = {gains[0]:g}, beta = {gains[1]:g} "
                         "(the paper's range is 1 to 20)")
        tries.append("looser tolerances than rtol = {:g}, atol = {:g}".format(
            np.max(self.options.rtol), np.max(self.options.atol)))
        return "try " + ", or ".join(tries)

    # -- the switching rule applied to one state ----------------------------------
    def _accelerations(self, t, s, sd, mode):
        """s'' of (12) on branch ``mode``: the formulation's fast form where it has one, else (12) solved."""
        try:
            fast = self._fast_accelerations[mode]
        except KeyError:                             # asked for once per branch and run
            fast = self._fast_accelerations[mode] = self.formulation.switch_accelerations(self.system, mode)
        if fast is not None:
            try:
                return fast(t, s, sd)
            except SingularConfigurationError:
                pass
        return self.system.constrained_accelerations(t, s, sd, mode)[0]

    def side_rates(self, t, s, sd, mode, i):
        """dh_i/dt along the constrained motion (12) with switch i off and on: ``(off, on)``."""
        values = self.force.switching_values         # Python floats: h_i alone, no arrays

        def h(time, q, qd):
            return values(time, q, qd)[i]

        now = h(t, s, sd)
        ahead = s + rule.RATE_STEP * sd               # the positions a step ahead: the same on both branches
        return tuple(rule.switching_rate(h, t, s, sd, self._accelerations(t, s, sd, branch), now, s_ahead=ahead)
                     for branch in (mode[:i] + (False,) + mode[i + 1:], mode[:i] + (True,) + mode[i + 1:]))

    def decide(self, t, s, sd, mode, i, stalled=False):
        """The branch of switch i at a state on its surface: (new mode, action).

        Where the rates vanish on both branches (a degenerate contact), or where the
        segment that the rates chose stopped at once (``stalled``: the motion they
        point to stays within the integration's round-off of the surface and comes
        back to it, as a slider at rest a hair past a dead centre does), the branches'
        own motions over :data:`~closedloop.simulation.switching.PROBE_TIME` decide.
        """
        off, on = self.side_rates(t, s, sd, mode, i)

        def accelerations(side):
            branch = mode[:i] + (side,) + mode[i + 1:]
            return lambda time, q, qd: self._accelerations(time, q, qd, branch)

        side, sticks = rule.choose_side(off, on, mode[i], rule.state_scale(s, sd), stalled, lambda _: rule.probe_rates(
            self.force.switching_functions, accelerations, t, s, sd, i))
        if sticks:
            if not self.force.can_stick[i]:
                raise rule.refuse_sliding(t, self.names[i])
            return mode, "stuck"
        action = "crossed" if side != mode[i] else "turned back"
        return mode[:i] + (side,) + mode[i + 1:], action

    def initial_mode(self, t, s, sd):
        """The branch of every switch at the start, and the switch the state sticks on (or None)."""
        if self.force is None or not self.names:
            return (), None
        values = self.force.switching_functions(t, s, sd)
        mode = tuple(bool(v > 0) for v in values)
        scale = rule.state_scale(s, sd)
        for i, v in enumerate(values):
            if rule.on_surface(v, scale):
                mode, action = self.decide(t, s, sd, mode, i)
                if action == "stuck":
                    return mode, i
        return mode, None

    # -- the loop -------------------------------------------------------------------
    def integrate(self, segment, t, s, sd):
        """Run segments (``segment(run, t0, s0, sd0, mode) -> SegmentEnd``) from switch to switch."""
        mode, stuck = self.initial_mode(t, s, sd)
        stalls = 0
        for _ in range(self.options.max_segments):
            if stuck is not None:
                t, s, sd, mode = self.stick(t, s, mode, stuck)
                stuck = None
                if t >= self.t_end:
                    return
                continue
            end = segment(self, t, s, sd, mode)
            stalls = stalls + 1 if rule.no_progress(end.t, t) else 0
            t, s, sd = end.t, end.s, end.sd
            if stalls > rule.MAX_STALLS:
                raise rule.chattering_error(t, self.names[end.event], "tighten rtol and atol, or regularise the force")
            if end.event is None:
                return
            if end.event == len(self.names):                 # stop_when fired
                self.stopped_at = t
                return
            mode, action = self.decide(t, s, sd, mode, end.event, stalled=stalls > 0)
            self.switch_events.append(SwitchEvent(t, self.names[end.event], action))
            if action == "stuck":
                stuck = end.event
        raise IntegrationError(
            f"more than {self.options.max_segments} switch segments before t = {t:.6g} s; raise max_segments "
            "or check the force for chattering"
        )

    def stick(self, t0, s, mode, i):
        """Hold the mechanism at rest on switch i until it is released (the sticking rule).

        Returns ``(t, s, s', mode)`` at the release, or at t_end.
        """
        system = self.system
        if system.f != 1:
            raise IntegrationError(
                f"the state sticks on switch {self.names[i]!r} at t = {t0:.6g} s; the sticking rule "
                f"holds the mechanism at rest, which is only valid for one degree of freedom (f = {system.f})"
            )
        sd = np.zeros(system.n)

        def margin(t):
            return rule.release_margin(*self.side_rates(t, s, sd, mode, i))

        t_release, past = self._find_release(margin, t0)
        t_stop = self.t_end if t_release is None else t_release
        self.sticking_intervals.append((t0, t_stop))
        times = self.outputs.due(None, until=t_stop)
        times = np.array([t0, t_stop]) if times is None else times
        held = mode[:i] + (False,) + mode[i + 1:]     # the force's free branch, plus the holding force
        work = np.full(times.size, self.work_done) if self.options.work else None   # at rest: no power
        self.outputs.add_rest(times, s, held, i, work)
        if t_release is None:
            return self.t_end, s, sd, mode
        # The side is read just past the root (at the sample where the margin is <= 0):
        # at the root itself the rate that ends the sticking is zero to round-off.
        off, _ = self.side_rates(past, s, sd, mode, i)
        side = bool(rule.side_after_release(off))
        self.switch_events.append(SwitchEvent(t_release, self.names[i], "released"))
        return t_release, s, sd, mode[:i] + (side,) + mode[i + 1:]

    def _find_release(self, margin, t0):
        """The release time after ``t0`` (None if held to t_end) and the sample just past it.

        The margin is sampled every ``sticking_resolution`` seconds; the first
        sample where it is <= 0 brackets the release, which
        :func:`~closedloop.simulation.switching.locate_release` then locates.
        Sampling ends after one period of the system's forcing
        (:func:`~closedloop.simulation.switching.forcing_period`): the margin at
        rest repeats itself after that, so a state held that long is held to t_end.
        """
        resolution = self.options.sticking_resolution
        period = rule.forcing_period(self.system)
        horizon = self.t_end if period is None else min(self.t_end, t0 + period + resolution)
        samples = (horizon - t0) / resolution          # inf for resolution = 5e-324: compared before ceil
        if samples > MAX_RELEASE_SAMPLES:
            reason = (" (the system's forcing is not periodic, so no check can be skipped)" if period is None
                      else "")
            raise IntegrationError(
                f"the state sticks on a switch at t = {t0:.6g} s, and its release would need {samples:.3g} checks "
                f"of the holding force up to t = {horizon:g} s, more than {MAX_RELEASE_SAMPLES:g}{reason}; give a "
                "larger sticking_resolution or a shorter t_end"
            )
        samples = math.ceil(samples)
        previous, previous_margin = t0, margin(t0)
        for k in range(1, samples + 1):
            t = min(t0 + k * resolution, self.t_end)
            value = margin(t)
            if value <= 0:
                located = rule.locate_release(lambda times, _: np.array([margin(float(times[0]))]),
                                              [previous], [t], [previous_margin], [value])
                return float(located[0]), t
            previous, previous_margin = t, value
        return None, None
