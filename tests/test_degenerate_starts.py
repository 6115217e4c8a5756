"""Starts where the switching rule's first-order rates say nothing: at rest at a dead centre.

At phi = 0 or pi, x_C' = 0 whatever phi' is, and at rest x_C'' = 0 too, on both branches of the
gas force: the contact with the switch x_C' = 0 is degenerate.  The branch is then chosen by each
branch's own motion over PROBE_TIME (closedloop.simulation.switching.probe).  The right answer is
the limit of the starts phi' = +-1e-6 rad/s, where the rates do decide.
"""

import math

import numpy as np
import pytest

from closedloop import simulate
from closedloop.cli import main
from closedloop.formulations import formulation_from_name
from closedloop.slider_crank import classify_motion, initial_state, slider_crank_system

GRID = np.linspace(0.0, 20.0, 201)


@pytest.fixture(scope="module")
def system():
    return slider_crank_system()


def run(system, phi0, dphi0, name="baumgarte", method="DOP853"):
    return simulate(system, initial_state(system, phi0, dphi0), 20.0, formulation=formulation_from_name(name),
                    method=method, rtol=1e-10, atol=1e-10, t_eval=GRID)


@pytest.mark.parametrize("phi0", [0.0, math.pi], ids=["outer dead centre", "inner dead centre"])
def test_a_rest_start_at_a_dead_centre_is_the_limit_of_slow_starts(system, phi0):
    rest = run(system, phi0, 0.0)
    ahead, behind = run(system, phi0, 1e-6), run(system, phi0, -1e-6)
    low, high = np.minimum(ahead.s, behind.s), np.maximum(ahead.s, behind.s)
    assert np.all(low - 1e-9 <= rest.s) and np.all(rest.s <= high + 1e-9)      # between its neighbours
    assert np.max(np.abs(rest.s - ahead.s)) < 1e-5
    other = run(system, phi0, 0.0, name="minimal")                             # another partition agrees
    assert np.max(np.abs(other.s - rest.s)) < 1e-7
    assert classify_motion(rest) == classify_motion(ahead) == "oscillation"


def test_the_closed_form_runs_from_the_inner_dead_centre(system):
    """phi0 = pi, at rest and moving, on the compiled DOP853 too."""
    moving = run(system, math.pi, 1.0, name="closed-form", method="ode.dop853")
    reference = run(system, math.pi, 1.0, name="minimal")
    assert np.max(np.abs(moving.s - reference.s)) < 1e-6
    resting = run(system, math.pi, 0.0, name="closed-form")
    assert np.max(np.abs(resting.s - run(system, math.pi, 0.0, name="minimal").s)) < 1e-6


def test_the_command_line_runs_a_rest_start_by_default(capsys):
    assert main(["simulate", "--phi0", "0", "--dphi0", "0"]) == 0
    assert "motion: oscillation" in capsys.readouterr().out


@pytest.mark.parametrize("phi0", [1e-6, 1e-9])
def test_a_rest_start_a_hair_past_the_dead_centre_answers_as_its_basin_cell_says(system, phi0, capsys):
    """At phi0 = 1e-6 rad the rates decide (x_C'' = 1.9e-6 m/s^2 outward on both branches: the gas force is zero
    at x_C = 5.5 m), and the slider moves out until the crank passes phi = 0 (about 1.8 ms), then back. Every
    segment stopped at t = 0: the event function, exactly zero at the segment's start, was located there, 51
    times, and the run said "chatters"; at 1e-9 a round-off excursion did the same on LSODA. The command now
    answers, as the basin map's cell and its per-cell reference do, and every formulation (and the closed form
    on every method) agrees with the sympy.physics.mechanics baseline, which shares no code with them."""
    from closedloop.formulations import FORMULATION_NAMES
    from closedloop.simulation.options import methods_taking
    from closedloop.studies.baseline import LagrangesBaseline
    from closedloop.studies.basin import basin_map, reference_outcome

    assert main(["simulate", "--phi0", f"{phi0:g}", "--dphi0", "0"]) == 0
    assert "motion: oscillation" in capsys.readouterr().out
    assert basin_map([phi0], [0.0], 20.0).outcome[0, 0] == 0 == reference_outcome(system, phi0, 0.0)
    state = initial_state(system, phi0, 0.0)
    times = np.linspace(0.0, 5.0, 51)
    baseline = LagrangesBaseline().simulate(state, 5.0, method="DOP853", rtol=1e-11, atol=1e-11, t_eval=times)
    runs = [(name, "DOP853") for name in FORMULATION_NAMES] + [
        ("closed-form", method) for method in methods_taking(formulation_from_name("closed-form"))]
    for name, method in runs:
        result = simulate(system, state, 5.0, formulation=formulation_from_name(name), method=method, rtol=1e-9,
                          atol=1e-9, t_eval=times)
        assert np.max(np.abs(result.s - baseline.s)) < 1e-5, (name, method)
        assert any(e.t < 2e-3 and e.action == "crossed" for e in result.switch_events), (name, method)
