"""Shared fixtures: the slider-crank of the paper and a pendulum with a known ODE."""

import atexit
import math
import os
import shutil
import tempfile

import numpy as np
import pytest
import sympy as sp

from closedloop import MultibodyModel, System
from closedloop.four_bar import four_bar_model
from closedloop.slider_crank import slider_crank_system


def pytest_configure(config):
    """Generated code goes to a fresh temporary cache folder (closedloop.codecache), never to ~/.cache.

    Set before any test is collected, so the commands that tests start inherit it too; removed
    when the session's process ends.
    """
    folder = tempfile.mkdtemp(prefix="closedloop-test-cache-")
    os.environ["CLOSEDLOOP_CACHE_DIR"] = folder
    atexit.register(shutil.rmtree, folder, ignore_errors=True)


@pytest.fixture(scope="session")
def slider_crank():
    """Table 1, the paper's reading of the data, torque and gas force on."""
    return slider_crank_system()


@pytest.fixture(scope="session")
def conservative_slider_crank():
    """Table 1 with the drive torque and the gas force switched off."""
    return slider_crank_system(torque=False, gas=False)


def pendulum_model():
    """A pendulum in redundant coordinates (theta, x, y): x = l sin theta, y = -l cos theta.

    Its exact motion obeys theta'' = -(g/l) sin theta, which the tests integrate
    independently of the library.
    """
    theta, x, y = sp.symbols("theta x y")
    dtheta, dx, dy = sp.symbols("dtheta dx dy")
    m, l, g = sp.symbols("m l g")
    return MultibodyModel(
        coordinates=(theta, x, y), velocities=(dtheta, dx, dy),
        kinetic_energy=m * (dx**2 + dy**2) / 2, potential_energy=m * g * y,
        constraints=(x - l * sp.sin(theta), y + l * sp.cos(theta)),
        independent=(theta,), parameters=(m, l, g),
    )


@pytest.fixture(scope="session")
def pendulum():
    return System(pendulum_model(), {"m": 2.0, "l": 1.5, "g": 9.81})


def random_states(count, seed):
    """Random (s, s') of the slider-crank, not necessarily consistent."""
    rng = np.random.default_rng(seed)
    for _ in range(count):
        s = np.array([rng.uniform(0, 2 * math.pi), rng.uniform(0.6 * math.pi, 1.4 * math.pi), rng.uniform(1, 6)])
        yield s, rng.normal(size=3)


@pytest.fixture(scope="session")
def four_bar():
    """The library's example four-bar linkage (closedloop.four_bar), with a Grashof crank-rocker's data."""
    return System(four_bar_model(), {"l0": 4.0, "l1": 1.0, "l2": 3.5, "l3": 3.0,
                                     "m1": 1.0, "m2": 3.0, "m3": 2.5, "g": 9.81})


#: A parallelogram four-bar (l0 = l2, l1 = l3, Grashof with equality): where all links lie on the
#: x axis (theta1 = 0 or pi) its two assembly branches meet, a change point.
PARALLELOGRAM = {"l0": 3.0, "l1": 1.0, "l2": 3.0, "l3": 1.0, "m1": 1.0, "m2": 2.0, "m3": 1.0, "g": 9.81}
#: Crank angle [rad] and rate [rad/s] of a swing at the bottom, too slow to reach theta1 = 0 or -pi.
SWINGING = (-math.pi / 2, 3.0)


@pytest.fixture(scope="session")
def parallelogram():
    return System(four_bar_model(), PARALLELOGRAM)


@pytest.fixture(scope="session")
def parallelogram_swing(parallelogram):
    """A 5 s swing below the change points, in minimal coordinates: ``(start, result)``."""
    from closedloop import Minimal, consistent_initial_state, simulate

    start = consistent_initial_state(parallelogram, [SWINGING[0]], [SWINGING[1]], [0.0, SWINGING[0]])
    t = np.linspace(0.0, 5.0, 1001)
    return start, simulate(parallelogram, start, 5.0, formulation=Minimal(), method="DOP853",
                           rtol=1e-11, atol=1e-11, t_eval=t)


@pytest.fixture(scope="session")
def quick_benchmark(tmp_path_factory):
    """``closedloop benchmark --quick`` run once: ``(data of the JSON file, printed text, figures folder)``.

    The study behind it (case 2, DOP853 and ode.dop853, rtol 1e-3, 1e-6, 1e-9, one repeat) is
    checked in test_benchmark.py, the command's output in test_cli.py.
    """
    import contextlib
    import io
    import json

    from closedloop.cli import main

    folder = tmp_path_factory.mktemp("benchmark")
    path = folder / "rows.json"
    out, err = io.StringIO(), io.StringIO()
    with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
        status = main(["benchmark", "--quick", "--json", str(path), "--figures", str(folder / "figures")])
    assert status == 0, err.getvalue()
    return json.loads(path.read_text()), out.getvalue(), folder / "figures"


# --- the built book, shared by every test that reads it ---------------------------------------
# The book is executed once per test session, by the README's build command, and every test of the
# chapters, the exercise pages, their downloads and the site reads that one build (nothing executes a
# chapter a second time, except the downloads' run in a plain Jupyter, tests/test_downloads.py). The build
# starts in the background as soon as the tests are collected, so it runs on one core while the library's
# tests run on the other; the tests that read it are moved to the end of the session and wait for it there.
# The course edition (`make course`) and the PDF (`make pdf`), which reuse that execution, are made after
# the book in the same background job, while the tests of the site run; the tests that read them
# (`built_course`, `built_pdf`) come last. CLOSEDLOOP_SITE_BUILT=1 reads the _build/html,
# _build/course/html and _build/pdf already there.
import os                                  # noqa: E402
import signal                              # noqa: E402
import subprocess                          # noqa: E402
import threading                           # noqa: E402
from pathlib import Path                   # noqa: E402

