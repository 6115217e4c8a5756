"""The compiled DOP853 called directly (closedloop.simulation.dop853_code): the same steps as scipy's ``ode``
used the usual way, a fixed count of evaluations, and the coefficients of scipy's DOP853."""

import contextlib
import math
import subprocess
import sys

import numpy as np
import pytest
from scipy.integrate import DOP853, ode

from closedloop.simulation import dop853_code


def oscillator(t, y):
    return [y[1], -y[0]]


def pendulum(t, y):
    return [y[1], -3.0 * math.sin(y[0]) + 0.2 * math.cos(2.0 * t)]


def blow_up(t, y):                          # y = 1 / (1 - t): infinite at t = 1
    return [y[0] * y[0]]


def stiff(t, y):
    return [-1e6 * (y[0] - math.cos(t))]


def recorded(f, calls):
    def g(t, y):
        calls.append((t, y.copy()))
        return f(t, y)
    return g


def through_ode(f, t0, y0, t_end, solout=None, **options):
    """``(t, y, code, f calls, solout calls)`` of scipy's ode(f).set_integrator("dop853", ...)."""
    calls, steps = [], []
    solver = ode(recorded(f, calls)).set_integrator("dop853", **options)
    if solout is not None:
        solver.set_solout(recorded(solout, steps))
    solver.set_initial_value(y0, t0)
    solver.integrate(t_end)
    return solver.t, solver.y, solver.get_return_code(), calls, steps


def direct(f, t0, y0, t_end, solout=None, **options):
    """The same through :func:`dop853_code.dopri853`."""
    calls, steps = [], []
    t, y, code = dop853_code.dopri853(recorded(f, calls), t0, y0, t_end,
                                      solout=None if solout is None else recorded(solout, steps), **options)
    return t, y, code, calls, steps


def assert_same(a, b):
    t_a, y_a, code_a, calls_a, steps_a = a
    t_b, y_b, code_b, calls_b, steps_b = b
    assert (t_a, code_a) == (t_b, code_b)
    assert np.array_equal(y_a, y_b)                             # to the last bit
    assert [t for t, _ in calls_a] == [t for t, _ in calls_b]  # the same evaluations, in the same order
    assert all(np.array_equal(u, v) for (_, u), (_, v) in zip(calls_a, calls_b))
    assert [t for t, _ in steps_a] == [t for t, _ in steps_b]
    assert all(np.array_equal(u, v) for (_, u), (_, v) in zip(steps_a, steps_b))


def stop_where_negative(t, y):              # a switch: stop the code at the step where y[0] < 0
    return -1 if y[0] < 0.0 else 0


def every_step(t, y):
    return 0


@pytest.mark.parametrize("f, y0, t_end, solout, options, code", [
    (oscillator, [1.0, 0.0], 10.0, stop_where_negative, dict(rtol=1e-10, atol=1e-10, nsteps=1000), 2),
    (pendulum, [1.0, 0.0], 20.0, every_step, dict(rtol=1e-9, atol=1e-9, nsteps=100_000), 1),
    (pendulum, [1.0, 0.0], 5.0, every_step, dict(rtol=1e-6, atol=1e-8, nsteps=1000, first_step=1e-3, max_step=0.05), 1),
    (oscillator, [1.0, 0.0], 100.0, every_step, dict(rtol=1e-8, atol=1e-8, nsteps=5), -2),
    (blow_up, [1.0], 2.0, every_step, dict(rtol=1e-8, atol=1e-8, nsteps=100_000), -3),
    (stiff, [1.0], 100.0, every_step, dict(rtol=1e-8, atol=1e-8, nsteps=1_000_000), -4),
], ids=["switch", "outputs", "first and max step", "nsteps", "step too small", "stiff"])
def test_the_direct_call_takes_the_steps_of_scipy_s_ode(f, y0, t_end, solout, options, code):
    with pytest.warns(UserWarning) if code < 0 else contextlib.nullcontext():   # ode also warns of a failure
        expected = through_ode(f, 0.0, y0, t_end, solout, **options)
    got = direct(f, 0.0, y0, t_end, solout, **options)
    assert got[2] == code
    assert_same(got, expected)
    if "first_step" in options:                                # the options arrive
        step_ends = [t for t, _ in got[4]]
        assert step_ends[1] - step_ends[0] == options["first_step"]
        assert max(np.diff(step_ends)) <= options["max_step"] * (1 + 1e-12)   # round-off of the differences
        assert len(step_ends) > 5 / options["max_step"]            # the steps max_step forces (t_end = 5)


