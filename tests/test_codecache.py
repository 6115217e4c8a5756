"""The disk cache of generated code (closedloop.codecache).

What a cached run loads computes the numbers of a fresh derivation, bit for bit (the model's
functions, the gas law, the closed form, the forcing period); a change of any part of
the key generates the code again; a corrupt file or a folder that cannot be written falls back to
generating, never to an error or a wrong function; and a run with a warm cache imports no sympy.
"""

import dataclasses
import itertools
import math
import os
import subprocess
import sys

import numpy as np
import pytest
import sympy as sp

from closedloop import codecache
from closedloop import slider_crank_gas_law as gas_law
from closedloop.codecache import cached_code
from closedloop.formulations import closed_form
from closedloop.four_bar import four_bar_model
from closedloop.model import System, model_functions
from closedloop.model_code import _generate, _identity
from closedloop.simulation import switching
from closedloop.slider_crank import slider_crank_model, slider_crank_system

from .conftest import pendulum_model

X = sp.Symbol("x")


@pytest.fixture
def cache(tmp_path, monkeypatch):
    """An empty cache folder of this test's own."""
    folder = tmp_path / "cache"
    monkeypatch.setenv(codecache.ENVIRONMENT_VARIABLE, str(folder))
    return folder


class Counting:
    """``generate`` for cached_code that counts its calls: a constant and a generated ``2 x``."""

    def __init__(self):
        self.calls = 0

    def __call__(self):
        self.calls += 1
        return {"value": 1.5, "twice": sp.lambdify(X, 2 * X, modules="math")}


NAMES = ("value", "twice")


# -- a hit computes what a fresh derivation computes --------------------------------------------
MODELS = {"slider-crank (by its builder)": slider_crank_model, "four-bar (by its builder)": four_bar_model,
          "pendulum (a MultibodyModel, by srepr)": pendulum_model()}


@pytest.mark.parametrize("name", MODELS)
def test_a_cache_hit_gives_the_numbers_of_a_fresh_derivation_bit_for_bit(cache, name):
    model = MODELS[name]
    written = model_functions.__wrapped__(model)          # a miss: derived, written, run from the written text
    [path] = cache.glob("model-*.py")
    loaded = model_functions.__wrapped__(model)           # a hit: read back
    assert written.dynamics.__code__.co_filename == loaded.dynamics.__code__.co_filename == str(path)
    fresh = _generate(model() if callable(model) else model)          # lambdify's own functions, no cache
    assert loaded.parameters == fresh["parameters"] and loaded.independent_index == fresh["independent_index"]

    rng = np.random.default_rng(14)
    n, k = len(loaded.coordinates), len(loaded.parameters)
    for _ in range(50):
        t, s, sd, p = rng.uniform(0, 20), rng.normal(size=n).tolist(), rng.normal(size=n).tolist(), \
            rng.uniform(0.5, 3.0, size=k).tolist()
        assert loaded.dynamics(t, s, sd, p) == fresh["dynamics"](t, s, sd, p)
        assert loaded.constraint_functions(s, p) == fresh["constraint_functions"](s, p)
        if fresh["generalized_forces"] is not None:
            assert loaded.generalized_forces(t, s, sd, p) == fresh["generalized_forces"](t, s, sd, p)
    s, sd, p = rng.normal(size=(n, 64)), rng.normal(size=(n, 64)), rng.uniform(0.5, 3.0, size=k)
    pairs = [(loaded.dynamics_many(1.5, list(s), list(sd), p.tolist()), fresh["dynamics_many"](1.5, list(s), list(sd), p.tolist())),
             (loaded.constraint_functions_many(list(s), p.tolist()), fresh["constraint_functions_many"](list(s), p.tolist())),
             (loaded.energies(s, sd, p), fresh["energies"](s, sd, p))]
    for cached_values, fresh_values in pairs:
        assert len(cached_values) == len(fresh_values)
        for a, b in zip(cached_values, fresh_values):
            assert np.array_equal(np.asarray(a), np.asarray(b))


