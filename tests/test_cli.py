"""The closedloop command line, every subcommand: what it prints and writes, its help, and one-line errors.

closedloop simulate, closedloop basin, closedloop benchmark (its study's rows are checked in
test_benchmark.py; the same quick run, ``quick_benchmark`` in conftest.py, serves both).
"""

import json
import math
import re
import subprocess
import sys

import numpy as np
import pytest

import closedloop.methods as methods
from closedloop.cli import build_parser, main


def run(*args):
    return subprocess.run([sys.executable, "-m", "closedloop.cli", *args], capture_output=True, text=True,
                          timeout=300)


# -- closedloop simulate ----------------------------------------------------------------------
def test_json_has_the_promised_fields_and_unwrapped_angles(capsys):
    assert main(["simulate", "--case", "2", "--json", "--method", "DOP853"]) == 0
    out = json.loads(capsys.readouterr().out)
    for key in ("phi0", "dphi0", "t_end", "formulation", "method", "reading", "motion", "final",
                "max_constraint_error", "cpu_s"):
        assert key in out
    assert set(out["final"]) >= {"phi", "psi", "x", "dphi", "dpsi", "dx"}
    assert (out["t_end"], out["formulation"], out["reading"]) == (20.0, "closed-form", "decimal-opposing")
    assert out["phi0"] == pytest.approx(math.pi / 2) and out["dphi0"] == 1.0
    assert out["motion"] == "full rotation"
    assert out["final"]["phi"] > out["phi0"] + 2 * math.pi        # unwrapped, not reduced modulo 2 pi
    assert 1.5 <= out["final"]["x"] <= 5.5
    assert 0 < out["max_constraint_error"] < 1e-6


def test_free_initial_condition_and_options(capsys):
    assert main(["simulate", "--phi0", "3.14159", "--dphi0", "0.5", "--t-end", "5", "--formulation", "orthogonal",
                 "--alpha", "10", "--beta", "10", "--method", "LSODA", "--rtol", "1e-8", "--atol", "1e-8",
                 "--json"]) == 0
    out = json.loads(capsys.readouterr().out)
    assert (out["formulation"], out["alpha"], out["method"], out["t_end"]) == ("orthogonal", 10.0, "LSODA", 5.0)


def test_the_sticking_time_is_the_start_of_the_run_s_first_sticking_interval(capsys):
    """Case 3 sticks at about 28.4 s and stays stuck to the end: stuck_at is the interval's start, the same
    run simulated here with the command's defaults (closed form, alpha = beta = 5, ode.dop853, 1e-9)."""
    from closedloop import ClosedForm, simulate
    from closedloop.slider_crank import get_case, initial_state, slider_crank_system

    assert main(["simulate", "--case", "3", "--t-end", "30", "--json"]) == 0
    data = json.loads(capsys.readouterr().out)
    system, case = slider_crank_system(), get_case(3)
    result = simulate(system, initial_state(system, case.phi0, case.dphi0), 30.0, formulation=ClosedForm(5, 5),
                      method="ode.dop853", rtol=1e-9, atol=1e-9)
    start, end = result.sticking_intervals[0]
    assert end == 30.0 and 20.0 < start < 30.0
    assert data["stuck_at"] == start
    assert main(["simulate", "--case", "3", "--t-end", "30"]) == 0
    assert f"(the slider sticks at t = {start:.2f} s)" in capsys.readouterr().out


def test_summary_is_readable(capsys):
    assert main(["simulate", "--case", "1", "--t-end", "5"]) == 0
    text = capsys.readouterr().out
    assert "motion: oscillation" in text and "max |f| (32)" in text
    assert len(text.splitlines()) <= 8


def test_a_short_run_says_what_oscillation_means_and_the_columns_align(capsys):
    """Case 2 over 2.5 s has turned less than 2 pi and still turns forward: "oscillation" by the rule alone
    was misleading, so the line says what the rule saw. The second line of the final state sat 2 columns
    off for a t_end such as 2.5."""
    assert main(["simulate", "--case", "2", "--t-end", "2.5"]) == 0
    lines = capsys.readouterr().out.splitlines()
    assert "motion: oscillation (the crank did not turn 2 pi beyond its start in 2.5 s)" in lines
    k = next(i for i, line in enumerate(lines) if line.startswith("at t ="))
    assert lines[k].index("phi =") == lines[k + 1].index("phi' =")


