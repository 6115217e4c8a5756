"""The basin map: the batch integrator against simulate(), the boundary, the sticking rule, workers, and
the batch integrator on a system other than the slider-crank.

The four cases' outcomes and sticking times by the batch integrator are checked with simulate's in
test_paper_cases.py; the basin command in test_cli.py; the map figure in test_plotting.py.

The four-bar of ``conftest.four_bar`` is a Grashof crank-rocker (l1 + l0 <= l2 + l3, the crank
shortest): its crank can turn full circle without meeting a change point.  No force drives it,
so each start either swings for ever or turns; the reference for each cell is one adaptive
:func:`closedloop.simulate` run (minimal coordinates, DOP853, rtol = atol = 1e-10).
"""

import math

import numpy as np
import pytest

from closedloop import InputError, Minimal, consistent_initial_state, simulate
from closedloop.four_bar import parameter_values
from closedloop.simulation import switching
from closedloop.simulation.batch import integrate_batch
from closedloop.simulation.batch_model import BatchModel
from closedloop.slider_crank import CASES, MOTIONS, GasForce, initial_state
from closedloop.studies.basin import (basin_map, boundary_cells, compare_outcomes, grid_values, integrate_outcomes,
                                      reference_outcome, reference_outcomes)

#: A 12 x 10 grid that cuts across the basin boundary (see the chapter's map).
SMALL_PHI0 = grid_values(0.5 * math.pi, 1.5 * math.pi, 12)
SMALL_DPHI0 = grid_values(0.5, 2.0, 10)


@pytest.fixture(scope="module")
def small_map():
    return basin_map(SMALL_PHI0, SMALL_DPHI0, 20.0)


@pytest.fixture(scope="module")
def small_reference():
    return reference_outcomes(SMALL_PHI0, SMALL_DPHI0, 20.0)


def test_small_grid_has_both_outcomes_and_a_boundary(small_reference):
    """The agreement test below is only worth something if the grid crosses the boundary."""
    assert 0.2 < np.mean(small_reference == 1) < 0.8
    assert np.sum(boundary_cells(small_reference)) >= 10


def test_map_agrees_with_per_trajectory_simulate_off_the_boundary(small_map, small_reference):
    """At least 99.5 % agreement: on 120 cells that allows no disagreement except on the boundary."""
    agreement = compare_outcomes(small_map.outcome, small_reference)
    assert agreement.cells == 120
    assert all(agreement.on_boundary), agreement.disagreeing
    assert len(agreement.disagreeing) <= 1


def test_batch_final_state_matches_simulate_to_the_step_error(slider_crank):
    """Case 3 swings for 20 s through many switches: the batch and simulate (rtol 1e-10) end together."""
    case = CASES[3]
    batch = integrate_outcomes(slider_crank, [case.phi0], [case.dphi0], 20.0)
    result = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 20.0,
                      formulation=Minimal(), method="DOP853", rtol=1e-10, atol=1e-10)
    assert batch.switch_events[0] >= 5
    assert batch.final_phi[0] == pytest.approx(result.coordinate("phi")[-1], abs=1e-6)
    assert batch.final_dphi[0] == pytest.approx(result.velocity("phi")[-1], abs=1e-6)
    assert batch.excursion[0] == pytest.approx(np.max(np.abs(result.coordinate("phi") - case.phi0)), abs=1e-4)
    assert batch.max_constraint_error < 1e-12


def test_batch_releases_a_stuck_slider_where_simulate_does():
    """A torque ripple of 60 N m frees the slider: stuck at t = 0, released, stuck again, as simulate finds."""
    from closedloop.slider_crank import OMEGA, SliderCrankParameters, SliderCrankSystem, get_reading

    reading, parameters = get_reading("decimal-opposing"), SliderCrankParameters()
    values = dict(parameters.as_dict(), torque_mean=reading.torque_mean, torque_ripple=60.0, omega=OMEGA)
    system = SliderCrankSystem(parameters, reading, values, GasForce(reading))
    phi0 = 1.34
    result = simulate(system, initial_state(system, phi0, 0.0), 4.0, formulation=Minimal(), method="DOP853",
                      rtol=1e-10, atol=1e-10)
    (start, end), *later = result.sticking_intervals
    assert start == 0.0 and len(later) >= 2
    batch = integrate_outcomes(system, [phi0], [0.0], 4.0, finish_early=False)
    assert batch.stuck_at[0] == 0.0
    # one release rule (closedloop.simulation.switching.locate_release) for both: the same root
    assert batch.released_at[0] == pytest.approx(end, abs=1e-11)
    assert batch.final_phi[0] == pytest.approx(result.coordinate("phi")[-1], abs=1e-6)
    assert batch.final_dphi[0] == result.velocity("phi")[-1] == 0.0     # stuck again at the end


