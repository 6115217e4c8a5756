"""An offline HTML player for an animation's frames: a slider, play and pause, and three repeat modes.

The frames are PNG images written into the page as data URIs; the page fetches nothing, and its
script and style are written out with it, so the player works in the book's HTML, in a notebook
(Jupyter, VS Code) and in a saved HTML file alike.  Without JavaScript the first frame shows as an
image with its alternative text and the controls stay hidden; a print shows that frame.

Every text the player shows or names is in the HTML as written here, none made by its script:
the repeat modes as ``<span>Once</span>``, ``<span>Loop</span>`` and ``<span>Reflect</span>``,
the buttons' names as ``title`` attributes (:data:`BUTTONS`), the slider's and the modes' as
``title="Frame"`` and ``title="Repeat"``, so that a translated edition can replace each one.
"""

from __future__ import annotations

import base64
import html
import json
import struct

__all__ = ["BUTTONS", "MODES", "player_html"]

#: The buttons: their action, their name (``title``), and their icon (an SVG path on a 16 x 16 grid).
BUTTONS = (
    ("first", "First frame", "M1 2h2v12H1zM9 2v12L3 8zM15 2v12L9 8z"),
    ("previous", "Previous frame", "M2 2h2v12H2zM14 2v12L5 8z"),
    ("play", "Play", "M4 2l10 6-10 6z"),
    ("pause", "Pause", "M3 2h4v12H3zM9 2h4v12H9z"),
    ("next", "Next frame", "M12 2h2v12h-2zM2 2v12l9-6z"),
    ("last", "Last frame", "M13 2h2v12h-2zM7 2v12l6-6zM1 2v12l6-6z"),
)
#: The repeat modes at the end of the frames: stop, start again, or play backwards (value, label).
MODES = (("once", "Once"), ("loop", "Loop"), ("reflect", "Reflect"))

_STYLE = """<style>
.closedloop-player { display: inline-block; max-width: 100%; text-align: center; }
.closedloop-player img.anim-frame { display: block; max-width: 100%; height: auto; margin: 0 auto; }
.closedloop-player .anim-slider { display: block; width: 100%; margin: 6px 0; }
.closedloop-player .anim-buttons button { min-width: 2.4em; height: 2em; margin: 0 2px; padding: 0 6px;
  border: 1px solid #999; border-radius: 4px; background: #fff; color: #222; cursor: pointer;
  vertical-align: middle; line-height: 1; }
.closedloop-player .anim-buttons button:hover { background: #e8e8e8; }
.closedloop-player .anim-buttons svg { width: 14px; height: 14px; fill: currentColor; vertical-align: middle; }
.closedloop-player .anim-modes { border: 0; margin: 6px 0 0; padding: 0; }
.closedloop-player .anim-modes label { margin: 0 8px; cursor: pointer; }
.closedloop-player .anim-modes input { margin: 0 0.3em 0 0; vertical-align: middle; }
.closedloop-player [hidden] { display: none !important; }
</style>"""

#: Starts every player of the page not started yet (so the same script may run once per player).
_SCRIPT = """<script>
(function () {
  "use strict";
  function start(box) {
    box.setAttribute("data-ready", "");
    var image = box.querySelector("img.anim-frame");
    var slider = box.querySelector("input.anim-slider");
    var play = box.querySelector('button[data-action="play"]');
    var pause = box.querySelector('button[data-action="pause"]');
    var modes = box.querySelectorAll("input.anim-mode");
    var frames = [image.getAttribute("src")].concat(JSON.parse(box.querySelector("script.anim-frames").textContent));
    var interval = parseFloat(box.getAttribute("data-interval"));
    var group = "closedloop-player-" + document.querySelectorAll("div.closedloop-player[data-ready]").length;
    var frame = 0, step = 1, timer = null, i;
    var decoded = frames.map(function (src) { var ahead = new Image(); ahead.src = src; return ahead; });
    for (i = 0; i < modes.length; i++) { modes[i].name = group; }
    function mode() {
      for (var i = 0; i < modes.length; i++) { if (modes[i].checked) { return modes[i].value; } }
      return "once";
    }
    function show(k) { frame = k; image.src = decoded[k].src; slider.value = String(k); }
    function swap(from, to) {
      var focused = document.activeElement === from;
      from.hidden = true; to.hidden = false;
      if (focused) { to.focus(); }
    }
    function stop() {
      if (timer !== null) { clearInterval(timer); timer = null; swap(pause, play); }
    }
    function tick() {
      var next = frame + step;
      if (next < 0 || next >= frames.length) {
        var how = mode();
        if (how === "loop") { next = step > 0 ? 0 : frames.length - 1; }
        else if (how === "reflect") { step = -step; next = frame + step; }
        else { stop(); return; }
      }
      show(next);
    }
    function run() {
      if (timer !== null) { return; }
      if (mode() !== "reflect") { step = 1; }
      if (mode() === "once" && frame === frames.length - 1) { show(0); }
      timer = setInterval(tick, interval);
      swap(play, pause);
    }
    var actions = {
      first: function () { stop(); show(0); },
      previous: function () { stop(); show(Math.max(frame - 1, 0)); },
      play: run,
      pause: stop,
      next: function () { stop(); show(Math.min(frame + 1, frames.length - 1)); },
      last: function () { stop(); show(frames.length - 1); }
    };
    var buttons = box.querySelectorAll("button[data-action]");
    for (i = 0; i < buttons.length; i++) {
      buttons[i].addEventListener("click", actions[buttons[i].getAttribute("data-action")]);
    }
    slider.addEventListener("input", function () { stop(); show(parseInt(slider.value, 10)); });
    box.querySelector("div.anim-controls").hidden = false;
  }
  function startAll() {
    var boxes = document.querySelectorAll("div.closedloop-player:not([data-ready])");
    for (var n = 0; n < boxes.length; n++) { start(boxes[n]); }
    return boxes.length;
  }
  if (!startAll()) { setTimeout(startAll, 0); }     // a front end that runs the script before showing its output
})();
</script>"""


