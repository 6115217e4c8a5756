"""The command line under faults: output paths refused before any computation, atomic writes,
``--json -``, negative numbers after an option, and Ctrl-C / SIGTERM ending in one line."""

import errno
import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import psutil
import pytest

import closedloop.simulation
import closedloop.slider_crank
import closedloop.studies.basin
import closedloop.studies.benchmark
import closedloop.studies.long_runs
from closedloop.cli import build_parser, main

from ._processes import started_workers

SRC = str(Path(__file__).resolve().parents[1] / "src")
BASIN = ["basin", "--phi0", "0:2pi:2", "--dphi0", "0.5:1.5:1", "--t-end", "0.5", "--workers", "1"]


@pytest.fixture
def no_computation(monkeypatch):
    """Every computation of the four commands fails the test if it starts."""
    def refuse(*args, **kwargs):
        raise AssertionError("a computation started before the refusal")

    monkeypatch.setattr(closedloop.studies.basin, "basin_map", refuse)
    monkeypatch.setattr(closedloop.studies.benchmark, "run_study", refuse)
    monkeypatch.setattr(closedloop.studies.long_runs, "run_long_runs", refuse)
    monkeypatch.setattr(closedloop.simulation, "simulate", refuse)
    monkeypatch.setattr(closedloop.slider_crank, "slider_crank_system", refuse)


def one_error_line(capsys, status, argv):
    """Run main(argv), check the exit status, nothing on stdout and one line on stderr; return that line."""
    assert main(argv) == status
    captured = capsys.readouterr()
    assert captured.out == ""
    lines = captured.err.splitlines()
    assert len(lines) == 1, captured.err
    return lines[0]


# -- output paths, checked before any computation ------------------------------------------------


def bad_outputs(tmp):
    (tmp / "folder.png").mkdir()
    (tmp / "a.png").write_bytes(b"old")
    (tmp / "b.json").symlink_to(tmp / "a.png")
    (tmp / "afile").write_text("x")
    (tmp / "figs").mkdir()
    return [
        (["simulate", "--case", "1", "--plot", f"{tmp}/nope/x.png"], f"--plot: the folder of {tmp}/nope/x.png does not exist"),
        (["simulate", "--case", "1", "--plot", f"{tmp}/folder.png"], f"--plot: {tmp}/folder.png is a folder"),
        (["simulate", "--case", "1", "--plot", f"{tmp}/x.svg"], "--plot: the figure is written as PNG"),
        ([*BASIN, "--json", f"{tmp}/nope/m.json"], f"--json: the folder of {tmp}/nope/m.json does not exist"),
        ([*BASIN, "--png", f"{tmp}/nope/m.png"], f"--png: the folder of {tmp}/nope/m.png does not exist"),
        ([*BASIN, "--json", str(tmp)], f"--json: {tmp} is a folder"),
        ([*BASIN, "--json", f"{tmp}/new/"], f"--json: {tmp}/new/ is a folder"),
        ([*BASIN, "--png", f"{tmp}/folder.png"], f"--png: {tmp}/folder.png is a folder"),
        ([*BASIN, "--json", f"{tmp}/m.png", "--png", f"{tmp}/m.png"], f"--json, --png: both name {tmp}/m.png"),
        ([*BASIN, "--json", f"{tmp}/b.json", "--png", f"{tmp}/a.png"], "--json, --png: both name"),   # a symlink
        (["benchmark", "--quick", "--json", f"{tmp}/nope/r.json"], "--json: the folder of"),
        (["benchmark", "--quick", "--figures", f"{tmp}/afile"], f"--figures: {tmp}/afile exists and is not a folder"),
        (["benchmark", "--quick", "--figures", f"{tmp}/afile/sub/dir"], f"--figures: cannot create {tmp}/afile/sub/dir"),
        (["benchmark", "--quick", "--json", f"{tmp}/figs", "--figures", f"{tmp}/figs"], f"--json: {tmp}/figs is a folder"),
        (["benchmark", "--quick", "--json", f"{tmp}/figs/residuals_case2.png", "--figures", f"{tmp}/figs"],
         "--json, --figures: both name"),
        (["long-runs", "--json", f"{tmp}/nope/l.json"], "--json: the folder of"),
        (["long-runs", "--json", str(tmp)], f"--json: {tmp} is a folder"),
    ]


