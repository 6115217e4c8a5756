"""Small tables for the book: an HTML table in a page, aligned plain text in a terminal.

A notebook shows the object's ``_repr_html_`` (a real ``<table>`` that fits the text column), and
a terminal or a plain-text output its ``__repr__`` (columns aligned with spaces).
:func:`rounded_bound` rounds a bound that a sentence states beside such printed numbers.
"""

from __future__ import annotations

import html
import math
import numbers
from collections.abc import Callable, Sequence
from decimal import Decimal

#: What a cell holding ``None`` shows.
MISSING = "-"


class Table:
    """Rows of values under column headings, formatted once, shown as HTML or as text.

    Parameters
    ----------
    rows : sequence of sequences
        One sequence of values per row, as many values as `columns`.
    columns : sequence of str
        The column headings.
    formats : sequence of (str or callable or None), optional
        One per column: a format specification for :func:`format` (``".1e"``, ``"d"``), a
        callable from the value to its text, or None for ``str``. A cell holding None shows
        :data:`MISSING` whatever its format.
    caption : str, optional
        A line shown above the table.

    Raises
    ------
    ValueError
        If a row or `formats` does not have one entry per column.

    Examples
    --------
    >>> Table([("RK45", 1.5e-3, 120)], ["method", "error [rad]", "steps"],
    ...       ["", ".1e", "d"])
    method  error [rad]  steps
    RK45        1.5e-03    120
    """

    def __init__(self, rows: Sequence[Sequence], columns: Sequence[str],
                 formats: Sequence[str | Callable | None] | None = None, caption: str | None = None):
        self.columns = [str(column) for column in columns]
        formats = [None] * len(self.columns) if formats is None else list(formats)
        if len(formats) != len(self.columns):
            raise ValueError(f"{len(formats)} formats for {len(self.columns)} columns")
        self.rows = [list(row) for row in rows]
        for number, row in enumerate(self.rows):
            if len(row) != len(self.columns):
                raise ValueError(f"row {number} has {len(row)} values for {len(self.columns)} columns")
        self.caption = caption
        self.cells = [[_format(value, spec) for value, spec in zip(row, formats)] for row in self.rows]
        # a column of numbers (None allowed) is right-aligned, any other left-aligned
        self.numeric = [all(row[k] is None or (isinstance(row[k], numbers.Number) and not isinstance(row[k], bool))
                            for row in self.rows) and any(row[k] is not None for row in self.rows)
                        for k in range(len(self.columns))]

    def __repr__(self) -> str:
        widths = [max([len(column), *(len(row[k]) for row in self.cells)]) for k, column in enumerate(self.columns)]

        def line(texts):
            return "  ".join(text.rjust(width) if numeric else text.ljust(width)
                             for text, width, numeric in zip(texts, widths, self.numeric)).rstrip()

        lines = [line(self.columns), *(line(row) for row in self.cells)]
        return "\n".join(([self.caption] if self.caption else []) + lines)

    def _repr_html_(self) -> str:
        def cells(tag, texts):
            return "".join(f'<{tag} class="{"num" if numeric else "text"}">{html.escape(text)}</{tag}>'
                           for text, numeric in zip(texts, self.numeric))

        caption = f"<caption>{html.escape(self.caption)}</caption>" if self.caption else ""
        body = "".join(f"<tr>{cells('td', row)}</tr>" for row in self.cells)
        return (f'<table class="closedloop-table">{caption}<thead><tr>{cells("th", self.columns)}</tr></thead>'
                f"<tbody>{body}</tbody></table>")


def _format(value, spec) -> str:
    if value is None:
        return MISSING
    if callable(spec):
        return str(spec(value))
    if not spec:
        return str(value)
    return format(value, spec)


def rounded_bound(value, spec, upper=True):
    """``value`` rounded in the safe direction to the digits that ``format(value, spec)`` shows.

    A sentence that states a bound beside printed numbers ("|f| stays at most 2.36e-09 m" above a
    table printing ``2.35e-09``) must hold for the value and for the value as printed. Rounding to
    nearest can break it (2.356 printed with ``.2f`` is 2.36, but "below 2.35" is false); this
    rounds an upper bound up and a lower bound down, with the same digits, so that the bound,
    printed with ``spec``, is at least (at most) both the value and the value printed with ``spec``.

    Parameters
    ----------
    value : float
        The value the bound is for: the largest of the values bounded, or for a lower bound the
        smallest.
    spec : str
        The format specification the page prints the bound with (``".2f"``, ``".1e"``, ``".0%"``).
    upper : bool, optional
        True (default) for an upper bound, rounded up; False for a lower bound, rounded down.

    Returns
    -------
    float
        The bound, which ``format(bound, spec)`` prints exactly.

    Raises
    ------
    ValueError
        If ``value`` is not finite.

    Examples
    --------
    >>> rounded_bound(2.3456e-9 / 1e-9, ".2f")
    2.35
    >>> rounded_bound(4.41e-9, ".1e")
    4.5e-09
    >>> rounded_bound(0.9687, ".3f", upper=False)
    0.968
    >>> format(rounded_bound(0.3401, ".0%"), ".0%")
    '35%'
    """
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"value must be finite, got {value!r}")
    text = format(value, spec)
    percent = text.endswith("%")
    shown = Decimal(text.rstrip("%"))
    step = Decimal(1).scaleb(shown.as_tuple().exponent)
    if percent:
        shown, step = shown / 100, step / 100
    if upper and float(shown) < value:
        shown += step
    elif not upper and float(shown) > value:
        shown -= step
    return float(shown)
