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
from closedloop.plotting import (animate_four_bar, animate_slider_crank, case_summary, four_bar_points,
                                 plot_basin_map, plot_slider_crank, slider_crank_points)
from closedloop.slider_crank import CASES, classify_motion, initial_state
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
    assert html.count("data:image/png;base64,") == 7
    assert "https://" not in html and "http://" not in html
    assert html.count("<svg") == 6 and 'class="fa' not in html         # its icons drawn in the page, no icon font
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
    assert html.count("data:image/png;base64,") == 5 and "http" not in html


def test_map_figure_marks_the_four_cases_where_they_are():
    whole = basin_map(grid_values(0.0, 2 * math.pi, 4), grid_values(0.0, 3.0, 3), 1.0)
    ax = plot_basin_map(whole).axes[0]
    marked = {(round(x, 9), round(y, 9)) for line in ax.lines for x, y in zip(*line.get_data())}
    assert marked == {(round(c.phi0, 9), round(c.dphi0, 9)) for c in CASES.values()}
    assert sorted(t.get_text() for t in ax.texts) == ["1", "2", "3", "4"]
    # a map drawn over [0.7 pi, 1.1 pi] x [0.55, 1.55] rad/s holds only cases 1 and 4
    part = basin_map(grid_values(0.8 * math.pi, 1.2 * math.pi, 2), grid_values(0.8, 1.8, 2), 1.0)
    assert sorted(t.get_text() for t in plot_basin_map(part).axes[0].texts) == ["1", "4"]
    legend = [t.get_text() for t in plot_basin_map(part).legends[0].get_texts()]
    assert "the paper's cases, numbered" in legend
    # a map that holds no case draws no marker, and its legend names none
    none = basin_map(grid_values(3.0, 3.2, 1), grid_values(1.0, 1.1, 1), 1.0)
    figure = plot_basin_map(none)
    assert len(figure.axes[0].texts) == 0 and "the paper's cases, numbered" not in [
        t.get_text() for t in figure.legends[0].get_texts()]


