"""Figures of the error-against-run-time study (chapter 8, ``closedloop benchmark --figures``).

The study itself, its rows and tables are :mod:`closedloop.studies.benchmark`;
this module only draws them, so that a change to a figure never changes the
study's source fingerprint (:func:`closedloop.studies.benchmark.source_fingerprint`
leaves ``plotting/`` out).  matplotlib is imported inside the functions only.
"""

from __future__ import annotations

import math

import numpy as np

from ..studies.benchmark import ALL_METHODS, PERFORMANCE_TARGET, study_entries

__all__ = ["work_precision_figure", "pareto_figure", "residual_figure"]


#: One marker per contestant, so that the curves part in greyscale too (filled and open alternate).
_MARKERS = ("o", "s", "^", "v", "D", "P", "X", "*", "h", "<", ">", "p")

#: One line style per integration method.
_METHOD_LINESTYLES = ("-", "--", "-.", ":", (0, (6, 2, 1, 2, 1, 2)), (0, (1, 1)), (0, (8, 3)))

#: The y-axis label: the max-norm over y = [phi, psi, x_C, phi', psi', x_C'] mixes units.
_ERROR_LABEL = "error at t = 10 s\n[rad, m, rad/s, m/s]"


def _colours(labels):
    from matplotlib import colormaps

    palette = colormaps["tab10"]
    return {label: palette(k % 10) for k, label in enumerate(labels)}


def _entry_styles(labels):
    """``label -> dict(color, marker, mfc)``: a colour and a marker of its own for each contestant."""
    colours = _colours(labels)
    return {label: dict(color=colours[label], marker=_MARKERS[k % len(_MARKERS)],
                        mfc=colours[label] if k % 2 == 0 else "white")
            for k, label in enumerate(labels)}


def _entry_legend(fig, styles, axes):
    """One legend below the panels: a plain line with each drawn contestant's colour and marker.

    Two columns where they fit the figure's width, else one: a legend wider than the figure would
    widen the saved image, and the book would shrink all its text to fit the column.
    """
    from matplotlib.lines import Line2D

    from .style import legend_outside

    drawn = {line.get_label() for ax in axes for line in ax.lines}
    handles = [Line2D([], [], lw=1.2, ms=5, label=label, **style) for label, style in styles.items()
               if label in drawn]
    legend = legend_outside(fig, handles, ncols=2)
    fig.draw_without_rendering()
    if legend.get_window_extent().width > fig.bbox.width:
        legend.remove()
        legend = legend_outside(fig, handles, ncols=1)
    return legend


def _method_linestyle(method):
    """The line style of an integration method in the benchmark's figures."""
    names = list(ALL_METHODS)
    return _METHOD_LINESTYLES[names.index(method) % len(_METHOD_LINESTYLES)] if method in names else "-"


def _log_axes(ax):
    """Grid lines at the decades, and no labels at the minor ticks (they collide on short axes)."""
    from matplotlib.ticker import NullFormatter

    ax.grid(True, which="major", lw=0.3)
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.yaxis.set_minor_formatter(NullFormatter())


