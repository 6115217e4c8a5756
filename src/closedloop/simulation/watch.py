"""The watch along the accepted steps of a run, on every runner: written once.

Every runner (solve_ivp, the compiled DOP853, naive switching) hands each accepted step end
to the run's :class:`PathWatch` (:meth:`~PathWatch.record`), the end of each segment to
:meth:`~PathWatch.end` and a failed segment to :meth:`~PathWatch.failed`.  The step ends are
checked in batches during the integration (the first after :data:`FIRST_BATCH` step ends,
then whenever those not yet checked reach :data:`BATCH_GROWTH` times those checked), so a run
that fails stops after at most about a quarter more than the run up to the failure.  Each
batch raises at the earliest of:

1. **A change point**, where Phi_s loses rank (:mod:`~closedloop.simulation.change_points`),
   or, for a redundant formulation, two assembly branches passing so near that the path's
   distance to the constraints reached half their gap.  ``branch_limit=math.inf`` turns it off.
2. **The branch guard** (redundant coordinates): where det Phi_z changes sign between two step
   ends, the crossing is located on the quintic Hermite interpolant of the positions and the
   Kantorovich number ``h = sigma_max(Phi_s) |f| / sigma_min(Phi_s)^2`` formed there with the
   larger |f| of the step's ends.  Above the run's ``branch_limit`` (default
   :data:`~closedloop.simulation.options.BRANCH_LIMIT`) the state is not unambiguously on one
   branch and the run stops (:class:`~closedloop.errors.SingularConfigurationError`); below
   it a dead position was passed, recorded in the result's ``partition_singularities``.
3. **A dead position of minimal coordinates** (formulations with ``guards_branch``): where
   the component of q' across the fold (along ``Phi_q^T u``, u the left singular vector of
   Phi_z's smallest singular value) changes sign, the turning point is located and the
   branch followed beyond it; where the mechanism does not assemble there, q turned back at
   a dead position (the equation in q turns back where the mechanism goes on along the other
   branch), and the run stops with an error naming the time and the configuration.
4. **Crawling**: :data:`CRAWL_STEPS` accepted steps in a row that advance less than
   :data:`CRAWL_FRACTION` of the run together stop the run with an error that says why,
   where the state shows it (:func:`diagnosis`: Phi_s or the partition nearly singular, a
   force that turned NaN, an overflow); short steps without such a cause go on (a fast
   motion needs them).  Not with ``switching="naive"``, which chatters by design.
"""

from __future__ import annotations

import math

import numpy as np

from .. import hermite
from ..errors import ConvergenceError, IntegrationError, SingularConfigurationError
from ..linalg import NEAR_RANK_LOSS, NEARLY_SINGULAR, partition_condition, partition_determinant
from ..loading import first_use
from .change_points import EPSILON, branch_error, change_point_error, find_change_point, meeting_point
from .work import without_work

__all__ = ["PathWatch", "diagnosis", "FIRST_BATCH", "BATCH_GROWTH", "CRAWL_STEPS", "CRAWL_FRACTION",
           "NEAR_RANK_LOSS"]

#: Step ends checked in the first batch of a run.
FIRST_BATCH = 64
#: A new batch is checked when the step ends not yet checked reach this fraction of those checked.
BATCH_GROWTH = 0.25
#: Accepted steps in a row (of one segment) whose total advance is compared with CRAWL_FRACTION.
CRAWL_STEPS = 100
#: A run whose last CRAWL_STEPS steps advanced less than this fraction of t_end - t_start crawls: at
#: that pace it would need 1e7 steps, ten times MAX_STEPS.
CRAWL_FRACTION = 1e-5


@first_use
def _brentq():
    """scipy.optimize's brentq, imported on first use (it costs about 0.1 s)."""
    from scipy.optimize import brentq

    return brentq


def _configuration(names, s):
    return ", ".join(f"{name} = {value:.6g}" for name, value in zip(names, s))


