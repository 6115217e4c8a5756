"""The slider-crank drawn: its labelled diagram (the paper's Fig. 1), the drawing of one state, its animation.

matplotlib is imported inside the functions only.
"""

from __future__ import annotations

import math

import numpy as np

from ..slider_crank import points
from .animation import animate
from .annotate import (FORCE, GROUND, INK, LINK, NOTE, angle_arc, arrow, centre_of_mass, check_labels, dimension,
                       joints, label_at, pivot, scale_bar, symbol_sizes, unit_vector, values_text)

__all__ = ["slider_crank_points", "slider_crank_centres", "draw_slider_crank", "slider_crank_diagram",
           "animate_slider_crank"]


def slider_crank_points(s, parameters):
    """The joints O, A (crank pin) and C (slider) at ``s``, as placed by :func:`closedloop.slider_crank.points`.

    Parameters
    ----------
    s : array_like
        ``[phi, psi, x_C]`` [rad, rad, m].
    parameters : SliderCrankParameters

    Returns
    -------
    ndarray, shape (3, 2)
        The rows O, A, C.
    """
    return _named(s, parameters, ("O", "A", "C"))


def slider_crank_centres(s, parameters):
    """The centres of mass C1 of the crank and C2 of the rod at ``s``, those of the potential energy (5.b).

    Parameters
    ----------
    s, parameters
        As for :func:`slider_crank_points`.

    Returns
    -------
    ndarray, shape (2, 2)
        The rows C1, C2 of :func:`closedloop.slider_crank.points`.
    """
    return _named(s, parameters, ("C1", "C2"))


def _named(s, parameters, names):
    """The points ``names`` of :func:`closedloop.slider_crank.points` at ``s``, as the rows of an array."""
    at = points(s, parameters.as_dict())
    return np.array([at[name] for name in names], dtype=float)


def _slider_crank_frame(ax, parameters, fontsize=12, guide=True):
    """The still parts: the pivot at O and the slider's guide over its stroke, with the x axis."""
    from matplotlib.patches import Rectangle

    reach = parameters.l1 + parameters.l2
    size = symbol_sizes(reach)
    (o,) = _named((0.0, 0.0, 0.0), parameters, ("O",))
    artists = pivot(ax, o, size["pivot"], zorder=1)
    if guide:                                            # one rail under the slider, over its stroke
        low = abs(parameters.l2 - parameters.l1) - 1.3 * size["half_width"]
        high = reach + 1.3 * size["half_width"]
        y = -size["half_height"]
        artists.append(ax.plot([low, high], [y, y], color=GROUND, lw=1.2, zorder=1)[0])
        artists.append(ax.add_patch(Rectangle((low, y - 0.5 * size["half_height"]), high - low,
                                              0.5 * size["half_height"], facecolor="none", edgecolor=GROUND,
                                              hatch="////", lw=0, zorder=1)))
    return artists


