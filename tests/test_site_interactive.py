"""The interactive figures in the built site, as a reader uses them: hover, click, offline.

Opens chapters 8 and 12 of the built book in headless Chromium (the ``site`` and ``browser``
fixtures of test_site.py), hovers a basin cell and a benchmark point, and checks the tooltip
against the library: the basin cell's outcome and sticking time recomputed for that start by
the batch integrator, the benchmark point's run read from book/data/benchmark.json.  Clicking a
cell must show that cell's motion.  Any request to a URL off the local server fails the test
(BokehJS is shipped in ``_static``), and each page stays under 5 MB.
"""

import json
import math
import re
from pathlib import Path

import numpy as np
import pytest

from .test_site import HTML, browser, site  # noqa: F401  (the fixtures)

ROOT = Path(__file__).resolve().parents[1]
PAGE_LIMIT = 5_000_000          # bytes of a page's HTML, its figures' data included

#: Where a cell or point is on screen, from the plot's own scales; and the tooltip's text.
LOCATE = """([plot, source, index, x, y]) => {
    const doc = Bokeh.documents[0];
    const view = Bokeh.index.get_one(doc.get_model_by_name(plot));
    view.el.scrollIntoView({block: "center"});
    const data = doc.get_model_by_name(source).data;
    const box = view.canvas_view.el.getBoundingClientRect();
    return {x: box.left + view.frame.x_scale.compute(data[x][index]),
            y: box.top + view.frame.y_scale.compute(data[y][index])};
}"""


def open_figure_page(browser, site, name, source):  # noqa: F811
    page = browser.new_page(viewport={"width": 1200, "height": 900})
    problems = []
    page.on("request", lambda r: r.url.startswith((site, "data:", "blob:"))
            or problems.append(f"request to a non-local URL: {r.url}"))
    page.on("requestfailed", lambda r: problems.append(f"request failed: {r.url}"))
    page.on("pageerror", lambda e: "THEBE_JS_URL" in str(e) or problems.append(f"page error: {e}"))
    page.goto(f"{site}/{name}.html", wait_until="networkidle")
    page.wait_for_function(f"""() => window.Bokeh && Bokeh.documents.length
                           && Bokeh.documents[0].get_model_by_name("{source}")""", timeout=20_000)
    return page, problems


def hover(page, plot, source, index, x, y):
    spot = page.evaluate(LOCATE, [plot, source, index, x, y])
    page.mouse.move(spot["x"], spot["y"])
    tooltip = page.locator(".bk-tooltip-content")
    tooltip.first.wait_for(state="visible", timeout=5_000)
    return "\n".join(tooltip.all_inner_texts()), spot


