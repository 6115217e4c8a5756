"""The gas force of section 4: the printed law and its constants, its branches, its sign in each reading,
and the numeric code generated from the one sympy expression (closedloop.slider_crank_gas_law)."""

import math

import numpy as np
import pytest
import sympy as sp

import closedloop.slider_crank_gas_law as gas_law
from closedloop.slider_crank import GasForce, gas_force, get_reading, slider_crank_system


def test_the_gas_law_holds_the_constants_the_paper_prints():
    assert gas_law.PRINTED_COEFFICIENTS == (282.857, 62.857, 110.0)
    assert gas_law.STROKE == (1.5, 5.5) and gas_law.CHANGE_POINT == 5.0
    x = gas_law.POSITION
    a, b, c = gas_law.COEFFICIENTS
    assert sp.simplify(gas_law.INNER_LAW - (-a / (6 - x) + b)) == 0
    outer = gas_law.branch_expression(True, x, (282.857, 62.857, 110.0))
    assert sp.simplify(outer - (-110 * (1 - sp.sin(2 * sp.pi * (x - sp.Rational(21, 4)))))) == 0
    # the printed law is continuous where it changes formula: -282.857 + 62.857 = -220 = -110 (1 + 1)
    inner_value = gas_law.branch_expression(False, x, (282.857, 62.857, 110.0)).subs(x, 5)
    assert float(inner_value) == pytest.approx(-220.0, abs=1e-12)
    assert float(outer.subs(x, 5)) == pytest.approx(-220.0, abs=1e-12)


@pytest.mark.parametrize("reading", ["decimal-opposing", "thousands-as-printed"])
def test_the_generated_numeric_gas_laws_equal_the_sympy_expression(reading):
    reading = get_reading(reading)
    force = GasForce(reading)
    x_symbol = gas_law.POSITION
    positions = np.array([1.5, 2.0, 3.3, 4.75, 5.0, 5.1, 5.25, 5.4, 5.5])
    for beyond in (False, True):
        expression = sp.Float(reading.force_sign) * gas_law.branch_expression(beyond, x_symbol,
                                                                             reading.gas_coefficients)
        exact = np.array([float(expression.subs(x_symbol, value).evalf(30)) for value in positions])
        one = np.array([force.components(0.0, [0.0, 0.0, value], [0.0, 0.0, 1.0], (True, beyond))[2]
                        for value in positions])
        mode = np.array([np.ones(positions.size, bool), np.full(positions.size, beyond)])
        many = force.many(0.0, np.vstack((0 * positions, 0 * positions, positions)), None, mode)[2]
        np.testing.assert_allclose(one, exact, rtol=4e-16, atol=0)
        np.testing.assert_array_equal(many, one)
    # the plain function agrees, chooses its branch by x_C, and is zero moving in or off the stroke
    printed = gas_force(positions, 1.0, reading)
    assert printed[0] == pytest.approx(reading.gas_coefficients[1] - reading.gas_coefficients[0] / 4.5, rel=1e-15)
    assert printed[-1] == pytest.approx(-reading.gas_coefficients[2] * (1 - math.sin(0.5 * math.pi)), abs=1e-9)
    assert gas_force(3.0, -0.1, reading) == 0.0 and gas_force(5.6, 1.0, reading) == 0.0



def test_gas_force_matches_the_printed_formula_and_is_continuous():
    # starts at zero up to the print's rounding: 282.857/4.5 - 62.857 = -1.1e-4 N (1980/7 and 440/7 rounded)
    assert gas_force(1.5, 1.0) == pytest.approx(-282.857 / 4.5 + 62.857, abs=1e-12)
    assert abs(gas_force(1.5, 1.0)) < 2e-4
    below, above = gas_force(5.0 - 1e-12, 1.0), gas_force(5.0 + 1e-12, 1.0)
    assert below == pytest.approx(-220.0, abs=1e-6) and above == pytest.approx(-220.0, abs=1e-6)
    assert gas_force(5.5, 1.0) == pytest.approx(0.0, abs=1e-12)
    assert gas_force(3.0, 1.0) == pytest.approx(-282.857 / 3.0 + 62.857)
    assert gas_force(3.0, 0.0) == 0.0 and gas_force(3.0, -1.0) == 0.0      # only for x_C' > 0
    assert gas_force(3.0, 1.0, "thousands-opposing") == pytest.approx(1000 * gas_force(3.0, 1.0))


def test_gas_force_enters_with_the_readings_sign(slider_crank):
    s, sd = np.array([2.0, 3.0, 3.0]), np.array([0.0, 0.0, 1.0])
    opposing = slider_crank.force(0.0, s, sd, (True, False))
    printed = slider_crank_system(reading="decimal-as-printed").force(0.0, s, sd, (True, False))
    assert opposing[2] == pytest.approx(gas_force(3.0, 1.0)) and opposing[2] < 0
    assert printed[2] == pytest.approx(-gas_force(3.0, 1.0))
    assert opposing[0] == opposing[1] == 0.0


def test_switching_values_are_the_switching_functions_as_floats_bit_for_bit():
    # The compiled runner watches switching_values after every step; it must give exactly the numbers of
    # switching_functions (the rate of a switch decision and the located crossing depend on them).
    from closedloop.forces import SwitchedForce

    force = GasForce()
    rng = np.random.default_rng(3)
    for _ in range(50):
        s, sd = rng.normal(scale=3.0, size=3), rng.normal(scale=10.0, size=3)
        s[2] = 5.0 + rng.normal(scale=1e-9)          # near the switch x_C = 5, where the subtraction cancels
        values = force.switching_values(0.3, s, sd)
        assert all(type(v) is float for v in values)
        assert values == force.switching_functions(0.3, s, sd).tolist()
        assert values == SwitchedForce.switching_values(force, 0.3, s, sd)   # the base class's conversion