def draw_slider_crank(ax, s, parameters, color=LINK, label=None, labels="none", force_sign=None,
                      fontsize=12):
    """Draw the slider-crank at state s on the axes ``ax``: crank OA, rod AC and slider C.

    The points are those of :func:`closedloop.slider_crank.points`, from which the model's
    constraints (27)-(28) and potential energy (5.b) are made (the paper's Fig. 1).

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    s : array_like
        ``[phi, psi, x_C]``.
    parameters : SliderCrankParameters
    color : color, optional
        Colour of the links.
    label : str, optional
        Legend label of the links.
    labels : {"none", "light", "full"}, optional
        ``"light"``: the points O, A, C and the angles phi, psi (for animations); ``"full"``: also
        C1, C2, l1, l2, a1, a2, x_C, m1, m2, m3, I1, I2, the drive torque M, gravity g and the gas
        force F.
    force_sign : {+1, -1}, optional
        The reading's ``force_sign`` (with ``labels="full"``): the gas force F <= 0 enters the
        equations as ``force_sign * F`` on x_C, so it pushes the slider along ``-force_sign * x``.
        Default +1, the reading that reproduces the paper.
    fontsize : float, optional
        Size of the labels [pt].

    Returns
    -------
    list of matplotlib.artist.Artist
        Everything drawn, so that an animation can remove it and draw the next state.

    Raises
    ------
    ValueError
        If ``labels`` is none of the three.
    """
    from matplotlib.patches import Rectangle

    check_labels(labels)
    p = parameters
    o, a, c, c1, c2 = _named(s, p, ("O", "A", "C", "C1", "C2"))
    phi, psi = float(s[0]), float(s[1])
    reach = p.l1 + p.l2
    size = symbol_sizes(reach)
    w, h = size["half_width"], size["half_height"]
    artists = [ax.add_patch(Rectangle((c[0] - w, -h), 2 * w, 2 * h, facecolor=color, alpha=0.35, edgecolor=INK,
                                      lw=1.2, zorder=4, gid="slider"))]
    artists.append(ax.plot([o[0], a[0], c[0]], [o[1], a[1], c[1]], "-", color=color, lw=4,
                           solid_capstyle="round", label=label, zorder=4, gid="links")[0])
    artists.append(joints(ax, np.array([o, a, c]), 7))
    if labels == "none":
        return artists
    away = 14 * max(1.0, fontsize / 12)                              # points between a joint and its name
    outward_a = unit_vector(math.atan2(a[1] - 0.5 * c[1], a[0] - 0.5 * c[0]))
    artists.append(label_at(ax, o, "$O$", (away, -0.8 * away), fontsize))
    artists.append(label_at(ax, a, "$A$", tuple(away * outward_a), fontsize))
    artists.append(label_at(ax, c, "$C$", (0.5 * away, 1.1 * away), fontsize))
    note = fontsize * (0.85 if labels == "light" else 1.0)
    artists += angle_arc(ax, o, 0.0, phi, 0.22 * p.l1, r"$\varphi$", note)
    artists += angle_arc(ax, c, 0.0, psi, 0.12 * p.l2, r"$\psi$", note,
                      reference=0.14 * p.l2 if labels == "full" else None, at=0.8)
    if labels == "light":
        return artists

    # lengths and centres of mass: l1 on the crank's left, a2 and l2 above the rod
    above = float(np.sign(c[0] - a[0]) or 1.0)
    artists += dimension(ax, o, a, 0.2 * p.l1, "$l_1$", fontsize)
    artists += dimension(ax, a, c, 0.15 * p.l2 * above, "$l_2$", fontsize)
    artists += dimension(ax, a, c2, 0.05 * p.l2 * above, "$a_2$", fontsize, text_shift=-0.05) \
        if p.a2 > 0 else [label_at(ax, a, "$a_2 = 0$", (away, -away), fontsize)]
    if p.a1 > 0:
        artists += dimension(ax, o, c1, -0.2 * p.l1, "$a_1$", fontsize)
    else:
        artists.append(label_at(ax, o, "$C_1$ at $O$ ($a_1 = 0$)\n$m_1,\\ I_1$", (-1.2 * away, -3.0 * away),
                              fontsize, ha="right"))
    artists.append(centre_of_mass(ax, c1, "C1"))
    artists.append(centre_of_mass(ax, c2, "C2"))
    rod_normal = unit_vector(psi + math.pi / 2)
    artists.append(label_at(ax, c2, "$C_2$\n$m_2,\\ I_2$", tuple(-2.0 * away * rod_normal * np.sign(rod_normal[1] or 1)),
                          fontsize))
    if p.a1 > 0:
        artists.append(label_at(ax, c1, "$C_1$\n$m_1,\\ I_1$", (1.6 * away, -1.6 * away), fontsize))
    artists.append(label_at(ax, c, "$m_3$", (0, -2.3 * away), fontsize))
    # the slider's coordinate x_C, measured along the guide from O
    artists += dimension(ax, o, c, -(2.6 * h + 0.08 * reach), "$x_C$", fontsize, gid="x_C")
    # the drive torque M on the crank, positive with phi, drawn behind the crank
    r = 0.2 * p.l1
    artists.append(ax.annotate("", xy=tuple(r * unit_vector(phi + 4.0)), xytext=tuple(r * unit_vector(phi + 2.3)), gid="M",
                               zorder=7,
                               arrowprops=dict(arrowstyle="-|>", color=FORCE, lw=1.6, mutation_scale=12,
                                               connectionstyle="arc3,rad=0.45", shrinkA=0, shrinkB=0)))
    artists.append(label_at(ax, r * unit_vector(phi + 2.3), "$M$", (-0.9 * away, 0.2 * away), fontsize, color=FORCE))
    # the gas force F on the slider, while the slider moves out
    direction = -(1 if force_sign is None else int(np.sign(force_sign)))        # -1: towards O
    edge = c[0] - direction * w                                                  # the face it pushes
    y = -0.45 * h
    tail = np.array([edge - direction * 0.14 * reach, y])
    artists += arrow(ax, tail, (edge, y), r"$F$ (while $\dot x_C > 0$)", fontsize, FORCE, text_at="tail",
                      offset=(-direction * 0.5 * away, 1.5 * away), gid="F")
    # gravity, down the y axis
    top = max(a[1], 0.0) + 0.1 * reach
    corner = np.array([reach + 0.05 * reach, top])
    artists += arrow(ax, corner, corner - np.array([0.0, 0.16 * reach]), "$g$", fontsize, INK, text_at="head",
                      offset=(away, 0.6 * away), gid="g")
    # the x axis, along the guide
    artists.append(label_at(ax, (reach + 1.3 * w, -h), "$x$", (0.8 * away, 0), fontsize, color=NOTE))
    return artists