def test_without_solout_the_code_evaluates_f_as_with_one():
    # scipy's C code reads an uninitialised flag when it has no solout, and then may evaluate f at the
    # start of every step twice (depending on the stack); the direct call always gives it one.
    options = dict(rtol=1e-9, atol=1e-9, nsteps=100_000)
    bare = direct(pendulum, 0.0, [1.0, 0.0], 20.0, **options)
    watched = through_ode(pendulum, 0.0, [1.0, 0.0], 20.0, every_step, **options)
    times = [t for t, _ in bare[3]]
    assert times == [t for t, _ in watched[3]] and len(times) > 100
    # no step start evaluated twice (the last call of a step, at its end, again as the next one's first)
    assert not any(ta == tb and np.array_equal(ya, yb) for (ta, ya), (tb, yb) in zip(bare[3], bare[3][1:]))
    assert bare[0] == watched[0] == 20.0 and np.array_equal(bare[1], watched[1])


def test_the_input_array_is_left_alone():
    y0 = np.array([1.0, 0.0])
    t, y, code = dop853_code.dopri853(oscillator, 0.0, y0, 1.0, rtol=1e-10, atol=1e-10, nsteps=1000)
    assert code == 1 and list(y0) == [1.0, 0.0]
    assert abs(y[0] - math.cos(1.0)) < 1e-9


def test_the_coefficients_are_those_of_scipy_s_dop853():
    c = dop853_code.coefficients()
    assert c.stages == DOP853.n_stages == 12
    assert c.A.shape == (12, 12) and c.A_EXTRA.shape == (3, 16) and c.D.shape == (4, 16)
    assert np.array_equal(c.A, DOP853.A) and np.array_equal(c.B, DOP853.B) and np.array_equal(c.C, DOP853.C)
    assert np.array_equal(c.D, DOP853.D)
    assert np.array_equal(c.A_EXTRA, DOP853.A_EXTRA) and np.array_equal(c.C_EXTRA, DOP853.C_EXTRA)
    # the pair's order conditions as a check that these are DOP853's: sum b = 1, sum b c = 1/2, sum b c^7 = 1/8
    assert sum(c.B) == pytest.approx(1.0, abs=1e-14)
    assert c.B @ c.C == pytest.approx(0.5, abs=1e-14) and c.B @ c.C ** 7 == pytest.approx(1 / 8, abs=1e-14)
    assert np.allclose(c.A.sum(axis=1), c.C, atol=1e-14)      # each stage's row sums to its node


FIRST_USE_PROBE = """
import sys
import closedloop
from closedloop.simulation import dop853_code
before = "scipy.integrate" in sys.modules
t, y, code = dop853_code.dopri853(lambda t, y: [y[1], -y[0]], 0.0, [1.0, 0.0], 1.0, rtol=1e-10, atol=1e-10,
                                  nsteps=1000)
print(before, "scipy.integrate" in sys.modules, code, abs(y[0] - 0.5403023058681398) < 1e-9)
"""


def test_scipy_integrate_is_imported_at_the_first_call_only():
    """``import closedloop`` imports no scipy subpackage; the first call of the code imports scipy.integrate."""
    done = subprocess.run([sys.executable, "-c", FIRST_USE_PROBE], capture_output=True, text=True, timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["False", "True", "1", "True"]