from print_pdf import chromium             # noqa: E402  (book/print: the browser make pdf prints with)

ROOT = Path(__file__).resolve().parents[1]
BUILD_LOG = ROOT / "_build" / "test-build.log"
COURSE_LOG = ROOT / "_build" / "test-course.log"
PDF_LOG = ROOT / "_build" / "test-pdf.log"
#: make's target for each fixture that reads a build, in the order they are built, and its log.
BUILDS = {"built_site": ("book", BUILD_LOG), "built_course": ("course", COURSE_LOG), "built_pdf": ("pdf", PDF_LOG)}


class BackgroundBuild:
    """``make -s TARGET`` for each target in turn, in a background thread; each one can be waited for.

    A target runs only if the one before succeeded; one that does not run reports exit code None.
    """

    def __init__(self, targets):
        self.targets = targets                       # [(target, log path)]
        self.codes, self.done = {}, {target: threading.Event() for target, _ in targets}
        self.process, self.stopped = None, False
        self.thread = threading.Thread(target=self._run, daemon=True)
        self.thread.start()

    def _run(self):
        failed = False
        for target, log_path in self.targets:
            if not (failed or self.stopped):
                with open(log_path, "w") as log:
                    self.process = subprocess.Popen(["make", "-s", target], cwd=ROOT, stdout=log,
                                                    stderr=subprocess.STDOUT, start_new_session=True)
                    self.codes[target] = self.process.wait()
                failed = self.codes[target] != 0
            self.done[target].set()

    def wait(self, target, timeout):
        """The exit code of ``make -s target`` (None if it did not run), once it has ended."""
        assert self.done[target].wait(timeout), f"make {target} still running after {timeout} s"
        return self.codes.get(target)

    def stop(self):
        """Stop the build under way, if any, and every target not started yet."""
        self.stopped = True
        if self.process is not None and self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGTERM)
            self.process.wait(timeout=30)
            try:                               # anything that outlived make in its group (execute_pages ends
                                               # its own workers on SIGTERM; this is the net behind it)
                os.killpg(self.process.pid, signal.SIGKILL)
            except ProcessLookupError:
                pass


@pytest.hookimpl(trylast=True)                 # after -k and -m have deselected: no build for tests not run
def pytest_collection_modifyitems(session, config, items):
    groups = {name: [item for item in items if name in getattr(item, "fixturenames", ())
                     and not any(later in getattr(item, "fixturenames", ()) for later in list(BUILDS)[i + 1:])]
              for i, name in enumerate(BUILDS)}
    reading = [item for name in BUILDS for item in groups[name]]
    if not reading:
        return
    waiting = {id(item) for item in reading}
    items[:] = [item for item in items if id(item) not in waiting] + reading
    if os.environ.get("CLOSEDLOOP_SITE_BUILT") == "1" or config.option.collectonly:
        return
    BUILD_LOG.parent.mkdir(exist_ok=True)
    names = list(BUILDS)
    last = max(names.index(name) for name in names if groups[name])
    # the PDF's tests read the site too: every target up to the last one wanted is built
    config._closedloop_build = BackgroundBuild([BUILDS[name] for name in names[:last + 1]])


def pytest_unconfigure(config):
    build = getattr(config, "_closedloop_build", None)
    if build is not None:                  # the session ended early (Ctrl-C, -x): stop the build too
        build.stop()


def _wait_for(request, target, log_path):
    build = getattr(request.config, "_closedloop_build", None)
    if build is not None:
        code = build.wait(target, timeout=1800)
        tail = log_path.read_text()[-4000:] if log_path.exists() else ""
        assert code is not None, f"make {target} did not run: the build before it failed (see {BUILD_LOG})"
        assert code == 0, f"make {target} failed (exit {code}); the end of {log_path}:\n{tail}"


@pytest.fixture(scope="session")
def built_site(request):
    """``_build/html``, built once for the session by ``make -s book`` (incremental)."""
    _wait_for(request, "book", BUILD_LOG)
    html = ROOT / "_build" / "html"
    assert (html / "index.html").exists(), f"no built site in {html}"
    return html


@pytest.fixture(scope="session")
def built_course(request):
    """``_build/course/html``, the course edition, built once for the session by ``make -s course`` after
    the book (from the same execution cache: nothing is executed again)."""
    _wait_for(request, "course", COURSE_LOG)
    html = ROOT / "_build" / "course" / "html"
    assert (html / "index.html").exists(), f"no course edition in {html}"
    return html


@pytest.fixture(scope="session")
def built_pdf(request):
    """``_build/pdf/closedloop.pdf``, made once for the session by ``make -s pdf`` after the book.

    Skipped, and says so, where the PDF cannot be made or read: without Debian's Chromium (its headless shell,
    or the whole browser) and poppler-utils.
    """
    missing = [tool for tool in ("pdfinfo", "pdftotext", "pdfimages", "pdftohtml", "pdftoppm")
               if shutil.which(tool) is None]
    if not Path(chromium()).exists():
        missing.insert(0, "chromium-headless-shell")
    if missing:
        pytest.skip(f"the PDF was NOT made or checked: {', '.join(missing)} not installed (Debian's "
                    "chromium-headless-shell and poppler-utils; make test tries to install them)")
    _wait_for(request, "pdf", PDF_LOG)
    pdf = ROOT / "_build" / "pdf" / "closedloop.pdf"
    assert pdf.exists(), f"no PDF at {pdf}"
    return pdf
