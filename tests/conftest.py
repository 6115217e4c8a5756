"""Shared fixtures: the slider-crank of the paper and a pendulum with a known ODE."""

import math

import numpy as np
import pytest
import sympy as sp

from closedloop import MultibodyModel, System
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


def four_bar_model():
    """A planar four-bar linkage in the vertical plane: crank theta1, coupler theta2, rocker theta3.

    Uniform bars of lengths l1, l2, l3 pinned at O = (0, 0) and D = (l0, 0); the loop
    closes with two constraints. Written only to show a new mechanism is a few lines.
    """
    th1, th2, th3 = sp.symbols("theta1 theta2 theta3")
    w1, w2, w3 = sp.symbols("dtheta1 dtheta2 dtheta3")
    l0, l1, l2, l3, m1, m2, m3, g = sp.symbols("l0 l1 l2 l3 m1 m2 m3 g")
    # centres of mass and their velocities
    x2 = l1 * sp.cos(th1) + l2 / 2 * sp.cos(th2)
    y2 = l1 * sp.sin(th1) + l2 / 2 * sp.sin(th2)
    v2_sq = sp.diff(x2, th1) * w1 + sp.diff(x2, th2) * w2
    v2_sq = v2_sq**2 + (sp.diff(y2, th1) * w1 + sp.diff(y2, th2) * w2) ** 2
    T = (m1 * l1**2 / 6 * w1**2 + m2 * v2_sq / 2 + m2 * l2**2 / 24 * w2**2 + m3 * l3**2 / 6 * w3**2)
    Pi = g * (m1 * l1 / 2 * sp.sin(th1) + m2 * y2 + m3 * l3 / 2 * sp.sin(th3))
    loop = (l1 * sp.cos(th1) + l2 * sp.cos(th2) - l0 - l3 * sp.cos(th3),
            l1 * sp.sin(th1) + l2 * sp.sin(th2) - l3 * sp.sin(th3))
    return MultibodyModel(coordinates=(th1, th2, th3), velocities=(w1, w2, w3), kinetic_energy=T,
                          potential_energy=Pi, constraints=loop, independent=(th1,),
                          parameters=(l0, l1, l2, l3, m1, m2, m3, g))


@pytest.fixture(scope="session")
def four_bar():
    return System(four_bar_model(), {"l0": 4.0, "l1": 1.0, "l2": 3.5, "l3": 3.0,
                                     "m1": 1.0, "m2": 3.0, "m3": 2.5, "g": 9.81})
