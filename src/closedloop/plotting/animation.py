"""Animations of a run: evenly spaced instants drawn to small PNG images, shown by the offline player.

:func:`animate` draws any mechanism given two functions, one for its still parts and one for its
state at an instant (as :func:`closedloop.plotting.animate_slider_crank` does); the frames are
played by :func:`closedloop.plotting.player.player_html`.  matplotlib and Pillow are imported
inside the functions only.
"""

from __future__ import annotations

import io
import math

import numpy as np

from .annotate import INK
from .player import player_html

__all__ = ["MAX_FRAMES", "MIN_PLAYBACK", "playback", "render_frames", "animate"]

#: At most this many frames by default: 20 s of motion at 15 frames per second play at 3x real time.
MAX_FRAMES = 100
#: A run shorter than this [s] is played in slow motion over this many seconds.
MIN_PLAYBACK = 4.0


def playback(duration, fps=15, speed=None, frames=None):
    """Frames and playback speed for ``duration`` seconds of motion at ``fps`` frames per second.

    Parameters
    ----------
    duration : float
        Seconds of motion.
    fps : float
    speed : float, optional
        Seconds of motion per second of playback.  Default: the smallest whole number that keeps
        the count within :data:`MAX_FRAMES`, or slow motion over :data:`MIN_PLAYBACK` seconds for
        a shorter run.
    frames : int, optional
        Number of frames; if given, ``speed`` follows from it.

    Returns
    -------
    (int, float)
        The number of frames and the speed.
    """
    if frames is not None:
        frames = max(2, int(frames))
        return frames, duration * fps / frames
    if speed is None:
        speed = max(1, math.ceil(duration * fps / MAX_FRAMES)) if duration >= MIN_PLAYBACK \
            else duration / MIN_PLAYBACK
    return max(2, int(round(duration * fps / speed))), float(speed)


