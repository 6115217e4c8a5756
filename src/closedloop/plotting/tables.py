"""Small tables for the book: an HTML table in a page, aligned plain text in a terminal.

A notebook shows the object's ``_repr_html_`` (a real ``<table>`` that fits the text column), and
a terminal or a plain-text output its ``__repr__`` (columns aligned with spaces).

:func:`rounded_bound` rounds a number that the prose states as a bound, on the side that keeps it one.
"""

from __future__ import annotations

import decimal
import html
import math
import numbers
from collections.abc import Callable, Sequence

__all__ = ["Table", "rounded_bound", "MISSING"]

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
    >>> Table([("RK45", 1.5e-3, 120)], ["method", "error [rad]", "steps"], ["", ".1e", "d"])
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


def rounded_bound(value: float, digits: int = 1, upper: bool = True) -> float:
    """``value`` rounded to ``digits`` significant digits on the side that keeps a bound a bound.

    A sentence such as "|f| stays below 3e-10 m" states an upper bound; printed with ``.0e`` from
    the value itself, 2.6e-10 would read 3e-10 but 2.4e-10 would read 2e-10, which the value
    exceeds. Rounded here first (up for an upper bound, down for a lower one), the number printed
    with ``digits`` significant digits (``.{digits - 1}e``) still bounds the value.

    Parameters
    ----------
    value : float
        The value the prose bounds.
    digits : int, optional
        Significant digits of the printed bound (1 by default).
    upper : bool, optional
        True (the default) for an upper bound ("below", "at most", "within"), rounded up;
        False for a lower bound ("at least", "more than"), rounded down.

    Returns
    -------
    float
        The rounded bound; 0, infinities and NaN are returned unchanged.

    Examples
    --------
    >>> rounded_bound(2.4e-10), rounded_bound(2.4e-10, upper=False), rounded_bound(0.0123, digits=2)
    (3e-10, 2e-10, 0.013)
    """
    if isinstance(digits, bool) or not isinstance(digits, int) or digits < 1:
        raise ValueError(f"digits: need a positive whole number of significant digits, got {digits!r}")
    value = float(value)
    if value == 0.0 or not math.isfinite(value):
        return value
    exact = decimal.Decimal(repr(value))    # the shortest decimal that is this float: 3e-12 stays 3e-12
    quantum = decimal.Decimal(1).scaleb(exact.adjusted() - digits + 1)
    rounded = exact.quantize(quantum, rounding=decimal.ROUND_CEILING if upper else decimal.ROUND_FLOOR)
    return float(rounded)
