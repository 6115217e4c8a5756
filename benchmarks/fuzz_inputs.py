"""Random inputs thrown at every validator of closedloop: each outcome is a result or the library's own error.

Run as ``python benchmarks/fuzz_inputs.py [--seed 0] [--count 500] [--timeout 60] [--only NAME]``.

For each target (SliderCrankParameters, initial_state, System for the slider-crank and the
four-bar, simulate, the command line's ``simulate`` and ``basin``) the script draws ``--count``
inputs with numpy's Generator (seed ``--seed``) from the same families of values as
tests/test_properties.py (numbers of every kind and size, NaN, infinities, numpy scalars,
fractions, decimals, complex numbers, strings, None, booleans, containers, objects), calls
the target, and sorts the outcome:

results
    a correct result: the object is valid (finite numbers, the constraints hold);
InputError / other ClosedLoopError
    the library's own error, with a one-line message that names the parameter;
any other exception
    anything else: another exception, a RuntimeWarning, a message of several lines or
    naming the wrong parameter, a command-line exit status or stderr outside the
    contract, or a run longer than ``--timeout`` seconds (a hang).  Must be 0.
NaN results
    a result holding a NaN or an infinity.  Must be 0.

The table ends with the slowest input of each target; every violation is listed
below it with its input.  Exit status 1 if any "other exception" or NaN result.

Left out of the families, as legitimate but long runs rather than wrong ones: Baumgarte gains
near their limit of 1e6 1/s and a max_step below 1e-3 s (both approach simulate's 1e6 steps).
The text ``--`` as an option's value (``--phi0=--``), once a bug of cli.py, is drawn like any other.
"""

from __future__ import annotations

import argparse
import contextlib
import decimal
import io
import math
import re
import signal
import sys
import time
import warnings
from fractions import Fraction

import numpy as np
import scipy.integrate

import closedloop
from closedloop import ClosedLoopError, InputError, System
from closedloop import four_bar, slider_crank
from closedloop.cli import main
from closedloop.formulations import FORMULATION_NAMES, formulation_from_name
from closedloop.methods import SOLVER_METHODS

# -- families of values ---------------------------------------------------------------------------

SPECIAL_FLOATS = (math.nan, -math.nan, math.inf, -math.inf, 0.0, -0.0, 5e-324, 2.2250738585072014e-308, 1e-300,
                  1e-12, 1e300, 1.7976931348623157e308, -1e300, -1.0, -5e-324)
HUGE_INTS = (10**400, -(10**400), 2**1024, 2**53 + 1, 10**5000, Fraction(10**5000, 3))


class Junk:
    """An object that is no number, no string and no container."""

    def __repr__(self):
        return "Junk()"


def _pick(rng, items):
    return items[int(rng.integers(len(items)))]


def plausible(rng, typical):
    """A value near ``typical`` (within a factor of 10 either way), sometimes of another numeric type."""
    value = typical * 10.0 ** rng.uniform(-1, 1) if typical else rng.uniform(0, 1)
    kind = rng.integers(6)
    if kind == 0:
        return np.float64(value)
    if kind == 1:
        return np.float32(value)
    if kind == 2:
        return max(1, int(round(value))) if typical >= 1 else value
    if kind == 3:
        return Fraction(value).limit_denominator(1000)
    return float(value)


