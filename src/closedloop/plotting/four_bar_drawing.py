"""The four-bar drawn: its labelled diagram, the drawing of one state, its animation.

matplotlib is imported inside the functions only.
"""

from __future__ import annotations

import math

import numpy as np

from ..four_bar import points
from .animation import animate
from .annotate import (INK, LINK, angle_arc, arrow, centre_of_mass, check_labels, dimension, joints, label_at,
                       pivot, scale_bar, symbol_sizes, values_text)

__all__ = ["four_bar_points", "four_bar_centres", "draw_four_bar", "four_bar_diagram", "animate_four_bar"]


def four_bar_points(s, lengths):
    """The joints O, A, B, D of the four-bar at ``s``, as placed by :func:`closedloop.four_bar.points`.

    Parameters
    ----------
    s : array_like
        ``[theta1, theta2, theta3]`` [rad].
    lengths : mapping
        Values of ``l0, l1, l2, l3`` [m] (more keys are ignored), e.g.
        :func:`closedloop.four_bar.parameter_values` of the system.

    Returns
    -------
    ndarray, shape (4, 2)
        The rows O, A, B (the coupler's end), D.
    """
    return _named(s, lengths, ("O", "A", "B", "D"))


def four_bar_centres(s, lengths):
    """The centres of mass C1, C2, C3 of the three bars at ``s``, those of the model's energies.

    Parameters
    ----------
    s, lengths
        As for :func:`four_bar_points`.

    Returns
    -------
    ndarray, shape (3, 2)
        The rows C1, C2, C3 of :func:`closedloop.four_bar.points`.
    """
    return _named(s, lengths, ("C1", "C2", "C3"))


def _named(s, lengths, names):
    """The points ``names`` of :func:`closedloop.four_bar.points` at ``s``, as the rows of an array."""
    at = points(s, lengths)
    return np.array([at[name] for name in names], dtype=float)


def _four_bar_frame(ax, lengths, reach):
    """The still parts: the pivots at O and D."""
    size = symbol_sizes(reach)
    o, d = _named((0.0, 0.0, 0.0), lengths, ("O", "D"))
    return pivot(ax, o, size["pivot"]) + pivot(ax, d, size["pivot"])


def draw_four_bar(ax, s, lengths, color=LINK, label=None, labels="none", fontsize=12):
    """Draw the four-bar at state s on ``ax``: crank OA, coupler AB, rocker DB, pivots O and D.

    The points are those of :func:`closedloop.four_bar.points`, from which the model of
    :func:`closedloop.four_bar.four_bar_model` is made.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    s : array_like
        ``[theta1, theta2, theta3]``.
    lengths : mapping
        Values of ``l0, l1, l2, l3`` [m] (more keys are ignored).
    labels : {"none", "light", "full"}, optional
        ``"light"``: O, A, B, D and theta1; ``"full"``: also theta2, theta3, l0..l3, the centres
        of mass C1..C3 with m1..m3, and gravity g.
    color, label, fontsize
        As for :func:`~closedloop.plotting.draw_slider_crank`.

    Returns
    -------
    list of matplotlib.artist.Artist
        Everything drawn.

    Raises
    ------
    ValueError
        If ``labels`` is none of the three.
    """
    check_labels(labels)
    o, a, b, d, *centres = _named(s, lengths, ("O", "A", "B", "D", "C1", "C2", "C3"))
    theta1, theta2, theta3 = (float(v) for v in s[:3])
    l0, l1, l2, l3 = (lengths[k] for k in ("l0", "l1", "l2", "l3"))
    reach = l0 + max(l1, l3)
    artists = [ax.plot([o[0], a[0], b[0], d[0]], [o[1], a[1], b[1], d[1]], "-", color=color, lw=4,
                       solid_capstyle="round", label=label, zorder=4, gid="links")[0]]
    artists.append(joints(ax, np.array([o, a, b, d]), 7))
    if labels == "none":
        return artists
    away = 14 * max(1.0, fontsize / 12)
    middle = (o + d) / 2 + np.array([0.0, 0.25 * max(l1, l3)])
    for point, name in ((a, "$A$"), (b, "$B$")):
        out = point - middle
        artists.append(label_at(ax, point, name, tuple(away * out / (np.hypot(*out) or 1.0)), fontsize))
    artists.append(label_at(ax, o, "$O$", (away, -0.8 * away), fontsize))
    artists.append(label_at(ax, d, "$D$", (-away, -0.8 * away), fontsize))
    note = fontsize * (0.85 if labels == "light" else 1.0)
    artists += angle_arc(ax, o, 0.0, theta1, 0.25 * l1, r"$\theta_1$", note)
    if labels == "light":
        return artists
    artists += angle_arc(ax, d, 0.0, theta3, 0.25 * l3, r"$\theta_3$", fontsize, reference=0.6 * l3)
    if abs(math.remainder(theta2, 2 * math.pi)) > 0.05:
        artists += angle_arc(ax, a, 0.0, theta2, 0.15 * l2, r"$\theta_2$", fontsize, reference=0.3 * l2)
    else:                                                    # the coupler lies along the x axis
        artists += angle_arc(ax, a, 0.0, 0.0, 0.12 * l2, r"$\theta_2 = 0$", fontsize * 0.9, reference=0.3 * l2)
        artists[-1].set_position(tuple(a + np.array([0.2 * l2, -0.09 * l2])))
    artists += dimension(ax, o, d, -0.12 * reach, "$l_0$", fontsize)
    artists += dimension(ax, o, a, 0.22 * l1, "$l_1$", fontsize)
    artists += dimension(ax, a, b, 0.1 * l2 * (1 if math.cos(theta2) >= 0 else -1), "$l_2$", fontsize)
    artists += dimension(ax, d, b, -0.3 * l3 * (1 if math.cos(theta3) >= 0 else -1), "$l_3$", fontsize)
    for k, centre in enumerate(centres, start=1):
        artists.append(centre_of_mass(ax, centre, f"C{k}"))
        side = {1: 1, 2: 1, 3: -1}[k]                       # towards the inside of the loop
        artists.append(label_at(ax, centre, f"$C_{k}$, $m_{k}$", (side * 2.6 * away, {1: 0.6, 2: -0.9, 3: 0.6}[k] * away),
                              fontsize))
    corner = np.array([max(b[0], l0) + 0.2 * reach, max(a[1], b[1], 0.0)])
    artists += arrow(ax, corner, corner - np.array([0.0, 0.12 * reach]), "$g$", fontsize, INK, text_at="head",
                      offset=(away, 0.6 * away), gid="g")
    return artists