def work_precision_figure(rows, case, entries=None):
    """Error at t = 10 s against CPU time, log-log: one panel per method, one curve per formulation.

    Each formulation has a colour and a marker of its own, each method a line style, so that the
    curves part in greyscale too.

    Parameters
    ----------
    rows : list of dict
        The rows of :func:`closedloop.studies.benchmark.run_study`.
    case : int
        The case (1-4) to draw.
    entries : sequence of Entry, optional
        The contestants, for labels and colours; default
        :func:`~closedloop.studies.benchmark.study_entries`.

    Returns
    -------
    matplotlib.figure.Figure

    Raises
    ------
    ValueError
        If no row of ``case`` succeeded (there is no curve to draw).
    """
    from matplotlib.figure import Figure

    from .style import book_style

    labels = [e.label for e in (study_entries() if entries is None else entries)]
    styles = _entry_styles(labels)
    ok = [r for r in rows if r["case"] == case and r["status"] == "ok"]
    methods = [m for m in ALL_METHODS if any(r["method"] == m for r in ok)]
    if not methods:
        raise ValueError(f"case {case}: no run of the study succeeded, so there is no curve to draw")
    columns = min(3, len(methods))                # the text column is 6.4 inches: at most 3 panels a row
    rows_of_panels = -(-len(methods) // columns)
    with book_style():
        fig = Figure(figsize=(6.4, 2.3 * rows_of_panels + 1.9), layout="constrained")
        grid = fig.subplots(rows_of_panels, columns, sharex=True, sharey=True, squeeze=False)
        axes = list(grid.flat)
        for ax in axes[len(methods):]:
            ax.set_visible(False)
        axes = axes[:len(methods)]
        for index, (ax, method) in enumerate(zip(axes, methods)):
            for label in labels:
                curve = [r for r in ok if r["method"] == method and r["label"] == label]
                if curve:
                    ax.loglog([r["cpu_s"] for r in curve], [max(r["error_t10"], 1e-16) for r in curve],
                              ms=5, lw=1.2, ls=_method_linestyle(method), label=label, **styles[label])
            ax.axhline(PERFORMANCE_TARGET, color="0.5", lw=0.9, ls=":")
            ax.set_title(method)
            if index + columns >= len(methods):       # the lowest panel of its column
                ax.set_xlabel("CPU time [s]")
                ax.xaxis.set_tick_params(labelbottom=True)
            if index % columns == 0:
                ax.set_ylabel(_ERROR_LABEL)
            _log_axes(ax)
        _entry_legend(fig, styles, axes)
        fig.suptitle(f"Case {case}: error against CPU time, one panel per method")
    return fig


def _pareto(points):
    """The points not beaten in both CPU and error, sorted by CPU."""
    front, best = [], math.inf
    for cpu, error in sorted(points):
        if error < best:
            front.append((cpu, error))
            best = error
    return front


def pareto_figure(rows, entries=None):
    """Per case, each formulation's best over all methods (its lower-left envelope), log-log.

    Parameters
    ----------
    rows : list of dict
        The rows of :func:`closedloop.studies.benchmark.run_study`.
    entries : sequence of Entry, optional
        As for :func:`work_precision_figure`.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    from .style import book_style

    labels = [e.label for e in (study_entries() if entries is None else entries)]
    styles = _entry_styles(labels)
    cases = sorted({r["case"] for r in rows})
    columns = min(2, len(cases))
    panel_rows = math.ceil(len(cases) / columns)
    with book_style():
        fig = Figure(figsize=(6.4, 2.6 * panel_rows + 1.7), layout="constrained")
        axes = np.atleast_1d(fig.subplots(panel_rows, columns, sharex=True, sharey=True, squeeze=False)).ravel()
        for index, (ax, case) in enumerate(zip(axes, cases)):
            for label in labels:
                points = [(r["cpu_s"], max(r["error_t10"], 1e-16)) for r in rows
                          if r["case"] == case and r["label"] == label and r["status"] == "ok"]
                if points:
                    front = _pareto(points)
                    ax.loglog(*zip(*front), ms=5, lw=1.2, label=label, **styles[label])
            ax.axhline(PERFORMANCE_TARGET, color="0.5", lw=0.9, ls=":")
            ax.set_title(f"case {case}")
            if index + columns >= len(cases):
                ax.set_xlabel("CPU time [s]")
                ax.xaxis.set_tick_params(labelbottom=True)
            if index % columns == 0:
                ax.set_ylabel(_ERROR_LABEL)
            _log_axes(ax)
        for ax in axes[len(cases):]:
            ax.set_visible(False)
        _entry_legend(fig, styles, axes)
    return fig


def residual_figure(traces, title=None):
    """|f| of (32) and |f'| = |Phi_s s'| of (9) against time, one curve per formulation (semilog).

    Parameters
    ----------
    traces : dict
        ``label -> (t, |f|, |f'|)``, as :func:`closedloop.studies.benchmark.residual_traces` returns.
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    from .style import book_style, legend_outside

    styles = _entry_styles([e.label for e in study_entries()])
    with book_style():
        fig = Figure(figsize=(6.4, 3.9), layout="constrained")
        axes = fig.subplots(1, 2, sharex=True)
        for k, (label, (t, f_norm, fd_norm)) in enumerate(traces.items()):
            style = dict(styles.get(label, {}), markevery=max(1, len(t) // 8), ms=5)
            for ax, values in zip(axes, (f_norm, fd_norm)):
                ax.semilogy(t, np.maximum(values, 1e-17), lw=1.0, label=label,
                            ls=("-", "--", ":")[k % 3], **style)       # curves that coincide stay visible
        axes[0].set_ylabel(r"$|\mathbf{f}|$ [m]")
        axes[1].set_ylabel(r"$|\dot{\mathbf{f}}|$ [m/s]")
        for ax in axes:
            ax.set_xlabel("t [s]")
            ax.set_ylim(1e-17, None)
            _log_axes(ax)
        legend_outside(fig, ncols=2)
        if title:
            fig.suptitle(title)
    return fig