def any_number(rng):
    """A number of any kind: Python, numpy, Fraction, special floats, huge integers."""
    kind = rng.integers(12)
    if kind == 0:
        return _pick(rng, SPECIAL_FLOATS)
    if kind == 1:
        return _pick(rng, HUGE_INTS)
    if kind == 2:
        return int(rng.integers(-10**6, 10**6))
    if kind == 3:
        return float(rng.normal() * 10.0 ** rng.integers(-5, 6))
    if kind == 4:
        return np.float64(_pick(rng, SPECIAL_FLOATS))
    if kind == 5:
        return np.float32(rng.normal())
    if kind == 6:
        return np.int64(rng.integers(-100, 100))
    if kind == 7:
        return np.float16(_pick(rng, (math.nan, math.inf, 65504.0, 1.0, -2.0)))
    if kind == 8:
        return Fraction(int(rng.integers(-50, 50)), int(rng.integers(1, 50)))
    if kind == 9:
        return _pick(rng, (Fraction(10**400, 3), Fraction(1, 10**400), np.longdouble("1e4000"), np.uint8(7),
                           np.int8(-3), np.float64(-0.0)))
    if kind == 10:
        return float(rng.uniform(-1e6, 1e6))
    return np.longdouble(rng.normal())


def junk(rng):
    """Anything that is no real number."""
    return _pick(rng, (None, True, False, np.bool_(True), "1", "1.0", "", "nan", "abc", "x" * 50, b"1", 1 + 2j,
                       complex(math.nan, 0), decimal.Decimal("1.5"), decimal.Decimal("NaN"), [1.0], (1.0, 2.0), {},
                       {"a": 1}, set(), Junk(), Junk, np.array([1.0, 2.0]), np.array(1.0), np.array([]),
                       np.datetime64("2020"), slice(1), float, "1\nsecond line"))


def any_value(rng, typical=1.0):
    """A plausible value (half the time), any number, or junk."""
    kind = rng.integers(10)
    if kind < 5:
        return plausible(rng, typical)
    if kind < 8:
        return any_number(rng)
    return junk(rng)


# -- outcome checks ---------------------------------------------------------------------------------

class Violation(Exception):
    """The outcome breaks the contract (raised by the checks below)."""


class Hang(BaseException):
    """The input ran longer than --timeout seconds."""


def one_line(error, prefixes=None):
    """The library error's message: one line (and starting with one of ``prefixes``, if given)."""
    text = str(error)
    if not text or "\n" in text or "\r" in text:
        raise Violation(f"{type(error).__name__} of {len(text.splitlines())} lines: {text!r}")
    if prefixes is not None and not text.startswith(tuple(prefixes)):
        raise Violation(f"{type(error).__name__} names none of {sorted(set(prefixes))}: {text!r}")


def finite(*arrays):
    return all(np.all(np.isfinite(np.asarray(a, dtype=float))) for a in arrays)


# -- the targets ------------------------------------------------------------------------------------
# Each ``draw(rng)`` returns the input (printed for a violation) and ``run(input)`` returns
# "result", "nan" or raises; ClosedLoopErrors are checked by ``error_check(input, error)``.

FIELDS = {f: getattr(slider_crank.SliderCrankParameters(), f) for f in
          ("l1", "a1", "m1", "I1", "l2", "a2", "m2", "I2", "m3", "g")}


class Target:
    name = ""

    def draw(self, rng):
        raise NotImplementedError

    def run(self, value):
        raise NotImplementedError

    def error_check(self, value, error):
        one_line(error)


class Parameters(Target):
    name = "SliderCrankParameters"

    def draw(self, rng):
        names = list(FIELDS) + ["full_rotation"]
        chosen = rng.choice(len(names), size=int(rng.integers(0, 4)), replace=False)
        fields = {}
        for k in chosen:
            name = names[k]
            if name == "full_rotation":
                fields[name] = _pick(rng, (True, False, np.bool_(False), 0, 1, "yes", None, 1.0))
            else:
                fields[name] = any_value(rng, FIELDS[name])
        if "full_rotation" in fields and fields["full_rotation"] is False and rng.random() < 0.7:
            fields.setdefault("l1", 3.5)
            fields.setdefault("l2", 2.0)
            fields.setdefault("a2", 1.0)
        return fields

    def run(self, fields):
        made = slider_crank.SliderCrankParameters(**fields)
        values = made.as_dict()
        if not finite(list(map(float, values.values()))):
            return "nan"
        if not (made.l1 < made.l2) == made.full_rotation or not 0 <= made.a2 <= made.l2:
            raise Violation(f"accepted an impossible geometry: {made}")
        return "result"

    def error_check(self, fields, error):
        one_line(error, [f"{name}:" for name in list(FIELDS) + ["full_rotation"]])


