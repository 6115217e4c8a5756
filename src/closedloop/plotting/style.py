"""The book's one figure style, ``closedloop.mplstyle``, and the rules every figure keeps.

Every plotting function of the package draws inside :func:`book_style`; a chapter that draws a
figure of its own calls :func:`use_book_style` once, in its first figure cell.  The numbers below
are what the style is measured against (``tests/test_plotting.py``): a figure shown in the
book's text column is :data:`DISPLAY_WIDTH_PX` CSS px wide, and no text in it may render
smaller than :data:`MIN_TEXT_PX`, the page's small print.  matplotlib is imported inside the
functions only.
"""

from __future__ import annotations

import contextlib
from pathlib import Path

__all__ = ["STYLE_PATH", "DISPLAY_WIDTH_PX", "MIN_TEXT_PX", "book_style", "use_book_style",
           "legend_outside", "rendered_text_px"]

#: The style file, shipped with the package (``package-data`` in pyproject.toml).
STYLE_PATH = Path(__file__).with_name("closedloop.mplstyle")

#: Width in CSS px of a figure in the book's text column (Chromium, 1200 x 900 window).
DISPLAY_WIDTH_PX = 624

#: The page's small print (code cells, footer), in CSS px: no figure text is smaller.
MIN_TEXT_PX = 14.0

#: The padding of IPython's tight crop of an inline figure, in inches.
_TIGHT_PAD_IN = 0.1


@contextlib.contextmanager
def book_style():
    """Draw inside the book's style: ``with book_style(): fig = Figure(...)``.

    The style is read when artists are made, so a figure made inside the block keeps it.
    """
    import matplotlib.pyplot as plt

    with plt.style.context(STYLE_PATH):
        yield


def use_book_style():
    """Make the book's style the default of this session (a chapter's first figure cell)."""
    import matplotlib.pyplot as plt

    plt.style.use(STYLE_PATH)


def legend_outside(target, handles=None, labels=None, where="below", ncols=None):
    """A legend beside or below the data, never on it.

    Parameters
    ----------
    target : matplotlib Figure or Axes
        Whose labelled artists to list.  On the right of an Axes, the legend is the axes' own, just
        outside its box; otherwise it is a figure legend in constrained layout's outer margin
        (below, or on the right of, every axes).
    handles, labels : list, optional
        Default: the labelled artists of the target (of all its axes, once each, for a Figure).
    where : {"below", "right"}
    ncols : int, optional
        Columns; default 1 on the right, and below as many as fit in three columns.

    Returns
    -------
    matplotlib.legend.Legend
    """
    from matplotlib.figure import Figure

    if handles is None:
        axes = target.axes if isinstance(target, Figure) else [target]
        handles, labels, seen = [], [], set()
        for ax in axes:
            for handle, label in zip(*ax.get_legend_handles_labels()):
                if label not in seen:
                    seen.add(label)
                    handles.append(handle)
                    labels.append(label)
    elif labels is None:
        labels = [handle.get_label() for handle in handles]
    if ncols is None:
        ncols = 1 if where == "right" else min(3, max(1, len(handles)))
    if where == "right" and not isinstance(target, Figure):
        return target.legend(handles, labels, loc="upper left", bbox_to_anchor=(1.02, 1.0), ncols=ncols,
                             borderaxespad=0.0)
    figure = target if isinstance(target, Figure) else target.figure
    loc = "outside right upper" if where == "right" else "outside lower center"
    return figure.legend(handles, labels, loc=loc, ncols=ncols)


def rendered_text_px(figure, fontsize_pt):
    """The CSS px a text of ``fontsize_pt`` points has when the figure is shown in the book.

    The inline figure is cropped tight (plus :data:`_TIGHT_PAD_IN` each side) and drawn at the
    figure's dpi; the page shows it at its natural width, or scaled down to
    :data:`DISPLAY_WIDTH_PX` when it is wider.

    Parameters
    ----------
    figure : matplotlib.figure.Figure
    fontsize_pt : float

    Returns
    -------
    float
    """
    figure.draw_without_rendering()                   # lays the figure out, as showing it would
    width_in = figure.get_tightbbox().width + 2 * _TIGHT_PAD_IN
    natural_px = width_in * figure.dpi
    scale = min(1.0, DISPLAY_WIDTH_PX / natural_px)
    return fontsize_pt * figure.dpi / 72.0 * scale
