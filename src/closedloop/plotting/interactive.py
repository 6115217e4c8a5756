"""Interactive figures for the book's HTML edition: the basin map (chapter 12) and error against time (chapter 8).

Each figure is a Bokeh document embedded in the page as JSON and drawn by BokehJS, which the
book ships with the site (``book/_ext/bokeh_offline.py`` copies it into ``_static``), so the
figures work offline and with no kernel: every number a reader can reach by hovering or
clicking is computed here, by the library, and stored in the page.

The static matplotlib figures (:mod:`~closedloop.plotting.basin`,
:mod:`~closedloop.plotting.benchmark`) stay the figures for print: an
:class:`InteractiveFigure` offers the HTML only to an HTML page, and a one-line note in
Markdown to every other output (LaTeX, plain text).

Bokeh is imported inside the functions only (the ``interactive`` extra of the package).
"""

from __future__ import annotations

import hashlib
import html
import json
import math

import numpy as np

from ..studies.basin import BasinMotions

__all__ = ["BasinMotions", "basin_motions", "interactive_basin_map", "interactive_work_precision",
           "InteractiveFigure", "bokeh_js_file"]

#: Colours of the two outcomes, as in :func:`closedloop.plotting.plot_basin_map` (oscillation, full rotation).
OUTCOME_COLOURS = ("#c6dbef", "#e6550d")
#: Markers of the integration methods in the work-precision figure.
METHOD_MARKERS = {"RK45": "circle", "DOP853": "square", "Radau": "triangle", "BDF": "diamond",
                  "LSODA": "inverted_triangle", "ode.dop853": "star"}
#: matplotlib's tab10, the palette of :func:`closedloop.plotting.work_precision_figure`.
TAB10 = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#7f7f7f", "#bcbd22",
         "#17becf")
#: The CSS class of the element an interactive figure is drawn into (the build looks for it).
CSS_CLASS = "closedloop-bokeh"


def basin_motions(basin, sample=0.2, workers=1):
    """The motion phi(t) behind each cell of a basin map: the map's own, or the map computed again with them.

    A map computed with ``basin_map(..., motions=sample)`` carries its cells' motions
    (:class:`~closedloop.studies.basin.BasinMotions`) from its one integration; they are
    returned as they are.  Otherwise the map is computed again, on its grid, ``t_end``, step
    and reading, with ``motions=sample`` (every cell then runs to ``t_end``).

    Parameters
    ----------
    basin : closedloop.studies.basin.BasinMap
    sample : float, optional
        Spacing of the stored samples [s]; default 0.2 s (101 samples over 20 s).
    workers : int, optional
        Processes, as for :func:`~closedloop.studies.basin.basin_map`, if the map is computed again.

    Returns
    -------
    BasinMotions
    """
    from ..studies.basin import basin_map, motion_times

    samples = motion_times(basin.t_end, sample)
    kept = getattr(basin, "motions", None)
    if kept is not None and kept.times.shape == samples.shape and np.allclose(kept.times, samples, rtol=0,
                                                                                 atol=1e-12):
        return kept
    return basin_map(basin.phi0, basin.dphi0, basin.t_end, step=basin.step, reading=basin.reading,
                     workers=workers, motions=sample).motions


class InteractiveFigure:
    """A Bokeh figure that shows itself as HTML in a page, and as a note anywhere else.

    Attributes
    ----------
    model : bokeh.model.Model
        The Bokeh layout; its data sources are named (``model.select_one({"name": ...})``).
    note : str
        What a reader of a medium without JavaScript (print, plain text) is told instead.
    """

    def __init__(self, model, note):
        self.model = model
        self.note = note

    def html(self):
        """The page fragment: a ``<div>``, the document as JSON, and a script that draws it with BokehJS.

        Without BokehJS in the page (e.g. a notebook opened in plain Jupyter) the script
        writes the note into the ``<div>`` instead, and raises no error.
        """
        from bokeh.embed import json_item

        item = json.dumps(json_item(self.model), separators=(",", ":"))
        ident = "cl-" + hashlib.sha256(item.encode()).hexdigest()[:12]
        item = item.replace("</", "<\\/")                   # never closes the <script> element early
        note = json.dumps(self.note)
        return (f'<div class="{CSS_CLASS}" id="{ident}" role="figure" aria-label="{html.escape(self.note)}"></div>\n'
                f'<script type="application/json" id="{ident}-data">{item}</script>\n'
                f'<script>(function () {{\n'
                f'  var box = document.getElementById("{ident}");\n'
                f'  if (typeof Bokeh === "undefined") {{ box.textContent = {note}; return; }}\n'
                f'  var item = JSON.parse(document.getElementById("{ident}-data").textContent);\n'
                f'  Bokeh.embed.embed_item(item, "{ident}");\n'
                f'}})();</script>\n')

    def _repr_mimebundle_(self, include=None, exclude=None):
        return {"text/html": self.html(), "text/markdown": f"*{self.note}*", "text/plain": self.note}