def test_the_default_method_is_one_the_formulation_takes(capsys):
    """ode.dop853 wherever the formulation takes it; DOP853 for Projected, which resets the state of a solve_ivp
    Runge-Kutta method after each step: --formulation projected alone must not fail on a method never given."""
    for formulation, method in (("closed-form", "ode.dop853"), ("baumgarte", "ode.dop853"),
                                ("projected", "DOP853")):
        assert main(["simulate", "--case", "2", "--t-end", "1", "--formulation", formulation, "--json"]) == 0
        assert json.loads(capsys.readouterr().out)["method"] == method


def test_a_tolerance_too_loose_to_classify_is_refused_before_the_run(tmp_path, capsys):
    """It used to integrate, then fail in classify_motion naming 'result', with no figure written."""
    path = tmp_path / "loose.png"
    assert main(["simulate", "--case", "4", "--rtol", "1e-2", "--plot", str(path)]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith("closedloop: error: --rtol: rtol = 0.01 is too loose")
    assert err.rstrip().endswith("rerun with rtol <= 0.001")
    assert not path.exists()
    assert main(["simulate", "--case", "4", "--t-end", "1", "--rtol", "1e-3", "--atol", "1e-3"]) == 0


def test_plot_writes_a_png(tmp_path, capsys):
    path = tmp_path / "case3.png"
    assert main(["simulate", "--case", "3", "--t-end", "4", "--plot", str(path)]) == 0
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert path.stat().st_size > 20_000


@pytest.mark.parametrize("args, message", [
    (["--case", "7"], "case: unknown 7; choose one of 1, 2, 3, 4"),
    (["--case", "two"], "case: unknown 'two'"),
    (["--case", "1", "--t-end", "-2"], "t_end: must be a finite number > 0 s"),
    (["--case", "1", "--rtol", "0"], "rtol: must be a finite number > 0"),
    (["--case", "1", "--atol", "-1"], "atol: must be a finite number > 0"),
    (["--case", "1", "--alpha", "-3"], "alpha: must be a finite number >= 0"),
    (["--case", "1", "--beta", "-3"], "beta: must be a finite number >= 0"),
    (["--case", "1", "--formulation", "kane"], "formulation: unknown 'kane'"),
    (["--case", "1", "--method", "Euler"], "method: unknown 'Euler'"),
    (["--case", "1", "--reading", "hundreds"], "reading: unknown 'hundreds'"),
    (["--phi0", "nan", "--dphi0", "1"], "phi0: must be a finite number"),
    (["--phi0", "1"], "--phi0, --dphi0: give both"),
    (["--case", "1", "--frobnicate"], "unrecognized arguments"),
])
def test_bad_input_is_one_line_on_stderr_and_a_nonzero_exit(args, message, capsys):
    assert main(["simulate", *args]) == 2
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1 and lines[0].startswith("closedloop: error: ") and message in lines[0]


def test_installed_command_prints_no_traceback_on_bad_input():
    """The same through a real process, as a reader would run it."""
    done = run("simulate", "--case", "1", "--t-end", "0")
    assert done.returncode == 2
    assert done.stderr.strip() == "closedloop: error: t_end: must be a finite number > 0 s, got 0.0"
    assert "Traceback" not in done.stderr


def test_the_command_line_help_lists_every_method(capsys):
    with pytest.raises(SystemExit):
        build_parser().parse_args(["simulate", "--help"])
    help_text = capsys.readouterr().out
    for name in methods.SOLVER_METHODS:
        assert f" {name}," in help_text or f" {name} " in help_text
    assert "ode.dop853" in help_text


# -- closedloop basin -------------------------------------------------------------------------
def test_basin_writes_json_and_png(tmp_path, capsys):
    path, png = tmp_path / "map.json", tmp_path / "map.png"
    assert main(["basin", "--phi0", "0:2pi:4", "--dphi0", "0.5:1.5:2", "--t-end", "6",
                 "--json", str(path), "--png", str(png)]) == 0
    captured = capsys.readouterr()
    assert captured.err == ""                                  # no progress bar when stderr is not a terminal
    assert "4 x 2 cells" in captured.out and "full rotation:" in captured.out
    data = json.loads(path.read_text())
    assert set(data) >= {"phi0", "dphi0", "t_end", "outcome", "labels", "version", "cpu_s"}
    assert data["phi0"] == pytest.approx([0.0, math.pi / 2, math.pi, 1.5 * math.pi])
    assert data["dphi0"] == pytest.approx([0.5, 1.0]) and data["t_end"] == 6.0
    assert np.array(data["outcome"]).shape == (2, 4)
    assert data["labels"] == {"0": "oscillation", "1": "full rotation"}
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"


@pytest.mark.parametrize("args, message", [
    (["--phi0", "0:1", "--dphi0", "0:3:5"], "phi0: expected START:STOP:N, got '0:1'"),
    (["--phi0", "0:1:0", "--dphi0", "0:3:5"], "phi0: N must be an integer >= 1, got 0"),
    (["--phi0", "0:1:2.5", "--dphi0", "0:3:5"], "phi0: N must be an integer >= 1, got '2.5'"),
    (["--phi0", "1:0:4", "--dphi0", "0:3:5"], "phi0: STOP must be > START"),
    (["--phi0", "0:7:4", "--dphi0", "0:3:5"], "phi0: the range must lie inside [0, 2pi]"),
    (["--phi0=-1:2:4", "--dphi0", "0:3:5"], "phi0: the range must lie inside [0, 2pi]"),
    (["--phi0", "0:2pi:4", "--dphi0=-1:3:5"], "dphi0: START must be >= 0"),
    (["--phi0", "0:x:4", "--dphi0", "0:3:5"], "phi0: expected a number, got 'x'"),
    (["--phi0", "0:2pi:4", "--dphi0", "0:3:5", "--t-end", "0"], "t_end: must be a finite number > 0 s"),
    (["--phi0", "0:2pi:4", "--dphi0", "0:3:5", "--t-end", "0.01"],      # it named the default step, not given
     "--t-end: 0.01 s is shorter than the default step 0.02 s"),
    (["--phi0", "0:2pi:4", "--dphi0", "0:3:5", "--png", "map.svg"], "png: the figure is written as PNG"),
    (["--phi0", "0:2pi:4"], "the following arguments are required: --dphi0"),
])
def test_basin_bad_input_is_one_line_and_exit_2(args, message, capsys):
    assert main(["basin", *args]) == 2
    captured = capsys.readouterr()
    lines = captured.err.splitlines()
    assert captured.out == "" and len(lines) == 1
    assert lines[0].startswith("closedloop: error: ") and message in lines[0]


def test_basin_progress_bar_only_on_a_terminal(monkeypatch, capsys):
    import io
    import sys

    class Terminal(io.StringIO):
        def isatty(self):
            return True

    terminal = Terminal()
    monkeypatch.setattr(sys, "stderr", terminal)
    assert main(["basin", "--phi0", "0:2pi:2", "--dphi0", "0:1:1", "--t-end", "0.5"]) == 0
    bar = terminal.getvalue()
    assert bar.startswith("\r[") and "100 %" in bar and bar.endswith("\n")
    assert "[" + "#" * 40 + "]" in bar
    assert "\r" not in capsys.readouterr().out                # the bar never goes to stdout


# -- closedloop benchmark ---------------------------------------------------------------------
def test_benchmark_prints_the_tables_and_writes_the_figures(quick_benchmark):
    _, text, figures = quick_benchmark
    assert "Cheapest choice per accuracy level" in text
    assert "case 2:" in text and "baseline CPU / best library CPU" in text
    names = sorted(p.name for p in figures.iterdir())
    assert names == ["best_per_formulation.png", "residuals_case2.png", "work_precision_case2.png"]
    assert all((figures / n).read_bytes()[:4] == b"\x89PNG" for n in names)


@pytest.mark.parametrize("args, message", [
    (["--json", "/no/such/folder/rows.json"], "json: the folder of"),
    (["--figures", __file__], "figures: .* is not a folder"),
    (["--repeats", "3"], "unrecognized arguments"),
])
def test_benchmark_bad_input_is_one_line_and_exit_2(capsys, args, message):
    assert main(["benchmark", "--quick", *args]) == 2
    err = capsys.readouterr().err.strip()
    assert len(err.splitlines()) == 1 and err.startswith("closedloop: error:")
    assert re.search(message, err)