@pytest.mark.parametrize("module", ["math", "numpy"])
def test_the_cached_gas_law_is_the_lambdified_law(cache, module):
    inner, outer = gas_law.numeric_branches.__wrapped__(module)           # a miss
    inner, outer = gas_law.numeric_branches.__wrapped__(module)           # a hit
    assert inner.__code__.co_filename.startswith(str(cache))
    fresh = [sp.lambdify(gas_law._ARGUMENTS, law, modules=module) for law in (gas_law.INNER_LAW, gas_law.OUTER_LAW)]
    x = np.linspace(1.5, 5.5, 41)
    for cached_branch, fresh_branch in zip((inner, outer), fresh):
        for value in x:
            assert cached_branch(value, 282.857, 62.857, 110.0, gas_law.WAVENUMBER) == \
                fresh_branch(value, 282.857, 62.857, 110.0, gas_law.WAVENUMBER)


def test_the_cached_closed_form_and_period_are_the_generated_ones(cache):
    """Two systems of one model and values: the first generates and writes, the second reads."""
    first, second = slider_crank_system(reading="thousands-opposing"), slider_crank_system(reading="thousands-opposing")
    rng = np.random.default_rng(3)
    states = [np.concatenate((rng.uniform(0, 2 * math.pi, 1), rng.uniform(2.5, 3.8, 1), rng.uniform(2, 5, 1),
                              rng.normal(size=3))) for _ in range(20)]
    for mode in itertools.product((False, True), repeat=2):
        closed_form.closed_form_rhs(first, mode, 5.0, 5.0)
        cached = closed_form.closed_form_rhs(second, mode, 5.0, 5.0)
        assert cached.__code__.co_filename.startswith(str(cache))
        fresh = closed_form._folded_rhs(second, mode, 5.0, 5.0)
        for y in states:
            assert cached(0.3, y) == fresh(0.3, y)
    closed_form.closed_form_accelerations(first)
    cached = closed_form.closed_form_accelerations(second)
    fresh = closed_form._accelerations(second)
    for y in states:
        s, sd = y[:3].tolist(), y[3:].tolist()
        assert cached(0.3, s, sd, [0.0, 0.0, -5.0], 5.0, 5.0) == fresh(0.3, s, sd, [0.0, 0.0, -5.0], 5.0, 5.0)
    switching.forcing_period(first)
    assert switching.forcing_period(second) == switching._forcing_period(second) == pytest.approx(1.0)
    assert len(list(cache.glob("forcing_period-*.py"))) == 1


# -- the key --------------------------------------------------------------------------------------
CHANGES = {
    "the package's source": lambda monkeypatch: monkeypatch.setattr(codecache, "source_fingerprint", lambda: "edited"),
    "sympy's version": lambda monkeypatch: monkeypatch.setattr(codecache, "sympy_version", lambda: "0.0"),
    "Python's version": lambda monkeypatch: monkeypatch.setattr(sys, "version", "2.7.18"),
    "numpy's version": lambda monkeypatch: monkeypatch.setattr(codecache.numpy, "__version__", "1.0"),
}


@pytest.mark.parametrize("change", [*CHANGES, "the caller's parts"])
def test_a_change_of_any_part_of_the_key_generates_the_code_again(cache, monkeypatch, change):
    generate = Counting()
    cached_code("test", ("model a",), generate, NAMES)
    cached_code("test", ("model a",), generate, NAMES)
    assert generate.calls == 1                                        # the second call read the file
    parts = ("model b",) if change == "the caller's parts" else ("model a",)
    if change in CHANGES:
        CHANGES[change](monkeypatch)
    made = cached_code("test", parts, generate, NAMES)
    assert generate.calls == 2
    assert made["twice"](3.0) == 6.0
    assert len(list(cache.glob("test-*.py"))) == 2                    # one file per key