def slider_crank_diagram(system=None, phi=0.9, fontsize=12, values=True):
    """The labelled drawing of the slider-crank (the paper's Fig. 1), from the model's data.

    The state is the library's own assembly at crank angle ``phi``
    (:func:`closedloop.slider_crank.initial_state`: psi and x_C solve (27)-(28) on the paper's
    branch), the lengths and centres of mass are those of ``system.parameters`` (Table 1), and the
    gas force points as the system's reading makes it act.  Every symbol of Table 1 and of
    s = [phi, psi, x_C] is marked: O, A, C, C1, C2, phi, psi, x_C, l1, l2, a1, a2, m1, m2, m3, I1,
    I2, the drive torque M, gravity g and the gas force F.

    Parameters
    ----------
    system : SliderCrankSystem, optional
        Default: :func:`closedloop.slider_crank.slider_crank_system` (Table 1, the default reading).
    phi : float, optional
        Crank angle [rad] to draw.
    fontsize : float, optional
        Size of the labels [pt].
    values : bool, optional
        Print the values of Table 1 (and g) below the drawing.

    Returns
    -------
    matplotlib.figure.Figure
    """
    from matplotlib.figure import Figure

    from ..slider_crank import initial_state, slider_crank_system

    system = slider_crank_system() if system is None else system
    p = system.parameters
    s = initial_state(system, phi, 0.0).s
    reach = p.l1 + p.l2
    fig = Figure(figsize=(8.0, 4.3 if values else 3.6), layout="constrained")
    ax = fig.add_subplot()
    _slider_crank_frame(ax, p, fontsize)
    draw_slider_crank(ax, s, p, labels="full", force_sign=system.reading.force_sign, fontsize=fontsize)
    ax.set_aspect("equal")
    ax.set_xlim(-0.45 * reach, 1.2 * reach)
    (pin,) = _named(s, p, ("A",))
    ax.set_ylim(min(pin[1], -0.24 * reach) - 0.04 * reach, max(pin[1], 0.0) + 0.12 * reach)
    ax.set_axis_off()
    if values:
        units = {"l1": "m", "a1": "m", "m1": "kg", "I1": "kg m²", "l2": "m", "a2": "m", "m2": "kg",
                 "I2": "kg m²", "m3": "kg", "g": "m/s²"}
        items = values_text(p.as_dict(), units)
        fig.text(0.5, 0.01, "crank: " + ", ".join(items[:4]) + "\nrod: " + ", ".join(items[4:8])
                 + "\nslider: " + items[8] + ";  " + items[9], ha="center", va="bottom", fontsize=fontsize * 0.85,
                 color=INK, linespacing=1.5)
        fig.get_layout_engine().set(rect=(0, 0.16, 1, 0.84))
    return fig


def animate_slider_crank(result, parameters, fps=15, speed=None, title=None, frames=None, dpi=90,
                         alt=None):
    """A smooth offline HTML animation of a slider-crank run, drawn by :func:`draw_slider_crank`.

    Each frame draws the mechanism at one instant with light labels (O, A, C, phi, psi), the
    time, the title and a 1 m scale bar.  The frames are small PNG images in the library's
    offline player (:func:`closedloop.plotting.player.player_html`).

    Parameters
    ----------
    result : SimulationResult
        A slider-crank run; its output times should be dense (the frames take the nearest ones).
    parameters : SliderCrankParameters
    fps : float, optional
        Frames per second of playback.
    speed : float, optional
        Seconds of motion per second of playback; default: see
        :func:`~closedloop.plotting.animation.playback` (20 s of motion play at 3x real time).
        Shown on every frame when it is not 1.
    title : str, optional
        Drawn on every frame (e.g. the case).
    frames : int, optional
        Number of frames; default ``fps`` x the playback time.  Overrides ``speed``.
    dpi : float, optional
        Resolution of the frames.
    alt : str, optional
        Alternative text of the animation's image (default: what it shows).

    Returns
    -------
    str
        HTML to show with ``IPython.display.HTML``.
    """
    p = parameters
    reach = p.l1 + p.l2

    def setup(ax):
        ax.set_xlim(-p.l1 - 0.1 * reach, reach + 0.12 * reach)
        ax.set_ylim(-p.l1 - 0.08 * reach, p.l1 + 0.08 * reach)
        _slider_crank_frame(ax, p)
        return scale_bar(ax, (-p.l1 - 0.05 * reach, -p.l1 - 0.03 * reach), 1.0, 10)

    def draw(ax, s):
        return draw_slider_crank(ax, s, p, labels="light", fontsize=11)

    what = alt or (f"Animation of the slider-crank{f' ({title})' if title else ''}: crank OA, rod AC and "
                   "slider C moving along their run, with the time, the title and a 1 m scale bar on each frame.")
    return animate(result, setup, draw, (6.4, 3.6), fps=fps, speed=speed, frames=frames, title=title, dpi=dpi,
                   alt=what)
