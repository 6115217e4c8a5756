"""The drawings' vocabulary: pivots, joints, centres of mass, labels, dimension lines, angles, arrows.

Each function draws one symbol on a matplotlib ``Axes`` and returns the artists it made, so that
an animation can remove them.  Lengths are in data units (metres), offsets of labels in points.
"""

from __future__ import annotations

import math

import numpy as np

__all__ = ["LINK", "INK", "NOTE", "FORCE", "GROUND", "LABELS", "check_labels", "unit_vector", "pivot", "centre_of_mass", "joints", "label_at",
           "dimension", "angle_arc", "arrow", "scale_bar", "symbol_sizes", "values_text"]

#: Colours of the drawings: links, joints' outline, annotations, forces.
LINK, INK, NOTE, FORCE, GROUND = "C0", "0.15", "0.35", "C3", "0.45"
#: How much a drawing of a mechanism names: nothing, its points and angles, or every symbol.
LABELS = ("none", "light", "full")


def check_labels(labels):
    """Raise ValueError, naming ``labels`` and :data:`LABELS`, unless ``labels`` is one of them."""
    if labels not in LABELS:
        raise ValueError(f"labels: must be 'none', 'light' or 'full', got {labels!r}")


def unit_vector(angle):
    """The unit vector at ``angle`` [rad] from the x axis, ``[cos angle, sin angle]``."""
    return np.array([math.cos(angle), math.sin(angle)])


def pivot(ax, point, size, zorder=1):
    """Draw a fixed pivot: a triangle standing on a hatched ground line, its tip at ``point``.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    point : (float, float)
        The pivot's centre [m].
    size : float
        The triangle's height [m].
    zorder : float, optional

    Returns
    -------
    list of matplotlib.artist.Artist
    """
    from matplotlib.patches import Polygon, Rectangle

    x, y = point
    artists = [ax.add_patch(Polygon([[x, y], [x - 0.6 * size, y - size], [x + 0.6 * size, y - size]],
                                    closed=True, facecolor="white", edgecolor=GROUND, lw=1.2, zorder=zorder)),
               ax.add_patch(Rectangle((x - size, y - 1.35 * size), 2 * size, 0.35 * size, facecolor="none",
                                      edgecolor=GROUND, hatch="////", lw=0, zorder=zorder))]
    artists.append(ax.plot([x - size, x + size], [y - size, y - size], color=GROUND, lw=1.2, zorder=zorder)[0])
    return artists


def centre_of_mass(ax, point, gid, size=9, zorder=6):
    """Draw the centre-of-mass symbol, a circle with its upper half filled.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    point : (float, float)
        The centre of mass [m].
    gid : str
        The artist's id (``C1``, ``C2``, ...), by which a test finds it.
    size, zorder : float, optional
        Marker size [pt] and drawing order.

    Returns
    -------
    matplotlib.lines.Line2D
    """
    return ax.plot([point[0]], [point[1]], marker="o", ms=size, fillstyle="top", markerfacecolor=INK,
                   markerfacecoloralt="white", markeredgecolor=INK, mew=1.0, ls="none", zorder=zorder,
                   gid=gid)[0]


def joints(ax, points, size, zorder=5):
    """Draw pin joints, white circles, at ``points`` (an array of shape (k, 2) [m]); ``size`` in points.

    Returns
    -------
    matplotlib.lines.Line2D
    """
    return ax.plot(points[:, 0], points[:, 1], "o", ms=size, markerfacecolor="white", markeredgecolor=INK,
                   mew=1.3, ls="none", zorder=zorder)[0]


def label_at(ax, point, text, offset, fontsize, color=INK, ha="center"):
    """Write ``text`` beside ``point`` on a white halo, so that a line passing under it does not strike it through.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    point : (float, float)
        The point named [m].
    text : str
    offset : (float, float)
        From ``point`` to the text's centre [pt].
    fontsize : float
        [pt].
    color : color, optional
    ha : {"center", "left", "right"}, optional

    Returns
    -------
    matplotlib.text.Annotation
    """
    from matplotlib import patheffects

    return ax.annotate(text, xy=tuple(point), xytext=tuple(offset), textcoords="offset points",
                       ha=ha, va="center", fontsize=fontsize, color=color, zorder=8,
                       path_effects=[patheffects.withStroke(linewidth=3, foreground="white")])


def dimension(ax, start, end, offset, text, fontsize, text_shift=0.0, color=NOTE, gid=None):
    """Draw a dimension line: a double arrow parallel to ``start``-``end``, extension lines, and its name.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    start, end : (float, float)
        The two points measured [m].
    offset : float
        Distance of the arrow from the segment, to its left looking from ``start`` to ``end`` [m]
        (negative: to its right).
    text : str
        The length's name, beyond the arrow.
    fontsize : float
        [pt].
    text_shift : float, optional
        Moves the name further out (or in, negative) [m at 12 pt].
    color : color, optional
    gid : str, optional
        The arrow's id; its ``xy`` is the end, its ``xyann`` the start.

    Returns
    -------
    list of matplotlib.artist.Artist
    """
    start, end = np.asarray(start, float), np.asarray(end, float)
    along = end - start
    normal = np.array([-along[1], along[0]]) / np.hypot(*along)
    p, q = start + offset * normal, end + offset * normal
    artists = [ax.annotate("", xy=tuple(q), xytext=tuple(p), zorder=3,
                           arrowprops=dict(arrowstyle="<|-|>", color=color, lw=0.9, shrinkA=0, shrinkB=0,
                                           mutation_scale=9), gid=gid),
               ax.plot(*np.transpose([start, p + 0.25 * offset * normal]), color=color, lw=0.6, zorder=3)[0],
               ax.plot(*np.transpose([end, q + 0.25 * offset * normal]), color=color, lw=0.6, zorder=3)[0]]
    middle = (p + q) / 2 + np.sign(offset) * (0.22 + text_shift) * normal * max(1.0, fontsize / 12)
    artists.append(ax.text(*middle, text, ha="center", va="center", fontsize=fontsize, color=color, zorder=8,
                           bbox=dict(boxstyle="round,pad=0.1", facecolor="white", edgecolor="none", alpha=0.85)))
    return artists