def four_bar_diagram(system, theta1=1.1, z_guess=None, fontsize=12, values=True):
    """The labelled drawing of the four-bar of :func:`closedloop.four_bar.four_bar_model`.

    The state is the library's assembly at crank angle ``theta1``
    (:func:`closedloop.consistent_initial_state`, Newton on (13.a)); the lengths and masses are
    those of ``system``.  Marked: O, A, B, D, theta1, theta2, theta3, l0..l3, the centres of mass
    C1..C3 with the masses m1..m3, and gravity g.

    Parameters
    ----------
    system : System
        A four-bar (``System(four_bar_model(), values)``).
    theta1 : float, optional
        Crank angle [rad].
    z_guess : array_like, optional
        Starting guess of ``[theta2, theta3]``, which picks the assembly branch; default
        ``[0, theta1]`` (the open branch, the parallelogram's).
    fontsize : float, optional
    values : bool, optional
        Print the lengths, masses and g below the drawing.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    from ..four_bar import parameter_values
    from ..kinematics import consistent_initial_state

    values_ = parameter_values(system)
    z_guess = [0.0, theta1] if z_guess is None else z_guess
    s = consistent_initial_state(system, [theta1], [0.0], z_guess).s
    l0, l1, l3 = values_["l0"], values_["l1"], values_["l3"]
    reach = l0 + max(l1, l3)
    fig = Figure(figsize=(8.0, 4.2 if values else 3.6), layout="constrained")
    ax = fig.add_subplot()
    _four_bar_frame(ax, values_, reach)
    draw_four_bar(ax, s, values_, labels="full", fontsize=fontsize)
    ax.set_aspect("equal")
    points = four_bar_points(s, values_)
    ax.set_xlim(min(points[:, 0].min(), 0.0) - 0.2 * reach, max(points[:, 0].max(), l0) + 0.32 * reach)
    ax.set_ylim(min(points[:, 1].min(), 0.0) - 0.2 * reach, max(points[:, 1].max(), 0.0) + 0.12 * reach)
    ax.set_axis_off()
    if values:
        units = {"l0": "m", "l1": "m", "l2": "m", "l3": "m", "m1": "kg", "m2": "kg", "m3": "kg", "g": "m/s²"}
        items = values_text(values_, units)
        fig.text(0.5, 0.01, ", ".join(items[:4]) + "\n" + ", ".join(items[4:]), ha="center", va="bottom",
                 fontsize=fontsize * 0.85, color=INK, linespacing=1.5)
        fig.get_layout_engine().set(rect=(0, 0.12, 1, 0.88))
    return fig


def animate_four_bar(result, lengths, fps=15, speed=None, title=None, frames=None, dpi=90, alt=None):
    """A smooth offline HTML animation of a four-bar run, drawn by :func:`draw_four_bar`.

    Parameters
    ----------
    result : SimulationResult
        A run of the four-bar (coordinates theta1, theta2, theta3).
    lengths : mapping
        Values of ``l0, l1, l2, l3`` [m].
    fps, speed, title, frames, dpi, alt
        As for :func:`animate_slider_crank`.

    Returns
    -------
    str
        HTML to show with ``IPython.display.HTML``.
    """
    l0, l1, l3 = lengths["l0"], lengths["l1"], lengths["l3"]
    arm = max(l1, l3)
    reach = l0 + arm

    def setup(ax):
        ax.set_xlim(-1.15 * arm, l0 + 1.15 * arm)
        ax.set_ylim(-1.2 * arm, 1.2 * arm)
        _four_bar_frame(ax, lengths, reach)
        return scale_bar(ax, (-1.0 * arm, -1.05 * arm), 1.0 if reach > 2.5 else 0.1, 10)

    def draw(ax, s):
        return draw_four_bar(ax, s, lengths, labels="light", fontsize=11)

    width = 6.4
    height = max(2.4, width * 2.4 * arm / (l0 + 2.3 * arm) + 0.5)
    what = alt or (f"Animation of the four-bar{f' ({title})' if title else ''}: crank OA, coupler AB and "
                   "rocker DB moving along their run, with the time, the title and a scale bar on each frame.")
    return animate(result, setup, draw, (width, height), fps=fps, speed=speed, frames=frames, title=title, dpi=dpi,
                   alt=what)
