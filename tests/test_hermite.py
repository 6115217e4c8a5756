"""The cubic Hermite interpolant's roots, written once (closedloop.hermite)."""

import numpy as np

from closedloop.hermite import first_root, slopes, turning_point, values


def test_one_state_and_many_give_the_same_earliest_root():
    """Numbers take a path without arrays (one event at a time); it must agree with the K-state path."""
    rng = np.random.default_rng(2018)
    g0 = rng.normal(size=2000)
    g1 = -np.sign(g0) * np.abs(rng.normal(size=2000))
    d0, d1 = 3 * rng.normal(size=2000), 3 * rng.normal(size=2000)
    many = first_root(g0, g1, d0, d1)
    one = np.array([first_root(*map(float, row)) for row in zip(g0, g1, d0, d1)])
    assert np.array_equal(many, one)
    assert np.max(np.abs(values(many, g0, g1, d0, d1))) < 1e-11
    # the earliest at the resolution of the eight samples: none before the root's part changes sign
    for u, a, b, c, d in zip(many, g0, g1, d0, d1):
        samples = np.arange(1, 9) / 8
        before = samples[samples < np.floor(u * 8) / 8 + 1e-15]
        assert np.all(np.sign(values(before, a, b, c, d)) == np.sign(a))


def test_the_turning_point_is_where_the_slope_vanishes():
    # p(u) = u (1 - u) has values 0, 0 and slopes 1, -1: it turns at u = 1/2
    assert turning_point(0.0, 0.0, 1.0, -1.0) == 0.5
    rng = np.random.default_rng(7)
    for _ in range(200):
        g0, g1, d0 = rng.normal(size=3)
        d1 = -np.sign(d0) * abs(rng.normal())
        u = turning_point(g0, g1, d0, d1)
        assert 0.0 <= u <= 1.0 and abs(slopes(u, g0, g1, d0, d1)) < 1e-9 * (1 + abs(d0) + abs(d1) + abs(g1 - g0))


def test_the_earliest_of_three_zeros_is_found():
    # A cubic is its own Hermite interpolant: (u - 0.2)(u - 0.5)(u - 0.9) has three zeros in [0, 1]
    def g(u):
        return (u - 0.2) * (u - 0.5) * (u - 0.9)

    def slope(u):
        return (u - 0.5) * (u - 0.9) + (u - 0.2) * (u - 0.9) + (u - 0.2) * (u - 0.5)

    assert abs(first_root(g(0.0), g(1.0), slope(0.0), slope(1.0)) - 0.2) < 1e-12
    assert abs(first_root(-g(0.0), -g(1.0), -slope(0.0), -slope(1.0)) - 0.2) < 1e-12
    assert first_root(0.0, 1.0, 5.0, 1.0) == 0.0                        # already on the surface
    assert abs(first_root(-1.0, 1.0, 2.0, 2.0) - 0.5) < 1e-12            # a straight line


def test_the_quintic_interpolant_reproduces_every_polynomial_of_degree_five():
    """Values, slopes and second derivatives at both ends fix a quintic: random ones are reproduced to round-off,
    with their slopes, on a step of any length h (slopes times h, second derivatives times h^2)."""
    from closedloop.hermite import quintic_slopes, quintic_values

    rng = np.random.default_rng(34)
    u = np.linspace(0.0, 1.0, 41)
    for _ in range(100):
        p = np.polynomial.Polynomial(rng.normal(size=6))
        h = 10.0 ** rng.uniform(-3, 1)
        t = h * u                                          # the polynomial in time, over [0, h]
        ends = (p(0.0), p(h), h * p.deriv()(0.0), h * p.deriv()(h), h * h * p.deriv(2)(0.0), h * h * p.deriv(2)(h))
        scale = np.max(np.abs(p(t))) + 1.0
        assert np.max(np.abs(quintic_values(u, *ends) - p(t))) < 1e-12 * scale
        assert np.max(np.abs(quintic_slopes(u, *ends) / h - p.deriv()(t))) < 1e-11 * (scale / h + np.max(
            np.abs(p.deriv()(t))))