def test_every_bad_output_path_is_refused_before_computing(tmp_path, capsys, no_computation):
    for argv, message in bad_outputs(tmp_path):
        line = one_error_line(capsys, 2, argv)
        assert line.startswith("closedloop: error: ") and message in line, (argv, line)
    assert (tmp_path / "a.png").read_bytes() == b"old"
    assert sorted(p.name for p in tmp_path.iterdir()) == ["a.png", "afile", "b.json", "figs", "folder.png"]


@pytest.mark.parametrize("argv, option", [
    (["simulate", "--case", "1", "--plot", "{tmp}/x.png"], "--plot"),
    ([*BASIN, "--json", "{tmp}/m.json"], "--json"),
    ([*BASIN, "--png", "{tmp}/m.png"], "--png"),
    (["benchmark", "--quick", "--json", "{tmp}/r.json"], "--json"),
    (["benchmark", "--quick", "--figures", "{tmp}/new/figures"], "--figures"),
])
def test_an_unwritable_folder_is_refused(argv, option, tmp_path, capsys, monkeypatch, no_computation):
    import closedloop.output

    monkeypatch.setattr(closedloop.output.os, "access", lambda path, mode: False)    # as for a user, not root
    line = one_error_line(capsys, 2, [a.format(tmp=tmp_path) for a in argv])
    assert line.startswith(f"closedloop: error: {option}: ") and "not writable" in line
    assert str(tmp_path) in line


def test_a_read_only_file_is_refused(tmp_path, capsys, monkeypatch, no_computation):
    import closedloop.output

    target = tmp_path / "m.json"
    target.write_text("old")
    real_access = os.access
    monkeypatch.setattr(closedloop.output.os, "access",
                        lambda path, mode: False if Path(path) == target else real_access(path, mode))
    line = one_error_line(capsys, 2, [*BASIN, "--json", str(target)])
    assert f"--json: {target} exists and is not writable" in line


@pytest.mark.parametrize("argv, option", [
    (["simulate", "--case", "2", "--t-end", "0.5", "--plot", "{folder}/x.png"], "--plot"),
    ([*BASIN, "--json", "{folder}/x.json"], "--json"),
    ([*BASIN, "--png", "{folder}/x.png"], "--png"),
    (["benchmark", "--quick", "--json", "{folder}/x.json"], "--json"),
])
def test_a_folder_the_system_will_not_write_into_is_refused_before_any_work(argv, option, capsys, monkeypatch,
                                                                            no_computation):
    """/proc passes os.access for root, yet no file can be made there: basin --json /proc/x.json computed the map,
    then failed to write it (the map lost), and simulate --plot /proc/x.png failed after the run without naming
    --plot. The folder is now tried with a file of its own before any work."""
    import closedloop.output

    folder = "/proc"
    if not os.path.isdir(folder) or not os.access(folder, os.W_OK):   # elsewhere: a folder that refuses files
        folder = "/proc" if os.path.isdir("/proc") else "/"
        real_access = os.access
        monkeypatch.setattr(closedloop.output.os, "access",
                            lambda path, mode: True if str(path) == folder else real_access(path, mode))
    line = one_error_line(capsys, 2, [a.format(folder=folder) for a in argv])
    assert line.startswith(f"closedloop: error: {option}: cannot write {folder}/x.")


@pytest.mark.skipif(os.geteuid() == 0, reason="root may write anywhere")
def test_a_folder_without_write_permission_is_refused(tmp_path, capsys, no_computation):
    locked = tmp_path / "locked"
    locked.mkdir(mode=0o500)
    try:
        line = one_error_line(capsys, 2, [*BASIN, "--json", str(locked / "m.json")])
    finally:
        locked.chmod(0o700)
    assert f"--json: the folder {locked} is not writable" in line


