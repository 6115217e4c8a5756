"""The labelled drawings of the mechanisms and their animations.

The drawings must sit where the model puts the bodies (checked against closed-form geometry that
does not use the library's Newton solver, against the constraints along a run, and against the
energies that the centres of mass enter), mark every symbol of Table 1 and of the coordinates,
follow a change of length, and point the gas force as the reading makes it act.  The animations
must play at least 15 frames per second over the whole run, with alt text, offline.
"""

import math
import re

import numpy as np
import pytest

from closedloop import System, simulate
from closedloop.four_bar import four_bar_model, parameter_values
from closedloop.four_bar import points as four_bar_named_points
from closedloop.plotting import (animate_four_bar, animate_slider_crank, four_bar_centres, four_bar_diagram,
                                 four_bar_points, slider_crank_centres, slider_crank_diagram, slider_crank_points)
from closedloop.plotting.animation import playback, render_frames
from closedloop.plotting.player import BUTTONS, player_html
from closedloop.slider_crank import CASES, SliderCrankParameters, initial_state, slider_crank_system
from closedloop.slider_crank import points as slider_crank_named_points

from .conftest import PARALLELOGRAM

#: Every symbol of Table 1, of s = [phi, psi, x_C], of the points and of the applied forces.
SLIDER_CRANK_SYMBOLS = ["$O$", "$A$", "$C$", "$C_1$", "$C_2$", r"$\varphi$", r"$\psi$", "$x_C$", "$l_1$", "$l_2$",
                        "$a_1", "$a_2$", "$m_1", "$m_2", "$m_3$", "I_1$", "I_2$", "$M$", "$g$", "$F$"]
FOUR_BAR_SYMBOLS = ["$O$", "$A$", "$B$", "$D$", r"$\theta_1$", r"$\theta_2", r"$\theta_3$", "$l_0$", "$l_1$",
                    "$l_2$", "$l_3$", "$C_1$, $m_1$", "$C_2$, $m_2$", "$C_3$, $m_3$", "$g$"]


def texts(figure):
    """Every text on the figure, annotations included."""
    return [t.get_text() for ax in figure.axes for t in ax.texts] + [t.get_text() for t in figure.texts]


def named(figure, gid):
    (artist,) = figure.findobj(lambda a: a.get_gid() == gid)
    return artist


def closed_form_slider(l1, l2, phi):
    """x_C of (27)-(28) on the paper's branch, solved by hand: x_C = l1 cos phi + sqrt(l2^2 - l1^2 sin^2 phi)."""
    return l1 * math.cos(phi) + math.sqrt(l2**2 - (l1 * math.sin(phi))**2)


@pytest.mark.parametrize("phi", [0.9, 2.5, -1.2])
def test_slider_crank_is_drawn_where_the_model_puts_it(slider_crank, phi):
    figure = slider_crank_diagram(slider_crank, phi=phi)
    p = slider_crank.parameters
    x_c = closed_form_slider(p.l1, p.l2, phi)
    o, a, c = named(figure, "links").get_xydata()
    assert np.allclose(o, 0.0)
    assert np.allclose(a, [2.0 * math.cos(phi), 2.0 * math.sin(phi)], atol=1e-12)        # Table 1: l1 = 2 m
    assert np.allclose(c, [x_c, 0.0], atol=1e-9)
    slider = named(figure, "slider")
    assert slider.get_x() + slider.get_width() / 2 == pytest.approx(x_c, abs=1e-9)
    assert named(figure, "x_C").xy == pytest.approx((x_c, named(figure, "x_C").xy[1]), abs=1e-9)
    assert named(figure, "x_C").xyann[0] == pytest.approx(0.0, abs=1e-12)                  # measured from O
    # C1 at O (a1 = 0), C2 at a2 = 1.75 m from A along the rod towards C
    assert np.allclose(named(figure, "C1").get_xydata(), [[0.0, 0.0]])
    (c2,) = named(figure, "C2").get_xydata()
    assert np.linalg.norm(c2 - a) == pytest.approx(1.75, abs=1e-9)
    assert np.allclose(c2, a + 1.75 / 3.5 * (c - a), atol=1e-9)


