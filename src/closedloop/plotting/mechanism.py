"""Drawings and light HTML animations of the mechanisms: the slider-crank and the four-bar.

The joint positions come from the loop equations, (27)-(28) for the slider-crank; the
animations share one offline player.  matplotlib is imported inside the functions only.
"""

from __future__ import annotations

import re

import numpy as np

__all__ = ["slider_crank_points", "draw_slider_crank", "animate_slider_crank", "four_bar_points",
           "draw_four_bar", "animate_four_bar"]


def slider_crank_points(s, parameters):
    """Joint positions O, A (crank pin) and C (slider) for a state s = [phi, psi, x_C].

    A = l1 (cos phi, sin phi) and C = (x_C, 0); by (27)-(28), C = A - l2 (cos psi, sin psi).

    Returns
    -------
    ndarray, shape (3, 2)
    """

    phi, _, x = s[0], s[1], s[2]
    return np.array([[0.0, 0.0], [parameters.l1 * np.cos(phi), parameters.l1 * np.sin(phi)], [x, 0.0]])


def draw_slider_crank(ax, s, parameters, color="C0", label=None):
    """Draw the mechanism at state s on the axes ``ax``: crank OA, rod AC, slider C.

    Returns the list of artists, so that an animation can update them.
    """
    points = slider_crank_points(s, parameters)
    (links,) = ax.plot(points[:, 0], points[:, 1], "-o", color=color, lw=3, ms=6, label=label)
    (slider,) = ax.plot([points[2, 0]], [0.0], "s", color=color, ms=14, alpha=0.6)
    return [links, slider]


def animate_slider_crank(result, parameters, frames=30, duration=None, title=None):
    """A light HTML/JavaScript animation of a slider-crank run.

    The run is downsampled to ``frames`` evenly spaced instants, drawn small at
    a low resolution: about 6 kB a frame, so 30 frames make about 190 kB.

    Parameters
    ----------
    result : SimulationResult
    parameters : SliderCrankParameters
    frames : int
        Number of frames (downsampled from the run).
    duration : float, optional
        Seconds of animation; default real time.
    title : str, optional

    Returns
    -------
    str
        HTML to show with ``IPython.display.HTML``.
    """
    reach = parameters.l1 + parameters.l2

    def setup(ax, s):
        ax.set_xlim(-1.1 * parameters.l1, 1.05 * reach)
        ax.set_ylim(-1.2 * parameters.l1, 1.2 * parameters.l1)
        ax.axhline(0.0, color="0.7", lw=1, zorder=0)
        return draw_slider_crank(ax, s, parameters)

    def move(artists, s):
        points = slider_crank_points(s, parameters)
        artists[0].set_data(points[:, 0], points[:, 1])
        artists[1].set_data([points[2, 0]], [0.0])

    return _animate(result, setup, move, (4.8, 2.4), frames, duration, title)


def four_bar_points(s, lengths):
    """Joints O, A, B, D of the four-bar of :func:`closedloop.four_bar.four_bar_model`.

    Parameters
    ----------
    s : array_like
        ``[theta1, theta2, theta3]``.
    lengths : mapping
        Values of ``l0, l1, l2, l3`` [m] (more keys are ignored), e.g.
        :func:`closedloop.four_bar.parameter_values` of the system.

    Returns
    -------
    ndarray, shape (4, 2)
        O = (0, 0), A = l1 (cos theta1, sin theta1), B = A + l2 (cos theta2, sin theta2), D = (l0, 0).
    """

    theta1, theta2 = s[0], s[1]
    a = lengths["l1"] * np.array([np.cos(theta1), np.sin(theta1)])
    b = a + lengths["l2"] * np.array([np.cos(theta2), np.sin(theta2)])
    return np.array([[0.0, 0.0], a, b, [lengths["l0"], 0.0]])


