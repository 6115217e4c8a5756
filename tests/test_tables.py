"""The book's tables (closedloop.plotting.Table): HTML in a page, aligned text elsewhere."""

import html.parser

import pytest

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


@pytest.mark.parametrize("spec", [".0f", ".1f", ".2f", ".3f", ".1e", ".2e", ".0%", ".3g"])
def test_a_rounded_bound_holds_for_the_value_and_for_the_value_as_printed(spec):
    """Rounded to nearest, a bound printed with the table's digits can fall below the table
    ("below 2.3" above 2.35e-09); rounded in the safe direction it never does, and one of the
    two directions is the number as printed."""
    import numpy as np

    values = np.random.default_rng(36).lognormal(0.0, 4.0, 2000) * np.random.default_rng(7).choice([-1, 1], 2000)
    for value in values:
        shown = float(format(value, spec).rstrip("%")) / (100 if spec.endswith("%") else 1)
        up, down = rounded_bound(value, spec), rounded_bound(value, spec, upper=False)
        assert format(up, spec) == format(float(format(up, spec).rstrip("%")) / (100 if spec.endswith("%") else 1), spec)
        assert up >= value and up >= shown and down <= value and down <= shown, (value, spec, up, down)
        assert up == shown or down == shown


def test_rounded_bound_refuses_a_value_that_is_not_finite():
    with pytest.raises(ValueError, match="finite"):
        rounded_bound(float("nan"), ".2f")