def test_slider_crank_drawing_marks_every_symbol_with_table_1(slider_crank):
    shown = texts(slider_crank_diagram(slider_crank))
    missing = [symbol for symbol in SLIDER_CRANK_SYMBOLS if not any(symbol in text for text in shown)]
    assert missing == []
    values = " ".join(shown)
    for entry in ("$l_1$ = 2 m", "$a_1$ = 0 m", "$m_1$ = 200 kg", "$I_1$ = 450 kg m²", "$l_2$ = 3.5 m",
                  "$a_2$ = 1.75 m", "$m_2$ = 35 kg", "$I_2$ = 35 kg m²", "$m_3$ = 25 kg", "$g$ = 9.81 m/s²"):
        assert entry in values


def test_changing_a_length_moves_the_drawing():
    longer = slider_crank_system(SliderCrankParameters(l1=1.5, a1=0.4, l2=4.0))
    figure = slider_crank_diagram(longer, phi=0.9)
    _, a, c = named(figure, "links").get_xydata()
    assert np.allclose(a, [1.5 * math.cos(0.9), 1.5 * math.sin(0.9)])
    assert c[0] == pytest.approx(closed_form_slider(1.5, 4.0, 0.9), abs=1e-9)
    assert c[0] != pytest.approx(closed_form_slider(2.0, 3.5, 0.9), abs=1e-3)
    assert np.allclose(named(figure, "C1").get_xydata(), [[0.4 * math.cos(0.9), 0.4 * math.sin(0.9)]])
    assert any("$a_1$" == text for text in texts(figure))                # a dimension line now, not "a1 = 0"


@pytest.mark.parametrize("reading, towards_o", [("decimal-opposing", True), ("decimal-as-printed", False)])
def test_gas_force_points_as_the_reading_makes_it_act(reading, towards_o):
    figure = slider_crank_diagram(slider_crank_system(reading=reading), phi=0.9)
    arrow = named(figure, "F")
    head, tail = arrow.xy[0], arrow.xyann[0]
    assert (head < tail) == towards_o
    assert named(figure, "g").xy[1] < named(figure, "g").xyann[1]           # gravity down
    assert named(figure, "g").xy[0] == named(figure, "g").xyann[0]


def test_four_bar_drawing_closes_the_loop_and_marks_every_symbol():
    system = System(four_bar_model(), PARALLELOGRAM)
    figure = four_bar_diagram(system, theta1=1.1)
    o, a, b, d = named(figure, "links").get_xydata()
    assert np.allclose(a, [math.cos(1.1), math.sin(1.1)])
    assert np.allclose(b, [3.0 + math.cos(1.1), math.sin(1.1)], atol=1e-9)           # the parallelogram
    assert np.allclose(d, [3.0, 0.0])
    assert np.allclose(named(figure, "C2").get_xydata(), [(a + b) / 2])
    shown = texts(figure)
    assert [symbol for symbol in FOUR_BAR_SYMBOLS if not any(symbol in text for text in shown)] == []
    wider = four_bar_diagram(System(four_bar_model(), dict(PARALLELOGRAM, l0=3.2)), theta1=1.1)
    assert named(wider, "links").get_xydata()[3] == pytest.approx([3.2, 0.0])
    assert "$l_0$ = 3.2 m" in " ".join(texts(wider))


# -- the positions have one home: the mechanism's points, which the model's equations use too -----

#: A slider-crank whose crank's centre of mass lies off the pivot (Table 1 puts it at O, a1 = 0).
OFFSET_CRANK = SliderCrankParameters(l1=1.5, a1=0.4, l2=4.0, a2=1.1)


def directional_derivative(function, s, direction, h=1e-6):
    """d/dt function(s + t direction) at t = 0, by central differences (error ~ h^2)."""
    return (function(s + h * direction) - function(s - h * direction)) / (2 * h)