def test_boundary_cells_are_those_with_a_neighbour_of_the_other_outcome():
    outcome = np.array([[0, 0, 0, 0],
                        [0, 0, 1, 1],
                        [0, -1, 1, 1]])
    expected = np.array([[0, 0, 1, 1],
                         [0, 1, 1, 1],
                         [0, 0, 0, 0]], bool)       # -1 (not computed) is no one's neighbour
    np.testing.assert_array_equal(boundary_cells(outcome), expected)
    agreement = compare_outcomes(np.array([[0, 1], [1, 1]]), np.array([[0, 0], [1, 1]]))
    assert agreement.disagreeing == [(0, 1)] and agreement.on_boundary == [True]
    assert agreement.fraction == 0.75


def test_two_workers_give_the_same_map_as_one():
    phi0, dphi0 = grid_values(0.0, 2 * math.pi, 8), grid_values(0.0, 3.0, 5)
    one = basin_map(phi0, dphi0, 3.0)
    two = basin_map(phi0, dphi0, 3.0, workers=2)
    np.testing.assert_array_equal(one.outcome, two.outcome)
    np.testing.assert_allclose(one.excursion, two.excursion, rtol=1e-12)
    assert two.workers == 2 and one.outcome.shape == (5, 8)


def test_a_map_keeps_its_cells_motions_from_the_same_integration(slider_crank):
    """basin_map(..., motions=h): phi(t) of every cell, sampled every h s, with the outcomes of the plain map."""
    phi0, dphi0 = grid_values(0.0, 2 * math.pi, 8), grid_values(0.0, 3.0, 5)
    plain = basin_map(phi0, dphi0, 8.0)
    kept = basin_map(phi0, dphi0, 8.0, motions=0.5, workers=2)
    motions = kept.motions
    assert plain.motions is None and 0 < plain.fraction_rotating < 1
    np.testing.assert_array_equal(kept.outcome, plain.outcome)
    swing = plain.outcome == 0
    np.testing.assert_allclose(kept.excursion[swing], plain.excursion[swing], rtol=0, atol=1e-12)
    assert np.all(kept.excursion[~swing] > plain.excursion[~swing])      # rotations kept turning to 8 s
    np.testing.assert_array_equal(motions.times, np.arange(17) * 0.5)
    np.testing.assert_array_equal(motions.phi[..., 0], np.broadcast_to(phi0, (5, 8)))
    # each sample is the batch's phi at that time: the last one its final state, an inner one simulate's
    grid_phi, grid_dphi = np.meshgrid(phi0, dphi0)
    batch = integrate_outcomes(slider_crank, grid_phi.ravel(), grid_dphi.ravel(), 8.0, finish_early=False)
    np.testing.assert_allclose(motions.phi[..., -1].ravel(), batch.final_phi, rtol=0, atol=1e-9)
    row, column = 2, 4                                       # phi0 = pi, dphi0 = 1.2 rad/s
    run = simulate(slider_crank, initial_state(slider_crank, phi0[column], dphi0[row]), 8.0, formulation=Minimal(),
                   method="DOP853", rtol=1e-10, atol=1e-10, t_eval=motions.times)
    np.testing.assert_allclose(motions.phi[row, column], run.coordinate("phi"), rtol=0, atol=1e-5)
    with pytest.raises(InputError, match="motions"):
        basin_map(phi0, dphi0, 8.0, motions=9.0)
    with pytest.raises(InputError, match="motions"):
        basin_map(phi0, dphi0, 8.0, motions=-0.5)