TABLE_1 = slider_crank.slider_crank_system()
ROCKING = slider_crank.slider_crank_system(
    slider_crank.SliderCrankParameters(l1=3.5, a1=0.0, l2=2.0, a2=1.0, full_rotation=False))


class InitialStateTarget(Target):
    def __init__(self, system, name):
        self.system, self.name = system, name

    def draw(self, rng):
        def value(typical, limit):
            kind = rng.integers(6)
            if kind == 0:
                return float(rng.uniform(-limit, limit))
            if kind == 1:
                return _pick(rng, (math.pi, math.pi / 2, -math.pi, 2 * math.pi, math.asin(2.0 / 3.5),
                                   math.pi - math.asin(2.0 / 3.5), limit, -limit, limit * (1 + 1e-15),
                                   np.nextafter(limit, math.inf)))
            return any_value(rng, typical)

        return value(1.0, 1e3), value(1.0, 1e3)

    def run(self, args):
        state = slider_crank.initial_state(self.system, *args)
        if not finite(state.s, state.sd):
            return "nan"
        f = self.system.constraints(state.s)
        velocity = self.system.jacobian(state.s) @ state.sd
        if np.max(np.abs(f)) > 1e-9 * (1 + np.max(np.abs(state.s))) or \
                np.max(np.abs(velocity)) > 1e-9 * (1 + np.max(np.abs(state.sd))):
            raise Violation(f"inconsistent state: |f| = {np.abs(f).max():.3g}, |f'| = {np.abs(velocity).max():.3g}")
        if self.system.parameters.full_rotation and state.s[2] <= 0:
            raise Violation(f"the slider is left of the crank: {state}")
        return "result"

    def error_check(self, args, error):
        if isinstance(error, InputError):
            one_line(error, ("phi0:", "dphi0:"))
        else:
            one_line(error)


class SystemTarget(Target):
    def __init__(self, model, values, name):
        self.model, self.values, self.name = model, values, name
        self.parameters = [str(p) for p in model.parameters]

    def draw(self, rng):
        if rng.random() < 0.08:
            return _pick(rng, (None, [], [1.0, 2.0], "l1", 5, np.array([1.0, 2.0]), Junk(), [("l1", 1.0)],
                               list(self.values.items()), {}, frozenset()))
        values = dict(self.values)
        for _ in range(int(rng.integers(0, 4))):
            name = _pick(rng, self.parameters)
            action = rng.integers(5)
            if action == 0:
                values.pop(name, None)
            elif action == 1:
                values[_pick(rng, ("extra", "L1", name + " ", 1, None, ("l1",), "x" * 3))] = any_value(rng)
            else:
                values[name] = any_value(rng, self.values[name] or 1.0)
        return values

    def run(self, values):
        system = System(self.model, values)
        if not finite(system.parameter_values):
            return "nan"
        return "result"

    def error_check(self, values, error):
        one_line(error, ["parameter_values"])
        if isinstance(error, InputError) and not any(repr(p) in str(error) for p in self.parameters) \
                and "expected a mapping" not in str(error):
            raise Violation(f"names no parameter: {error}")


SLIDER_CRANK_VALUES = four_bar.parameter_values(TABLE_1)
FOUR_BAR_VALUES = {"l0": 4.0, "l1": 1.0, "l2": 3.5, "l3": 3.0, "m1": 1.0, "m2": 3.0, "m3": 2.5, "g": 9.81}

START = slider_crank.initial_state(TABLE_1, math.pi, 1.0)         # case 1: on the switch x_C' = 0
AT_REST = slider_crank.initial_state(TABLE_1, 1.0, 0.0)            # sticks from t = 0