def draw_four_bar(ax, s, lengths, color="C0", label=None):
    """Draw the four-bar at state s on ``ax``: crank OA, coupler AB, rocker BD. Returns the artists."""
    points = four_bar_points(s, lengths)
    (links,) = ax.plot(points[:, 0], points[:, 1], "-o", color=color, lw=3, ms=6, label=label)
    (ground,) = ax.plot(points[[0, 3], 0], points[[0, 3], 1], "^", color="0.3", ms=10)
    return [links, ground]


def animate_four_bar(result, lengths, frames=30, duration=None, title=None):
    """A light HTML/JavaScript animation of a four-bar run, like :func:`animate_slider_crank`.

    Parameters
    ----------
    result : SimulationResult
        A run of the four-bar (coordinates theta1, theta2, theta3).
    lengths : mapping
        Values of ``l0, l1, l2, l3`` [m].
    frames, duration, title
        As for :func:`animate_slider_crank`.

    Returns
    -------
    str
        HTML to show with ``IPython.display.HTML``.
    """
    l0, l1, l3 = lengths["l0"], lengths["l1"], lengths["l3"]
    reach = max(l1, l3)

    def setup(ax, s):
        ax.set_xlim(-1.1 * reach, l0 + 1.1 * reach)
        ax.set_ylim(-1.15 * reach, 1.15 * reach)
        ax.axhline(0.0, color="0.85", lw=1, zorder=0)
        return draw_four_bar(ax, s, lengths)

    def move(artists, s):
        points = four_bar_points(s, lengths)
        artists[0].set_data(points[:, 0], points[:, 1])

    width = 4.8
    height = max(1.6, width * 2.3 * reach / (l0 + 2.2 * reach))
    return _animate(result, setup, move, (width, height), frames, duration, title)


def _animate(result, setup, move, size, frames, duration, title):
    """The shared player: ``frames`` evenly spaced instants of ``result``, as offline HTML.

    ``setup(ax, s)`` draws the mechanism at the first state and returns its
    artists; ``move(artists, s)`` moves them to the state s.
    """
    from matplotlib.animation import FuncAnimation
    from matplotlib.figure import Figure

    times = np.linspace(result.t[0], result.t[-1], frames)
    index = np.minimum(np.searchsorted(result.t, times), result.t.size - 1)
    fig = Figure(figsize=size, dpi=64, layout="constrained")
    ax = fig.add_subplot()
    ax.set_aspect("equal")
    ax.set_xticks([])
    ax.set_yticks([])
    artists = setup(ax, result.s[:, index[0]])
    stamp = ax.text(0.02, 0.88, "", transform=ax.transAxes, fontsize=11)
    if title:
        ax.set_title(title, fontsize=11)

    def update(k):
        move(artists, result.s[:, index[k]])
        stamp.set_text(f"t = {times[k]:4.1f} s")
        return [*artists, stamp]

    seconds = (result.t[-1] - result.t[0]) if duration is None else duration
    animation = FuncAnimation(fig, update, frames=frames, interval=1000.0 * seconds / frames, blit=False)
    return _offline_player(animation.to_jshtml(default_mode="loop"))


#: matplotlib's player asks for Font Awesome 4 from a CDN; the book's theme ships Font Awesome 6.
_PLAYER_ICONS = {
    "fa fa-fast-backward": "fa-solid fa-backward-fast",
    "fa fa-step-backward": "fa-solid fa-backward-step",
    "fa fa-play fa-flip-horizontal": "fa-solid fa-play fa-flip-horizontal",
    "fa fa-pause": "fa-solid fa-pause",
    "fa fa-play": "fa-solid fa-play",
    "fa fa-step-forward": "fa-solid fa-forward-step",
    "fa fa-fast-forward": "fa-solid fa-forward-fast",
    "fa fa-minus": "fa-solid fa-minus",
    "fa fa-plus": "fa-solid fa-plus",
}


def _offline_player(html):
    """The animation's HTML with no request to the network: no CDN stylesheet, local icon names."""

    html = re.sub(r'<link rel="stylesheet"\s*href="https://maxcdn[^"]*font-awesome[^"]*">', "", html)
    for old, new in _PLAYER_ICONS.items():
        html = html.replace(f'class="{old}"', f'class="{new}"')
    return html
