"""The ``closedloop`` command line, for readers who do not open a notebook.

    closedloop simulate (--case N | --phi0 A --dphi0 W) [--t-end T] [--formulation NAME]
                        [--method NAME] [--rtol R] [--atol A] [--alpha a --beta b]
                        [--reading NAME] [--json] [--plot FILE.png]
    closedloop benchmark [--quick] [--json FILE] [--figures DIR]

Bad input is reported as one line on stderr, with exit status 2, before any
integration starts; a failed integration is one line too, with exit status 1.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

import numpy as np

from .errors import ClosedLoopError, InputError

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
                     help="solve_ivp method: RK45, RK23, DOP853, Radau, BDF or LSODA (default RK45)")
    sim.add_argument("--rtol", type=str, default="1e-9", help="relative tolerance (default 1e-9)")
    sim.add_argument("--atol", type=str, default="1e-9", help="absolute tolerance (default 1e-9)")
    sim.add_argument("--alpha", type=str, help="Baumgarte alpha of (15) (default 5)")
    sim.add_argument("--beta", type=str, help="Baumgarte beta of (15) (default 5)")
    sim.add_argument("--reading", default=DEFAULT_READING,
                     help=f"how to read the paper's data: {', '.join(READINGS)} (default {DEFAULT_READING})")
    sim.add_argument("--json", action="store_true", help="print one JSON object")
    sim.add_argument("--plot", metavar="FILE.png", help="write a paper-style figure")
    _add_benchmark_parser(commands)
    return parser


def _add_benchmark_parser(commands):
    """The ``benchmark`` subcommand: error against run time (closedloop.benchmark)."""
    from .benchmark import DEFAULT_SETTINGS, QUICK_SETTINGS

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
            f"{default.plateau} tolerances in a row that do not halve its best error; a failed run is recorded\n"
            "and the curve goes on.\n"
            "The projection method runs only with RK45 and DOP853.\n\n"
            f"default: cases {', '.join(map(str, default.cases))}; in case {default.main_case} the methods "
            f"{', '.join(default.methods)},\n         in the others {', '.join(default.other_case_methods)}; "
            f"rtol {default.rtols[0]:.0e} .. {default.rtols[-1]:.0e} in decades; {default.repeats} repeats\n"
            "         (under 10 minutes on two cores)\n"
            f"--quick: case {', '.join(map(str, quick.cases))}; {', '.join(quick.methods)}; rtol "
            f"{', '.join(f'{r:.0e}' for r in quick.rtols)}; {quick.repeats} repeat; cap {quick.time_cap_s:g} s "
            "(under a minute)"))
    bench.add_argument("--quick", action="store_true", help="the small study (see above)")
    bench.add_argument("--json", metavar="FILE", help="write the rows and the settings that made them as JSON")
    bench.add_argument("--figures", metavar="DIR", help="write the figures (PNG) into DIR, created if needed")


def _number(name, text):
    if text is None:
        return None
    try:
        value = float(text)
    except ValueError:
        raise InputError(f"{name}: expected a number, got {text!r}") from None
    if not math.isfinite(value):
        raise InputError(f"{name}: must be finite, got {text!r}")
    return value


def _initial_condition(args):
    from .slider_crank import get_case

    if args.case is not None:
        if args.phi0 is not None or args.dphi0 is not None:
            raise InputError("--case: give either --case or --phi0 with --dphi0, not both")
        try:
            number = int(args.case)
        except ValueError:
            raise InputError(f"case: unknown {args.case!r}; choose 1, 2, 3 or 4") from None
        case = get_case(number)
        return number, case.phi0, case.dphi0
    if args.phi0 is None or args.dphi0 is None:
        raise InputError("--phi0, --dphi0: give both (or --case N)")
    return None, _number("phi0", args.phi0), _number("dphi0", args.dphi0)


def run_simulate(args):
    """Carry out ``closedloop simulate``; returns the JSON-ready summary."""
    from .formulations import formulation_from_name
    from .simulation import SOLVER_METHODS, simulate
    from .slider_crank import classify_motion, get_reading, initial_state, slider_crank_system

    case, phi0, dphi0 = _initial_condition(args)
    t_end = _number("t_end", args.t_end)
    if t_end <= 0:
        raise InputError(f"t_end: must be > 0 s, got {args.t_end}")
    rtol, atol = _number("rtol", args.rtol), _number("atol", args.atol)
    for name, value in (("rtol", rtol), ("atol", atol)):
        if value <= 0:
            raise InputError(f"{name}: must be > 0, got {value:g}")
    if args.method not in SOLVER_METHODS:
        raise InputError(f"method: unknown {args.method!r}; choose one of {', '.join(SOLVER_METHODS)}")
    formulation = formulation_from_name(args.formulation, _number("alpha", args.alpha), _number("beta", args.beta))
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
        "motion": classify_motion(result, phi0),
        "final": final,
        "max_constraint_error": result.max_constraint_error,
        "max_velocity_constraint_error": float(np.max(result.velocity_constraint_error)),
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
        f"motion: {summary['motion']}"
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
    from pathlib import Path

    from .benchmark import (DEFAULT_SETTINGS, QUICK_SETTINGS, format_table, pareto_figure, residual_figure,
                            residual_traces, run_study, work_precision_figure)

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
        if args.command == "benchmark":
            print(run_benchmark(args))
            return 0
        summary = run_simulate(args)
    except ClosedLoopError as error:
        print(f"closedloop: error: {error}", file=sys.stderr)
        return 2 if isinstance(error, InputError) else 1
    print(json.dumps(summary, indent=2) if args.json else _format(summary))
    return 0


if __name__ == "__main__":
    sys.exit(main())
