"""Shared fixtures: the slider-crank of the paper and a pendulum with a known ODE."""

import math

import numpy as np
import pytest
import sympy as sp

from closedloop import MultibodyModel, System
from closedloop.four_bar import four_bar_model
from closedloop.slider_crank import slider_crank_system


@pytest.fixture(scope="session")
def slider_crank():
    """Table 1, the paper's reading of the data, torque and gas force on."""
    return slider_crank_system()


@pytest.fixture(scope="session")
def conservative_slider_crank():
    """Table 1 with the drive torque and the gas force switched off."""
    return slider_crank_system(torque=False, gas=False)


def pendulum_model():
    """A pendulum in redundant coordinates (theta, x, y): x = l sin theta, y = -l cos theta.

    Its exact motion obeys theta'' = -(g/l) sin theta, which the tests integrate
    independently of the library.
    """
    theta, x, y = sp.symbols("theta x y")
    dtheta, dx, dy = sp.symbols("dtheta dx dy")
    m, l, g = sp.symbols("m l g")
    return MultibodyModel(
        coordinates=(theta, x, y), velocities=(dtheta, dx, dy),
        kinetic_energy=m * (dx**2 + dy**2) / 2, potential_energy=m * g * y,
        constraints=(x - l * sp.sin(theta), y + l * sp.cos(theta)),
        independent=(theta,), parameters=(m, l, g),
    )


@pytest.fixture(scope="session")
def pendulum():
    return System(pendulum_model(), {"m": 2.0, "l": 1.5, "g": 9.81})


def random_states(count, seed):
    """Random (s, s') of the slider-crank, not necessarily consistent."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        s = np.array([rng.uniform(0, 2 * math.pi), rng.uniform(0.6 * math.pi, 1.4 * math.pi), rng.uniform(1, 6)])
        yield s, rng.normal(size=3)


@pytest.fixture(scope="session")
def four_bar():
    """The library's example four-bar linkage (closedloop.four_bar), with a Grashof crank-rocker's data."""
    return System(four_bar_model(), {"l0": 4.0, "l1": 1.0, "l2": 3.5, "l3": 3.0,
                                     "m1": 1.0, "m2": 3.0, "m3": 2.5, "g": 9.81})


#: A parallelogram four-bar (l0 = l2, l1 = l3, Grashof with equality): where all links lie on the
#: x axis (theta1 = 0 or pi) its two assembly branches meet, a change point.
PARALLELOGRAM = {"l0": 3.0, "l1": 1.0, "l2": 3.0, "l3": 1.0, "m1": 1.0, "m2": 2.0, "m3": 1.0, "g": 9.81}
#: Crank angle [rad] and rate [rad/s] of a swing at the bottom, too slow to reach theta1 = 0 or -pi.
SWINGING = (-math.pi / 2, 3.0)


@pytest.fixture(scope="session")
def parallelogram():
    return System(four_bar_model(), PARALLELOGRAM)


@pytest.fixture(scope="session")
def parallelogram_swing(parallelogram):
    """A 5 s swing below the change points, in minimal coordinates: ``(start, result)``."""
    from closedloop import Minimal, consistent_initial_state, simulate

    start = consistent_initial_state(parallelogram, [SWINGING[0]], [SWINGING[1]], [0.0, SWINGING[0]])
    t = np.linspace(0.0, 5.0, 1001)
    return start, simulate(parallelogram, start, 5.0, formulation=Minimal(), method="DOP853",
                           rtol=1e-11, atol=1e-11, t_eval=t)


@pytest.fixture(scope="session")
def quick_benchmark(tmp_path_factory):
    """``closedloop benchmark --quick`` run once: ``(data of the JSON file, printed text, figures folder)``.

    The study behind it (case 2, DOP853 and ode.dop853, rtol 1e-3, 1e-6, 1e-9, one repeat) is
    checked in test_benchmark.py, the command's output in test_cli.py.
    """
    import contextlib
    import io
    import json

    from closedloop.cli import main

    folder = tmp_path_factory.mktemp("benchmark")
    path = folder / "rows.json"
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(["benchmark", "--quick", "--json", str(path), "--figures", str(folder / "figures")])
    assert status == 0, err.getvalue()
    return json.loads(path.read_text()), out.getvalue(), folder / "figures"