def is_short_step(value):
    """A real number from 1e-300 to 1e-3."""
    if isinstance(value, (bool, np.bool_)) or not isinstance(value, (int, float, np.number, Fraction)):
        return False
    try:
        return 1e-300 <= float(value) < 1e-3
    except (OverflowError, TypeError, ValueError):
        return False


class SimulateTarget(Target):
    name = "simulate"

    def draw(self, rng):
        if rng.random() < 0.4:
            return self._valid(rng)
        kwargs = {}
        kind = rng.integers(8)
        if kind < 4:
            t_end = float(rng.uniform(0.001, 0.5))
        elif kind == 4:
            t_end = _pick(rng, (5e-324, 1e-310, 1e-300, 1e-13, 1e-12, 2e-12, 1e-9, 1e-6, np.float32(0.1),
                                Fraction(1, 10), np.int64(0), 0.5, float(10.0 ** rng.uniform(-13, -3))))
        else:
            t_end = any_value(rng, 0.1)
            if isinstance(t_end, (int, float, np.number, Fraction)) and not isinstance(t_end, (bool, np.bool_)):
                try:
                    if float(t_end) > 0.5:
                        t_end = 0.5
                except OverflowError:
                    pass
        if rng.random() < 0.5:
            kwargs["rtol"] = self._tolerance(rng, rtol=True)
        if rng.random() < 0.4:
            kwargs["atol"] = self._tolerance(rng, rtol=False)
        if rng.random() < 0.5:
            kwargs["method"] = _pick(rng, SOLVER_METHODS + SOLVER_METHODS + (
                "rk45", "", " RK45", "ode.DOP853", None, 5, ["RK45"], np.array(["RK45", "BDF"]), np.array("RK45"),
                scipy.integrate.RK23, scipy.integrate.OdeSolver, int, Junk(), b"RK45"))
        if rng.random() < 0.5:
            kwargs["formulation"] = _pick(rng, tuple(formulation_from_name(n) for n in FORMULATION_NAMES) * 2 + (
                "baumgarte", None, 5, closedloop.Baumgarte, Junk(), ["minimal"]))
        if rng.random() < 0.3:
            kwargs["t_eval"] = self._t_eval(rng, t_end)
        for name, typical in (("max_steps", 1000), ("max_nfev", 1000)):
            if rng.random() < 0.25:
                kwargs[name] = _pick(rng, (1, 2, 5, 50, 1000, 10**6, 10**400, 0, -1, 10.0, np.int64(20),
                                           np.uint8(3), True, None, "10")) if rng.random() < 0.7 else any_value(
                    rng, typical)
        if rng.random() < 0.25:
            kwargs["sticking_resolution"] = any_value(rng, 0.01) if rng.random() < 0.5 else _pick(
                rng, (5e-324, 1e-300, 1e-12, 1e-5, 0.5, 1e300, 0.01))
        if rng.random() < 0.25:
            kwargs["branch_limit"] = any_value(rng, 0.01) if rng.random() < 0.5 else _pick(
                rng, (math.inf, 10**400, 5e-324, 1e300, 0.0, -1.0, math.nan))
        if rng.random() < 0.1:
            name = _pick(rng, ("max_step", "first_step"))
            value = any_value(rng, 0.01)
            if name == "max_step" and is_short_step(value):
                value = 0.001                  # 1e6 steps of 1e-9 s would be a long run, not a wrong one
            kwargs[name] = value
        state = START if rng.random() < 0.7 else AT_REST
        return t_end, state is AT_REST, kwargs

    @staticmethod
    def _valid(rng):
        """Options that are all valid (a run of up to 0.5 s), each given or not."""
        t_end = float(rng.uniform(1e-3, 0.5))
        formulation = formulation_from_name(_pick(rng, FORMULATION_NAMES))
        methods = ("RK23", "RK45", "DOP853") if formulation.name == "projected" else (
            SOLVER_METHODS if formulation.guards_partition else SOLVER_METHODS[:-1])
        choices = {
            "rtol": lambda: float(10.0 ** rng.uniform(-11, -3)),
            "atol": lambda: float(10.0 ** rng.uniform(-12, -3)),
            "method": lambda: _pick(rng, methods),
            "formulation": lambda: formulation,
            "t_eval": lambda: sorted(set(rng.uniform(0.0, t_end, size=int(rng.integers(1, 6))).tolist())),
            "max_steps": lambda: int(rng.integers(1, 10**6)),
            "max_nfev": lambda: int(rng.integers(1, 10**6)),
            "sticking_resolution": lambda: float(10.0 ** rng.uniform(-4, 0)),
            "branch_limit": lambda: float(10.0 ** rng.uniform(-6, 0)),
            "max_step": lambda: float(10.0 ** rng.uniform(-3, 0)),
            "first_step": lambda: float(10.0 ** rng.uniform(-6, 0)),
        }
        kwargs = {name: make() for name, make in choices.items() if rng.random() < 0.4}
        if "method" in kwargs:
            kwargs["formulation"] = formulation
        return t_end, bool(rng.random() < 0.3), kwargs

    @staticmethod
    def _tolerance(rng, rtol):
        kind = rng.integers(6)
        if kind < 2:
            return float(10.0 ** rng.uniform(-11 if rtol else -14, -3))
        if kind == 2:
            return _pick(rng, (1e-13, 2.3e-14, 2.2e-14, 1e-14, 1.0, 10.0, 1e300, 5e-324, 1e-300, 0.0, -1e-9))
        if kind == 3:
            size = _pick(rng, (6, 6, 2, 0, 7))
            values = list(10.0 ** rng.uniform(-10, -4, size=size))
            if size and rng.random() < 0.3:
                values[0] = _pick(rng, (math.nan, -1.0, 0.0, "a"))
            return values if rng.random() < 0.5 else np.array(values, dtype=object)
        return any_value(rng, 1e-6)

    @staticmethod
    def _t_eval(rng, t_end):
        end = float(t_end) if isinstance(t_end, float) and math.isfinite(t_end) and t_end > 0 else 0.1
        kind = rng.integers(8)
        if kind < 3:
            return list(np.sort(rng.uniform(0, end, size=int(rng.integers(1, 6)))))
        if kind == 3:
            return _pick(rng, ([], [math.nan], [0.0, end], [end, 0.0], [0.0, 0.0, end], [-1.0, end], [0.0, 2 * end],
                               [[0.0, end]], np.linspace(0, end, 5), end, [0.0, math.inf], "0.1", None,
                               [0.0, "x"], np.array([[0.0], [end]])))
        if kind == 4:
            return [0.0, end / 2, end]
        return any_value(rng, end / 2)

    def run(self, args):
        t_end, at_rest, kwargs = args
        result = closedloop.simulate(TABLE_1, AT_REST if at_rest else START, t_end, **kwargs)
        if not isinstance(result, closedloop.SimulationResult):
            raise Violation(f"returned a {type(result).__name__}")
        if not finite(result.t, result.s, result.sd):
            return "nan"
        return "result"

    def error_check(self, args, error):
        known = ("t_start", "t_end", "rtol", "atol", "method", "formulation", "t_eval", "max_steps", "max_nfev",
                 "sticking_resolution", "branch_limit", "max_step", "first_step", "solver options", "initial_state")
        one_line(error, known if isinstance(error, InputError) else None)