def test_the_source_fingerprint_changes_with_any_module_of_the_package(tmp_path, monkeypatch):
    package = tmp_path / "package"
    (package / "sub").mkdir(parents=True)
    (package / "a.py").write_text("A = 1\n")
    (package / "sub" / "b.py").write_text("B = 2\n")
    monkeypatch.setattr(codecache, "_PACKAGE_ROOT", package)
    fingerprint = codecache.source_fingerprint.__wrapped__
    seen = {fingerprint()}
    (package / "sub" / "b.py").write_text("B = 3\n")                  # an edit below a subfolder
    seen.add(fingerprint())
    (package / "c.py").write_text("")                                  # a new, empty module
    seen.add(fingerprint())
    (package / "c.py").rename(package / "sub" / "c.py")                # a module moved
    seen.add(fingerprint())
    (package / "notes.txt").write_text("not code")                     # not a module: no change
    seen.add(fingerprint())
    assert len(seen) == 4
    without_sub = codecache.package_fingerprint(("sub",))                 # a study's fingerprint leaves a folder out
    (package / "sub" / "b.py").write_text("B = 4\n")
    assert codecache.package_fingerprint(("sub",)) == without_sub
    assert codecache.package_fingerprint(("sub",)) != codecache.package_fingerprint(("a.py",))
    (package / "a.py").write_bytes(b"A = 1\r\n")                       # line endings do not count
    assert codecache.package_fingerprint(("sub",)) == without_sub


def test_a_model_is_known_by_its_builder_or_by_every_symbol_and_expression():
    assert _identity(slider_crank_model) == "builder closedloop.slider_crank.slider_crank_model"
    assert _identity(pendulum_model()) == _identity(pendulum_model())          # rebuilt: the same model
    theta, x, y, m, g = sp.symbols("theta x y m g")
    l = sp.Symbol("l", positive=True)                                             # an assumption more
    base = pendulum_model()
    heavier = dataclasses.replace(base, potential_energy=2 * m * g * y)
    positive = dataclasses.replace(base, parameters=(m, l, g),
                                   constraints=(x - l * sp.sin(theta), y + l * sp.cos(theta)))
    assert len({_identity(base), _identity(heavier), _identity(positive)}) == 3


class Wobble(sp.Function):
    """sin of its argument, printed by methods of its own: code that srepr does not show."""

    def fdiff(self, argindex=1):
        return sp.cos(self.args[0])

    def _pythoncode(self, printer):
        return f"sin({printer._print(self.args[0])})"

    _numpycode = _pythoncode


def test_a_model_with_a_function_class_of_its_own_is_not_kept_on_disk(cache):
    theta, y, m, g = sp.symbols("theta y m g")
    model = dataclasses.replace(pendulum_model(), potential_energy=m * g * y + Wobble(theta))
    assert _identity(model) is None and _identity(pendulum_model()) is not None
    functions = model_functions.__wrapped__(model)
    assert functions.identity is None
    assert not list(cache.glob("*.py"))
    T, Pi = functions.energies(np.array([0.5, 0.0, 0.0]), np.zeros(3), np.array([2.0, 1.5, 9.81]))
    assert (T, Pi) == (0.0, math.sin(0.5))
    system = System(model, {"m": 2.0, "l": 1.5, "g": 9.81})
    assert switching.forcing_period(system) == 0.0 and not list(cache.glob("*.py"))


