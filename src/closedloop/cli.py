"""The ``closedloop`` command line, for readers who do not open a notebook.

    closedloop simulate (--case N | --phi0 A --dphi0 W) [--t-end T] [--formulation NAME]
                        [--method NAME] [--rtol R] [--atol A] [--alpha a --beta b]
                        [--reading NAME] [--json] [--plot FILE.png]
    closedloop basin --phi0 START:STOP:N --dphi0 START:STOP:M [--t-end T] [--step H]
                     [--workers W] [--json FILE|-] [--png FILE.png]
    closedloop benchmark [--quick] [--json FILE|-] [--figures DIR]
    closedloop long-runs --json FILE|-

Bad input is reported as one line on stderr, with exit status 2, before any
integration starts; output files count as input: a missing or unwritable
folder, a folder where a file is expected, two options naming one file, or a
figure without matplotlib is refused before the run. A failed integration or
a failed write is one line too, with exit status 1. Files are written
atomically: a failed write leaves the previous file as it was. ``--json -``
writes the JSON to standard output (the summary then goes to stderr).
Ctrl-C ends the run with the line ``closedloop: interrupted`` and exit status
130, SIGTERM with ``closedloop: terminated`` and 143; basin's worker
processes end with it.
Negative numbers may follow their option with a space (``--dphi0 -1e-3``) or
an equals sign (``--dphi0=-1e-3``).
"""

from __future__ import annotations

import argparse
import contextlib
import json
import math
import os
import re
import signal
import sys
import threading
import time
from pathlib import Path

import numpy as np

from .errors import ClosedLoopError, InputError
from .methods import SOLVER_METHODS
from .output import (STDOUT, WriteError, atomic_write, check_distinct, check_file, check_folder, require_matplotlib,
                     save_figure)
from .validation import finite_number, one_of, positive_integer

__all__ = ["main", "build_parser"]

DEFAULT_T_END = 20.0
#: The command answers with the library's cheapest route at the default tolerance (chapter 8: the closed
#: form (26) with the compiled DOP853 reaches every case's accuracy first); the formulation is
#: ClosedForm, named by the registry (build_parser). Any other is an option.
DEFAULT_METHOD = "ode.dop853"
#: The method for a formulation that does not take DEFAULT_METHOD (Projected: it resets the state of a
#: solve_ivp Runge-Kutta method after every step).
FALLBACK_METHOD = "DOP853"
#: What the summary and the figure say of a run whose warnings keep it from being classified.
NOT_CLASSIFIED = "not classified (see the warning)"