# -- the command line -------------------------------------------------------------------------------

#: "--" as the value of --phi0=-- reaches cli.py as [] (argparse of Python 3.11); it was a bug, now refused.
KNOWN_BUG_TEXTS = ("--",)


def number_text(rng, typical, high=None, junk_rate=0.3):
    """A number in one of many spellings (near ``typical``, at most ``high``), or text that is none."""
    if rng.random() >= junk_rate:
        value = typical * 10.0 ** rng.uniform(-1, 1) * (1 if rng.random() < 0.85 else -1)
        if high is not None:
            value = min(value, high)
        return _pick(rng, (repr(value), repr(value), f"{value:g}", f"{value:.3e}", f" {value:.4f} ", f"+{value:.2f}",
                           f"{value:E}", f"{value:.6f}".rstrip("0"), f"{value:_.3f}"))
    if rng.random() < 0.4:
        return _pick(rng, ("1", "1.0", "1e0", "+1", " 1 ", "1_0", "0x1", "0b1", "1,5", "\u0661", "\u22121",
                           "1e-3", ".5", "5.", "-0", "0", "-1", "1/2", "pi", "2pi", "1e-300", "5e-324", "1e-320"))
    return _pick(rng, ("inf", "-inf", "Infinity", "nan", "NaN", "-nan", "1e400", "-1e400", "1e308", "1e309",
                       "", " ", "abc", "-", "1 2", "1\n", "\x00", "one", "0.1.2", "1e", "e5", "nan(1)",
                       "\u221e", "1" * 400, "-h", "--help", "--json") + KNOWN_BUG_TEXTS)


