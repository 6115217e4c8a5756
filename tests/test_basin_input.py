"""The basin map refuses what it can not compute right, before any work: coarse steps, huge maps."""

import math

import numpy as np
import pytest

from closedloop import InputError
from closedloop.cli import main
from closedloop.simulation.batch_limits import MAX_ANGLE_PER_STEP, MAX_CELL_STEPS, MAX_STEPS
from closedloop.studies.basin import basin_map, grid_values, integrate_outcomes
from closedloop.slider_crank import slider_crank_system


@pytest.fixture(scope="module")
def system():
    return slider_crank_system()


def test_a_step_too_coarse_for_the_forcing_is_refused(system):
    """The drive's ripple has period 1 s: 2 pi rad/s x step must stay <= MAX_ANGLE_PER_STEP."""
    bound = MAX_ANGLE_PER_STEP / (2 * math.pi)
    with pytest.raises(InputError, match=rf"^step: 10 s can not resolve this map: its fastest rate is 6.28 rad/s "
                                         rf"\(the forcing's 2 pi / period\), so the step must be <= {bound:.3g} s"):
        integrate_outcomes(system, [1.0], [1.0], 20.0, 10.0)
    outcome = integrate_outcomes(system, [1.0], [1.0], 1.0, 0.999 * bound)       # just inside: it runs
    assert outcome.codes.shape == (1,)


def test_a_step_too_coarse_for_the_fastest_start_is_refused(system):
    with pytest.raises(InputError, match=rf"fastest rate is 50 rad/s \(the largest starting speed \|dphi0\|\), "
                                         rf"so the step must be <= {MAX_ANGLE_PER_STEP / 50:.3g} s"):
        integrate_outcomes(system, [1.0, 2.0], [1.0, -50.0], 1.0, 0.02)


def test_a_map_of_hours_is_refused(system):
    cells, step = 20_000, 0.01                   # 1e5 steps each (MAX_STEPS): 2e9 cell-steps in all
    with pytest.raises(InputError, match=r"cell-steps, more than the 1e\+09 a map may take"):
        integrate_outcomes(system, np.zeros(cells), np.zeros(cells), MAX_STEPS * step, step)


def test_the_work_limit_counts_the_whole_map_not_one_worker_s_share(monkeypatch):
    """The limit was checked in each worker on its share, so two workers let a map of twice the limit
    run. With the limit lowered to 3000 cell-steps, a 2 x 2 map of 1000 steps (4000 in all, 2000 a
    worker) is refused with one worker and with two."""
    import closedloop.simulation.batch_limits

    monkeypatch.setattr(closedloop.simulation.batch_limits, "MAX_CELL_STEPS", 3000)
    phi0, dphi0 = grid_values(0.0, 2 * math.pi, 2), grid_values(0.0, 1.0, 2)
    for workers in (1, 2):
        with pytest.raises(InputError, match=r"^t_end: 4 cells x t_end / step = 4e\+03 cell-steps"):
            basin_map(phi0, dphi0, 1.0, step=1e-3, workers=workers)


def test_a_grid_of_4m_angles_holds_a_quarter_and_a_half_turn_exactly():
    """k (stop - start) / count missed pi/2 or pi by an ulp for 58 of m = 1 .. 399 (m = 11, 13, ...)."""
    missed = [m for m in range(1, 400)
              if not (grid_values(0.0, 2 * math.pi, 4 * m)[m] == math.pi / 2
                      and grid_values(0.0, 2 * math.pi, 4 * m)[2 * m] == math.pi)]
    assert missed == []


def test_the_command_line_refuses_a_coarse_step_in_one_line(capsys):
    assert main(["basin", "--phi0", "0:2pi:8", "--dphi0", "0:6:8", "--step", "10"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("closedloop: error: step: 10 s can not resolve this map")


def test_a_grid_of_absurd_speeds_is_refused_naming_dphi0(capsys):
    assert main(["basin", "--phi0", "0:2pi:3", "--dphi0", "0:1e300:3"]) == 2
    assert capsys.readouterr().err == ("closedloop: error: dphi0: values must lie within -1000 .. 1000 rad/s, "
                                       "got up to 6.66667e+299\n")
