"""The basin map figure: every cell of a grid of initial conditions coloured by its outcome.

The map is computed by :mod:`closedloop.studies.basin`.  matplotlib is imported inside the
functions only.
"""

from __future__ import annotations

import numpy as np

__all__ = ["plot_basin_map"]


def plot_basin_map(basin, title=None, cases=True, ax=None):
    """The basin map: each cell coloured by its outcome, the paper's four cases marked.

    Parameters
    ----------
    basin : closedloop.studies.basin.BasinMap
    title : str, optional
    cases : bool, optional
        Mark and number the four cases of section 4 that lie inside the map.
    ax : matplotlib Axes, optional
        Draw into these axes; by default a new Figure is made.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.colors import ListedColormap
    from matplotlib.figure import Figure
    from matplotlib.patches import Patch

    from ..slider_crank import CASES
    from .style import book_style, legend_outside

    with book_style():
        if ax is None:
            fig = Figure(figsize=(6.4, 4.4), layout="constrained")
            ax = fig.add_subplot()
        else:
            fig = ax.figure
        phi_edges = _cell_edges(basin.phi0)
        dphi_edges = _cell_edges(basin.dphi0)
        colours = ("#c6dbef", "#e6550d")          # oscillation, full rotation
        ax.pcolormesh(phi_edges, dphi_edges, basin.outcome, cmap=ListedColormap(colours), vmin=-0.5, vmax=1.5,
                      shading="flat", rasterized=True)
        handles = [Patch(color=colours[code], label=basin.labels[code]) for code in (0, 1)]
        inside = [case for case in CASES.values() if cases
                  and phi_edges[0] <= case.phi0 <= phi_edges[-1] and dphi_edges[0] <= case.dphi0 <= dphi_edges[-1]]
        for case in inside:
            ax.plot(case.phi0, case.dphi0, "o", ms=9, mfc="white", mec="black", mew=1.5)
            ax.annotate(f"{case.number}", (case.phi0, case.dphi0), xytext=(7, 5), textcoords="offset points",
                        fontsize=12, fontweight="bold")
        if inside:                                  # the legend names the marker only where one is drawn
            handles.append(ax.plot([], [], "o", ms=9, mfc="white", mec="black", mew=1.5,
                                   label="the paper's cases, numbered")[0])
        ax.grid(False)
        ax.set_xlim(phi_edges[0], phi_edges[-1])
        ax.set_ylim(dphi_edges[0], dphi_edges[-1])
        span = phi_edges[-1] - phi_edges[0]
        if span >= np.pi:
            ticks = np.arange(0.0, 2.0 * np.pi + 1e-9, np.pi / 2)
            ticks = ticks[(ticks >= phi_edges[0] - 1e-9) & (ticks <= phi_edges[-1] + 1e-9)]
            names = {0: "0", 1: r"$\pi/2$", 2: r"$\pi$", 3: r"$3\pi/2$", 4: r"$2\pi$"}
            ax.set_xticks(ticks, [names[int(round(v / (np.pi / 2)))] for v in ticks])
        ax.set_xlabel(r"initial crank angle $\varphi_0$ [rad]")
        ax.set_ylabel(r"initial crank speed $\dot\varphi_0$ [rad/s]")
        legend_outside(ax, handles, where="below")
        ax.set_title(title if title is not None else
                     f"Outcome after {basin.t_end:g} s, {basin.outcome.shape[1]} x {basin.outcome.shape[0]} cells")
    return fig


def _cell_edges(values):
    """Edges of cells centred on evenly spaced sample values (one sample gets a width of 1e-3)."""

    values = np.asarray(values, dtype=float)
    width = values[1] - values[0] if values.size > 1 else 1e-3
    return np.append(values - 0.5 * width, values[-1] + 0.5 * width)
