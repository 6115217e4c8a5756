"""Rules written once: the method names, the input checks, the gas law, Newton on f = 0, the minimal ODE."""

import math

import numpy as np
import pytest

import closedloop.methods as methods
from closedloop import simulation
from closedloop.cli import build_parser
from closedloop.formulations.projected import PROJECTABLE_METHODS
from closedloop.simulation import dop853
from closedloop.slider_crank import initial_state
from closedloop.studies import benchmark, baseline


def test_every_list_of_methods_comes_from_one_place():
    assert simulation.SOLVER_METHODS == methods.SOLVER_METHODS
    assert methods.SOLVER_METHODS == ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA", "ode.dop853")
    assert dop853.METHOD == methods.COMPILED_METHOD
    assert list(PROJECTABLE_METHODS) == ["RK23", "RK45", "DOP853"]
    assert baseline.BASELINE_METHODS == methods.SOLVE_IVP_METHODS
    assert benchmark.ALL_METHODS == ("RK45", "DOP853", "Radau", "BDF", "LSODA", "ode.dop853")
    assert benchmark.EXPLICIT_RK == ("RK45", "DOP853")


def test_the_command_line_help_lists_every_method(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["simulate", "--help"])
    help_text = capsys.readouterr().out
    for name in methods.SOLVER_METHODS:
        assert f" {name}," in help_text or f" {name} " in help_text
    assert "ode.dop853" in help_text


def test_the_dynamics_are_a_named_tuple_that_still_unpacks(slider_crank):
    state = initial_state(slider_crank, math.pi / 2, 1.0)
    dynamics = slider_crank.dynamics(0.0, state.s, state.sd)
    M, p1, constraint_values, Phi, gamma = dynamics
    assert dynamics.mass_matrix is M and dynamics.jacobian is Phi
    assert dynamics.constraints is constraint_values and dynamics.jacobian_rate_product is gamma
    assert np.abs(dynamics.constraints).max() < 1e-14            # a consistent state: f = 0 (6)
    # Table 1: the slider's mass m3 = 25 kg is the last diagonal entry of M
    assert dynamics.mass_matrix[2, 2] == 25.0
    many = slider_crank.dynamics_many(0.0, state.s[:, None], state.sd[:, None])
    np.testing.assert_allclose(many.jacobian[:, :, 0], Phi, rtol=1e-14)
