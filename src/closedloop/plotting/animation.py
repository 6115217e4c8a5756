"""Animations of a mechanism's run as offline HTML: evenly spaced instants drawn to palette PNGs, in a player.

matplotlib and Pillow are imported inside the functions only.
"""

from __future__ import annotations

import base64
import io
import math
import re

import numpy as np

from .annotate import INK

__all__ = ["MAX_FRAMES", "MIN_PLAYBACK", "playback", "animate"]

#: At most this many frames by default (about 0.5 MB of palette PNGs for the slider-crank): 20 s of
#: motion play at 3x real time, in 100 frames that cost about 1.5 s to draw.
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


def animate(result, setup, draw, size, fps, speed, frames, title, dpi, alt):
    """The shared player: evenly spaced instants of ``result`` as palette PNGs in an offline HTML player.

    ``setup(ax)`` draws the still parts; ``draw(ax, s)`` draws the mechanism at state ``s`` and
    returns its artists, which are removed before the next frame.
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

    frames_png = []
    moving = []
    still = _StillBackground(canvas, ax)
    for k in range(count):
        for artist in moving:
            artist.remove()
        moving = draw(ax, result.s[:, index[k]])
        stamp.set_text(f"t = {result.t[index[k]]:.2f} s{pace}")
        still.draw(moving)         # the pixels canvas.draw() would give, the still parts rendered once
        image = Image.frombuffer("RGBA", canvas.get_width_height(), canvas.buffer_rgba()).convert("RGB")
        # 32 colours by the fast octree (MEDIANCUT took 4 of every 5 ms of a frame; the frames look the same)
        image = image.quantize(colors=32, method=Image.Quantize.FASTOCTREE, dither=Image.Dither.NONE)
        packed = io.BytesIO()
        # zlib level 8: the same pixels as optimize=True (level 9) in 2/5 of its time, ~1.5 % more bytes
        image.save(packed, format="png", compress_level=8)
        frames_png.append(base64.encodebytes(packed.getvalue()).decode("ascii"))

    html = _player_html(frames_png, fps)
    html = html.replace('<img id="_anim_img', f'<img alt="{_escape(alt)}" id="_anim_img', 1)
    return _offline_player(html)


class _StillBackground:
    """The frames of an animation drawn as ``canvas.draw()`` would draw them, the still parts once.

    A full draw paints the figure's background, then the axes' children sorted by zorder (a
    stable sort: the still artists of ``setup``, added first, come before moving ones of the same
    zorder), then the figure's texts.  Everything that comes before the first moving artist is
    the same in every frame: it is rendered once into a saved background (one per lowest zorder
    of the moving artists), and each frame restores it and draws the rest in the same order, so
    the pixels are those of a full draw.  The moving artists are those given to :meth:`draw`;
    every other artist of the axes must be still, and the figure's own artists (title, time
    stamp) are drawn after the axes in every frame.
    """

    def __init__(self, canvas, ax):
        self.canvas, self.ax, self.fig = canvas, ax, canvas.figure
        self.still = [a for a in self._drawn_by_axes() if not a.get_animated()]
        self.backgrounds = {}              # lowest moving zorder -> (saved pixels, still artists drawn on top)
        on_top = [a for a in self.fig.get_children() if a is not self.fig.patch and a is not ax]
        # only the layout assumed here: one axes, without images, and the figure's artists above it
        self.exact = (self.fig.axes == [ax] and not ax.images and self.fig.get_layout_engine() is None
                      and all(a.get_zorder() >= ax.get_zorder() for a in on_top))
        self.on_top = sorted(on_top, key=lambda a: a.get_zorder())

    def _drawn_by_axes(self):
        """The axes' children that ``Axes.draw`` draws, in its order before sorting."""
        ax = self.ax
        skip = {id(ax.patch)}
        if not (ax.axison and ax._frameon):
            skip.update(id(spine) for spine in ax.spines.values())
        if not ax.axison:
            skip.update(id(axis) for axis in ax._axis_map.values())
        return [a for a in ax.get_children() if id(a) not in skip]

    def draw(self, moving):
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
        renderer = self.canvas.get_renderer()
        wanted = {id(a) for a in on_top} | {id(a) for a in moving}
        for artist in sorted((a for a in self._drawn_by_axes() if id(a) in wanted), key=lambda a: a.get_zorder()):
            artist.draw(renderer)
        for artist in self.on_top:
            artist.draw(renderer)


def _escape(text):
    return text.replace("&", "&amp;").replace('"', "&quot;").replace("<", "&lt;").replace(">", "&gt;")


def _player_html(frames_png, fps):
    """matplotlib's JavaScript player (as :meth:`Animation.to_jshtml` writes it) around PNG frames."""
    import uuid

    from matplotlib._animation_data import DISPLAY_TEMPLATE, JS_INCLUDE, STYLE_INCLUDE
    from matplotlib.animation import _embedded_frames

    return JS_INCLUDE + STYLE_INCLUDE + DISPLAY_TEMPLATE.format(
        id=uuid.uuid4().hex, Nframes=len(frames_png), fill_frames=_embedded_frames(frames_png, "png"),
        interval=int(round(1000 / fps)), once_checked="", loop_checked="checked", reflect_checked="")


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
