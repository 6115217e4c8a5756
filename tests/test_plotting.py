"""Figures and the animation the book shows: right content, and nothing fetched from the network."""

import re

import numpy as np

from closedloop import simulate
from closedloop.plotting import animate_slider_crank, plot_slider_crank, slider_crank_points
from closedloop.slider_crank import CASES, initial_state


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
