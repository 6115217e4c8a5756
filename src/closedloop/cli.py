"""The ``closedloop`` command line, for readers who do not open a notebook.

    closedloop simulate (--case N | --phi0 A --dphi0 W) [--t-end T] [--formulation NAME]
                        [--method NAME] [--rtol R] [--atol A] [--alpha a --beta b]
                        [--reading NAME] [--json] [--plot FILE.png]
    closedloop basin --phi0 START:STOP:N --dphi0 START:STOP:M [--t-end T] [--step H]
                     [--workers W] [--json FILE] [--png FILE.png]
    closedloop benchmark [--quick] [--json FILE] [--figures DIR]

Bad input is reported as one line on stderr, with exit status 2, before any
integration starts; a failed integration is one line too, with exit status 1.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from pathlib import Path

import numpy as np

from .errors import ClosedLoopError, InputError
from .methods import SOLVER_METHODS
from .validation import finite_number, one_of, positive_integer

__all__ = ["main", "build_parser"]

DEFAULT_T_END = 20.0
DEFAULT_METHOD = "RK45"
DEFAULT_FORMULATION = "baumgarte"


class _Parser(argparse.ArgumentParser):
    """argparse, but a usage error is one line and no usage dump."""

    def error(self, message):
        raise InputError(message)


def build_parser():
    """The argument parser of ``closedloop``."""
    from .formulations import FORMULATION_NAMES
    from .slider_crank import DEFAULT_READING, READINGS

    parser = _Parser(prog="closedloop", description="Simulate the slider-crank of Khang, Quyen and Mai Anh (2018).")
    commands = parser.add_subparsers(dest="command", required=True, parser_class=_Parser)
    sim = commands.add_parser("simulate", help="simulate one initial condition")
    sim.add_argument("--case", type=str, help="one of the paper's cases: 1, 2, 3 or 4")
    sim.add_argument("--phi0", type=str, help="initial crank angle [rad]")
    sim.add_argument("--dphi0", type=str, help="initial crank speed [rad/s]")
    sim.add_argument("--t-end", type=str, default=str(DEFAULT_T_END), help="final time [s] (default 20)")
    sim.add_argument("--formulation", default=DEFAULT_FORMULATION,
                     help=f"{', '.join(FORMULATION_NAMES)} (default {DEFAULT_FORMULATION})")
    sim.add_argument("--method", default=DEFAULT_METHOD,
                     help=f"integration method: {', '.join(SOLVER_METHODS)} (default {DEFAULT_METHOD})")
    sim.add_argument("--rtol", type=str, default="1e-9", help="relative tolerance (default 1e-9)")
    sim.add_argument("--atol", type=str, default="1e-9", help="absolute tolerance (default 1e-9)")
    sim.add_argument("--alpha", type=str, help="Baumgarte alpha of (15) (default 5)")
    sim.add_argument("--beta", type=str, help="Baumgarte beta of (15) (default 5)")
    sim.add_argument("--reading", default=DEFAULT_READING,
                     help=f"how to read the paper's data: {', '.join(READINGS)} (default {DEFAULT_READING})")
    sim.add_argument("--json", action="store_true", help="print one JSON object")
    sim.add_argument("--plot", metavar="FILE.png", help="write a paper-style figure")
    _add_basin_parser(commands)
    _add_benchmark_parser(commands)
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
    basin.add_argument("--json", metavar="FILE", help="write the grid and the outcome of each cell as JSON")
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
            "sympy.physics.mechanics), every method and a ladder of tolerances (atol = rtol); print the\n"
            "cheapest choice per accuracy level and the speed-up over the sympy baseline at error <= 1e-8.\n\n"
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
    bench.add_argument("--json", metavar="FILE", help="write the rows and the settings that made them as JSON")
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
    from .slider_crank import classify_motion, get_reading, initial_state, slider_crank_system

    case, phi0, dphi0 = _initial_condition(args)
    t_end = _positive("t_end", args.t_end, unit="s")
    rtol, atol = _positive("rtol", args.rtol), _positive("atol", args.atol)
    formulation = formulation_from_name(args.formulation, _number("alpha", args.alpha), _number("beta", args.beta))
    one_of("method", args.method, methods_taking(formulation))
    reading = get_reading(args.reading)
    if args.plot is not None and not args.plot.lower().endswith(".png"):
        raise InputError(f"plot: the figure is written as PNG; give a file name ending in .png, got {args.plot!r}")

    system = slider_crank_system(reading=reading)
    state = initial_state(system, phi0, dphi0)
    t_eval = np.linspace(0.0, t_end, int(min(4001, max(201, 100 * t_end + 1))))
    result = simulate(system, state, t_end, formulation=formulation, method=args.method,
                      rtol=rtol, atol=atol, t_eval=t_eval)
    final = {name: float(result.s[k, -1]) for k, name in enumerate(("phi", "psi", "x"))}
    final.update({f"d{name}": float(result.sd[k, -1]) for k, name in enumerate(("phi", "psi", "x"))})
    summary = {
        "case": case,
        "phi0": phi0,
        "dphi0": dphi0,
        "t_end": t_end,
        "formulation": formulation.name,
        "alpha": getattr(formulation, "alpha", None),
        "beta": getattr(formulation, "beta", None),
        "method": args.method,
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
        plot_slider_crank(result, title=f"Slider-crank, {label}: {summary['motion']}").savefig(args.plot, dpi=120)
        summary["plot"] = args.plot
    return summary


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
    step = DEFAULT_STEP if args.step is None else _positive("step", args.step, unit="s")   # basin_map: step <= t_end
    cores = os.cpu_count() or 1
    if args.workers is None:
        workers = cores if n * m >= 1000 else 1
    else:
        try:
            workers = int(args.workers)
        except ValueError:
            workers = args.workers             # refused below, with the range
        positive_integer("workers", workers)
    if args.png is not None and not args.png.lower().endswith(".png"):
        raise InputError(f"png: the figure is written as PNG; give a file name ending in .png, got {args.png!r}")
    basin = basin_map(grid_values(phi_start, phi_stop, n), grid_values(dphi_start, dphi_stop, m), t_end,
                      step=step, workers=workers, progress=progress)
    if args.json is not None:
        with open(args.json, "w", encoding="utf-8") as handle:
            json.dump(basin.as_json(), handle)
    if args.png is not None:
        from .plotting import plot_basin_map

        plot_basin_map(basin).savefig(args.png, dpi=120)
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
    lines = [
        f"{columns} x {rows} cells: phi0 {basin.phi0[0]:.4g} .. {basin.phi0[-1]:.4g} rad, "
        f"dphi0 {basin.dphi0[0]:.4g} .. {basin.dphi0[-1]:.4g} rad/s, t = 0 .. {basin.t_end:g} s, "
        f"reading {basin.reading}",
        f"full rotation: {100 * basin.fraction_rotating:.1f} % of the cells, oscillation: "
        f"{100 * (1 - basin.fraction_rotating):.1f} %",
        f"{basin.wall_time:.1f} s wall, {basin.cpu_time:.1f} s CPU, {basin.workers} worker(s), "
        f"step {basin.step:g} s",
    ]
    if args.json is not None:
        lines.append(f"grid and outcomes written to {args.json}")
    if args.png is not None:
        lines.append(f"figure written to {args.png}")
    return "\n".join(lines)


def _format(summary):
    head = f"case {summary['case']}: " if summary["case"] else ""
    gains = (f" (alpha = {summary['alpha']:g}, beta = {summary['beta']:g})"
             if summary["alpha"] is not None else "")
    f = summary["final"]
    lines = [
        f"{head}phi0 = {summary['phi0']:.6g} rad, dphi0 = {summary['dphi0']:.6g} rad/s, "
        f"t = 0 .. {summary['t_end']:g} s, reading {summary['reading']}",
        f"formulation {summary['formulation']}{gains}, {summary['method']}, "
        f"rtol = {summary['rtol']:g}, atol = {summary['atol']:g}",
        f"motion: {summary['motion'] or 'not classified (see the warning)'}"
        + (f" (the slider sticks at t = {summary['stuck_at']:.2f} s)" if summary["stuck_at"] is not None else ""),
        f"at t = {summary['t_end']:g} s: phi = {f['phi']:.6f} rad, psi = {f['psi']:.6f} rad, x_C = {f['x']:.6f} m",
        f"{'':{len(str(summary['t_end'])) + 9}}phi' = {f['dphi']:.6f} rad/s, psi' = {f['dpsi']:.6f} rad/s, "
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

    if args.json is not None and not Path(args.json).resolve().parent.is_dir():
        raise InputError(f"json: the folder of {args.json!r} does not exist")
    figures = None if args.figures is None else Path(args.figures)
    if figures is not None and figures.exists() and not figures.is_dir():
        raise InputError(f"figures: {args.figures!r} exists and is not a folder")
    data = run_study(QUICK_SETTINGS if args.quick else DEFAULT_SETTINGS,
                     progress=lambda text: print(text, file=sys.stderr, flush=True))
    lines = [format_table(data)]
    if args.json is not None:
        with open(args.json, "w", encoding="utf-8") as stream:
            json.dump(data, stream, indent=1)
            stream.write("\n")
        lines.append(f"rows and settings written to {args.json}")
    if figures is not None:
        from .plotting.benchmark import pareto_figure, residual_figure, work_precision_figure

        figures.mkdir(parents=True, exist_ok=True)
        written = {f"work_precision_case{case}.png": work_precision_figure(data["rows"], case)
                   for case in data["settings"]["cases"]}
        written["best_per_formulation.png"] = pareto_figure(data["rows"])
        written["residuals_case2.png"] = residual_figure(
            residual_traces(2, "DOP853", 1e-6), "Case 2, DOP853, rtol = atol = 1e-6")
        for name, fig in written.items():
            fig.savefig(figures / name, dpi=110)
        lines.append(f"figures written to {figures}: {', '.join(written)}")
    return "\n".join(lines)


def main(argv=None):
    """Entry point of ``closedloop``; returns the exit status."""
    try:
        args = build_parser().parse_args(argv)
        if args.command == "basin":
            return _main_basin(args)
        if args.command == "benchmark":
            print(run_benchmark(args))
            return 0
        summary = run_simulate(args)
    except ClosedLoopError as error:
        print(f"closedloop: error: {error}", file=sys.stderr)
        return 2 if isinstance(error, InputError) else 1
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
    print(_format_basin(basin, args))
    return 0


if __name__ == "__main__":
    sys.exit(main())
