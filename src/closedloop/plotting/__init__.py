"""Figures and animations of the book, one module per subject; matplotlib only inside functions.

- :mod:`~closedloop.plotting.slider_crank_drawing`, :mod:`~closedloop.plotting.four_bar_drawing`: the
  labelled drawings and animations of the slider-crank and the four-bar, drawn with the symbols of
  :mod:`~closedloop.plotting.annotate`, their frames drawn by :mod:`~closedloop.plotting.animation` and
  played by :mod:`~closedloop.plotting.player` (offline HTML);
- :mod:`~closedloop.plotting.cases`: the paper-style figures of one slider-crank run (figures 3-14)
  and its key numbers;
- :mod:`~closedloop.plotting.basin`: the basin map (chapter 12);
- :mod:`~closedloop.plotting.benchmark`: the error-against-run-time figures (chapter 8);
- :mod:`~closedloop.plotting.style`: the book's one style (``closedloop.mplstyle``), applied by
  every figure function here and by :func:`use_book_style` in a chapter that draws its own figure;
- :mod:`~closedloop.plotting.tables`: `Table`, the book's printed tables as HTML tables, and
  `rounded_bound`, a bound stated beside printed numbers, rounded in the safe direction.

The figures, drawings and tables of these modules are re-exported here, so ``from
closedloop.plotting import X`` works for them; the interactive figures (Bokeh) are imported
from :mod:`~closedloop.plotting.interactive` itself, which a chapter pays for only when it
draws one, and the style's helpers (``STYLE_PATH``, ``rendered_text_px``) from
:mod:`~closedloop.plotting.style`, and `playback` from :mod:`~closedloop.plotting.animation`.  No module
of the package imports matplotlib at import time, so simulating never pulls it in; and the
package lies outside the benchmark's source fingerprint, so a figure change never makes the
stored study stale.
"""

from __future__ import annotations

from .basin import plot_basin_map
from .benchmark import pareto_figure, residual_figure, work_precision_figure
from .cases import case_summary, plot_slider_crank
from .four_bar_drawing import animate_four_bar, draw_four_bar, four_bar_centres, four_bar_diagram, four_bar_points
from .slider_crank_drawing import (animate_slider_crank, draw_slider_crank, slider_crank_centres, slider_crank_diagram,
                                   slider_crank_points)
from .style import book_style, legend_outside, use_book_style
from .tables import Table, rounded_bound

__all__ = ["plot_slider_crank", "case_summary", "slider_crank_points", "slider_crank_centres", "draw_slider_crank",
           "slider_crank_diagram", "animate_slider_crank", "four_bar_points", "four_bar_centres", "draw_four_bar",
           "four_bar_diagram", "animate_four_bar", "plot_basin_map",
           "work_precision_figure", "pareto_figure", "residual_figure",
           "Table", "rounded_bound", "book_style", "use_book_style", "legend_outside"]