def render_frames(result, setup, draw, size, fps=15, speed=None, frames=None, title=None, dpi=90, blit=True):
    """Evenly spaced instants of a run, each drawn to a PNG image of 32 colours.

    Each frame shows the mechanism at the output time of ``result`` nearest its instant, the
    time, the playback speed when it is not 1, and ``title``.

    Parameters
    ----------
    result : SimulationResult
        The run; its output times should be dense (the frames take the nearest ones).
    setup : callable
        ``setup(ax)`` draws the still parts on the frames' axes (their limits too).
    draw : callable
        ``draw(ax, s)`` draws the mechanism at state ``s`` and returns the artists it made, which
        are removed before the next frame.
    size : (float, float)
        Width and height of a frame [inches].
    fps, speed, frames
        As for :func:`playback`.
    title : str, optional
        Drawn on every frame.
    dpi : float, optional
        Pixels per inch of the frames.
    blit : bool, optional
        Render the still parts once and draw only the moving ones on them (the same pixels as
        drawing every frame whole, which ``False`` does).

    Returns
    -------
    list of bytes
        The frames, each a PNG file.
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from PIL import Image

    t0, t1 = float(result.t[0]), float(result.t[-1])
    count, speed = playback(t1 - t0, fps, speed, frames)
    times = np.linspace(t0, t1, count)
    index = np.abs(result.t[None, :] - times[:, None]).argmin(axis=1)          # the nearest output time
    fig = Figure(figsize=size, dpi=dpi)
    canvas = FigureCanvasAgg(fig)   # one renderer for all frames: its mathtext and glyph caches are kept
    line = 16.0 / (72.0 * size[1])                     # one line of 11-12 pt text, as a fraction of the height
    ax = fig.add_axes((0.0, 0.0, 1.0, 1.0 - 2.6 * line))
    ax.set_aspect("equal")
    ax.set_axis_off()
    setup(ax)
    if title:
        fig.text(0.015, 0.98, title, ha="left", va="top", fontsize=12, color=INK, weight="bold")
    pace = "" if speed == 1 else f", played at {speed:.2g}x real time"
    stamp = fig.text(0.015, 0.98 - (1.15 * line if title else 0.0), "", ha="left", va="top", fontsize=11,
                     color=INK)

    pngs = []
    moving = []
    still = _StillBackground(canvas, ax) if blit else None
    for k in range(count):
        for artist in moving:
            artist.remove()
        moving = draw(ax, result.s[:, index[k]])
        stamp.set_text(f"t = {result.t[index[k]]:.2f} s{pace}")
        if still is None:
            canvas.draw()
        else:
            still.draw(moving)
        image = Image.frombuffer("RGBA", canvas.get_width_height(), canvas.buffer_rgba()).convert("RGB")
        # the fast octree: the frames look as with median cut, which is several times slower
        image = image.quantize(colors=32, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
        packed = io.BytesIO()
        image.save(packed, format="png", compress_level=8)   # level 9's pixels, faster, barely larger
        pngs.append(packed.getvalue())
    return pngs


def animate(result, setup, draw, size, fps=15, speed=None, frames=None, title=None, dpi=90, alt=""):
    """An offline HTML animation of a run: :func:`render_frames` in :func:`~closedloop.plotting.player.player_html`.

    Parameters
    ----------
    result, setup, draw, size, fps, speed, frames, title, dpi
        As for :func:`render_frames`.
    alt : str, optional
        The alternative text of the frames: what the animation shows.

    Returns
    -------
    str
        HTML to show with ``IPython.display.HTML``; it starts paused on the first frame and loops.
    """
    pngs = render_frames(result, setup, draw, size, fps=fps, speed=speed, frames=frames, title=title, dpi=dpi)
    return player_html(pngs, fps, alt)


class _StillBackground:
    """Frames drawn as ``canvas.draw()`` would draw them, the still parts rendered once.

    A full draw paints the figure's background, then the axes' children sorted by zorder (a
    stable sort: the still artists of ``setup``, added first, come before moving ones of the
    same zorder), then the figure's texts.  Everything below the lowest moving artist is the same
    in every frame: it is rendered once into a saved background (one per lowest zorder of the
    moving artists), and each frame restores it and draws the rest in the same order with
    matplotlib's blitting interface (``set_animated``, ``copy_from_bbox``, ``restore_region``,
    ``draw_artist``).  The moving artists are those given to :meth:`draw`; every other artist of
    the axes must be still.  Any other layout than :func:`render_frames`'s (one axes without
    axis lines or images, no layout engine, the figure's texts above the axes) is drawn whole.
    """

    def __init__(self, canvas, ax):
        self.canvas, self.ax, self.fig = canvas, ax, canvas.figure
        self.still = [a for a in self._drawn_by_axes() if not a.get_animated()]
        self.backgrounds = {}              # lowest moving zorder -> (saved pixels, still artists drawn on top)
        on_top = [a for a in self.fig.get_children() if a is not self.fig.patch and a is not ax]
        self.exact = (self.fig.axes == [ax] and not ax.axison and not ax.images
                      and self.fig.get_layout_engine() is None
                      and all(a.get_zorder() >= ax.get_zorder() for a in on_top))
        self.on_top = sorted(on_top, key=lambda a: a.get_zorder())

    def _drawn_by_axes(self):
        """The axes' children that ``Axes.draw`` draws when the axis is off, in its order before sorting."""
        ax = self.ax
        skip = {id(ax.patch), id(ax.xaxis), id(ax.yaxis), *(id(spine) for spine in ax.spines.values())}
        return [a for a in ax.get_children() if id(a) not in skip]

    def draw(self, moving):
        """Render the frame with the artists ``moving`` on the still parts."""
        if not self.exact or not moving:
            self.canvas.draw()
            return
        lowest = min(a.get_zorder() for a in moving)
        for artist in moving:
            artist.set_animated(True)      # left out of canvas.draw(), drawn below
        if lowest not in self.backgrounds:
            on_top = [a for a in self.still if a.get_zorder() > lowest]
            for artist in self.still:
                artist.set_animated(artist.get_zorder() > lowest)
            for artist in self.on_top:
                artist.set_animated(True)
            self.canvas.draw()             # the background: figure patch and the still artists below
            self.backgrounds[lowest] = (self.canvas.copy_from_bbox(self.fig.bbox), on_top)
        pixels, on_top = self.backgrounds[lowest]
        self.canvas.restore_region(pixels)
        wanted = {id(a) for a in on_top} | {id(a) for a in moving}
        for artist in sorted((a for a in self._drawn_by_axes() if id(a) in wanted), key=lambda a: a.get_zorder()):
            self.ax.draw_artist(artist)
        for artist in self.on_top:
            self.fig.draw_artist(artist)