@pytest.mark.parametrize("argv, option", [
    (["simulate", "--case", "1", "--plot", "{tmp}/x.png"], "--plot"),
    ([*BASIN, "--png", "{tmp}/m.png"], "--png"),
    (["benchmark", "--quick", "--figures", "{tmp}/figures"], "--figures"),
])
def test_a_figure_without_matplotlib_is_refused(argv, option, tmp_path, capsys, monkeypatch, no_computation):
    monkeypatch.setitem(sys.modules, "matplotlib", None)                   # import matplotlib -> ImportError
    line = one_error_line(capsys, 2, [a.format(tmp=tmp_path) for a in argv])
    assert line.startswith(f"closedloop: error: {option}: writing a figure needs matplotlib")


def test_a_figures_folder_that_can_be_created_passes_and_is_not_created_early(tmp_path, monkeypatch, capsys):
    def stop(*args, **kwargs):
        raise closedloop.errors.IntegrationError("stopped by the test")

    import closedloop.errors

    monkeypatch.setattr(closedloop.studies.benchmark, "run_study", stop)
    line = one_error_line(capsys, 1, ["benchmark", "--quick", "--figures", str(tmp_path / "a" / "b")])
    assert line == "closedloop: error: stopped by the test"
    assert not (tmp_path / "a").exists()


# -- --json - -------------------------------------------------------------------------------------