def diagnosis(system, formulation, s):
    """What the configuration ``s`` says about an integration that could not go on there, or None.

    A Phi_s that nearly loses rank (a change point), or, for a formulation that uses
    the model's partition (R of (20), Phi_z), a nearly singular Phi_z (a dead
    position of the independent coordinates): one clause with the number and the
    remedy.
    """
    try:
        Phi = system.jacobian(np.asarray(s, dtype=float))
        singular_values = np.linalg.svd(Phi, compute_uv=False)
    except (ArithmeticError, ValueError, np.linalg.LinAlgError):
        return None
    if not np.all(np.isfinite(singular_values)):
        return None
    largest, smallest = singular_values[0], singular_values[-1]
    rank = math.inf if smallest == 0.0 else largest / smallest
    if rank > NEARLY_SINGULAR:
        point, gap = (None, 0.0) if smallest == 0.0 else meeting_point(system, s)
        if smallest == 0.0 or point is not None:
            return (f"Phi_s nearly loses rank there (cond(Phi_s) = {rank:.3g}): two assembly branches meet, and no "
                    "formulation of this library passes a change point: end the run before it, or change the "
                    "geometry")
        return (f"Phi_s nearly loses rank there (cond(Phi_s) = {rank:.3g}): two assembly branches pass within about "
                f"{gap:.2g} of each other, without meeting; give a max_step, so that the steps stay short where "
                "they are near, or tighten rtol and atol")
    if formulation.guards_partition or formulation.guards_branch:
        condition = partition_condition(Phi, system.z_index)
        if condition > NEARLY_SINGULAR:
            return (f"Phi_z is nearly singular there (|Phi_s| |Phi_z^-1| = {condition:.3g}): a dead position of the "
                    f"independent coordinates, which {type(formulation).__name__} can not pass; use the NullSpace "
                    "formulation, which needs no partition")
    return None


