"""Every figure and animation the book shows: right content, nothing fetched from the network,
matplotlib imported only by a figure, and every plotting name the book imports exported.

The slider-crank, the four-bar and the basin map; the figures the benchmark command writes are
checked with the command in test_cli.py.
"""

import math
import re

import numpy as np
import pytest

from closedloop import simulate
from closedloop.four_bar import parameter_values
from closedloop.plotting import (animate_four_bar, animate_slider_crank, four_bar_points, plot_basin_map,
                                 plot_slider_crank, slider_crank_points)
from closedloop.slider_crank import CASES, initial_state
from closedloop.studies.basin import basin_map, grid_values

from .conftest import PARALLELOGRAM


def test_drawn_joints_close_the_loop(slider_crank):
    state = initial_state(slider_crank, 1.0, 0.0)
    O, A, C = slider_crank_points(state.s, slider_crank.parameters)
    assert np.allclose(O, 0.0) and C[1] == 0.0
    assert np.linalg.norm(A - O) == np.float64(slider_crank.parameters.l1)
    assert abs(np.linalg.norm(C - A) - slider_crank.parameters.l2) < 1e-12      # the rod has its length


def test_animation_is_downsampled_and_offline(slider_crank):
    case = CASES[2]
    result = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 2.0,
                      t_eval=np.linspace(0, 2, 201))
    html = animate_slider_crank(result, slider_crank.parameters, frames=7)
    assert len(re.findall(r"frames\[\d+\] = ", html)) == 7
    assert "https://" not in html and "http://" not in html
    assert 'class="fa fa-' not in html and "fa-solid fa-play" in html
    assert len(html) < 7 * 10_000


def test_paper_style_figure_has_its_five_panels(slider_crank):
    case = CASES[1]
    result = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 2.0)
    figure = plot_slider_crank(result, title="case 1")
    assert len(figure.axes) == 5
    assert figure.axes[-1].get_yscale() == "log"
    assert np.allclose(figure.axes[2].lines[0].get_ydata(), result.coordinate("x"))


def test_four_bar_drawing_closes_the_loop_and_animates(parallelogram, parallelogram_swing):
    _, result = parallelogram_swing
    lengths = parameter_values(parallelogram)
    points = four_bar_points(result.s[:, 123], lengths)
    assert np.linalg.norm(points[2] - points[3]) == pytest.approx(PARALLELOGRAM["l3"], abs=1e-9)   # |BD| = l3
    html = animate_four_bar(result, lengths, frames=5)
    assert html.count("data:image/png;base64") == 5 and "maxcdn" not in html


def test_map_figure_marks_the_four_cases_where_they_are():
    whole = basin_map(grid_values(0.0, 2 * math.pi, 4), grid_values(0.0, 3.0, 3), 1.0)
    ax = plot_basin_map(whole).axes[0]
    marked = {(round(x, 9), round(y, 9)) for line in ax.lines for x, y in zip(*line.get_data())}
    assert marked == {(round(c.phi0, 9), round(c.dphi0, 9)) for c in CASES.values()}
    assert sorted(t.get_text() for t in ax.texts) == ["1", "2", "3", "4"]
    # a map drawn over [0.7 pi, 1.1 pi] x [0.55, 1.55] rad/s holds only cases 1 and 4
    part = basin_map(grid_values(0.8 * math.pi, 1.2 * math.pi, 2), grid_values(0.8, 1.8, 2), 1.0)
    assert sorted(t.get_text() for t in plot_basin_map(part).axes[0].texts) == ["1", "4"]


def test_simulating_never_imports_matplotlib_and_a_figure_does():
    """Every plotting module imports matplotlib inside its functions only; a fresh interpreter shows it."""
    import subprocess
    import sys

    script = (
        "import sys\n"
        "import closedloop.plotting, closedloop.plotting.basin, closedloop.plotting.benchmark\n"
        "import closedloop.plotting.cases, closedloop.plotting.mechanism\n"
        "from closedloop import simulate\n"
        "from closedloop.slider_crank import initial_state, slider_crank_system\n"
        "system = slider_crank_system()\n"
        "result = simulate(system, initial_state(system, 1.0, 1.0), 0.5)\n"
        "print('after simulate:', 'matplotlib' in sys.modules)\n"
        "closedloop.plotting.plot_slider_crank(result)\n"
        "print('after a figure:', 'matplotlib' in sys.modules)\n"
    )
    done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    assert done.stdout.split("\n")[:2] == ["after simulate: False", "after a figure: True"]


def test_every_plotting_name_the_book_imports_is_exported():
    """``from closedloop.plotting import X`` in the chapters and exercises: each X is in __all__."""
    from pathlib import Path

    import closedloop.plotting

    root = Path(__file__).resolve().parents[1]
    names = set()
    for path in [*root.glob("chapters/*.md"), *root.glob("exercises/*.md"), *root.glob("exercises/checking/*.py")]:
        for match in re.finditer(r"from closedloop\.plotting import ([^\n(]+)", path.read_text(encoding="utf-8")):
            names |= {name.strip() for name in match.group(1).split(",")}
    assert {"plot_slider_crank", "draw_four_bar", "plot_basin_map", "pareto_figure"} <= names
    assert names <= set(closedloop.plotting.__all__)
    assert all(callable(getattr(closedloop.plotting, name)) for name in closedloop.plotting.__all__)