@pytest.mark.parametrize("phi0", [0.0, math.pi], ids=["outer dead centre", "inner dead centre"])
def test_where_both_rates_vanish_simulate_and_the_map_decide_through_the_same_probe(slider_crank, phi0, monkeypatch):
    """At rest at a dead centre x_C' = 0 and x_C'' = 0 on both branches of the gas force: the rates of the switch
    x_C' = 0 say nothing, and simulate's Run and the batch integrator both ask the rule's probe (each branch's own
    motion over PROBE_TIME).  They get the same probed rates (their accelerations differ by round-off only), so
    the same branch, and the cell ends where simulate's run ends."""
    start = initial_state(slider_crank, phi0, 0.0)
    model = BatchModel(slider_crank)
    s, sd = start.s[:, None], start.sd[:, None]
    point = model.evaluate(0.0, s[model.q], sd[model.q], s[model.z], np.zeros((2, 1), bool))
    off, on = model.side_rates(0.0, s, point["sd"], s[model.q], sd[model.q], s[model.z], np.zeros((2, 1), bool), 0)
    assert switching.uninformative(off, on, switching.state_scale(s, sd))[0]

    calls = []
    probe_rates = switching.probe_rates

    def spy(h, accelerations, t, s, sd, i):
        rates = probe_rates(h, accelerations, t, s, sd, i)
        calls.append((i, float(np.ravel(t)[0]), float(np.ravel(rates[0])[0]), float(np.ravel(rates[1])[0])))
        return rates

    monkeypatch.setattr(switching, "probe_rates", spy)
    result = simulate(slider_crank, start, 3.0, formulation=Minimal(), method="DOP853", rtol=1e-10, atol=1e-10)
    by_simulate, calls[:] = calls[:], []
    batch = integrate_outcomes(slider_crank, [phi0], [0.0], 3.0, finish_early=False)
    by_map = calls[:]
    basin_map([phi0], [0.0], 3.0)
    assert calls[len(by_map):] == by_map                     # the map is the batch integrator's cell
    (switch, t, probed_off, probed_on), = by_simulate[:1]
    assert (switch, t) == (0, 0.0) == by_map[0][:2]
    assert abs(probed_off) > 1e-8 and abs(probed_on) > 1e-8                  # the probe does say something
    np.testing.assert_allclose(by_map[0][2:], (probed_off, probed_on), rtol=1e-6)
    assert switching.decide(probed_off, probed_on, False) == switching.decide(*by_map[0][2:], False)
    assert batch.final_phi[0] == pytest.approx(result.coordinate("phi")[-1], abs=1e-6)
    assert batch.final_dphi[0] == pytest.approx(result.velocity("phi")[-1], abs=1e-6)


def test_no_module_outside_the_simulation_package_reaches_the_switching_rule():
    """Switches, sticks and releases are decided in closedloop.simulation alone: no other module of the package
    imports its switching rule (the basin study included), so none can decide one its own way."""
    import ast
    from pathlib import Path

    import closedloop

    root = Path(closedloop.__file__).resolve().parent
    reaching = []
    for path in sorted(root.rglob("*.py")):
        if path.parent.name == "simulation":
            continue
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
            names = []
            if isinstance(node, ast.ImportFrom):
                names = [node.module or ""] + [f"{node.module}.{alias.name}" for alias in node.names]
            elif isinstance(node, ast.Import):
                names = [alias.name for alias in node.names]
            if any(name.split(".")[-1] == "switching" or ".switching." in name for name in names):
                reaching.append(f"{path.relative_to(root)}:{node.lineno}")
    assert not reaching, reaching
    assert (root / "studies" / "basin.py").exists()            # the scan reads the study


# -- any one-degree-of-freedom system: the four-bar -------------------------------------------
#: A 6 x 6 grid of the four-bar's crank angles [rad] and rates [rad/s]; both outcomes occur on it.
ANGLES = grid_values(0.0, 2.0 * math.pi, 6)
RATES = grid_values(0.0, 12.0, 6)
T_END = 5.0
FULL_TURN = 2.0 * math.pi