def bokeh_js_file():
    """Path of the BokehJS file that the installed Bokeh needs in the page (``bokeh-<version>.min.js``)."""
    from pathlib import Path

    import bokeh

    return Path(bokeh.__file__).parent / "server" / "static" / "js" / "bokeh.min.js"


def _cell_index_at(values, value):
    return int(np.argmin(np.abs(np.asarray(values) - value)))


def interactive_basin_map(basin, motions=None, selected=(np.pi, 1.0)):
    """The basin map to explore: hover a cell for its start and outcome, click it for its motion.

    Left, the map as :func:`closedloop.plotting.plot_basin_map` draws it; hovering a cell
    shows its initial state (phi0, phi0'), its outcome and when its slider first stuck.
    Right, phi(t) of the selected cell with the lines phi0 +- 2 pi of rule (12.a); clicking a
    cell selects it.  All motions are stored in the page (float32), so this works with no kernel.

    Parameters
    ----------
    basin : closedloop.studies.basin.BasinMap
    motions : BasinMotions, optional
        The cells' motions; default the map's own (``basin_map(..., motions=0.2)``), else
        ``basin_motions(basin)``.
    selected : (float, float), optional
        (phi0 [rad], phi0' [rad/s]) of the cell selected at first; default case 1's (pi, 1).

    Returns
    -------
    InteractiveFigure
        Data sources named ``"basin-cells"`` (one row per cell, row-major: phi0, dphi0,
        outcome, stuck_at, ...) and ``"basin-motion"`` (t, phi of the selected cell).
    """
    from bokeh.layouts import row
    from bokeh.models import ColumnDataSource, CustomJS, HoverTool, Legend, LegendItem, TapTool
    from bokeh.plotting import figure

    motions = basin_motions(basin) if motions is None else motions
    rows, columns = basin.outcome.shape
    if motions.phi.shape[:2] != (rows, columns):
        raise ValueError(f"motions: {motions.phi.shape[:2]} cells, the map has {(rows, columns)}")
    phi0, dphi0 = np.meshgrid(basin.phi0, basin.dphi0)
    width = basin.phi0[1] - basin.phi0[0] if columns > 1 else 1e-3
    height = basin.dphi0[1] - basin.dphi0[0] if rows > 1 else 1e-3
    outcome = basin.outcome.ravel().astype(int)
    stuck = basin.stuck_at.ravel()
    cells = ColumnDataSource(name="basin-cells", data={
        "phi0": phi0.ravel(), "dphi0": dphi0.ravel(), "phi0_over_pi": phi0.ravel() / np.pi,
        "code": outcome, "outcome": [basin.labels[int(c)] for c in outcome],
        "colour": [OUTCOME_COLOURS[int(c)] for c in outcome],
        "stuck_at": stuck, "stuck": ["never" if not np.isfinite(s) else f"at t = {s:.2f} s" for s in stuck],
    })
    first = _cell_index_at(basin.dphi0, selected[1]) * columns + _cell_index_at(basin.phi0, selected[0])
    cells.selected.indices = [first]
    track = motions.phi.reshape(rows * columns, -1).astype(np.float32)
    motion = ColumnDataSource(name="basin-motion", data={"t": motions.times, "phi": track[first].astype(float)})

    tip = ('<div style="font-size: 13px">'
           "<b>@outcome</b><br>"
           "φ₀ = @phi0{0.0000} rad (@phi0_over_pi{0.000} π)<br>"
           "φ̇₀ = @dphi0{0.0000} rad/s<br>"
           "slider stuck: @stuck</div>")
    tools = "pan,wheel_zoom,box_zoom,reset,save"
    left = figure(title=f"Outcome after {basin.t_end:g} s",
                  x_axis_label="initial crank angle φ₀ [rad]", y_axis_label="initial crank speed φ̇₀ [rad/s]",
                  x_range=(basin.phi0[0] - width / 2, basin.phi0[-1] + width / 2),
                  y_range=(basin.dphi0[0] - height / 2, basin.dphi0[-1] + height / 2),
                  tools=tools, sizing_mode="stretch_width", height=400, min_width=300, toolbar_location="above",
                  name="basin-map")
    boxes = left.rect("phi0", "dphi0", width, height, source=cells, fill_color="colour", line_color="colour", line_width=1,
                      selection_line_color="black", selection_line_width=2, nonselection_fill_alpha=1.0,
                      selection_fill_alpha=1.0)
    left.add_tools(HoverTool(renderers=[boxes], tooltips=tip), TapTool(renderers=[boxes]))
    if basin.phi0[-1] - basin.phi0[0] >= np.pi:
        left.xaxis.ticker = [v * np.pi / 2 for v in range(5)]
        left.xaxis.major_label_overrides = {0: "0", np.pi / 2: "π/2", np.pi: "π", 3 * np.pi / 2: "3π/2",
                                            2 * np.pi: "2π"}
    items = [LegendItem(label=basin.labels[code], renderers=[boxes], index=int(np.argmax(outcome == code)))
             for code in (0, 1) if np.any(outcome == code)]
    left.add_layout(Legend(items=items, orientation="horizontal", location="center"), "below")

    # min_border_right: room for the last time tick, centred on the frame's right edge (t_end), which the
    # edge would otherwise cut
    right = figure(title="φ(t) of the selected cell", x_axis_label="time t [s]", y_axis_label="crank angle φ [rad]",
                   tools=tools, sizing_mode="stretch_width", height=400, min_width=250, toolbar_location="above",
                   x_range=(0.0, basin.t_end), min_border_right=16, name="basin-motion-plot")
    right.line("t", "phi", source=motion, line_width=2, color="black")
    start = float(phi0.ravel()[first])
    limits = ColumnDataSource(name="basin-limits", data=_limits(start, basin.t_end))
    right.segment("t0", "phi", "t1", "phi", source=limits, line_dash="dashed", line_color=OUTCOME_COLOURS[1],
                  line_width=1.5)
    right.title.text = _motion_title(start, float(dphi0.ravel()[first]))

    cells.selected.js_on_change("indices", CustomJS(
        args={"cells": cells, "motion": motion, "track": track.ravel(), "samples": int(track.shape[1]),
              "limits": limits, "title": right.title},
        code="""
        const picked = cells.selected.indices;
        if (picked.length === 0) { return; }
        const i = picked[picked.length - 1];
        const phi = Array.from(track.slice(i * samples, (i + 1) * samples));
        motion.data = {t: motion.data.t, phi: phi};
        const p0 = cells.data.phi0[i], d0 = cells.data.dphi0[i];
        limits.data = {t0: limits.data.t0, t1: limits.data.t1, phi: [p0 - 2 * Math.PI, p0 + 2 * Math.PI]};
        title.text = "φ(t) from φ₀ = " + p0.toFixed(2) + ", φ̇₀ = " + d0.toFixed(2);
        """))
    note = ("The HTML edition of this book shows this basin map interactively: hovering a cell shows its start "
            "and outcome, clicking it shows its motion.")
    return InteractiveFigure(row(left, right, sizing_mode="stretch_width"), note)