def test_simulating_never_imports_matplotlib_and_a_figure_does():
    """Every plotting module imports matplotlib inside its functions only; a fresh interpreter shows it."""
    import subprocess
    import sys

    script = (
        "import importlib, pkgutil, sys\n"
        "import closedloop.plotting\n"
        "for module in pkgutil.iter_modules(closedloop.plotting.__path__):\n"
        "    importlib.import_module('closedloop.plotting.' + module.name)\n"
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


# --- Figures a reader can read: the book's style, units on every axis, legends off the data ---------

UNIT = re.compile(r"(\[[^\[\]]+\]|\((?!\d+\))[^()]+\))\s*$")      # "[m]", "(rad/s)"; not "(32)"


def figure_problems(figure):
    """What makes a figure hard to read in the book, as a list of sentences (empty: none).

    - an axis that shows tick labels has a label ending in its unit, in brackets or parentheses,
      and not "[-]";
    - no legend overlaps the data area of any visible axes;
    - no visible text renders smaller than the page's small print at the figure's shown size.
    """
    from matplotlib.text import Text

    from closedloop.plotting.style import MIN_TEXT_PX, rendered_text_px

    problems = []
    figure.draw_without_rendering()
    axes = [ax for ax in figure.axes if ax.get_visible() and ax.axison]
    for ax in axes:
        for name, axis in (("x", ax.xaxis), ("y", ax.yaxis)):
            shown = any(t.get_visible() and t.get_text() for t in axis.get_ticklabels())
            label = axis.get_label_text()
            if shown and not (UNIT.search(label) and not re.search(r"\[\s*-\s*\]", label)):
                problems.append(f"{ax.get_title() or 'axes'}: {name} label {label!r} has no unit")
    legends = [*figure.legends, *(ax.get_legend() for ax in axes if ax.get_legend() is not None)]
    for legend in legends:
        box = legend.get_window_extent()
        for ax in axes:
            area = ax.get_window_extent()
            overlap = min(box.x1, area.x1) - max(box.x0, area.x0), min(box.y1, area.y1) - max(box.y0, area.y0)
            if overlap[0] > 1 and overlap[1] > 1:
                problems.append(f"legend {[t.get_text() for t in legend.get_texts()][:2]} on the data of "
                                f"{ax.get_title() or 'an axes'}")
    texts = [t for t in figure.findobj(Text) if t.get_visible() and t.get_text().strip()]
    smallest = min((t.get_fontsize() for t in texts), default=None)
    if smallest is not None and rendered_text_px(figure, smallest) < MIN_TEXT_PX:
        problems.append(f"text of {smallest:g} pt renders at {rendered_text_px(figure, smallest):.1f} px")
    return problems


def test_the_check_finds_what_the_issue_found():
    """A figure of before: 8 pt legend on the data, 10 inches wide, an axis with no unit."""
    from matplotlib.figure import Figure

    figure = Figure(figsize=(10, 3.8), dpi=100)
    ax = figure.add_subplot()
    ax.plot([0, 1], [0, 1], label="a curve")
    ax.plot([0, 1], [1, 0], label="another")
    ax.legend(fontsize=8, loc="center")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("error at t = 10 s")
    problems = figure_problems(figure)
    assert len(problems) == 3, problems
    assert "no unit" in problems[0] and "on the data" in problems[1] and "renders at" in problems[2]
    # 8 pt at 100 dpi, the tight crop of a 10 inch figure (8.4 inches) shown 624 px wide: about 8 px
    figure.draw_without_rendering()
    crop = figure.get_tightbbox().width + 0.2
    assert 8.0 < crop < 9.0
    assert problems[2].endswith(f"renders at {8 * 624 / (72 * crop):.1f} px")


@pytest.fixture(scope="module")
def library_figures(slider_crank):
    """Every figure function of closedloop.plotting, on small but real data."""
    import json
    from pathlib import Path

    from closedloop.plotting import pareto_figure, residual_figure, work_precision_figure

    case = CASES[1]
    result = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 2.0)
    rows = json.loads((Path(__file__).resolve().parents[1] / "book" / "data" / "benchmark.json").read_text())["rows"]
    t = np.linspace(0.0, 1.0, 50)
    traces = {"Augmented (12)": (t, 1e-9 * (1 + t), 1e-8 * (1 + t)), "Minimal": (t, 1e-16 + 0 * t, 1e-16 + 0 * t)}
    basin = basin_map(grid_values(0.0, 2 * math.pi, 4), grid_values(0.0, 3.0, 3), 1.0)
    return {"plot_slider_crank": plot_slider_crank(result, title="case 1"),
            "plot_basin_map": plot_basin_map(basin),
            "work_precision_figure": work_precision_figure(rows, case=2),
            "pareto_figure": pareto_figure(rows),
            "residual_figure": residual_figure(traces, "two traces")}


@pytest.mark.parametrize("name", ["plot_slider_crank", "plot_basin_map", "work_precision_figure", "pareto_figure",
                                  "residual_figure"])
def test_library_figure_reads_in_the_book(library_figures, name):
    assert figure_problems(library_figures[name]) == []


def test_work_precision_curves_part_without_colour(library_figures):
    """Within a panel (one method) every formulation has its own marker and fill: greyscale tells them apart."""
    from matplotlib.lines import Line2D

    figure = library_figures["work_precision_figure"]
    for ax in figure.axes:
        curves = [line for line in ax.lines if not line.get_label().startswith("_")]
        looks = {(line.get_marker(), str(line.get_markerfacecolor()) == "white") for line in curves}
        assert len(looks) == len(curves)
        assert len({line.get_linestyle() for line in curves}) <= 1          # the method's own line style
    from closedloop.plotting.benchmark import _method_linestyle
    from closedloop.studies.benchmark import ALL_METHODS

    assert len({str(_method_linestyle(method)) for method in ALL_METHODS}) == len(ALL_METHODS)
    for ax in figure.axes:
        if ax.get_visible() and ax.lines:                                  # each panel draws its method's style
            expected = Line2D([], [], ls=_method_linestyle(ax.get_title()))
            assert ax.lines[0]._unscaled_dash_pattern == expected._unscaled_dash_pattern