class PathWatch:
    """The accepted step ends of one run, checked in batches as they come (see the module's notes).

    Parameters
    ----------
    system : System
    formulation : Formulation
    options : RunOptions
    run : Run
        Where crossings of det Phi_z = 0 are recorded (``run.partition_singularities``).
    """

    def __init__(self, system, formulation, options, run):
        self.system, self.formulation, self.options, self.run = system, formulation, options, run
        self.active = math.isfinite(options.branch_limit)          # the change points
        self.guard = not formulation.guards_branch                  # the branch guard, else the turning points
        # naive switching chatters by design, and max_nfev bounds it: no crawl check there
        self.crawl_limit = CRAWL_FRACTION * (options.t_end - options.t_start) if options.switching != "naive" else 0.0
        self.largest_residuals = (0.0, 0.0)                         # max |f|, max |f'| over every step end checked
        self.checked = 0                                            # step ends checked in the run
        self.error = None                                           # the error a check raised, once raised
        # step ends moved out of their segment, not yet checked (after `context` that were): times, s, s', y,
        # and the segment each belongs to
        self.times, self.s, self.sd, self.y, self.segment_of = [], [], [], [], []
        self.context = 0
        self.modes = []                                             # the branch of the force, per segment
        # the current segment's step ends as recorded, the first `moved` of them moved out already
        self.raw_times, self.raw_states, self.moved = [], [], 0
        self.unpack = None
        self.waiting, self.due = 0, FIRST_BATCH                  # step ends not checked; a batch's size
        self.crawl_checked = 0                                   # step ends of the segment checked for crawling

    # -- what the runners call ------------------------------------------------------
    def start(self, t0, y0, s0, mode):
        """Begin a segment on branch ``mode`` at ``(t0, y0)``, whose coordinates are ``s0``."""
        self.modes.append(mode)
        self.unpack = self.formulation.unpacker(self.system)
        self.unpack.seed(s0)
        self.raw_times, self.raw_states, self.moved = [t0], [np.array(y0, dtype=float)], 0
        self.crawl_checked = 0
        self.waiting = len(self.times) - self.context           # moved out of earlier segments, not checked

    def record(self, t, y):
        """One accepted step end (an array the caller will not change again); checks a batch when one is due
        (and raises at a failure)."""
        raw = self.raw_times
        raw.append(t)
        self.raw_states.append(y)
        self.waiting += 1
        if self.waiting >= self.due:
            self._crawl_check()
            self._move(len(raw) - 1)                # the last one may have overshot a switch: kept back
            self._check(more=True)

    def end(self, t_stop=None, y_stop=None):
        """The segment ended at t_end, or at ``(t_stop, y_stop)`` (a switch, stop_when): step ends past it go.

        Its step ends are checked with the next batch (or by :meth:`flush`, when the run ends here)."""
        self._crawl_check()
        if t_stop is not None:
            keep = self.moved + sum(1 for t in self.raw_times[self.moved:] if t < t_stop)
            del self.raw_times[keep:], self.raw_states[keep:]
            self.raw_times.append(t_stop)
            self.raw_states.append(np.array(y_stop, dtype=float))
        self._move(len(self.raw_times))
        self.waiting = len(self.times) - self.context
        if self.waiting >= self.due:
            self._check(more=True)

    def failed(self, failed_at=None):
        """The segment failed at ``failed_at`` (after its last step end): check every step end recorded.

        Raises the earliest failure found along them (a change point passed before is the real
        cause of a failure after it, and so are steps that crawled); returns when there is none, or
        when a check has raised already.
        """
        if self.error is not None:
            return
        self._crawl_check()
        if self.unpack is not None:
            try:
                self._move(len(self.raw_times))
            except ClosedLoopErrors:
                pass                                # the step ends that could be unpacked are checked
        self._check(failed_at)

    def flush(self):
        """Check every step end not checked yet (at the end of a run)."""
        if self.error is None:
            self._check()

    # -- the batches ------------------------------------------------------------------
    def force_clause_before(self, t):
        """:meth:`Run.force_clause` at time ``t`` and the last finite state recorded before it (``""`` if the forces are
        finite there): whether a force that is not finite is why the state became so."""
        for k in range(len(self.times) - 1, -1, -1):
            if self.times[k] <= t and np.all(np.isfinite(self.s[k])) and np.all(np.isfinite(self.sd[k])):
                mode = self.modes[self.segment_of[k]]
                return self.run.force_clause(t, self.s[k], self.sd[k], mode)
        for y in reversed(self.raw_states):
            if np.all(np.isfinite(y)):
                try:
                    s, sd = self.unpack(without_work(y, self.options.work), t)
                except ClosedLoopErrors:
                    return ""
                return self.run.force_clause(t, s, sd, self.modes[-1] if self.modes else None)
        return ""

    def _move(self, upto):
        """Move the current segment's step ends ``moved .. upto-1`` out, with their coordinates and velocities."""
        if upto <= self.moved:
            return
        times = self.raw_times[self.moved:upto]
        states = without_work(np.column_stack(self.raw_states[self.moved:upto]), self.options.work)
        self.moved = upto
        s, sd = self.unpack.many(states, np.asarray(times))
        segment = len(self.modes) - 1
        self.times.extend(times)
        self.s.extend(s.T)
        self.sd.extend(sd.T)
        self.y.extend(states.T)
        self.segment_of.extend([segment] * len(times))

    def _check(self, failed_at=None, more=False):
        """Check the step ends moved out (after the context kept from the last batch); raise the earliest failure.

        ``more``: the path goes on after the last of them (a batch during the run).
        """
        new = len(self.times) - self.context
        if new <= 0 or len(self.times) < 2:
            return
        times = np.asarray(self.times, dtype=float)
        s, sd = np.array(self.s).T, np.array(self.sd).T
        finite = np.all(np.isfinite(s), axis=0) & np.all(np.isfinite(sd), axis=0)
        if not np.all(finite):                  # an accepted step to a non-finite state (LSODA takes some)
            k = int(np.argmin(finite))
            force = self.force_clause_before(times[k])
            self.error = IntegrationError(
                f"the state became non-finite at t = {times[k]:.6g} s with {self.options.method_name}{force}; "
                + (f"end the run before t = {times[k]:.6g} s, or mend the force" if force else self.run.advice()))
            raise self.error
        residuals, jacobians = self.system.constraints_and_jacobian_many(s)
        failures, changed = [], None
        if self.active:
            velocity = np.einsum("ijk,jk->ik", jacobians, sd)
            self.largest_residuals = (
                max(self.largest_residuals[0], float(np.sqrt(np.max(np.sum(residuals ** 2, 0))))),
                max(self.largest_residuals[1], float(np.sqrt(np.max(np.sum(velocity ** 2, 0))))))
            found = find_change_point(self.system, times, s, sd, failed_at, evaluated=(residuals, jacobians),
                                      open_start=self.context > 0, open_end=more)
            if found is not None:
                changed = change_point_error(found, self.system, self.options.method_name)
                failures.append((found[0], changed))
        crossings = []
        steps = self._steps(times)
        if self.guard:
            self._branch_guard(steps, times, residuals, jacobians, crossings, failures)
        else:
            self._turning_points(steps, times, s, sd, jacobians, failures)
        if failures:
            t, error = min(failures, key=lambda failure: failure[0])
            if changed is not None and error is not changed:
                # where the path can not tell the branches apart, the branch guard objects too, within a step
                found_at = next(at for at, failure in failures if failure is changed)
                if found_at - t <= float(np.max(np.diff(times))):
                    t, error = found_at, changed
            self.error = error
            raise error
        self.run.partition_singularities.extend(t for t in crossings if not self.run.partition_singularities
                                                or t != self.run.partition_singularities[-1])
        self.checked += new
        self.waiting = len(self.raw_times) - self.moved - 1     # recorded, not moved out (the one kept back)
        self.due = max(FIRST_BATCH, BATCH_GROWTH * self.checked)
        keep = min(2, len(self.times))            # context for the next batch: a minimum between batches
        for stored in (self.times, self.s, self.sd, self.y, self.segment_of):
            del stored[:-keep]
        self.context = keep

    def _steps(self, times):
        """Indices k of the steps from step end k to k + 1 that are new in this batch: one segment, t increasing."""
        segment = np.asarray(self.segment_of)
        k = np.arange(max(self.context - 1, 0), times.size - 1)
        return k[(segment[k] == segment[k + 1]) & (times[k + 1] > times[k])]

    def _interpolant(self, k, times, rows):
        """``(position(u), slope(u))`` of the coordinates ``rows`` over step k, quintic where the accelerations
        at both ends are known (from the formulation's right-hand side), else cubic; u in [0, 1]."""
        h = times[k + 1] - times[k]
        y0, y1 = self.y[k], self.y[k + 1]
        size = len(rows)
        p0, p1 = y0[rows], y1[rows]
        v0, v1 = h * y0[rows_velocity(rows, y0.size)], h * y1[rows_velocity(rows, y1.size)]
        try:
            a0 = h * h * np.asarray(self._rhs(k, times[k], y0), dtype=float)[size:2 * size]
            a1 = h * h * np.asarray(self._rhs(k + 1, times[k + 1], y1), dtype=float)[size:2 * size]
            if not (np.all(np.abs(a0) < LARGE) and np.all(np.abs(a1) < LARGE)):   # not finite, or a rejected stage
                raise ArithmeticError
        except (ArithmeticError, np.linalg.LinAlgError, ValueError):
            return (lambda u: hermite.values(u, p0, p1, v0, v1)), (lambda u: hermite.slopes(u, p0, p1, v0, v1))
        return ((lambda u: hermite.quintic_values(u, p0, p1, v0, v1, a0, a1)),
                (lambda u: hermite.quintic_slopes(u, p0, p1, v0, v1, a0, a1)))

    def _rhs(self, k, t, y):
        """The formulation's right-hand side at step end k (a fresh unpacker, seeded there)."""
        system, formulation = self.system, self.formulation
        mode = self.modes[self.segment_of[k]]
        if mode is None:                        # naive switching: the branch the state lies on
            mode = () if system.force is None else system.force.mode_at(t, self.s[k], self.sd[k])
        unpack = formulation.unpacker(system)
        unpack.seed(self.s[k])
        return formulation.make_rhs(system, mode, unpack)(t, y)

    # -- the branch guard ---------------------------------------------------------------
    def _branch_guard(self, steps, times, residuals, jacobians, crossings, failures):
        """Each step where det Phi_z changes sign: the crossing located, the Kantorovich number checked."""
        system = self.system
        det = partition_determinant(jacobians, system.z_index)
        flips = steps[(det[steps] * det[steps + 1] < 0.0) | ((det[steps] == 0.0) & (det[steps + 1] != 0.0))
                      | ((det[steps + 1] == 0.0) & (det[steps] != 0.0))]
        brentq = _brentq() if flips.size else None
        rows = np.arange(system.n)
        for k in flips.tolist():
            position, _ = self._interpolant(k, times, rows)

            def det_at(u):
                return partition_determinant(system.jacobian(position(u)), system.z_index)

            if det[k] == 0.0:
                u = 0.0
            elif det[k + 1] == 0.0:
                u = 1.0
            else:
                start, stop = det_at(0.0), det_at(1.0)
                u = brentq(det_at, 0.0, 1.0, xtol=4 * EPSILON, rtol=4 * EPSILON) if start * stop < 0 else (
                    0.0 if abs(start) <= abs(stop) else 1.0)
            t = float(times[k] + u * (times[k + 1] - times[k]))
            Phi = system.jacobian(position(u))
            singular_values = np.linalg.svd(Phi, compute_uv=False)
            # the run's own distance to the constraints, at the step's ends (the interpolant adds its own error)
            error = float(max(np.linalg.norm(residuals[:, k]), np.linalg.norm(residuals[:, k + 1])))
            largest, smallest = singular_values[0], singular_values[-1]
            kantorovich = math.inf if smallest == 0 else largest * error / smallest ** 2
            if kantorovich > self.options.branch_limit:
                condition = largest / smallest if smallest > 0 else math.inf
                if condition > NEAR_RANK_LOSS:      # two branches close by: do they meet (a change point)?
                    failures.append((t, branch_error(t, position(u), smallest, largest, error, kantorovich,
                                                     self.options.branch_limit, system, self.options.method_name,
                                                     list(system.coordinate_names))))
                    return
                failures.append((t, SingularConfigurationError(
                    f"the path crossed a singular configuration of Phi_z at t = {t:.6g} s (cond(Phi_s) = "
                    f"{condition:.3g}, |f| = {error:.3g}, Kantorovich number {kantorovich:.3g} > "
                    f"{self.options.branch_limit:g}): the constraint error is as large as the distance between "
                    "assembly branches, so the run may have changed branch; tighten rtol and atol")))
                return
            crossings.append(t)

    # -- dead positions of minimal coordinates ----------------------------------------------
    def _turning_points(self, steps, times, s, sd, jacobians, failures):
        """Each step where q' turns across a fold of the partition: an ordinary turning point, or a dead position."""
        system = self.system
        qi, zi = system.q_index, system.z_index
        qd = sd[qi]
        if system.f == 1:
            across = qd[0]
            candidates = steps[(across[steps] * across[steps + 1] < 0.0)
                               | ((across[steps + 1] == 0.0) & (across[steps] != 0.0))]
            normals = None
        else:
            normals = _fold_normals(jacobians, qi, zi)
            near = np.where(normals[1][steps] <= normals[1][steps + 1], steps, steps + 1)
            n = normals[0][:, near]
            before = np.einsum("ik,ik->k", n, qd[:, steps])
            after = np.einsum("ik,ik->k", n, qd[:, steps + 1])
            chosen = (before * after < 0.0) | ((after == 0.0) & (before != 0.0))
            candidates, normals = steps[chosen], dict(zip(steps[chosen].tolist(), n[:, chosen].T))
        for k in candidates.tolist():
            found = self._dead_position(k, times, s, normals[k] if normals is not None else np.ones(1))
            if found is not None:
                failures.append(found)
                return

    def _dead_position(self, k, times, s, normal):
        """``(t, error)`` when q turns back over step k at a dead position of the partition, else None."""
        system = self.system
        qi = system.q_index
        f = system.f
        position, slope = self._interpolant(k, times, np.arange(f))

        def across(u):
            return float(normal @ slope(u))

        start, stop = across(0.0), across(1.0)
        u = (_brentq()(across, 0.0, 1.0, xtol=4 * EPSILON, rtol=4 * EPSILON) if start * stop < 0.0
             else (1.0 if stop == 0.0 else 0.0))
        t = float(times[k] + u * (times[k + 1] - times[k]))
        q_turn = np.asarray(position(u), dtype=float)
        ends = (s[qi, k], s[qi, k + 1])
        far = max(ends, key=lambda q: abs(float(normal @ (q - q_turn))))
        beyond = 2.0 * q_turn - far
        # at least sqrt(eps) (1 + |q|) beyond: a step so short that its far end lies within round-off of the
        # turning point can not tell a dead position (there Newton finds no z that near beyond it) apart
        reach = math.sqrt(EPSILON) * (1.0 + float(np.max(np.abs(q_turn))))
        across = normal / np.linalg.norm(normal)
        if abs(float(across @ (beyond - q_turn))) < reach:
            direction = np.sign(float(across @ (q_turn - far))) or 1.0
            beyond = q_turn + direction * reach * across
        near = k if abs(float(normal @ (s[qi, k] - q_turn))) <= abs(float(normal @ (s[qi, k + 1] - q_turn))) else k + 1
        unpack = self.formulation.unpacker(system)
        unpack.seed(s[:, near])
        at_turn = s[:, near]
        try:
            at_turn = unpack.follow(q_turn, t)
            unpack.follow(beyond, t)
        except (SingularConfigurationError, ConvergenceError):
            Phi = system.jacobian(at_turn)
            names = list(system.coordinate_names)
            return t, SingularConfigurationError(
                f"minimal coordinates turned back at a dead position of q at t = {t:.6g} s "
                f"({_configuration(names, at_turn)}; |Phi_s| |Phi_z^-1| = "
                f"{partition_condition(Phi, system.z_index):.3g} there): the mechanism does not assemble on its "
                f"branch {float(np.max(np.abs(beyond - q_turn))):.3g} beyond where q turned, so Phi_z is singular "
                "in between and the mechanism goes on along its other assembly branch, while the equation in q "
                "alone turned back on the same one; use the NullSpace formulation, which passes dead positions")
        return None

    # -- crawling ------------------------------------------------------------------------------
    def _crawl_check(self):
        """At the last window of CRAWL_STEPS steps of the segment, among those not checked yet, that advanced
        less than the crawl limit together: raise where the state says why the steps are so short."""
        times = self.raw_times
        if len(times) <= CRAWL_STEPS or self.crawl_limit <= 0.0:
            return
        first = max(self.crawl_checked, CRAWL_STEPS)
        self.crawl_checked = len(times)
        ends = np.asarray(times[first - CRAWL_STEPS:])
        advance = ends[CRAWL_STEPS:] - ends[:-CRAWL_STEPS]         # over the CRAWL_STEPS steps ending at each
        slow = np.flatnonzero(advance < self.crawl_limit)
        if slow.size:                              # the latest: nearest to what the steps creep towards
            k = first + int(slow[-1])
            self._crawling(times[k], self.raw_states[k], times[k] - times[k - CRAWL_STEPS], times[k] - times[k - 1])

    def _crawling(self, t, y, advance, last):
        """Raise the error of a run whose last CRAWL_STEPS steps crawl, where the state says why (see the
        module's notes); return where it does not."""
        options, run = self.options, self.run
        why = None
        try:
            state = without_work(y, options.work)
            s = self.unpack(np.asarray(state, dtype=float), t)[0]
            why = diagnosis(self.system, self.formulation, s)
        except ClosedLoopErrors:
            pass
        kind = IntegrationError if why is None else SingularConfigurationError
        force = self.force_clause_before(t)
        if why is None and force:
            why = f"{force[2:]}; end the run before t = {t:.6g} s, or mend the force"
        if why is None and run.overflows:
            at, detail = run.overflows[-1]
            why = (f"the right-hand side overflowed at t = {at:.6g} s ({detail}): the motion ran away at rtol = "
                   f"{np.max(options.rtol):g}, atol = {np.max(options.atol):g}; tighten rtol and atol")
        if why is None:
            return
        self.error = kind(
            f"{options.method_name} crawls at t = {t:.6g} s: its last {CRAWL_STEPS} steps advanced "
            f"{advance:.3g} s in all (the last {last:.3g} s), less than {CRAWL_FRACTION:g} of the "
            f"run's {options.t_end - options.t_start:g} s; {why}")
        raise self.error


#: Accelerations at a step end this large (or not finite) are not used for the quintic interpolant.
LARGE = 1e100
ClosedLoopErrors = (SingularConfigurationError, ConvergenceError, ArithmeticError, np.linalg.LinAlgError)


def rows_velocity(rows, size):
    """The rows of the velocities of the coordinates ``rows`` in a state ``y = [positions, velocities]`` of ``size``."""
    return rows + size // 2


def _fold_normals(jacobians, q_index, z_index):
    """``(normals, smallest)``: ``Phi_q^T u`` at K step ends (f x K), u the left singular vector of Phi_z's smallest
    singular value there, and that value relative to |Phi_s| (K,)."""
    Phi = np.moveaxis(jacobians, 2, 0)                       # (K, r, n)
    Phi_z, Phi_q = Phi[:, :, z_index], Phi[:, :, q_index]
    U, sigma, _ = np.linalg.svd(Phi_z)
    u = U[:, :, -1]                                          # (K, r)
    normals = np.einsum("krf,kr->fk", Phi_q, u)
    scale = np.linalg.norm(Phi, axis=(1, 2))
    return normals, sigma[:, -1] / np.where(scale > 0, scale, 1.0)