def _data_uri(png):
    return "data:image/png;base64," + base64.b64encode(png).decode("ascii")


def _size(png):
    """Width and height [px] of a PNG image, from its header."""
    if png[:8] != b"\x89PNG\r\n\x1a\n":
        raise ValueError("frames: each frame must be a PNG image")
    return struct.unpack(">II", png[16:24])


def player_html(frames, fps, alt, mode="loop"):
    """The HTML of a player that shows ``frames`` at ``fps`` frames per second, offline.

    Parameters
    ----------
    frames : sequence of bytes
        The frames, each a PNG file, all of one size.
    fps : float
        Frames per second when playing, > 0.
    alt : str
        The alternative text of the frame's image: what the animation shows.
    mode : {"once", "loop", "reflect"}, optional
        The repeat mode selected at first.

    Returns
    -------
    str
        A ``<div class="animation closedloop-player">`` holding the first frame as an ``<img>``,
        the controls and the other frames (JSON), then its style and its script.

    Raises
    ------
    ValueError
        If there is no frame, a frame is not a PNG image, ``fps`` is not positive or ``mode``
        is not one of :data:`MODES`.
    """
    if not frames:
        raise ValueError("frames: need at least one frame")
    if not fps > 0:
        raise ValueError(f"fps: must be > 0, got {fps!r}")
    if mode not in dict(MODES):
        raise ValueError(f"mode: must be one of {[value for value, _ in MODES]}, got {mode!r}")
    width, height = _size(frames[0])
    buttons = "\n".join(
        f'      <button type="button" data-action="{action}" title="{name}"{" hidden" if action == "pause" else ""}>'
        f'<svg viewBox="0 0 16 16" aria-hidden="true" focusable="false"><path d="{path}"/></svg></button>'
        for action, name, path in BUTTONS)
    modes = "\n".join(
        f'      <label><input type="radio" class="anim-mode" value="{value}"{" checked" if value == mode else ""}>'
        f"<span>{label}</span></label>"
        for value, label in MODES)
    rest = "[" + ",\n".join(json.dumps(_data_uri(png)) for png in frames[1:]) + "]"      # a frame a line
    return (f'<div class="animation closedloop-player" data-interval="{1000.0 / fps:.6g}">\n'
            f'  <img class="anim-frame" src="{_data_uri(frames[0])}" alt="{html.escape(alt, quote=True)}" '
            f'width="{width}" height="{height}">\n'
            f'  <div class="anim-controls" hidden>\n'
            f'    <input type="range" class="anim-slider" min="0" max="{len(frames) - 1}" step="1" value="0" '
            f'title="Frame">\n'
            f'    <div class="anim-buttons">\n{buttons}\n    </div>\n'
            f'    <fieldset class="anim-modes" title="Repeat">\n{modes}\n    </fieldset>\n'
            f'  </div>\n'
            f'  <script type="application/json" class="anim-frames">{rest}</script>\n'
            f'</div>\n{_STYLE}\n{_SCRIPT}\n')