def test_basin_json_dash_is_standard_output(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    assert main([*BASIN, "--json", "-"]) == 0
    captured = capsys.readouterr()
    data = json.loads(captured.out)
    assert data["phi0"] and data["t_end"] == 0.5
    assert "2 x 1 cells" in captured.err and "standard output" in captured.err
    assert list(tmp_path.iterdir()) == []                                 # no file named '-'


def test_benchmark_json_dash_is_standard_output(tmp_path, capsys, monkeypatch):
    monkeypatch.chdir(tmp_path)
    data = {"rows": [{"case": 2, "error": 1e-9}], "settings": {"cases": [2]}}
    monkeypatch.setattr(closedloop.studies.benchmark, "run_study", lambda settings, progress=None: data)
    monkeypatch.setattr(closedloop.studies.benchmark, "format_table", lambda data: "the table")
    assert main(["benchmark", "--quick", "--json", "-"]) == 0
    captured = capsys.readouterr()
    assert json.loads(captured.out) == data
    assert captured.err.strip() == "the table"
    assert list(tmp_path.iterdir()) == []


def test_basin_json_dash_through_a_real_process():
    done = subprocess.run([sys.executable, "-m", "closedloop.cli", *BASIN, "--json", "-"], capture_output=True,
                          text=True, timeout=60, env={**os.environ, "PYTHONPATH": SRC})
    assert done.returncode == 0, done.stderr
    assert json.loads(done.stdout)["outcome"]


# -- atomic writes --------------------------------------------------------------------------------


def leftovers(folder, keep):
    return sorted(p.name for p in folder.iterdir() if p.name not in keep)


def test_a_failed_json_write_keeps_the_previous_file(tmp_path, capsys, monkeypatch):
    target = tmp_path / "m.json"
    target.write_text("previous")

    def full_disk(data, handle, **kwargs):
        handle.write('{"phi0": [0.0, ')
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(json, "dump", full_disk)
    line = one_error_line(capsys, 1, [*BASIN, "--json", str(target)])
    assert line == f"closedloop: error: --json: cannot write {target}: No space left on device"
    assert target.read_text() == "previous"
    assert leftovers(tmp_path, {"m.json"}) == []                          # no temporary file left behind


def test_a_failed_figure_write_keeps_the_previous_file(tmp_path, capsys, monkeypatch):
    from matplotlib.figure import Figure

    target = tmp_path / "m.png"
    target.write_bytes(b"previous")

    def full_disk(self, handle, **kwargs):
        assert kwargs.get("format") == "png"
        handle.write(b"\x89PNG\r\n\x1a\n partial")
        raise OSError(errno.ENOSPC, "No space left on device")

    monkeypatch.setattr(Figure, "savefig", full_disk)
    line = one_error_line(capsys, 1, [*BASIN, "--png", str(target)])
    assert line == f"closedloop: error: --png: cannot write {target}: No space left on device"
    assert target.read_bytes() == b"previous"
    assert leftovers(tmp_path, {"m.png"}) == []


def test_an_interrupt_while_writing_keeps_the_previous_file(tmp_path, capsys, monkeypatch):
    target = tmp_path / "m.json"
    target.write_text("previous")

    def interrupted(data, handle, **kwargs):
        handle.write("{")
        raise KeyboardInterrupt

    monkeypatch.setattr(json, "dump", interrupted)
    assert one_error_line(capsys, 130, [*BASIN, "--json", str(target)]) == "closedloop: interrupted"
    assert target.read_text() == "previous"
    assert leftovers(tmp_path, {"m.json"}) == []


def test_a_good_write_replaces_the_file_and_keeps_its_permissions(tmp_path, capsys):
    target, png = tmp_path / "m.json", tmp_path / "m.png"
    target.write_text("previous")
    target.chmod(0o640)
    assert main([*BASIN, "--json", str(target), "--png", str(png)]) == 0
    assert json.loads(target.read_text())["t_end"] == 0.5
    assert target.stat().st_mode & 0o777 == 0o640
    assert png.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n"
    assert leftovers(tmp_path, {"m.json", "m.png"}) == []
    out = capsys.readouterr().out
    assert f"written to {target}" in out and f"written to {png}" in out


# -- negative numbers after an option -------------------------------------------------------------


@pytest.mark.parametrize("argv, name, value", [
    (["simulate", "--phi0", "1", "--dphi0", "-1e-3"], "dphi0", "-1e-3"),
    (["simulate", "--phi0", "-2.5E+1", "--dphi0", "1"], "phi0", "-2.5E+1"),
    (["simulate", "--phi0", "1", "--dphi0=-1e-3"], "dphi0", "-1e-3"),
    (["simulate", "--phi0", "1", "--dphi0", "-.5"], "dphi0", "-.5"),
    (["simulate", "--case", "1", "--t-end", "-1e-3"], "t_end", "-1e-3"),
    (["simulate", "--case", "1", "--t", "-1e-3"], "t_end", "-1e-3"),               # an abbreviation
    (["simulate", "--case", "1", "--alpha", "-inf"], "alpha", "-inf"),
    (["basin", "--phi0", "0:1:2", "--dphi0", "-1e-3:1:2"], "dphi0", "-1e-3:1:2"),
    (["basin", "--phi0", "0:1:2", "--dphi0", "1:2:2", "--step", "-1e-3"], "step", "-1e-3"),
])
def test_negative_numbers_follow_their_option(argv, name, value):
    assert getattr(build_parser().parse_args(argv), name) == value


@pytest.mark.parametrize("argv, message", [
    (["simulate", "--case", "1", "--t-end", "-1e-3"], "t_end: must be a finite number > 0 s, got -0.001"),
    (["simulate", "--case", "1", "--rtol", "-1E-9"], "rtol: must be a finite number > 0"),
    (["basin", "--phi0", "0:2pi:2", "--dphi0", "-1e-3:1:2"], "dphi0: START must be >= 0"),
    (["simulate", "--phi0", "--dphi0", "1"], "argument --phi0: expected one argument"),     # still an error
])
def test_negative_numbers_reach_the_checks(argv, message, capsys, no_computation):
    line = one_error_line(capsys, 2, argv)
    assert message in line and "Traceback" not in line


def test_a_negative_speed_runs(capsys):
    assert main(["simulate", "--phi0", "1", "--dphi0", "-1e-3", "--t-end", "0.05", "--json"]) == 0
    assert json.loads(capsys.readouterr().out)["dphi0"] == -1e-3


# -- errors and interrupts in main() --------------------------------------------------------------


def test_an_os_error_is_one_line_and_exit_1(capsys, monkeypatch):
    def broken(*args, **kwargs):
        raise OSError(errno.EIO, "Input/output error", "/some/file")

    monkeypatch.setattr(closedloop.studies.basin, "basin_map", broken)
    assert one_error_line(capsys, 1, BASIN) == "closedloop: error: /some/file: Input/output error"


def test_keyboard_interrupt_in_process_and_the_handlers_are_restored(capsys, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    before = signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)
    monkeypatch.setattr(closedloop.studies.basin, "basin_map", interrupted)
    assert one_error_line(capsys, 130, BASIN) == "closedloop: interrupted"
    assert (signal.getsignal(signal.SIGINT), signal.getsignal(signal.SIGTERM)) == before


def start(*argv):
    # A shell's background job (nohup, `&`) inherits SIGINT ignored, and Python then keeps it ignored:
    # the command starts with SIGINT at its default, as when a user runs it in a terminal.
    return subprocess.Popen([sys.executable, "-m", "closedloop.cli", *argv], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True, env={**os.environ, "PYTHONPATH": SRC},
                            preexec_fn=lambda: signal.signal(signal.SIGINT, signal.SIG_DFL))


BIG_BASIN = ["basin", "--phi0", "0:2pi:90", "--dphi0", "0:3:90", "--t-end", "20", "--workers", "2"]   # ~20 s


@pytest.mark.parametrize("signum, status, word", [(signal.SIGTERM, 143, "terminated"),
                                                  (signal.SIGINT, 130, "interrupted")])
def test_a_signal_ends_basin_and_its_workers(signum, status, word):
    process = start(*BIG_BASIN)
    try:
        children = started_workers(process)
        time.sleep(1.0)
        process.send_signal(signum)
        out, err = process.communicate(timeout=30)
    finally:
        if process.poll() is None:
            process.kill()
    assert process.returncode == status
    assert err == f"closedloop: {word}\n" and out == ""
    _, alive = psutil.wait_procs(children, timeout=5)
    assert not alive, f"workers outlived the command: {alive}"


def wait_for_cpu(process, seconds, timeout=60):
    """Return once ``process`` has used ``seconds`` of CPU time: past its start-up, and working."""
    watched, deadline = psutil.Process(process.pid), time.monotonic() + timeout
    while sum(watched.cpu_times()[:2]) < seconds:
        assert process.poll() is None, f"the command ended before it had used {seconds} s of CPU"
        assert time.monotonic() < deadline, f"the command used less than {seconds} s of CPU in {timeout} s"
        time.sleep(0.05)


@pytest.fixture(scope="module")
def generated_code():
    """The slider-crank's generated functions in the session's code cache, so that a command's start-up
    (import, cache load: about 0.2 s of CPU) is short and the same in every test that times it."""
    done = subprocess.run([sys.executable, "-m", "closedloop.cli", "simulate", "--case", "2", "--t-end", "0.01"],
                          capture_output=True, text=True, env={**os.environ, "PYTHONPATH": SRC})
    assert done.returncode == 0, done.stderr


@pytest.mark.parametrize("method", ["ode.dop853", "RK45"])
@pytest.mark.parametrize("signum, status, word", [(signal.SIGINT, 130, "interrupted"),
                                                  (signal.SIGTERM, 143, "terminated")])
def test_a_signal_ends_simulate_in_one_line(generated_code, method, signum, status, word):
    """ode.dop853's compiled code calls the right-hand side back: a signal arriving there comes out
    of scipy as a SystemError, which must still end the run as the signal, not as an internal error.

    The signal is sent once the command has used 1 s of CPU: its start-up takes about 0.2 s, so the
    signal arrives well inside the integration (a run to t = 1e5 takes minutes)."""
    process = start("simulate", "--case", "2", "--t-end", "1e5", "--method", method)
    wait_for_cpu(process, 1.0)
    process.send_signal(signum)
    out, err = process.communicate(timeout=30)
    assert (process.returncode, err, out) == (status, f"closedloop: {word}\n", "")


def test_a_defect_of_the_library_is_one_line_not_a_traceback(monkeypatch, capsys):
    """Whatever escapes the library's own errors (a bug) still ends in one line and exit 1."""
    import closedloop.cli

    def broken(args):
        raise ZeroDivisionError("a bug")

    monkeypatch.setattr(closedloop.cli, "run_simulate", broken)
    assert closedloop.cli.main(["simulate", "--case", "1"]) == 1
    assert capsys.readouterr().err == ("closedloop: error: internal error (ZeroDivisionError: a bug); please "
                                       "report it with the command that caused it\n")
