"""The interactive figures of chapters 8 and 12 (closedloop.plotting.interactive): what they store.

A reader sees only what the figure's data sources hold, so these check the sources against the
library: each basin cell's hover fields against its BasinMap, each cell's motion against the
map's own outcome and excursion, each point of error against time against its row of
book/data/benchmark.json.  The browser side (the tooltip appears) is tests/test_site_interactive.py.
"""

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

pytest.importorskip("bokeh")

from closedloop.plotting.interactive import (CSS_CLASS, basin_motions, bokeh_js_file,  # noqa: E402
                                             interactive_basin_map, interactive_work_precision)
from closedloop.studies.basin import basin_map, grid_values  # noqa: E402
from closedloop.studies.benchmark import load_study  # noqa: E402

ROOT = Path(__file__).resolve().parents[1]


@pytest.fixture(scope="module")
def small_map():
    """8 x 5 cells over 8 s: swings, rotations and sticking sliders."""
    basin = basin_map(grid_values(0.0, 2 * math.pi, 8), grid_values(0.0, 3.0, 5), t_end=8.0)
    assert 0 < basin.fraction_rotating < 1 and np.any(np.isfinite(basin.stuck_at))
    return basin, basin_motions(basin, sample=0.1)


def test_motions_start_at_each_cell_and_reproduce_its_outcome(small_map):
    basin, motions = small_map
    phi0 = np.broadcast_to(basin.phi0, basin.outcome.shape)
    assert motions.times[0] == 0.0 and motions.times[-1] == basin.t_end and motions.step == basin.step
    assert np.array_equal(motions.phi[..., 0], phi0)
    swing = basin.outcome == 0
    # the same integrator: a swing reaches the map's excursion (the batch's Newton runs over other cells)
    assert np.allclose(motions.excursion[swing], basin.excursion[swing], rtol=0, atol=1e-12)
    assert np.all(motions.excursion[~swing] >= 2 * np.pi) and np.all(motions.excursion[swing] < 2 * np.pi)
    # a rotating cell's samples cross phi0 +- 2 pi no earlier than the map says it turned, and within a sample after
    reach = np.abs(motions.phi - phi0[..., None])
    for row, column in zip(*np.nonzero(~swing)):
        first = motions.times[np.argmax(reach[row, column] >= 2 * np.pi)]
        assert basin.decided_at[row, column] <= first + 1e-12
        assert first <= basin.decided_at[row, column] + 0.1 + basin.step
    # a swing's samples stay within its excursion
    assert np.all(reach[swing].max(axis=-1) <= basin.excursion[swing] + 1e-12)


def test_basin_hover_fields_are_the_maps_values(small_map):
    basin, motions = small_map
    figure = interactive_basin_map(basin, motions, selected=(math.pi, 1.3))
    cells = figure.model.select_one({"name": "basin-cells"}).data
    rows, columns = basin.outcome.shape
    for row in range(rows):
        for column in range(columns):
            k = row * columns + column
            assert cells["phi0"][k] == basin.phi0[column] and cells["dphi0"][k] == basin.dphi0[row]
            assert cells["code"][k] == basin.outcome[row, column]
            assert cells["outcome"][k] == basin.labels[int(basin.outcome[row, column])]
            stuck = basin.stuck_at[row, column]
            if np.isfinite(stuck):
                assert cells["stuck_at"][k] == stuck and cells["stuck"][k] == f"at t = {stuck:.2f} s"
            else:
                assert cells["stuck"][k] == "never"
    assert set(cells["outcome"]) == {"oscillation", "full rotation"}