# -- failures: generate again, never an error, never a wrong function --------------------------------
def _corrupt(path, how):
    text = path.read_text()
    first, _, body = text.partition("\n")
    if how == "garbage":
        path.write_bytes(b"\x00\xff not python at all")
    elif how == "empty":
        path.write_text("")
    elif how == "truncated":
        path.write_text(text[: len(text) // 2])
    elif how == "edited (2 x made 3 x)":
        path.write_text(text.replace("2*x", "3*x"))
    elif how == "another key":
        body = body.replace(body.split("'")[1], "0" * 64)
        path.write_text(module_header(body) + body)
    elif how == "raises when run":
        body += "raise RuntimeError('broken')\n"
        path.write_text(module_header(body) + body)
    elif how == "a name missing":
        body = body.replace("value = 1.5", "other = 1.5")
        path.write_text(module_header(body) + body)


def module_header(body):
    import hashlib

    return f"{codecache._HEADER} {hashlib.sha256(body.encode()).hexdigest()}\n"


@pytest.mark.parametrize("how", ["garbage", "empty", "truncated", "edited (2 x made 3 x)", "another key",
                                 "raises when run", "a name missing"])
def test_a_corrupt_file_is_generated_again(cache, how):
    generate = Counting()
    cached_code("test", ("a",), generate, NAMES)
    [path] = cache.glob("test-*.py")
    _corrupt(path, how)
    made = cached_code("test", ("a",), generate, NAMES)
    assert generate.calls == 2
    assert made["value"] == 1.5 and made["twice"](3.0) == 6.0
    cached_code("test", ("a",), generate, NAMES)                       # rewritten: read again
    assert generate.calls == 2


def test_a_folder_that_cannot_be_written_only_costs_the_generation(tmp_path, monkeypatch):
    blocker = tmp_path / "a file"
    blocker.write_text("")
    monkeypatch.setenv(codecache.ENVIRONMENT_VARIABLE, str(blocker / "cache"))   # below a file: no mkdir
    generate = Counting()
    for _ in range(2):
        made = cached_code("test", ("a",), generate, NAMES)
        assert made["value"] == 1.5 and made["twice"](3.0) == 6.0
    assert generate.calls == 2
    system = System(pendulum_model(), {"m": 2.0, "l": 1.5, "g": 9.81})           # a whole model too
    assert system.constraints(np.array([0.3, 1.5 * math.sin(0.3), -1.5 * math.cos(0.3)])) == pytest.approx(0)


def test_code_that_cannot_be_written_as_a_module_is_used_from_memory_and_not_cached(cache):
    from sympy.utilities.lambdify import implemented_function

    plus_one = implemented_function("plus_one", lambda value: value + 1)      # a Python function in the code
    made = cached_code("test", ("a",), lambda: {"f": sp.lambdify(X, 3 * plus_one(X), modules="math")}, ("f",))
    assert made["f"](1.0) == 6.0
    assert not list(cache.glob("test-*.py"))


def test_the_folder_is_named_by_the_environment(monkeypatch, tmp_path):
    monkeypatch.setenv("CLOSEDLOOP_CACHE_DIR", str(tmp_path / "mine"))
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    assert codecache.cache_folder() == tmp_path / "mine"
    monkeypatch.delenv("CLOSEDLOOP_CACHE_DIR")
    assert codecache.cache_folder() == tmp_path / "xdg" / "closedloop"
    monkeypatch.setenv("XDG_CACHE_HOME", "relative/path")               # the XDG rule: only an absolute path
    monkeypatch.setenv("HOME", str(tmp_path / "home"))
    assert codecache.cache_folder() == tmp_path / "home" / ".cache" / "closedloop"


def test_sympy_s_version_is_read_without_importing_it():
    assert codecache.sympy_version.__wrapped__() == sp.__version__
    code = "import sys; from closedloop import codecache; print(codecache.sympy_version(), 'sympy' in sys.modules)"
    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=120, check=True).stdout
    assert out.split() == [sp.__version__, "False"]


# -- a cached run imports no sympy ----------------------------------------------------------------------
#: What a run with cached code does not need: the derivation and the figures; and what it does, the compiled
#: DOP853 reached through scipy.integrate's public ode.
HEAVY = ("sympy", "matplotlib", "scipy.integrate")
PROBE = """
import contextlib, io, sys
import closedloop
bare = 'sympy' in sys.modules
from closedloop.cli import main
with contextlib.redirect_stdout(io.StringIO()):
    status = main(sys.argv[2:])
print(status, bare, 'sympy' in sys.modules, 'matplotlib' in sys.modules)
print(','.join(name for name in sys.argv[1].split(',') if name in sys.modules) or 'none')
"""


@pytest.mark.parametrize("arguments", [
    ["simulate", "--case", "2"],
    ["simulate", "--case", "3", "--reading", "thousands-opposing"],           # sticks: the forcing period
    ["simulate", "--case", "1", "--formulation", "closed-form", "--method", "ode.dop853"],
], ids=["case 2", "sticking", "closed form"])
def test_a_run_with_a_warm_cache_imports_no_sympy(tmp_path, arguments):
    environment = dict(os.environ, CLOSEDLOOP_CACHE_DIR=str(tmp_path / "cache"))

    def run():
        done = subprocess.run([sys.executable, "-c", PROBE, ",".join(HEAVY), *arguments], env=environment,
                              capture_output=True, text=True, timeout=600)
        assert done.returncode == 0, done.stderr
        return done.stdout.split()

    assert run()[:4] == ["0", "False", "True", "False"]      # cold: import closedloop alone has no sympy; the run derives
    # warm: no sympy, no matplotlib without a figure; scipy.integrate for the compiled DOP853 (ode)
    assert run() == ["0", "False", "False", "False", "scipy.integrate"]