def _limits(phi0, t_end):
    """The dashed lines phi0 +- 2 pi of rule (12.a), as segments over the run."""
    return {"t0": [0.0, 0.0], "t1": [t_end, t_end], "phi": [phi0 - 2 * np.pi, phi0 + 2 * np.pi]}


def _motion_title(phi0, dphi0):
    return f"φ(t) from φ₀ = {phi0:.2f}, φ̇₀ = {dphi0:.2f}"


def interactive_work_precision(rows, case=2, entries=None):
    """Error at t = 10 s against CPU time, one point per row: hover a point for its run.

    Colour is the formulation (as in :func:`closedloop.plotting.work_precision_figure`), marker
    the method; clicking a legend entry hides that formulation.  Hovering a point shows its
    formulation, method, tolerance, error e10 and CPU time.

    Parameters
    ----------
    rows : list of dict
        The rows of :func:`closedloop.studies.benchmark.run_study` (e.g. ``book/data/benchmark.json``).
    case : int, optional
        The case (1-4) to draw; default 2, the one run with every method.
    entries : sequence of Entry, optional
        The contestants, for labels and colours; default
        :func:`~closedloop.studies.benchmark.study_entries`.

    Returns
    -------
    InteractiveFigure
        One data source per formulation, named ``"benchmark-<key>"``, with the columns
        cpu_s, error_t10 (the rows' values), error (error_t10, at least 1e-16 for the log
        axis), rtol, method, label and their texts.
    """
    from bokeh.models import ColumnDataSource, HoverTool, Legend, Span
    from bokeh.plotting import figure

    from ..studies.benchmark import PERFORMANCE_TARGET, study_entries

    entries = list(study_entries() if entries is None else entries)
    ok = [r for r in rows if r["case"] == case and r["status"] == "ok"]
    if not ok:
        raise ValueError(f"case: no successful rows for case {case}")
    plot = figure(title=f"Case {case}: error at t = 10 s against CPU time",       # short: the toolbar shares its row
                  x_axis_type="log", y_axis_type="log", x_axis_label="CPU time [s]",
                  y_axis_label="error e₁₀ at t = 10 s", tools="pan,wheel_zoom,box_zoom,reset,save",
                  sizing_mode="stretch_width", height=460, min_width=300, toolbar_location="above",
                  x_range=_decades_around([r["cpu_s"] for r in ok]), name="benchmark-plot")
    renderers, items = [], []
    for k, entry in enumerate(entries):
        mine = [r for r in ok if r["formulation"] == entry.key]
        if not mine:
            continue
        source = ColumnDataSource(name=f"benchmark-{entry.key}", data=_benchmark_columns(mine))
        glyph = plot.scatter("cpu_s", "error", source=source, marker="marker", size=8, fill_color=TAB10[k % 10],
                             line_color="black", line_width=0.5, fill_alpha=0.85)
        renderers.append(glyph)
        items.append((entry.label, [glyph]))
    plot.add_layout(Span(location=PERFORMANCE_TARGET, dimension="width", line_dash="dotted", line_color="#999999"))
    legend = Legend(items=items, click_policy="hide", title="formulation (click: hide)", label_text_font_size="11px")
    plot.add_layout(legend, "right")
    methods = [m for m in METHOD_MARKERS if any(r["method"] == m for r in ok)]
    plot.add_layout(Legend(items=[(m, [plot.scatter([math.nan], [math.nan], marker=METHOD_MARKERS[m],
                                                    size=8, fill_color="white", line_color="black")]) for m in methods],
                           title="method", label_text_font_size="11px"), "right")
    plot.add_tools(HoverTool(renderers=renderers, tooltips=(
        '<div style="font-size: 13px"><b>@label</b><br>method @method, rtol @rtol_text, atol @atol_text<br>'
        "error e₁₀ = @error_text<br>CPU time = @cpu_text</div>")))
    note = ("The HTML edition of this book shows this figure interactively: hovering a point shows its "
            "formulation, method, tolerance, error and CPU time.")
    return InteractiveFigure(plot, note)