def short_time(rng, high):
    """--t-end: a short time, 0, negative, or junk; never longer than ``high`` seconds."""
    text = number_text(rng, high / 4, high=high)
    try:
        value = float(text)
    except ValueError:
        return text
    return text if not math.isfinite(value) or value <= high else repr(high)


def _option(rng, args, name, value):
    if rng.random() < 0.75:
        args.append(f"{name}={value}")
    else:
        args += [name, value]


def cli_simulate_args(rng):
    args = ["simulate"]
    if rng.random() < 0.15:
        _option(rng, args, "--case", _pick(rng, ("1", "2", "3", "4", "0", "5", "x", "", " 2", "1.0", "\uff11")))
    if rng.random() < 0.95 or len(args) == 1:
        _option(rng, args, "--phi0", number_text(rng, 3.0, junk_rate=0.15))
    if rng.random() < 0.95 or len(args) == 2:
        _option(rng, args, "--dphi0", number_text(rng, 1.0, high=50.0, junk_rate=0.15))
    _option(rng, args, "--t-end", short_time(rng, 0.5))
    for name in ("--rtol", "--atol"):
        if rng.random() < 0.4:
            _option(rng, args, name, number_text(rng, 1e-6, high=1e-3, junk_rate=0.1) if rng.random() < 0.7 else _pick(
                rng, ("1e-14", "1e-13", "2.2e-14", "0.5", "0.9", "1", "10", "1e10", "1e300", "0", "-1e-9", "1e-300")))
    if rng.random() < 0.3:
        _option(rng, args, "--formulation", _pick(rng, FORMULATION_NAMES * 2 + ("", "Baumgarte", "closed_form", "x")))
    if rng.random() < 0.3:
        _option(rng, args, "--method", _pick(rng, SOLVER_METHODS * 2 + ("", "rk45", "x", "ode.dop853 ")))
    for name in ("--alpha", "--beta"):
        if rng.random() < 0.15:
            _option(rng, args, name, number_text(rng, 5.0, high=20.0) if rng.random() < 0.6 else _pick(
                rng, ("1e200", "1e160", "1e100", "1e7", "-1", "0", "nan", "inf", "x")))
    if rng.random() < 0.15:
        _option(rng, args, "--reading", _pick(rng, tuple(slider_crank.READINGS) * 2 + ("", "decimal", "x")))
    if rng.random() < 0.3:
        args.append("--json")
    return args


def angle_text(rng):
    return _pick(rng, ("0", "pi", "2pi", "0.5pi", "0.5*pi", "*pi", "1", "3", "6.2", "-1", "7", "nan", "inf", "-inf",
                       "1e308pi", "-1e308pi", "nanpi", "abc", "", " pi ", "1e-320", "5e-324", "0x1", "\u0661"))