def test_the_drawn_joints_satisfy_the_constraints_along_a_run(slider_crank, parallelogram, parallelogram_swing):
    """Each frame of an animation draws the run's state: its links have their lengths as far as the state
    satisfies f(s) = 0 (the triangle inequality: | |AC| - l2 | <= |f|), and the slider stays on its guide."""
    case = CASES[2]
    run = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 2.0, t_eval=np.linspace(0, 2, 101))
    p = slider_crank.parameters
    for s in run.s.T:
        o, a, c = slider_crank_points(s, p)
        residual = np.linalg.norm(slider_crank.constraints(s))
        assert residual < 1e-6
        assert np.array_equal(o, [0.0, 0.0]) and c[1] == 0.0 and c[0] == s[2]
        assert abs(np.linalg.norm(a - o) - p.l1) < 1e-12
        assert abs(np.linalg.norm(c - a) - p.l2) <= residual + 1e-12
    _, swing = parallelogram_swing
    lengths = parameter_values(parallelogram)
    for s in swing.s.T[::10]:
        o, a, b, d = four_bar_points(s, lengths)
        residual = np.linalg.norm(parallelogram.constraints(s))
        assert residual < 1e-6 and np.array_equal(o, [0.0, 0.0]) and np.array_equal(d, [lengths["l0"], 0.0])
        assert abs(np.linalg.norm(a - o) - lengths["l1"]) < 1e-12
        assert abs(np.linalg.norm(b - a) - lengths["l2"]) < 1e-12
        assert abs(np.linalg.norm(b - d) - lengths["l3"]) <= residual + 1e-12


def test_the_model_s_constraints_close_the_loop_of_the_points(parallelogram):
    """Off the loop too (any s), f(s) is the gap between the two ends that the loop joins."""
    system = slider_crank_system(OFFSET_CRANK)
    rng = np.random.default_rng(35)
    for s in rng.uniform(-4.0, 4.0, (20, 3)):
        at = slider_crank_named_points(s, OFFSET_CRANK.as_dict())
        assert np.allclose(system.constraints(s), np.subtract(at["rod end"], at["C"]), rtol=0, atol=1e-14)
        at = four_bar_named_points(s, parameter_values(parallelogram))
        assert np.allclose(parallelogram.constraints(s), np.subtract(at["B"], at["rocker end"]), rtol=0, atol=1e-14)


def test_the_drawn_centres_are_those_of_the_energies():
    """T and Pi of the model, against the same energies summed over the drawn centres of mass: m g y for Pi,
    m |v|^2 / 2 + I omega^2 / 2 for T with v the centre's velocity (differentiated numerically), so that
    the kinetic energy (5.a) as printed, typed apart from the points, checks them too."""
    system = slider_crank_system(OFFSET_CRANK)
    p = OFFSET_CRANK
    rng = np.random.default_rng(36)
    for s, sd in zip(rng.uniform(-4.0, 4.0, (20, 3)), rng.uniform(-3.0, 3.0, (20, 3))):
        T, Pi = system.kinetic_and_potential_energy(s, sd)
        c1, c2 = slider_crank_centres(s, p)
        c = slider_crank_points(s, p)[2]
        v1, v2 = directional_derivative(lambda q: slider_crank_centres(q, p), s, sd)
        vc = directional_derivative(lambda q: slider_crank_points(q, p)[2], s, sd)
        assert p.a1 > 0 and np.linalg.norm(c1) == pytest.approx(p.a1)
        assert Pi == pytest.approx(p.g * (p.m1 * c1[1] + p.m2 * c2[1] + p.m3 * c[1]), rel=1e-12, abs=1e-9)
        assert T == pytest.approx(0.5 * (p.m1 * v1 @ v1 + p.I1 * sd[0]**2 + p.m2 * v2 @ v2 + p.I2 * sd[1]**2
                                         + p.m3 * vc @ vc), rel=1e-8)
    values = dict(PARALLELOGRAM, l0=3.2, l2=2.5, m1=1.5, m2=2.0, m3=0.7)
    four = System(four_bar_model, values)
    masses = np.array([values["m1"], values["m2"], values["m3"]])
    inertias = masses * np.array([values["l1"], values["l2"], values["l3"]]) ** 2 / 12      # uniform bars
    for s, sd in zip(rng.uniform(-4.0, 4.0, (20, 3)), rng.uniform(-3.0, 3.0, (20, 3))):
        T, Pi = four.kinetic_and_potential_energy(s, sd)
        centres = four_bar_centres(s, values)
        velocities = directional_derivative(lambda q: four_bar_centres(q, values), s, sd)
        assert Pi == pytest.approx(values["g"] * masses @ centres[:, 1], rel=1e-12, abs=1e-9)
        assert T == pytest.approx(0.5 * (masses @ np.sum(velocities**2, axis=1) + inertias @ sd**2), rel=1e-8)


