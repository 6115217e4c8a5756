"""Paper-style figures of one slider-crank run (figures 3-14 of the paper).

matplotlib is imported inside the functions only, so simulating never pulls it in.
"""

from __future__ import annotations

__all__ = ["plot_slider_crank"]


def plot_slider_crank(result, title=None):
    """Angles and rates (figs 3, 6, 9, 12), slider position and speed (4, 7, 10, 13), |f| (5, 8, 11, 14).

    Five panels in the book's style; one legend below them names the crank, rod and slider colours.

    Parameters
    ----------
    result : SimulationResult
        A run of the slider-crank (coordinates phi, psi, x).
    title : str, optional

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    from .style import book_style, legend_outside

    with book_style():
        fig = Figure(figsize=(6.4, 7.2), layout="constrained")
        grid = fig.add_gridspec(3, 2)
        t = result.t
        crank, rod, slider = "C0", "C1", "C2"
        panels = [
            (grid[0, 0], [(result.coordinate("phi"), crank), (result.coordinate("psi"), rod)],
             r"$\varphi$, $\psi$ [rad]"),
            (grid[0, 1], [(result.velocity("phi"), crank), (result.velocity("psi"), rod)],
             r"$\dot\varphi$, $\dot\psi$ [rad/s]"),
            (grid[1, 0], [(result.coordinate("x"), slider)], r"slider $x_C$ [m]"),
            (grid[1, 1], [(result.velocity("x"), slider)], r"slider $\dot x_C$ [m/s]"),
        ]
        for spec, curves, ylabel in panels:
            ax = fig.add_subplot(spec)
            for values, colour in curves:
                ax.plot(t, values, color=colour)
            ax.set_ylabel(ylabel)
            ax.set_xlabel("t [s]")
        ax = fig.add_subplot(grid[2, :])
        ax.semilogy(t, result.constraint_error, color="k")
        ax.set_xlabel("t [s]")
        ax.set_ylabel(r"$|\mathbf{f}|$ of (32) [m]")
        ax.grid(True, which="both", alpha=0.25)
        handles = [fig.axes[0].lines[0], fig.axes[0].lines[1], fig.axes[2].lines[0]]
        legend_outside(fig, handles, [r"crank: $\varphi$, $\dot\varphi$", r"rod: $\psi$, $\dot\psi$",
                                      r"slider: $x_C$, $\dot x_C$"])
        if title:
            fig.suptitle(title)
    return fig