def angle_arc(ax, centre, start, stop, radius, text, fontsize, color=NOTE, reference=None, at=0.5):
    """Draw an angle: an arc from ``start`` to ``stop`` around ``centre``, an arrow head at ``stop``, its name.

    The arc goes the short way, so a negative angle turns clockwise; an angle under 1e-3 rad
    draws only its name.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    centre : (float, float)
        The vertex [m].
    start, stop : float
        The directions the angle is measured from and to [rad].
    radius : float
        The arc's radius [m].
    text : str
        The angle's name, written beyond the arc.
    fontsize : float
        [pt].
    color : color, optional
    reference : float, optional
        Length of a dashed ray along ``start`` [m]; none by default.
    at : float, optional
        Where along the arc the name stands, from 0 (``start``) to 1 (``stop``).

    Returns
    -------
    list of matplotlib.artist.Artist
    """
    from matplotlib.patches import Arc

    sweep = math.remainder(stop - start, 2 * math.pi)
    artists = []
    if reference:
        end = np.asarray(centre) + reference * unit_vector(start)
        artists.append(ax.plot([centre[0], end[0]], [centre[1], end[1]], ls=(0, (4, 3)), color=color, lw=0.8,
                               zorder=2)[0])
    if abs(sweep) > 1e-3:
        low, high = sorted((start, start + sweep))
        artists.append(ax.add_patch(Arc(tuple(centre), 2 * radius, 2 * radius, theta1=math.degrees(low),
                                        theta2=math.degrees(high), color=color, lw=1.0, zorder=3)))
        tip = np.asarray(centre) + radius * unit_vector(start + sweep)
        back = np.asarray(centre) + radius * unit_vector(start + sweep - math.copysign(min(0.3, 0.5 * abs(sweep)), sweep))
        artists.append(ax.annotate("", xy=tuple(tip), xytext=tuple(back), zorder=3,
                                   arrowprops=dict(arrowstyle="-|>", color=color, lw=1.0, shrinkA=0, shrinkB=0,
                                                   mutation_scale=9)))
    where = np.asarray(centre) + (1.25 * radius + 0.12 * max(1.0, fontsize / 12)) * unit_vector(start + at * sweep)
    artists.append(ax.text(*where, text, ha="center", va="center", fontsize=fontsize, color=color, zorder=8))
    return artists


def arrow(ax, tail, head, text, fontsize, color, text_at="tail", offset=(0, 0), gid=None):
    """Draw a force: an arrow from ``tail`` to ``head`` [m] and its name.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
    tail, head : (float, float)
    text : str
        The name; none if empty.
    fontsize : float
        [pt].
    color : color
    text_at : {"tail", "head"}, optional
        The end the name is written at.
    offset : (float, float), optional
        From that end to the name [pt].
    gid : str, optional
        The arrow's id; its ``xy`` is the head, its ``xyann`` the tail.

    Returns
    -------
    list of matplotlib.artist.Artist
    """
    artists = [ax.annotate("", xy=tuple(head), xytext=tuple(tail), zorder=7, gid=gid,
                           arrowprops=dict(arrowstyle="-|>", color=color, lw=2.0, shrinkA=0, shrinkB=0,
                                           mutation_scale=16))]
    if text:
        artists.append(label_at(ax, tail if text_at == "tail" else head, text, offset, fontsize, color=color))
    return artists


def scale_bar(ax, origin, length, fontsize):
    """Draw a scale bar of ``length`` [m] from ``origin`` rightwards, its length written above it.

    Returns
    -------
    list of matplotlib.artist.Artist
    """
    x, y = origin
    return [ax.plot([x, x + length], [y, y], color=INK, lw=3, solid_capstyle="butt", zorder=8)[0],
            ax.text(x + length / 2, y, f"{length:g} m", ha="center", va="bottom", fontsize=fontsize,
                    color=INK, zorder=8)]


def symbol_sizes(reach):
    """Sizes of the symbols [m] for a mechanism of ``reach`` [m]: ``half_width`` and ``half_height`` of a
    slider, ``pivot`` (a pivot's height)."""
    return {"half_width": 0.055 * reach, "half_height": 0.04 * reach, "pivot": 0.045 * reach}


def values_text(values, units):
    """``"$l_1$ = 2 m"`` for each key of ``units``, in its order, with its value from ``values``.

    Parameters
    ----------
    values : mapping
        A value per parameter name (``l1``, ``m2``, ``I1``, ``g``, ...).
    units : mapping
        The unit of each parameter to write, in the order wanted.

    Returns
    -------
    list of str
        Mathtext, for matplotlib.
    """
    names = {"l0": "l_0", "l1": "l_1", "l2": "l_2", "l3": "l_3", "a1": "a_1", "a2": "a_2", "m1": "m_1",
             "m2": "m_2", "m3": "m_3", "I1": "I_1", "I2": "I_2", "g": "g"}
    return [f"${names[key]}$ = {values[key]:g} {unit}" for key, unit in units.items()]