def test_playback_is_at_least_15_frames_a_second():
    assert playback(20.0) == (100, 3.0)               # 20 s of motion in 6.7 s of playback
    assert playback(5.0) == (75, 1.0)
    assert playback(0.5, fps=20) == (80, 0.125)            # slow motion over 4 s
    frames, speed = playback(3.0, frames=30)
    assert frames / (3.0 / speed) == pytest.approx(15.0)


def test_animations_are_smooth_labelled_and_offline(slider_crank, parallelogram_swing):
    case = CASES[2]
    result = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 1.0,
                      t_eval=np.linspace(0, 1, 101))
    html = animate_slider_crank(result, slider_crank.parameters, title="Case 2")
    assert html.count("data:image/png;base64,") == 60            # 1 s of motion in 4 s of playback
    assert 'data-interval="66.6667"' in html                     # ms a frame: 15 frames a second
    assert 'alt="Animation of the slider-crank (Case 2)' in html
    assert "https://" not in html and "http://" not in html and "<link" not in html and "src=\"/" not in html
    assert len(html) < 60 * 8_000
    _, swing = parallelogram_swing
    html = animate_four_bar(swing, {k: PARALLELOGRAM[k] for k in ("l0", "l1", "l2", "l3")}, alt="a swing")
    assert html.count("data:image/png;base64,") == 75 and 'alt="a swing"' in html


def test_the_player_names_each_control_once_in_its_html():
    """Each text of the player stands once, as written, in the HTML (a translated edition replaces it there)."""
    frames = [_png(k) for k in range(3)]
    html = player_html(frames, 10, 'a "quoted" <alt>', mode="reflect")
    for text in ("<span>Once</span>", "<span>Loop</span>", "<span>Reflect</span>", 'title="Frame"',
                 'title="Repeat"', *(f'title="{name}"' for _, name, _ in BUTTONS)):
        assert html.count(text) == 1, text
    assert 'alt="a &quot;quoted&quot; &lt;alt&gt;"' in html
    assert re.findall(r'value="(\w+)" checked', html) == ["reflect"]
    assert 'width="4" height="3"' in html and 'data-interval="100"' in html
    for bad, message in (([], "frames"), ([b"GIF89a"], "PNG"), ):
        with pytest.raises(ValueError, match=message):
            player_html(bad, 10, "x")
    with pytest.raises(ValueError, match="fps"):
        player_html(frames, 0, "x")
    with pytest.raises(ValueError, match="mode"):
        player_html(frames, 10, "x", mode="bounce")


def _png(shade, size=(4, 3)):
    """A small grey PNG file."""
    import io

    from PIL import Image

    packed = io.BytesIO()
    Image.new("L", size, 40 * shade).save(packed, format="png")
    return packed.getvalue()


def test_drawing_only_the_moving_parts_gives_the_pixels_of_whole_frames(slider_crank):
    """render_frames draws the still parts once (blitting); its frames are those of drawing each whole, byte for
    byte, with still parts below the mechanism (a grey copy) and above it (the scale bar)."""
    from closedloop.plotting import draw_slider_crank
    from closedloop.plotting.annotate import scale_bar

    case = CASES[4]
    result = simulate(slider_crank, initial_state(slider_crank, case.phi0, case.dphi0), 2.0,
                      t_eval=np.linspace(0, 2, 41))
    p = slider_crank.parameters

    def setup(ax):
        ax.set_xlim(-2.5, 6.0)
        ax.set_ylim(-2.5, 2.5)
        draw_slider_crank(ax, result.s[:, 0], p, color="0.8")
        scale_bar(ax, (0.5, -0.1), 1.0, 10)                        # drawn over the moving links' zorder

    def draw(ax, s):
        return draw_slider_crank(ax, s, p, labels="light", fontsize=11)

    blitted = render_frames(result, setup, draw, (4.0, 2.6), frames=6, title="t", dpi=60)
    whole = render_frames(result, setup, draw, (4.0, 2.6), frames=6, title="t", dpi=60, blit=False)
    assert len(blitted) == 6 and len(set(blitted)) == 6
    assert blitted == whole


