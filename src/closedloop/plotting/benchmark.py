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


def _colours(labels):
    from matplotlib import colormaps

    palette = colormaps["tab10"]
    return {label: palette(k % 10) for k, label in enumerate(labels)}


def _log_axes(ax):
    """Grid lines at the decades, and no labels at the minor ticks (they collide on short axes)."""
    from matplotlib.ticker import NullFormatter

    ax.grid(True, which="major", lw=0.3)
    ax.xaxis.set_minor_formatter(NullFormatter())
    ax.yaxis.set_minor_formatter(NullFormatter())


def work_precision_figure(rows, case, entries=None):
    """Error at t = 10 s against CPU time, log-log: one panel per method, one curve per formulation.

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
    """
    from matplotlib.figure import Figure

    labels = [e.label for e in (study_entries() if entries is None else entries)]
    colours = _colours(labels)
    ok = [r for r in rows if r["case"] == case and r["status"] == "ok"]
    methods = [m for m in ALL_METHODS if any(r["method"] == m for r in ok)]
    columns = min(3, len(methods))                # a page is about 7 inches wide: at most 3 panels a row
    rows_of_panels = -(-len(methods) // columns)
    fig = Figure(figsize=(3.0 * columns + 0.8, 2.8 * rows_of_panels + 1.2), layout="constrained")
    grid = fig.subplots(rows_of_panels, columns, sharex=True, sharey=True, squeeze=False)
    axes = list(grid.flat)
    for ax in axes[len(methods):]:
        ax.set_visible(False)
    axes = axes[:len(methods)]
    for index, (ax, method) in enumerate(zip(axes, methods)):
        for label in labels:
            curve = [r for r in ok if r["method"] == method and r["label"] == label]
            if curve:
                ax.loglog([r["cpu_s"] for r in curve], [max(r["error_t10"], 1e-16) for r in curve], "o-",
                          ms=3, lw=1.2, color=colours[label], label=label)
        ax.axhline(PERFORMANCE_TARGET, color="0.6", lw=0.8, ls=":")
        ax.set_title(method)
        if index + columns >= len(methods):       # the lowest panel of its column
            ax.set_xlabel("CPU time [s]")
            ax.xaxis.set_tick_params(labelbottom=True)
        if index % columns == 0:
            ax.set_ylabel("error at t = 10 s")
        _log_axes(ax)
    handles, names = axes[0].get_legend_handles_labels()
    for ax in axes[1:]:
        for h, n in zip(*ax.get_legend_handles_labels()):
            if n not in names:
                handles.append(h)
                names.append(n)
    fig.legend(handles, names, loc="outside lower center", ncol=3, fontsize=8)
    fig.suptitle(f"Case {case}: work-precision, one curve per formulation and method")
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

    labels = [e.label for e in (study_entries() if entries is None else entries)]
    colours = _colours(labels)
    cases = sorted({r["case"] for r in rows})
    columns = min(2, len(cases))
    fig = Figure(figsize=(5.2 * columns, 3.6 * math.ceil(len(cases) / columns) + 0.6), layout="constrained")
    axes = np.atleast_1d(fig.subplots(math.ceil(len(cases) / columns), columns, sharex=True, sharey=True,
                                      squeeze=False)).ravel()
    for ax, case in zip(axes, cases):
        for label in labels:
            points = [(r["cpu_s"], max(r["error_t10"], 1e-16)) for r in rows
                      if r["case"] == case and r["label"] == label and r["status"] == "ok"]
            if points:
                front = _pareto(points)
                ax.loglog(*zip(*front), "o-", ms=3, lw=1.2, color=colours[label], label=label)
        ax.axhline(PERFORMANCE_TARGET, color="0.6", lw=0.8, ls=":")
        ax.set_title(f"case {case}")
        ax.set_xlabel("CPU time [s]")
        ax.set_ylabel("error at t = 10 s")
        _log_axes(ax)
    for ax in axes[len(cases):]:
        ax.set_visible(False)
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncol=4, fontsize=8)
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

    colours = _colours([e.label for e in study_entries()])
    fig = Figure(figsize=(10, 3.8), layout="constrained")
    axes = fig.subplots(1, 2, sharex=True)
    for k, (label, (t, f_norm, fd_norm)) in enumerate(traces.items()):
        for ax, values in zip(axes, (f_norm, fd_norm)):
            ax.semilogy(t, np.maximum(values, 1e-17), lw=1.0, color=colours.get(label), label=label,
                        ls=("-", "--", ":")[k % 3])       # curves that coincide stay visible
    axes[0].set_ylabel(r"$|\mathbf{f}|$ [m]")
    axes[1].set_ylabel(r"$|\dot{\mathbf{f}}|$ [m/s]")
    for ax in axes:
        ax.set_xlabel("t [s]")
        ax.set_ylim(1e-17, None)
        ax.grid(True, which="major", lw=0.3)
    fig.legend(*axes[0].get_legend_handles_labels(), loc="outside lower center", ncol=6, fontsize=8)
    if title:
        fig.suptitle(title)
    return fig