def speed_text(rng):
    return _pick(rng, ("0", "0.5", "1", "2", "3", "-1", "1e3", "1500", "nan", "inf", "1e308pi", "pi", "abc", "",
                       "1e-320", "0.25pi"))


GOOD_ANGLES = (("0", 0.0), ("0.5pi", math.pi / 2), ("1", 1.0), ("pi", math.pi), ("3", 3.0), ("1.5*pi", 1.5 * math.pi),
               ("6.2", 6.2), ("2pi", 2 * math.pi))
GOOD_SPEEDS = (("0", 0.0), ("0.5", 0.5), ("1", 1.0), ("1.5", 1.5), ("2", 2.0), ("3", 3.0))


def range_text(rng, part, good):
    """START:STOP:N: an increasing range of good values and N <= 3 (most of the time), or anything."""
    kind = rng.integers(10)
    if kind < 6:
        first, second = sorted(rng.choice(len(good), size=2, replace=False))
        return f"{good[first][0]}:{good[second][0]}:{rng.integers(1, 4)}"
    count = _pick(rng, ("1", "2", "3", "2", "1", "0", "-1", "x", "1.5", "", " 2 ", "1e0", "\u0662"))
    if kind < 9:
        return f"{part(rng)}:{part(rng)}:{count}"
    return _pick(rng, ("", "0:1", "0:1:2:3", ":::", "0;1;2", "0:1:", "abc", "0:5e-324:3", "0:1e-320:2")
                 + KNOWN_BUG_TEXTS)


def cli_basin_args(rng):
    args = ["basin"]
    if rng.random() < 0.97:
        _option(rng, args, "--phi0", range_text(rng, angle_text, GOOD_ANGLES))
    if rng.random() < 0.97:
        _option(rng, args, "--dphi0", range_text(rng, speed_text, GOOD_SPEEDS))
    if rng.random() < 0.95:
        _option(rng, args, "--t-end", short_time(rng, 1.0) if rng.random() < 0.5 else f"{rng.uniform(0.05, 1):.3g}")
    if rng.random() < 0.3:
        _option(rng, args, "--step", _pick(rng, ("0.02", "0.01", "0.05", "0.5", "0.02", "2", "1e-9", "1e-300", "0",
                                                  "-0.1", "nan", "inf", "x", "")))
    if rng.random() < 0.2:
        _option(rng, args, "--workers", _pick(rng, ("1", "1", "0", "-1", "x", "1.5", "", "10000", "1e1")))
    return args


class CommandLine(Target):
    def __init__(self, name, draw_args):
        self.name, self.draw_args = name, draw_args

    def draw(self, rng):
        return self.draw_args(rng)

    def run(self, argv):
        out, err = io.StringIO(), io.StringIO()
        with contextlib.redirect_stdout(out), contextlib.redirect_stderr(err):
            status = main(list(argv))
        lines = err.getvalue().splitlines()
        if status == 0:
            if lines:
                raise Violation(f"status 0 with stderr {lines!r}")
            if re.search(r"\bnan\b|\binf\b", out.getvalue(), re.IGNORECASE):
                return "nan"
            return "result"
        if status == 2 or status == 1:
            errors = [line for line in lines if line.startswith("closedloop: error: ")]
            warned = [line for line in lines if line.startswith("closedloop: warning: ")]
            if errors and len(lines) == 1:
                return "InputError" if status == 2 else "ClosedLoopError"
            if status == 1 and warned and len(warned) == len(lines):
                return "result"                  # a result that carries warnings (its residuals)
        raise Violation(f"status {status!r} with stderr {lines!r}")


# -- the loop -------------------------------------------------------------------------------------