#: An option's value that argparse would take for an option: ``-1e-3``, ``-.5``, ``-inf``, ``-1:2:4``.
_NEGATIVE_VALUE = re.compile(r"-(\d|\.\d|inf|nan|pi)", re.IGNORECASE)


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line and no usage dump, and ``--dphi0 -1e-3`` works.

    argparse reads ``-1e-3`` (scientific notation, unlike ``-1`` or ``-0.5``) as an
    option, so ``--dphi0 -1e-3`` fails with "expected one argument"; here a value
    that starts with a minus sign and looks like a number, written after an
    option of this parser that takes one value, is joined to it as ``--dphi0=-1e-3``
    before argparse reads the line.
    """

    def error(self, message):
        raise InputError(message)

    def __init__(self, *args, **kwargs):
        self._value_options = []               # option strings that take exactly one value
        super().__init__(*args, **kwargs)

    def add_argument(self, *args, **kwargs):
        action = super().add_argument(*args, **kwargs)
        if action.option_strings and action.nargs is None:
            self._value_options.extend(action.option_strings)
        return action

    def parse_known_args(self, args=None, namespace=None):
        args = sys.argv[1:] if args is None else list(args)
        namespace, extras = super().parse_known_args(self._join_negative_values(args), namespace)
        for action in self._actions:            # argparse (3.11) hands --phi0=-- over as [], not as text
            if action.option_strings and action.nargs is None and isinstance(getattr(namespace, action.dest, None),
                                                                             list):
                raise InputError(f"{action.option_strings[-1]}: expected a value, got '--'")
        return namespace, extras

    def _takes_one_value(self, token):
        """True if ``token`` is, or (as argparse allows) abbreviates, an option taking one value."""
        if token in self._value_options:
            return True
        named = [name for name in self._value_options if name.startswith(token)]
        return self.allow_abbrev and token.startswith("--") and len(named) == 1

    def _join_negative_values(self, args):
        joined, k = [], 0
        while k < len(args):
            token = args[k]
            if token == "--":
                return joined + args[k:]
            if k + 1 < len(args) and _NEGATIVE_VALUE.match(args[k + 1]) and self._takes_one_value(token):
                joined.append(f"{token}={args[k + 1]}")
                k += 2
            else:
                joined.append(token)
                k += 1
        return joined


def build_parser():
    """The argument parser of ``closedloop``."""
    from . import __version__
    from .formulations import FORMULATION_NAMES, ClosedForm
    from .slider_crank import CLASSIFY_RTOL_LIMIT, DEFAULT_READING, READINGS

    default_formulation = ClosedForm.name

    parser = _Parser(prog="closedloop", description="Simulate the slider-crank of Khang, Quyen and Mai Anh (2018).")
    parser.add_argument("--version", action="version", version=f"closedloop {__version__}")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    sim = commands.add_parser("simulate", help="simulate one initial condition")
    sim.add_argument("--case", type=str, help="one of the paper's cases: 1, 2, 3 or 4")
    sim.add_argument("--phi0", type=str, help="initial crank angle [rad]")
    sim.add_argument("--dphi0", type=str, help="initial crank speed [rad/s]")
    sim.add_argument("--t-end", type=str, default=str(DEFAULT_T_END), help="final time [s] (default 20)")
    sim.add_argument("--formulation", default=default_formulation,
                     help=f"{', '.join(FORMULATION_NAMES)} (default {default_formulation})")
    sim.add_argument("--method",
                     help=f"integration method: {', '.join(SOLVER_METHODS)} (default {DEFAULT_METHOD} where the "
                          f"formulation takes it, else {FALLBACK_METHOD})")
    sim.add_argument("--rtol", type=str, default="1e-9",
                     help=f"relative tolerance, at most {CLASSIFY_RTOL_LIMIT:g} to classify the motion (default 1e-9)")
    sim.add_argument("--atol", type=str, default="1e-9", help="absolute tolerance (default 1e-9)")
    sim.add_argument("--alpha", type=str, help="Baumgarte alpha of (15) (default 5)")
    sim.add_argument("--beta", type=str, help="Baumgarte beta of (15) (default 5)")
    sim.add_argument("--reading", default=DEFAULT_READING,
                     help=f"how to read the paper's data: {', '.join(READINGS)} (default {DEFAULT_READING})")
    sim.add_argument("--json", action="store_true", help="print one JSON object")
    sim.add_argument("--plot", metavar="FILE.png", help="write a paper-style figure")
    _add_basin_parser(commands)
    _add_benchmark_parser(commands)
    long_runs = commands.add_parser(
        "long-runs", help="case 2 for 1000 s with each formulation: drift and energy balance (chapter 9)")
    long_runs.add_argument("--json", metavar="FILE", required=True,
                           help="write the runs' summaries, traces and provenance as JSON")
    return parser


def _add_basin_parser(commands):
    """The ``basin`` subcommand: classify a grid of initial conditions."""
    basin = commands.add_parser("basin", help="map full rotation / oscillation over a grid of initial conditions")
    basin.add_argument("--phi0", required=True, metavar="START:STOP:N",
                       help="N crank angles from START to STOP, STOP left out; inside [0, 2pi]; "
                            "numbers may end in pi, e.g. 0:2pi:100")
    basin.add_argument("--dphi0", required=True, metavar="START:STOP:M",
                       help="M crank speeds [rad/s] from START to STOP, STOP left out; START >= 0")
    basin.add_argument("--t-end", type=str, default=str(DEFAULT_T_END), help="final time [s] (default 20)")
    basin.add_argument("--step", type=str, default=None, help="step of the batch integrator [s] (default 0.02)")
    basin.add_argument("--workers", type=str, default=None,
                       help="processes (default: one per core for 1000 cells or more, else 1)")
    basin.add_argument("--json", metavar="FILE|-",
                       help="write the grid and the outcome of each cell as JSON (- for standard output)")
    basin.add_argument("--png", metavar="FILE.png", help="write the map as a PNG figure")



def _add_benchmark_parser(commands):
    """The ``benchmark`` subcommand: error against run time (closedloop.studies.benchmark)."""
    from .studies.benchmark import DEFAULT_SETTINGS, PLATEAU_RATIO, QUICK_SETTINGS

    default, quick = DEFAULT_SETTINGS, QUICK_SETTINGS
    bench = commands.add_parser(
        "benchmark", help="error against CPU time of every formulation and solve_ivp method",
        formatter_class=argparse.RawDescriptionHelpFormatter,
        description=(
            "Integrate the four cases over 0-20 s with every formulation (and the same model written with\n"
            "sympy.physics.mechanics, lambdified for numpy and for math), every method and a ladder of\n"
            "tolerances (atol = rtol); print the cheapest choice per accuracy level and the speed-up over\n"
            "the sympy baseline at its best (printer, method, rtol) at error <= 1e-8.\n\n"
            "Errors are max-norms of [phi, psi, x_C, phi', psi', x_C'] against the minimal-coordinate\n"
            "solution at rtol = 1e-13 (DOP853): at t = 10 s, and over a 2001-point grid. CPU time is the\n"
            "median process time of repeated 20 s runs.\n\n"
            "Pruning: along each curve (case, formulation, method) the tolerances go from loose to tight,\n"
            f"and the curve stops after a run whose CPU time exceeds a cap ({default.time_cap_s:g} s), after\n"
            f"{default.plateau} tolerances in a row that do not halve its best error while it stays above\n"
            f"{PLATEAU_RATIO:g} x rtol; a failed run is recorded and the curve goes on.\n"
            "The projection method runs only with RK45 and DOP853.\n\n"
            f"default: cases {', '.join(map(str, default.cases))}; in case {default.main_case} the methods "
            f"{', '.join(default.methods)},\n         in the others {', '.join(default.other_case_methods)} "
            f"(the baseline: {', '.join(default.baseline_methods)}); "
            f"rtol {default.rtols[0]:.0e} .. {default.rtols[-1]:.0e} in decades; {default.repeats} repeats\n"
            "         (under 10 minutes on two cores)\n"
            f"--quick: case {', '.join(map(str, quick.cases))}; {', '.join(quick.methods)}; rtol "
            f"{', '.join(f'{r:.0e}' for r in quick.rtols)}; {quick.repeats} repeat; cap {quick.time_cap_s:g} s "
            "(under a minute)"))
    bench.add_argument("--quick", action="store_true", help="the small study (see above)")
    bench.add_argument("--json", metavar="FILE|-",
                       help="write the rows and the settings that made them as JSON (- for standard output)")
    bench.add_argument("--figures", metavar="DIR", help="write the figures (PNG) into DIR, created if needed")


def _number(name, text, **bounds):
    """The number written in ``text`` (None stays None), checked by :func:`~closedloop.validation.finite_number`."""
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{name}: expected a number, got {text!r}") from None
    return finite_number(name, value, **bounds)


def _positive(name, text, unit=None):
    """A number > 0 written in ``text``."""
    return _number(name, text, minimum=0.0, strict=True, unit=unit)


def _initial_condition(args):
    from .slider_crank import get_case

    if args.case is not None:
        if args.phi0 is not None or args.dphi0 is not None:
            raise InputError("--case: give either --case or --phi0 with --dphi0, not both")
        try:
            number = int(args.case)
        except ValueError:
            number = args.case                 # refused by get_case, with the choices
        case = get_case(number)
        return number, case.phi0, case.dphi0
    if args.phi0 is None or args.dphi0 is None:
        raise InputError("--phi0, --dphi0: give both (or --case N)")
    return None, _number("phi0", args.phi0), _number("dphi0", args.dphi0)


def run_simulate(args):
    """Carry out ``closedloop simulate``; returns the JSON-ready summary."""
    from .formulations import formulation_from_name
    from .simulation import simulate
    from .simulation.options import methods_taking
    from .slider_crank import (check_classification_tolerance, classify_motion, get_reading, initial_state,
                               slider_crank_system)

    case, phi0, dphi0 = _initial_condition(args)
    t_end = _positive("t_end", args.t_end, unit="s")
    rtol, atol = _positive("rtol", args.rtol), _positive("atol", args.atol)
    check_classification_tolerance("--rtol", rtol)   # before the run: classify_motion would refuse it after
    formulation = formulation_from_name(args.formulation, _number("alpha", args.alpha), _number("beta", args.beta))
    methods = methods_taking(formulation)
    method = args.method if args.method is not None else (
        DEFAULT_METHOD if DEFAULT_METHOD in methods else FALLBACK_METHOD)
    if method in SOLVER_METHODS:
        formulation.check_method(method)          # a method the formulation does not take: its own reason
    one_of("method", method, methods)
    reading = get_reading(args.reading)
    _check_figure_file("--plot", args.plot)

    system = slider_crank_system(reading=reading)
    state = initial_state(system, phi0, dphi0)
    t_eval = np.linspace(0.0, t_end, int(min(4001, max(201, 100 * t_end + 1))))
    result = simulate(system, state, t_end, formulation=formulation, method=method,
                      rtol=rtol, atol=atol, t_eval=t_eval)
    final = {name: float(result.s[k, -1]) for k, name in enumerate(("phi", "psi", "x"))}
    final.update({f"d{name}": float(result.sd[k, -1]) for k, name in enumerate(("phi", "psi", "x"))})
    summary = {
        "case": case,
        "phi0": phi0,
        "dphi0": dphi0,
        "t_end": t_end,
        "formulation": formulation.name,
        "alpha": formulation.gains[0] if formulation.gains else None,
        "beta": formulation.gains[1] if formulation.gains else None,
        "method": method,
        "rtol": rtol,
        "atol": atol,
        "reading": reading.name,
        "motion": None if result.warnings else classify_motion(result, phi0),
        "warnings": result.warnings,
        "final": final,
        "max_constraint_error": result.max_constraint_error,
        "max_velocity_constraint_error": result.max_velocity_constraint_error,
        "nfev": result.nfev,
        "cpu_s": result.cpu_time,
        "stuck_at": result.sticking_intervals[0][0] if result.sticking_intervals else None,
    }
    if args.plot is not None:
        from .plotting import plot_slider_crank

        label = f"case {case}" if case else f"phi0 = {phi0:g} rad, dphi0 = {dphi0:g} rad/s"
        motion = summary["motion"] or NOT_CLASSIFIED
        save_figure(plot_slider_crank(result, title=f"Slider-crank, {label}: {motion}"), args.plot, dpi=120,
                    option="--plot")
        summary["plot"] = args.plot
    return summary


def _check_figure_file(option, path):
    """Refuse a figure file (None: no figure) that cannot be written, before any computation."""
    if path is None:
        return
    if not path.lower().endswith(".png"):
        raise InputError(f"{option}: the figure is written as PNG; give a file name ending in .png, got {path!r}")
    check_file(option, path)
    require_matplotlib(option)


def _check_json_file(option, path):
    """Refuse a JSON file (None: none, ``-``: standard output) that cannot be written."""
    if path is not None and path != STDOUT:
        check_file(option, path)


def _write_json(path, data, indent=None, option="--json"):
    """``data`` as JSON into ``path``, atomically, or onto standard output for ``-``."""
    if path == STDOUT:
        json.dump(data, sys.stdout, indent=indent)
        sys.stdout.write("\n")
        sys.stdout.flush()
        return
    with atomic_write(path, option=option) as handle:
        json.dump(data, handle, indent=indent)
        handle.write("\n")


def _angle(name, text):
    """A number, or a number followed by ``pi`` (``2pi``, ``0.5pi``, ``pi``)."""
    body = text.strip().lower()
    if body.endswith("pi"):
        factor = body[:-2].rstrip("*") or "1"
        return _number(name, factor) * math.pi
    return _number(name, text)


def parse_range(name, text):
    """``START:STOP:N`` as (start, stop, N), with a one-line error for anything else."""
    parts = text.split(":")
    if len(parts) != 3:
        raise InputError(f"{name}: expected START:STOP:N, got {text!r}")
    start, stop = _angle(name, parts[0]), _angle(name, parts[1])
    try:
        count = int(parts[2])
    except ValueError:
        raise InputError(f"{name}: N must be an integer >= 1, got {parts[2]!r}") from None
    if count < 1:
        raise InputError(f"{name}: N must be an integer >= 1, got {count}")
    if not stop > start:
        raise InputError(f"{name}: STOP must be > START, got {text!r}")
    return start, stop, count


def run_basin(args, progress=None):
    """Carry out ``closedloop basin``; returns the BasinMap."""
    from .studies.basin import DEFAULT_STEP, basin_map, grid_values

    phi_start, phi_stop, n = parse_range("phi0", args.phi0)
    if phi_start < 0 or phi_stop > 2 * math.pi * (1 + 1e-12):
        raise InputError(f"phi0: the range must lie inside [0, 2pi] rad, got {args.phi0!r}")
    dphi_start, dphi_stop, m = parse_range("dphi0", args.dphi0)
    if dphi_start < 0:
        raise InputError(f"dphi0: START must be >= 0 rad/s, got {args.dphi0!r}")
    if n * m > 1_000_000:
        raise InputError(f"phi0, dphi0: at most 1 000 000 cells, got {n} x {m}")
    t_end = _positive("t_end", args.t_end, unit="s")
    step = DEFAULT_STEP if args.step is None else _positive("step", args.step, unit="s")
    if args.step is None and step > t_end:          # basin_map would name a step the user never gave
        raise InputError(f"--t-end: {t_end:g} s is shorter than the default step {DEFAULT_STEP:g} s; give a longer "
                         "--t-end, or a --step <= --t-end")
    cores = os.cpu_count() or 1
    if args.workers is None:
        workers = cores if n * m >= 1000 else 1
    else:
        try:
            workers = int(args.workers)
        except ValueError:
            workers = args.workers             # refused below, with the range
        positive_integer("workers", workers)
    _check_json_file("--json", args.json)
    _check_figure_file("--png", args.png)
    check_distinct([("--json", args.json), ("--png", args.png)])
    basin = basin_map(grid_values(phi_start, phi_stop, n), grid_values(dphi_start, dphi_stop, m), t_end,
                      step=step, workers=workers, progress=progress)
    if args.json is not None:
        _write_json(args.json, basin.as_json())
    if args.png is not None:
        from .plotting import plot_basin_map

        save_figure(plot_basin_map(basin), args.png, dpi=120, option="--png")
    return basin


class _ProgressBar:
    """A plain text progress bar on stderr: ``[#####.....]  50 %  12 s``."""

    def __init__(self, stream, width=40):
        self.stream, self.width, self.clock, self.start = stream, width, time.perf_counter, time.perf_counter()

    def __call__(self, fraction):
        filled = int(round(self.width * fraction))
        self.stream.write(f"\r[{'#' * filled}{'.' * (self.width - filled)}] {100 * fraction:3.0f} %"
                          f" {self.clock() - self.start:5.0f} s")
        self.stream.flush()

    def close(self):
        self.stream.write("\n")
        self.stream.flush()


def _format_basin(basin, args):
    rows, columns = basin.outcome.shape
    cells, rotating = basin.outcome.size, int(np.count_nonzero(basin.outcome == 1))   # 1 in 10 000 is 0.0 %
    lines = [
        f"{columns} x {rows} cells: phi0 {basin.phi0[0]:.4g} .. {basin.phi0[-1]:.4g} rad, "
        f"dphi0 {basin.dphi0[0]:.4g} .. {basin.dphi0[-1]:.4g} rad/s, t = 0 .. {basin.t_end:g} s, "
        f"reading {basin.reading}",
        f"full rotation: {100 * basin.fraction_rotating:.1f} % of the cells ({rotating} of {cells}), "
        f"oscillation: {100 * (1 - basin.fraction_rotating):.1f} % ({cells - rotating})",
        f"{basin.wall_time:.1f} s wall, {basin.cpu_time:.1f} s CPU, {basin.workers} worker(s), "
        f"step {basin.step:g} s",
    ]
    if args.json is not None:
        lines.append(f"grid and outcomes written to {'standard output' if args.json == STDOUT else args.json}")
    if args.png is not None:
        lines.append(f"figure written to {args.png}")
    return "\n".join(lines)


def _motion_text(summary):
    """The motion as the summary line says it: "oscillation" means no full turn within the run."""
    if summary["motion"] is None:
        return NOT_CLASSIFIED
    if summary["motion"] == "oscillation":
        return f"oscillation (the crank did not turn 2 pi beyond its start in {summary['t_end']:g} s)"
    return summary["motion"]


def _format(summary):
    head = f"case {summary['case']}: " if summary["case"] else ""
    gains = (f" (alpha = {summary['alpha']:g}, beta = {summary['beta']:g})"
             if summary["alpha"] is not None else "")
    f = summary["final"]
    at = f"at t = {summary['t_end']:g} s:"
    lines = [
        f"{head}phi0 = {summary['phi0']:.6g} rad, dphi0 = {summary['dphi0']:.6g} rad/s, "
        f"t = 0 .. {summary['t_end']:g} s, reading {summary['reading']}",
        f"formulation {summary['formulation']}{gains}, {summary['method']}, "
        f"rtol = {summary['rtol']:g}, atol = {summary['atol']:g}",
        f"motion: {_motion_text(summary)}"
        + (f" (the slider sticks at t = {summary['stuck_at']:.2f} s)" if summary["stuck_at"] is not None else ""),
        f"{at} phi = {f['phi']:.6f} rad, psi = {f['psi']:.6f} rad, x_C = {f['x']:.6f} m",
        f"{'':{len(at) + 1}}phi' = {f['dphi']:.6f} rad/s, psi' = {f['dpsi']:.6f} rad/s, "
        f"x_C' = {f['dx']:.6f} m/s",
        f"max |f| (32) = {summary['max_constraint_error']:.2e}, {summary['nfev']} right-hand-side "
        f"evaluations, {summary['cpu_s']:.3f} s CPU",
    ]
    if "plot" in summary:
        lines.append(f"figure written to {summary['plot']}")
    return "\n".join(lines)


def run_benchmark(args):
    """Carry out ``closedloop benchmark``; returns the text to print."""
    from .studies.benchmark import DEFAULT_SETTINGS, QUICK_SETTINGS, format_table, residual_traces, run_study

    settings = QUICK_SETTINGS if args.quick else DEFAULT_SETTINGS
    _check_json_file("--json", args.json)
    figures = None if args.figures is None else Path(args.figures)
    names = [f"work_precision_case{case}.png" for case in settings.cases]
    names += ["best_per_formulation.png", "residuals_case2.png"]
    if figures is not None:
        check_folder("--figures", args.figures)
        require_matplotlib("--figures")
        if figures.is_dir():
            for name in names:
                check_file("--figures", str(figures / name))
        check_distinct([("--json", args.json), ("--figures", args.figures)]
                       + [("--figures", str(figures / name)) for name in names])
    data = run_study(settings, progress=lambda text: print(text, file=sys.stderr, flush=True))
    lines = [format_table(data)]
    if args.json is not None:
        _write_json(args.json, data, indent=1)
        if args.json != STDOUT:
            lines.append(f"rows and settings written to {args.json}")
    if figures is not None:
        from .plotting.benchmark import pareto_figure, residual_figure, work_precision_figure

        try:
            figures.mkdir(parents=True, exist_ok=True)
        except OSError as error:
            raise WriteError(f"cannot create {figures}: {error.strerror or error}") from None
        drawn = {row["case"] for row in data["rows"] if row["status"] == "ok"}    # a case whose runs all failed
        written = {f"work_precision_case{case}.png": work_precision_figure(data["rows"], case)   # has no figure
                   for case in data["settings"]["cases"] if case in drawn}
        written["best_per_formulation.png"] = pareto_figure(data["rows"])
        written["residuals_case2.png"] = residual_figure(
            residual_traces(2, "DOP853", 1e-6), "Case 2, DOP853, rtol = atol = 1e-6")
        for name, fig in written.items():
            save_figure(fig, str(figures / name), dpi=110, option="--figures")
        lines.append(f"figures written to {figures}: {', '.join(written)}")
    return "\n".join(lines)


def run_long_runs(args):
    """Carry out ``closedloop long-runs``; returns the text to print."""
    from .studies.long_runs import run_long_runs as run_study

    _check_json_file("--json", args.json)
    data = run_study(progress=lambda text: print(text, file=sys.stderr, flush=True))
    _write_json(args.json, data)
    lines = [f"{name}: {run['n_steps']} steps, max |f| {run['max_constraint_error']:.1e} m, "
             f"max |dE - W| {run['max_balance_residual']:.1e} J" for name, run in data["runs"].items()]
    if args.json != STDOUT:
        lines.append(f"runs and settings written to {args.json}")
    return "\n".join(lines)


class _Terminated(BaseException):
    """SIGTERM, raised in the main process like KeyboardInterrupt for SIGINT (so that ``with`` blocks clean up)."""


#: Exit status and line on stderr for each signal (128 + the signal's number, as a shell reports it).
_SIGNALS = {signal.SIGINT: (KeyboardInterrupt, 130, "interrupted"), signal.SIGTERM: (_Terminated, 143, "terminated")}


@contextlib.contextmanager
def _signals_as_exceptions(received):
    """SIGINT raises KeyboardInterrupt and SIGTERM :class:`_Terminated` in this process, once.

    The signal's number is appended to the list ``received`` first, so that the caller knows of
    it even when compiled code turns the exception into another.

    The first signal starts an orderly end (basin's ``with Pool`` terminates its workers);
    further ones are ignored while it runs. Processes forked meanwhile (basin's workers)
    inherit the handler: there SIGINT is ignored, the parent ends them, and SIGTERM kills
    as by default. Signals ignored on entry (``nohup``) stay ignored; the previous handlers
    are restored on exit.
    """
    if threading.current_thread() is not threading.main_thread():
        yield
        return
    parent = os.getpid()

    def handler(signum, frame):
        if os.getpid() != parent:
            if signum == signal.SIGTERM:
                signal.signal(signum, signal.SIG_DFL)
                os.kill(os.getpid(), signum)
            return
        for other in previous:
            signal.signal(other, signal.SIG_IGN)
        received.append(signum)
        raise _SIGNALS[signum][0]

    previous = {number: signal.getsignal(number) for number in _SIGNALS}
    previous = {number: old for number, old in previous.items() if old is not signal.SIG_IGN}
    try:
        for number in previous:
            signal.signal(number, handler)
        yield
    finally:
        for number, old in previous.items():
            signal.signal(number, old)


def _error(message):
    print(f"closedloop: error: {message}", file=sys.stderr)


def main(argv=None):
    """Entry point of ``closedloop``; returns the exit status.

    0 done; 1 the run or a write failed; 2 bad input (nothing computed); 130 Ctrl-C; 143 SIGTERM.
    Every failure is one line on stderr.
    """
    received = []
    try:
        with _signals_as_exceptions(received):
            return _run(argv)
    except BaseException as error:
        # a signal's exception raised inside a callback from compiled code (scipy's ode calls the
        # right-hand side from Fortran) comes out as another exception (a SystemError): the signal decides
        stop = next((number for number, (kind, _, _) in _SIGNALS.items() if isinstance(error, kind)), None)
        if received or stop is not None:
            _, status, word = _SIGNALS[received[0] if received else stop]
            print(f"closedloop: {word}", file=sys.stderr)
            return status
        return _failure(error)


def _failure(error):
    """Exit status of a run that ``error`` ended, after its one line on stderr."""
    try:
        raise error
    except BrokenPipeError:                    # stdout closed early (``| head``): end quietly, as Unix tools do
        with contextlib.suppress(OSError):
            os.dup2(os.open(os.devnull, os.O_WRONLY), sys.stdout.fileno())
        return 1
    except ClosedLoopError as error:
        _error(error)
        return 2 if isinstance(error, InputError) else 1
    except OSError as error:                   # a write outside closedloop.output, e.g. onto standard output
        _error(f"{error.filename}: {error.strerror}" if error.filename else error.strerror or error)
        return 1
    except Exception as error:                 # a defect of closedloop itself: still one line, and no traceback
        _error(f"internal error ({type(error).__name__}: {error}); please report it with the command that "
               "caused it")
        return 1


def _run(argv):
    args = build_parser().parse_args(argv)
    if args.command == "basin":
        return _main_basin(args)
    if args.command in ("benchmark", "long-runs"):
        text = (run_benchmark if args.command == "benchmark" else run_long_runs)(args)
        print(text, file=sys.stderr if args.json == STDOUT else sys.stdout)
        return 0
    summary = run_simulate(args)
    print(json.dumps(summary, indent=2) if args.json else _format(summary))
    for warning in summary["warnings"]:
        print(f"closedloop: warning: {warning}", file=sys.stderr)
    return 1 if summary["warnings"] else 0


def _main_basin(args):
    """``closedloop basin``: a progress bar on stderr only when stderr is a terminal."""
    bar = _ProgressBar(sys.stderr) if sys.stderr.isatty() else None
    try:
        basin = run_basin(args, progress=bar)
    finally:
        if bar is not None:
            bar.close()
    print(_format_basin(basin, args), file=sys.stderr if args.json == STDOUT else sys.stdout)
    return 0


if __name__ == "__main__":
    sys.exit(main())
