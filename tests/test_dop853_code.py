"""The compiled DOP853 called directly (closedloop.simulation.dop853_code): the same steps as scipy's ``ode``,
loaded without scipy.integrate, and the ordinary import when loading fails."""

import contextlib
import math
import os
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
    n = c.N_STAGES
    assert n == DOP853.n_stages == 12
    assert np.array_equal(c.A[:n, :n], DOP853.A) and np.array_equal(c.B, DOP853.B)
    assert np.array_equal(c.C[:n], DOP853.C) and np.array_equal(c.D, DOP853.D)
    assert np.array_equal(c.A[n + 1:], DOP853.A_EXTRA) and np.array_equal(c.C[n + 1:], DOP853.C_EXTRA)


def test_if_loading_the_files_fails_the_ordinary_import_serves(monkeypatch):
    expected = dop853_code.dopri853(pendulum, 0.0, [1.0, 0.0], 3.0, rtol=1e-9, atol=1e-9, nsteps=1000)

    def broken():
        raise ImportError("another layout of scipy")

    monkeypatch.setattr(dop853_code, "_loaded", {})
    monkeypatch.delitem(sys.modules, dop853_code.EXTENSION_NAME)
    monkeypatch.delitem(sys.modules, dop853_code.COEFFICIENTS_NAME, raising=False)
    monkeypatch.setattr(dop853_code, "_load_extension", broken)
    monkeypatch.setattr(dop853_code, "_load_coefficients", broken)
    module = dop853_code.extension()
    assert module is sys.modules[dop853_code.EXTENSION_NAME]    # imported again, the ordinary way
    assert module.__name__ == "scipy.integrate._dop"
    got = dop853_code.dopri853(pendulum, 0.0, [1.0, 0.0], 3.0, rtol=1e-9, atol=1e-9, nsteps=1000)
    assert got[0] == expected[0] and got[2] == expected[2] == 1 and np.array_equal(got[1], expected[1])
    assert dop853_code.coefficients() is sys.modules[dop853_code.COEFFICIENTS_NAME]
    assert np.array_equal(dop853_code.coefficients().D, DOP853.D)


LOADER_PROBE = """
import sys
from closedloop.simulation import dop853_code
extension, coefficients = dop853_code.extension(), dop853_code.coefficients()
print(extension.__file__.startswith(sys.argv[1]), sys.modules["scipy.integrate._dop"] is extension,
      any(name in sys.modules for name in ("scipy.integrate", "scipy.integrate._ivp", "scipy.optimize")),
      coefficients.N_STAGES)
import scipy.integrate
from scipy.integrate import _ode
print(_ode._dop is extension)
"""


def test_the_extension_is_loaded_from_scipy_s_folder_without_scipy_integrate():
    import scipy

    folder = os.path.join(os.path.dirname(scipy.__file__), "integrate", "_dop.")
    done = subprocess.run([sys.executable, "-c", LOADER_PROBE, folder], capture_output=True, text=True,
                          timeout=120)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split() == ["True", "True", "False", "12", "True"]   # and scipy's ode uses that module


_DENSE_OUTPUT_CALL = """
import sys
import numpy as np
from closedloop.simulation import dop853_code
n = 2
work = np.zeros(11 * n + 8 * n + 21)       # room for the 8 n coefficients of the dense output
work[1], work[2], work[3] = dop853_code.SAFETY, dop853_code.DFACTOR, dop853_code.IFACTOR
iwork = np.zeros(21 + n, dtype=np.int32)
iwork[4] = n                                # dense output of every component
iout = int(sys.argv[1])                     # 2: dense output; 1: the same call without it
dop853_code.extension().dopri853(lambda t, y: [y[1], -y[0]], 0.0, np.array([1.0, 0.0]), 10.0, 1e-8, 1e-10,
                                 lambda t, y: 0, iout, work, iwork, 100000, -1, ())
print("returned")
"""


def test_the_codes_own_dense_output_still_crashes():
    """Why :mod:`closedloop.simulation.dop853` interpolates itself (its module docstring): scipy's dp86co with
    iout = 2 moves its pointer nfcn instead of the count, and the process dies.  When this fails, a scipy
    has fixed it, and the code's own coefficients (read in ``solout`` from the work array) are the faster route
    to the outputs; the docstring is then stale."""
    def call(iout):
        return subprocess.run([sys.executable, "-c", _DENSE_OUTPUT_CALL, str(iout)], capture_output=True, text=True,
                              env={**os.environ, "PYTHONFAULTHANDLER": ""}, timeout=120)

    control = call(1)                       # the same arrays and call without dense output: it returns
    assert control.returncode == 0 and "returned" in control.stdout, control.stderr[-500:]
    done = call(2)
    assert done.returncode < 0 and "returned" not in done.stdout, done.stderr[-500:]   # killed by a signal