def targets():
    return [
        Parameters(),
        InitialStateTarget(TABLE_1, "initial_state"),
        InitialStateTarget(ROCKING, "initial_state (rocking)"),
        SystemTarget(slider_crank.slider_crank_model(), SLIDER_CRANK_VALUES, "System (slider-crank)"),
        SystemTarget(four_bar.four_bar_model(), FOUR_BAR_VALUES, "System (four-bar)"),
        SimulateTarget(),
        CommandLine("cli simulate", cli_simulate_args),
        CommandLine("cli basin", cli_basin_args),
    ]


def _alarm(signum, frame):
    raise Hang


def outcome(target, value, timeout):
    """``(kind, seconds, detail)``: kind is result, nan, InputError, ClosedLoopError or other."""
    signal.signal(signal.SIGALRM, _alarm)
    start = time.perf_counter()
    detail = None
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        signal.setitimer(signal.ITIMER_REAL, timeout)
        try:
            kind = target.run(value)
        except Hang:
            kind, detail = "other", f"hang: still running after {timeout:g} s"
        except Violation as violation:
            kind, detail = "other", str(violation)
        except ClosedLoopError as error:
            kind = "InputError" if isinstance(error, InputError) else "ClosedLoopError"
            try:
                target.error_check(value, error)
            except Violation as violation:
                kind, detail = "other", str(violation)
        except Exception as error:               # noqa: BLE001 - what this script looks for
            kind, detail = "other", f"{type(error).__name__}: {error}"
        finally:
            signal.setitimer(signal.ITIMER_REAL, 0)
    seconds = time.perf_counter() - start
    runtime = [w for w in caught if issubclass(w.category, RuntimeWarning)]
    if runtime and kind != "other":
        kind, detail = "other", f"RuntimeWarning: {runtime[0].message}"
    if kind == "nan":
        detail = "a result holding NaN or infinity"
    return kind, seconds, detail


def run(count, seed, timeout, only=None, stream=sys.stdout):
    rng = np.random.default_rng(seed)
    rows, problems = [], []
    for target in targets():
        if only and only not in target.name:
            continue
        tally = {"result": 0, "InputError": 0, "ClosedLoopError": 0, "other": 0, "nan": 0}
        slowest = (0.0, None)
        for _ in range(count):
            value = target.draw(rng)
            kind, seconds, detail = outcome(target, value, timeout)
            tally[kind] += 1
            if seconds > slowest[0]:
                slowest = (seconds, value)
            if detail is not None:
                problems.append((target.name, value, detail))
        rows.append((target.name, count, tally, slowest))
    header = (f"{'target':26} {'inputs':>7} {'results':>8} {'InputError':>11} {'other CLE':>10} "
              f"{'other exc.':>11} {'NaN':>5} {'max s':>7}")
    print(header, file=stream)
    print("-" * len(header), file=stream)
    for name, n, tally, (seconds, _) in rows:
        print(f"{name:26} {n:7d} {tally['result']:8d} {tally['InputError']:11d} {tally['ClosedLoopError']:10d} "
              f"{tally['other']:11d} {tally['nan']:5d} {seconds:7.2f}", file=stream)
    total = sum(n for _, n, _, _ in rows)
    print(f"{'total':26} {total:7d}", file=stream)
    for name, n, tally, (seconds, value) in rows:
        print(f"slowest {name}: {seconds:.2f} s for {value!r}", file=stream)
    for name, value, detail in problems:
        print(f"VIOLATION {name}: {value!r}: {detail}", file=stream)
    return not problems


def parse_args(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seed", type=int, default=0, help="seed of numpy's Generator (default 0)")
    parser.add_argument("--count", type=int, default=500, help="inputs per target (default 500)")
    parser.add_argument("--timeout", type=float, default=60.0,
                        help="seconds after which an input counts as a hang (default 60)")
    parser.add_argument("--only", help="run only the targets whose name contains this")
    return parser.parse_args(argv)


if __name__ == "__main__":
    options = parse_args()
    sys.exit(0 if run(options.count, options.seed, options.timeout, options.only) else 1)