def test_basin_click_shows_the_selected_cells_motion(small_map):
    basin, motions = small_map
    figure = interactive_basin_map(basin, motions, selected=(math.pi, 1.3))
    source = figure.model.select_one({"name": "basin-cells"})
    (k,) = source.selected.indices
    assert source.data["phi0"][k] == basin.phi0[4] and source.data["dphi0"][k] == basin.dphi0[2]   # pi, 1.2
    motion = figure.model.select_one({"name": "basin-motion"}).data
    assert np.array_equal(motion["t"], motions.times)
    assert np.allclose(motion["phi"], motions.phi[2, 4], rtol=1e-6)      # stored as float32
    callback = source.selected.js_property_callbacks["change:indices"][0]
    track = callback.args["track"]
    assert track.dtype == np.float32 and track.size == motions.phi.size
    assert np.allclose(track.reshape(motions.phi.shape), motions.phi, rtol=1e-6)
    limits = figure.model.select_one({"name": "basin-limits"}).data
    assert np.allclose(limits["phi"], [math.pi - 2 * math.pi, math.pi + 2 * math.pi])


def test_figure_html_is_offline_and_self_contained(small_map):
    basin, motions = small_map
    figure = interactive_basin_map(basin, motions)
    page = figure.html()
    assert f'class="{CSS_CLASS}"' in page
    assert not re.search(r"https?://(?!www\.w3\.org)", page), "the figure must not name a remote URL"
    data = re.search(r'<script type="application/json" id="[^"]+">(.*?)</script>', page, re.S).group(1)
    item = json.loads(data)
    assert item["root_id"] and item["doc"]["roots"]
    assert page.count("<script") == 2 and "typeof Bokeh" in page      # without BokehJS: the note, no error
    bundle = figure._repr_mimebundle_()
    assert bundle["text/html"] == page and figure.note in bundle["text/markdown"]
    assert bokeh_js_file().is_file()
    assert len(page.encode()) < 60_000          # 40 cells x 81 samples: far below the book's 5 MB per page


def test_benchmark_points_are_the_json_rows():
    rows = load_study(ROOT / "book" / "data" / "benchmark.json")["rows"]
    figure = interactive_work_precision(rows, case=2)
    sources = [m for m in figure.model.references() if getattr(m, "name", "") and m.name.startswith("benchmark-")
               and m.name != "benchmark-plot"]
    wanted = [r for r in rows if r["case"] == 2 and r["status"] == "ok"]
    seen = 0
    for source in sources:
        key = source.name.removeprefix("benchmark-")
        mine = [r for r in wanted if r["formulation"] == key]
        data = source.data
        assert len(data["cpu_s"]) == len(mine) > 0
        for k, r in enumerate(mine):
            assert data["cpu_s"][k] == r["cpu_s"] and data["error_t10"][k] == r["error_t10"]
            assert data["rtol"][k] == r["rtol"] and data["method"][k] == r["method"] and data["label"][k] == r["label"]
            assert data["error"][k] == max(r["error_t10"], 1e-16)
            assert data["rtol_text"][k] == f"{r['rtol']:.0e}" and data["atol_text"][k] == f"{r['atol']:.0e}"
            assert data["error_text"][k] == f"{r['error_t10']:.2e}"
            assert data["cpu_text"][k] == f"{1e3 * r['cpu_s']:.2f} ms"
        seen += len(mine)
    assert seen == len(wanted) > 50
    with pytest.raises(ValueError, match="no successful rows"):
        interactive_work_precision(rows, case=99)


@pytest.mark.parametrize("case", [1, 2, 3, 4])
def test_the_cpu_axis_spans_two_decades_around_every_point(case):
    # Over less than two decades BokehJS's LogTicker places linear ticks: case 2's CPU times (7 ms to 0.39 s)
    # were labelled 0.1, 0.2, 0.3 and 0.4 s only, nothing below, on screen and in the PDF.
    rows = load_study(ROOT / "book" / "data" / "benchmark.json")["rows"]
    times = [r["cpu_s"] for r in rows if r["case"] == case and r["status"] == "ok"]
    axis = interactive_work_precision(rows, case=case).model.x_range
    low, high = min(times), max(times)
    assert math.log10(axis.end / axis.start) >= 2.2 - 1e-12               # 10 % over the threshold
    assert axis.start <= low / 2 and axis.end >= high * 2                  # every point well inside
    assert math.isclose(low / axis.start, axis.end / high)                 # widened alike at both ends
