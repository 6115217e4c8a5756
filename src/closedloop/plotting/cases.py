"""Paper-style figures of one slider-crank run (figures 3-14 of the paper).

matplotlib is imported inside the functions only, so simulating never pulls it in.
"""

from __future__ import annotations

__all__ = ["plot_slider_crank"]


def plot_slider_crank(result, title=None):
    """Angles and rates (figs 3, 6, 9, 12), slider position and speed (4, 7, 10, 13), |f| (5, 8, 11, 14).

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

    fig = Figure(figsize=(10, 8), layout="constrained")
    grid = fig.add_gridspec(3, 2)
    t = result.t
    panels = [
        (grid[0, 0], [("phi", result.coordinate("phi"), r"$\varphi$"), ("psi", result.coordinate("psi"), r"$\psi$")],
         "angle [rad]"),
        (grid[0, 1], [("dphi", result.velocity("phi"), r"$\dot\varphi$"), ("dpsi", result.velocity("psi"), r"$\dot\psi$")],
         "angular velocity [rad/s]"),
        (grid[1, 0], [("x", result.coordinate("x"), r"$x_C$")], "slider position [m]"),
        (grid[1, 1], [("dx", result.velocity("x"), r"$\dot x_C$")], "slider velocity [m/s]"),
    ]
    for spec, curves, ylabel in panels:
        ax = fig.add_subplot(spec)
        for _, values, label in curves:
            ax.plot(t, values, label=label)
        ax.set_ylabel(ylabel)
        ax.set_xlabel("t [s]")
        ax.grid(alpha=0.3)
        if len(curves) > 1:
            ax.legend(loc="best")
    ax = fig.add_subplot(grid[2, :])
    ax.semilogy(t, result.constraint_error, color="k", label=r"$|f| = \sqrt{f_1^2 + f_2^2}$ (32)")
    ax.set_xlabel("t [s]")
    ax.set_ylabel("constraint error [m]")
    ax.grid(alpha=0.3, which="both")
    ax.legend(loc="best")
    if title:
        fig.suptitle(title)
    return fig