@pytest.fixture(scope="module")
def chromium_page():
    """A page of headless Chromium that records console errors and requests; skipped without Chromium."""
    import sys
    from pathlib import Path

    sys.path.insert(0, str(Path(__file__).resolve().parents[1] / "book" / "print"))
    from print_pdf import CHROMIUM_FLAGS, chromium

    if not Path(chromium()).exists():
        pytest.skip(f"the player was NOT tried in a browser: {chromium()} not found (make test installs it)")
    from playwright.sync_api import sync_playwright

    with sync_playwright() as playwright:
        browser = playwright.chromium.launch(executable_path=chromium(), args=CHROMIUM_FLAGS)
        page = browser.new_page()
        page.problems, page.requests = [], []
        page.on("console", lambda m: m.type == "error" and page.problems.append(m.text))
        page.on("pageerror", lambda e: page.problems.append(str(e)))
        page.on("request", lambda r: page.requests.append(r.url))
        yield page
        browser.close()


def test_the_player_s_controls_work_in_a_browser(chromium_page):
    """Two players on one page (the same frames twice): the buttons, the slider and the three repeat modes of the
    first, while the second stays where it was; no request, no error."""
    page = chromium_page
    frames = [_png(k) for k in range(5)]
    one = player_html(frames, 50, "five greys")
    page.set_content(f"<!doctype html><html><body>{one}{one}</body></html>")
    first, second = page.locator("div.closedloop-player").all()
    sources = [f"data:image/png;base64,{__import__('base64').b64encode(png).decode()}" for png in frames]

    def shown(box=first):
        return sources.index(box.locator("img").get_attribute("src"))

    def button(action):
        return first.locator(f'button[data-action="{action}"]')

    assert first.locator("div.anim-controls").is_visible() and not button("pause").is_visible()
    for action, expected in (("next", 1), ("last", 4), ("previous", 3), ("first", 0)):
        button(action).click()
        assert shown() == expected, action
    first.locator("input.anim-slider").fill("2")
    assert shown() == 2
    first.get_by_text("Once", exact=True).click()
    button("play").click()
    assert button("pause").is_visible() and not button("play").is_visible()
    page.wait_for_function("box => !box.querySelector('button[data-action=\"play\"]').hidden", arg=first.element_handle(),
                           timeout=5000)
    assert shown() == 4                                             # once: stopped at the last frame
    page.evaluate("""box => {
        const image = box.querySelector('img');
        window.shownFrames = [];
        new MutationObserver(() => window.shownFrames.push(image.getAttribute('src')))
            .observe(image, {attributes: true, attributeFilter: ['src']});
    }""", first.element_handle())
    seen, paused_at = {}, {}
    for mode in ("Loop", "Reflect"):
        first.get_by_text(mode, exact=True).click()
        page.evaluate("() => { window.shownFrames = []; }")
        button("play").click()
        page.wait_for_function("() => window.shownFrames.length >= 12", timeout=5000)
        button("pause").click()
        seen[mode] = [sources.index(src) for src in page.evaluate("() => window.shownFrames")][:12]
        paused_at[mode] = shown()
    assert seen["Loop"] == [0, 1, 2, 3, 4, 0, 1, 2, 3, 4, 0, 1]          # from the last frame, once left it
    expected, frame, step = [], paused_at["Loop"], 1                     # Reflect goes on from there, forwards
    while len(expected) < 12:
        if not 0 <= frame + step <= 4:
            step = -step                                                 # and turns back at either end
        frame += step
        expected.append(frame)
    assert seen["Reflect"] == expected and max(expected) == 4 and min(expected) == 0
    paused = shown()
    page.wait_for_timeout(150)
    assert shown() == paused
    assert shown(second) == 0 and second.locator("input.anim-mode:checked").get_attribute("value") == "loop"
    names = page.evaluate("() => [...document.querySelectorAll('input.anim-mode')].map(r => r.name)")
    assert len(set(names[:3])) == len(set(names[3:])) == 1 and names[0] != names[3]
    assert page.problems == [] and page.requests == []