#: Decades a log axis of Bokeh must span for its ticks to be powers of ten: over less, BokehJS's LogTicker
#: places linear ticks.
_LOG_TICKS_DECADES = 2.0


def _decades_around(values):
    """``(low, high)``: the range of the positive ``values`` widened by the same factor at both ends, at least
    2 on each side and enough that it spans 10 % more than :data:`_LOG_TICKS_DECADES`."""
    low, high = min(values), max(values)
    factor = max(2.0, 10.0 ** ((1.1 * _LOG_TICKS_DECADES - math.log10(high / low)) / 2))
    return low / factor, high * factor


def _benchmark_columns(rows):
    """The columns of one formulation's points: the rows' numbers and the texts the tooltip shows."""
    return {
        "cpu_s": [r["cpu_s"] for r in rows],
        "error_t10": [r["error_t10"] for r in rows],
        "error": [max(r["error_t10"], 1e-16) for r in rows],
        "rtol": [r["rtol"] for r in rows],
        "method": [r["method"] for r in rows],
        "label": [r["label"] for r in rows],
        "marker": [METHOD_MARKERS.get(r["method"], "circle") for r in rows],
        "rtol_text": [f"{r['rtol']:.0e}" for r in rows],
        "atol_text": [f"{r['atol']:.0e}" for r in rows],
        "error_text": [f"{r['error_t10']:.2e}" for r in rows],
        "cpu_text": [f"{1e3 * r['cpu_s']:.2f} ms" for r in rows],
    }
