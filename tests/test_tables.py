"""The book's tables (closedloop.plotting.Table): HTML in a page, aligned text elsewhere; and the bounds its
prose states (closedloop.plotting.rounded_bound), rounded on their safe side."""

import html.parser
import math

import pytest
from hypothesis import given
from hypothesis import strategies as st

from closedloop.plotting import Table, rounded_bound


class Cells(html.parser.HTMLParser):
    """Collect (tag, class, text) of every th and td."""

    def __init__(self):
        super().__init__()
        self.cells, self.open = [], None

    def handle_starttag(self, tag, attrs):
        if tag in ("th", "td"):
            self.open = [tag, dict(attrs).get("class"), ""]

    def handle_data(self, data):
        if self.open:
            self.open[2] += data

    def handle_endtag(self, tag):
        if tag in ("th", "td"):
            self.cells.append(tuple(self.open))
            self.open = None


def parse(table):
    parser = Cells()
    parser.feed(table._repr_html_())
    return parser.cells


def test_values_are_formatted_once_per_column():
    table = Table([("RK45", 1.234e-3, 120), ("Radau", None, 7)], ["method", "error [rad]", "steps"],
                  ["", ".1e", "d"])
    assert table.cells == [["RK45", "1.2e-03", "120"], ["Radau", "-", "7"]]
    assert parse(table) == [("th", "text", "method"), ("th", "num", "error [rad]"), ("th", "num", "steps"),
                            ("td", "text", "RK45"), ("td", "num", "1.2e-03"), ("td", "num", "120"),
                            ("td", "text", "Radau"), ("td", "num", "-"), ("td", "num", "7")]


def test_plain_text_aligns_numbers_right_and_words_left():
    table = Table([("a", 1.5), ("long name", 10.25)], ["name", "x"], ["", ".2f"], caption="two rows")
    assert repr(table).splitlines() == ["two rows",
                                        "name           x",
                                        "a           1.50",
                                        "long name  10.25"]


def test_text_is_escaped_and_a_callable_formats():
    table = Table([("<b>&", 3)], ["what", "n"], [None, lambda n: f"{n} x"], caption="a < b")
    markup = table._repr_html_()
    assert "<b>&" not in markup and "&lt;b&gt;&amp;" in markup
    assert "<caption>a &lt; b</caption>" in markup
    assert parse(table)[-1] == ("td", "num", "3 x")


def test_a_column_of_text_stays_left_aligned_even_with_numbers_in_other_columns():
    table = Table([(True, "x"), (False, "y")], ["flag", "name"])
    assert [cell[1] for cell in parse(table)[:2]] == ["text", "text"]


@pytest.mark.parametrize("rows, columns, formats", [
    ([(1, 2, 3)], ["a", "b"], None),
    ([(1, 2)], ["a", "b"], ["d"]),
])
def test_a_row_or_formats_of_the_wrong_length_is_refused(rows, columns, formats):
    with pytest.raises(ValueError, match="columns"):
        Table(rows, columns, formats)


@given(value=st.floats(min_value=1e-300, max_value=1e300), digits=st.integers(1, 4), upper=st.booleans())
def test_a_rounded_bound_printed_with_its_digits_still_bounds_the_value(value, digits, upper):
    bound = rounded_bound(value, digits, upper)
    printed = float(format(bound, f".{digits - 1}e"))      # what the prose shows, read back
    assert printed == bound
    assert (printed >= value) if upper else (printed <= value)
    unit = 10.0 ** (math.floor(math.log10(value)) - digits + 1)   # one step of the last printed digit
    assert abs(printed - value) <= 1.000001 * unit, "rounded further than one digit"


@pytest.mark.parametrize("value, digits, upper, expected", [
    (2.4e-10, 1, True, 3e-10), (2.4e-10, 1, False, 2e-10), (2.6e-12, 1, True, 3e-12), (3e-12, 1, True, 3e-12),
    (9.99e-13, 1, True, 1e-12), (0.0123, 2, True, 0.013), (-2.4e-10, 1, True, -2e-10), (0.0, 1, True, 0.0),
])
def test_rounded_bound_examples(value, digits, upper, expected):
    """Nearest rounding prints 2.4e-10 as 2e-10, below the value: an upper bound goes up instead."""
    assert rounded_bound(value, digits, upper) == expected


@pytest.mark.parametrize("digits", [0, 1.5, True])
def test_rounded_bound_refuses_a_number_of_digits_that_is_not_a_positive_whole_number(digits):
    with pytest.raises(ValueError, match="digits"):
        rounded_bound(1.0, digits)
