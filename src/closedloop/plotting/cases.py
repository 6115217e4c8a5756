"""One slider-crank run of the paper's cases: its figure (figures 3-14 of the paper) and its key numbers.

matplotlib is imported inside the functions only, so simulating never pulls it in.
"""

from __future__ import annotations

import numpy as np

__all__ = ["plot_slider_crank", "case_summary"]


def case_summary(result, case, system):
    """The outcome and the key numbers of one run of a paper's case, as lines of text (chapter 6).

    Parameters
    ----------
    result : SimulationResult
        A run of the slider-crank from the case's start.
    case : closedloop.slider_crank.Case
        The case run: its start and the paper's finding.
    system : System
        The slider-crank the run integrated, for its energy T + Pi.

    Returns
    -------
    str
        The case and its start; the computed motion (:func:`~closedloop.slider_crank.classify_motion`)
        beside the paper's finding; the largest excursion of the crank, in rad and in revolutions;
        the ranges of phi' and x_C and the final phi'; T + Pi at the start and at the end; the
        largest |f| of (32), the number of evaluations and the CPU time.
    """
    from ..slider_crank import classify_motion

    phi, dphi = result.coordinate("phi"), result.velocity("phi")
    x = result.coordinate("x")
    energy = system.energy(result.s, result.sd)                                   # T + Pi
    swing = float(np.max(np.abs(phi - case.phi0)))
    return "\n".join([
        f"case {case.number}: phi0 = {case.phi0:.4f} rad, dphi0 = {case.dphi0:g} rad/s",
        f"  computed motion: {classify_motion(result)}   (paper: {case.finding})",
        f"  max |phi - phi0| = {swing:.3f} rad = {swing / (2 * np.pi):.2f} revolutions",
        f"  phi' between {dphi.min():.3f} and {dphi.max():.3f} rad/s, final phi' = {dphi[-1]:.3f} rad/s",
        f"  x_C between {x.min():.3f} and {x.max():.3f} m",
        f"  T + Pi: {energy[0]:.1f} J at t = 0, {energy[-1]:.1f} J at t = {result.t[-1]:g} s",
        f"  max |f| = {result.max_constraint_error:.1e} m, {result.nfev} evaluations, "
        f"{result.cpu_time:.2f} s CPU",
    ])


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