def test_style_file_is_package_data_and_meets_the_minimum_at_its_size():
    from pathlib import Path

    import matplotlib as mpl

    from closedloop.plotting.style import DISPLAY_WIDTH_PX, MIN_TEXT_PX, STYLE_PATH

    root = Path(__file__).resolve().parents[1]
    assert STYLE_PATH.is_file() and STYLE_PATH.parent == root / "src" / "closedloop" / "plotting"
    assert '"closedloop.plotting" = ["*.mplstyle"]' in (root / "pyproject.toml").read_text()
    style = mpl.rc_params_from_file(STYLE_PATH, use_default_template=False)
    width = style["figure.figsize"][0] + 0.2                              # the tight crop's padding
    smallest = min(style[key] for key in ("font.size", "axes.labelsize", "xtick.labelsize", "ytick.labelsize",
                                          "legend.fontsize", "axes.titlesize"))
    assert smallest * DISPLAY_WIDTH_PX / (72 * width) >= MIN_TEXT_PX
    assert style["figure.dpi"] * width >= DISPLAY_WIDTH_PX                  # never blown up past its pixels
    # a session style that set a layout engine would impose it on every later figure, also on the
    # animations' hand-placed axes (savefig then runs constrained layout on them and warns)
    assert not any(key.startswith("figure.constrained_layout") for key in style)


def test_chapter_figure_cells_use_the_style():
    """A chapter that draws its own figure applies the style once and never shrinks its text or widens
    its figure past the style's width."""
    from pathlib import Path

    root = Path(__file__).resolve().parents[1]
    for path in sorted([*root.glob("chapters/*.md"), *root.glob("exercises/*.md")]):
        text = path.read_text(encoding="utf-8")
        if "plt.subplots(" in text or "plt.figure(" in text:
            assert text.count("use_book_style()") == 1, path.name
            assert text.index("use_book_style()") < text.index("plt.subplots(" if "plt.subplots(" in text
                                                              else "plt.figure("), path.name
        assert not re.search(r"fontsize=([0-9]|10)\b", text), path.name
        for width in re.findall(r"figsize=\((\d+(?:\.\d+)?),", text):
            assert float(width) <= 6.4, (path.name, width)
        for call in _calls(text, ".legend("):
            assert "bbox_to_anchor" in call or "outside" in call, (path.name, call)
        for call in _calls(text, "plt.subplots("):                 # the style leaves layout to each figure
            assert 'layout="constrained"' in call, (path.name, call)


def _calls(text, opening):
    """The text of each call that starts with ``opening`` (which ends in "("), to its closing parenthesis."""
    calls = []
    for match in re.finditer(re.escape(opening), text):
        depth, end = 1, match.end()
        while depth and end < len(text):
            depth += {"(": 1, ")": -1}.get(text[end], 0)
            end += 1
        calls.append(text[match.start():end])
    return calls


def test_a_case_without_a_successful_run_is_named_not_a_zero_division():
    """work_precision_figure divided by zero columns when every run of a case had failed; the command
    then drew no figure for that case at all."""
    import json
    from pathlib import Path

    from closedloop.plotting import work_precision_figure

    rows = json.loads((Path(__file__).resolve().parents[1] / "book" / "data" / "benchmark.json").read_text())["rows"]
    failed = [dict(row, status="failed: made up") if row["case"] == 3 else row for row in rows]
    with pytest.raises(ValueError, match=r"^case 3: no run of the study succeeded"):
        work_precision_figure(failed, 3)


def test_case_summary_states_the_runs_own_numbers(slider_crank):
    """Chapter 6's summary of a case: the computed motion beside the paper's, and the run's extremes."""
    case = CASES[4]
    result = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 6.0,
                      t_eval=np.linspace(0, 6, 601), rtol=1e-8, atol=1e-8)
    lines = case_summary(result, case, slider_crank).splitlines()
    phi, dphi, x = result.coordinate("phi"), result.velocity("phi"), result.coordinate("x")
    energy = slider_crank.energy(result.s, result.sd)
    swing = np.max(np.abs(phi - case.phi0))
    assert lines[0] == "case 4: phi0 = 3.1416 rad, dphi0 = 1.5 rad/s"
    assert lines[1] == f"  computed motion: {classify_motion(result)}   (paper: full rotation)"
    assert f"= {swing:.3f} rad = {swing / (2 * math.pi):.2f} revolutions" in lines[2]
    assert f"between {dphi.min():.3f} and {dphi.max():.3f} rad/s, final phi' = {dphi[-1]:.3f}" in lines[3]
    assert lines[4] == f"  x_C between {x.min():.3f} and {x.max():.3f} m"
    assert lines[5] == f"  T + Pi: {energy[0]:.1f} J at t = 0, {energy[-1]:.1f} J at t = 6 s"
    assert lines[6].startswith(f"  max |f| = {result.max_constraint_error:.1e} m, {result.nfev} evaluations")