def open_branch_start(system, theta1, rate):
    """A consistent start with the coupler above the line AD (elbow up), from the triangle A-B-D.

    theta2 = angle(D - A) + alpha with cos alpha = (l2^2 + |AD|^2 - l3^2) / (2 l2 |AD|), and
    theta3 = angle(B - D); Newton and (9) then make it exact.
    """
    lengths = parameter_values(system)
    a = lengths["l1"] * np.array([math.cos(theta1), math.sin(theta1)])
    to_d = np.array([lengths["l0"], 0.0]) - a
    distance = math.hypot(*to_d)
    alpha = math.acos((lengths["l2"] ** 2 + distance ** 2 - lengths["l3"] ** 2) / (2 * lengths["l2"] * distance))
    theta2 = math.atan2(to_d[1], to_d[0]) + alpha
    b = a + lengths["l2"] * np.array([math.cos(theta2), math.sin(theta2)])
    theta3 = math.atan2(b[1], b[0] - lengths["l0"])
    return consistent_initial_state(system, [theta1], [rate], [theta2, theta3])


@pytest.fixture(scope="module")
def cells():
    angles, rates = np.meshgrid(ANGLES, RATES)
    return angles.ravel(), rates.ravel()


@pytest.fixture(scope="module")
def batch(four_bar, cells):
    """The engine's batch integrator alone: nothing of the slider-crank's module takes part."""
    return integrate_batch(four_bar, *cells, T_END, initial_state=open_branch_start)


@pytest.fixture(scope="module")
def reference_excursions(four_bar, cells):
    """max |theta1(t) - theta1(0)| of one simulate() run per cell, stopped once past 2 pi + 0.5 rad."""
    limit = FULL_TURN + 0.5
    excursions = []
    for angle, rate in zip(*cells):
        result = simulate(four_bar, open_branch_start(four_bar, angle, rate), T_END, formulation=Minimal(),
                          method="DOP853", rtol=1e-10, atol=1e-10,
                          stop_when=lambda t, s, sd: abs(s[0] - angle) - limit)
        excursions.append(np.max(np.abs(result.coordinate("theta1") - angle)))
    return np.array(excursions)


def test_the_grid_holds_both_outcomes_away_from_the_boundary(reference_excursions):
    """The agreement below is only worth something if both outcomes occur and no cell is a near miss."""
    rotating = reference_excursions >= FULL_TURN
    assert 0.2 < np.mean(rotating) < 0.8
    assert np.min(np.abs(reference_excursions - FULL_TURN)) > 0.3


def test_every_four_bar_cell_gets_the_outcome_of_its_own_simulate_run(batch, reference_excursions):
    expected = (reference_excursions >= FULL_TURN).astype(int)
    np.testing.assert_array_equal(batch.codes, expected)
    swinging = expected == 0
    # both see a swing's peak at their step ends only (0.02 s apart in the batch), so a little short of it
    np.testing.assert_allclose(batch.excursion[swinging], reference_excursions[swinging], rtol=0, atol=0.01)
    assert np.all(batch.excursion[~swinging] >= FULL_TURN)
    assert np.all(batch.decided_at[~swinging] < T_END) and np.all(np.isnan(batch.decided_at[swinging]))
    assert batch.max_constraint_error < 1e-10 and batch.switch_events.sum() == 0      # no switched force


def test_the_per_cell_reference_classifies_the_four_bar_too(four_bar, batch, cells):
    """reference_outcome follows the independent coordinate, whatever its name (theta1 here)."""
    for k in (0, 7, 14, 21, 35):                           # swings and turns, across the grid
        code = reference_outcome(four_bar, cells[0][k], cells[1][k], T_END, initial_state=open_branch_start)
        assert MOTIONS[code] == MOTIONS[batch.codes[k]]
    assert {int(batch.codes[k]) for k in (0, 7, 14, 21, 35)} == {0, 1}


def test_a_system_other_than_the_slider_crank_must_say_how_it_starts(four_bar):
    with pytest.raises(InputError, match=r"initial_state: needed for a system other than the slider-crank"):
        integrate_outcomes(four_bar, [0.0], [1.0], 1.0)


def test_a_start_that_moves_the_independent_coordinate_is_refused(four_bar):
    def shifted(system, theta1, rate):
        return open_branch_start(system, theta1 + 0.1, rate)

    with pytest.raises(InputError, match=r"initial_state: returned q = 0\.1.*must keep them"):
        integrate_outcomes(four_bar, [0.0], [1.0], 1.0, initial_state=shifted)