def test_basin_map_tooltip_and_click(browser, site):  # noqa: F811
    from closedloop.slider_crank import MOTIONS, slider_crank_system
    from closedloop.studies.basin import integrate_outcomes

    page, problems = open_figure_page(browser, site, "chapters/12-basins", "basin-cells")
    cells = page.evaluate("""() => {const d = Bokeh.documents[0].get_model_by_name("basin-cells").data;
        return {phi0: Array.from(d.phi0), dphi0: Array.from(d.dphi0), code: Array.from(d.code),
                stuck_at: Array.from(d.stuck_at, v => Number.isFinite(v) ? v : null)}}""")
    codes, stuck = np.array(cells["code"]), np.array([s is not None for s in cells["stuck_at"]])
    picks = [int(np.flatnonzero(codes == 1)[len(np.flatnonzero(codes == 1)) // 2]),     # a full rotation
             int(np.flatnonzero((codes == 0) & stuck)[0])]                             # a swing that sticks
    system = slider_crank_system()
    for index in picks:
        text, spot = hover(page, "basin-map", "basin-cells", index, "phi0", "dphi0")
        phi0, dphi0 = cells["phi0"][index], cells["dphi0"][index]
        assert f"φ₀ = {phi0:.4f} rad" in text and f"φ̇₀ = {dphi0:.4f} rad/s" in text, text
        run = integrate_outcomes(system, [phi0], [dphi0], 20.0)          # the map's integrator, this cell alone
        assert MOTIONS[int(run.codes[0])] in text.splitlines()[0], text
        expected = "never" if not np.isfinite(run.stuck_at[0]) else f"at t = {run.stuck_at[0]:.2f} s"
        assert f"slider stuck: {expected}" in text, text
        page.mouse.click(spot["x"], spot["y"])                            # click: this cell's motion
        page.wait_for_timeout(300)
        motion = page.evaluate("""() => {const doc = Bokeh.documents[0];
            return {phi: Array.from(doc.get_model_by_name("basin-motion").data.phi),
                    title: doc.get_model_by_name("basin-motion-plot").title.text}}""")
        assert abs(motion["phi"][0] - phi0) < 1e-5, motion["phi"][:3]
        assert f"φ₀ = {phi0:.2f}, φ̇₀ = {dphi0:.2f}" in motion["title"], motion["title"]
        reach = np.max(np.abs(np.array(motion["phi"]) - phi0))
        assert (reach >= 2 * math.pi - 1e-3) == (int(run.codes[0]) == 1)
    shots = ROOT / "_build" / "screenshots"
    shots.mkdir(parents=True, exist_ok=True)
    hover(page, "basin-map", "basin-cells", picks[0], "phi0", "dphi0")
    page.screenshot(path=str(shots / "basin-tooltip.png"))
    page.close()
    assert problems == []


def test_benchmark_point_tooltip(browser, site):  # noqa: F811
    rows = json.loads((ROOT / "book" / "data" / "benchmark.json").read_text())["rows"]
    page, problems = open_figure_page(browser, site, "chapters/08-error-vs-runtime", "benchmark-minimal")
    points = page.evaluate("""() => {const d = Bokeh.documents[0].get_model_by_name("benchmark-minimal").data;
        const all = {cpu: [], error: []};
        for (const m of Bokeh.documents[0].all_models)
            if (m.data && m.data.cpu_s && m.data.error) {
                all.cpu.push(...Array.from(m.data.cpu_s)); all.error.push(...Array.from(m.data.error)); }
        return {cpu: Array.from(d.cpu_s), error: Array.from(d.error), n: d.cpu_s.length, all: all}}""")
    # the point farthest (in log space) from every other point on the plot, of any formulation: the
    # tooltip under the pointer is then its own (a point of another formulation on top would show first)
    x, y = np.log10(points["cpu"]), np.log10(points["error"])
    every_x, every_y = np.log10(points["all"]["cpu"]), np.log10(points["all"]["error"])
    spread = [np.sort(np.hypot(every_x - x[k], every_y - y[k]))[1] for k in range(len(x))]   # [0]: itself
    index = int(np.argmax(spread))
    text, _ = hover(page, "benchmark-plot", "benchmark-minimal", index, "cpu_s", "error")
    page.close()
    assert problems == []
    block = re.search(r"(.+)\nmethod (\S+), rtol (\S+), atol (\S+)\nerror e₁₀ = (\S+)\nCPU time = (\S+) ms", text)
    assert block, f"tooltip did not show a run: {text!r}"
    label, method, rtol, atol, error, cpu = block.groups()
    row = [r for r in rows if r["case"] == 2 and r["status"] == "ok" and r["label"] == label
           and r["method"] == method and f"{r['rtol']:.0e}" == rtol]
    assert len(row) == 1, (text, len(row))
    row = row[0]
    assert row["formulation"] == "minimal"
    assert atol == f"{row['atol']:.0e}" and error == f"{row['error_t10']:.2e}" and cpu == f"{1e3 * row['cpu_s']:.2f}"
    assert abs(row["cpu_s"] - points["cpu"][index]) == 0                     # the point hovered is this row


@pytest.mark.parametrize("name", ["chapters/08-error-vs-runtime", "chapters/12-basins"])
def test_interactive_pages_stay_light_and_ship_bokehjs(site, name):  # noqa: F811
    page = (HTML / f"{name}.html").read_text()
    assert len(page.encode()) < PAGE_LIMIT, f"{name}.html is {len(page.encode()) / 1e6:.2f} MB"
    scripts = re.findall(r'<script[^>]+src="([^"]*bokeh[^"]*)"', page)
    assert len(scripts) == 1 and not scripts[0].startswith(("http:", "https:", "//")), scripts
    assert (HTML / name).parent.joinpath(scripts[0].split("?")[0]).resolve().is_file()
