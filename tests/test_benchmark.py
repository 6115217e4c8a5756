"""closedloop benchmark: the study's rows, the tables read from rows, and the rules that prune it.

The quick study runs once per session (``quick_benchmark`` in conftest.py: case 2, DOP853 and
ode.dop853, three tolerances, one repeat); the command's printed tables and figures are checked
in test_cli.py. No test here asserts a speed: timings on a shared machine are noise.
"""

import re
from types import SimpleNamespace

import numpy as np
import pytest

from closedloop.errors import InputError
from closedloop.studies.benchmark import (BASELINE_KEY, BASELINE_KEYS, BASELINE_MATH_KEY, QUICK_SETTINGS,
                                          REFERENCE_METHOD, REFERENCE_TOL, Entry, StudySettings, cheapest_choices,
                                          performance_ratios, run_study, source_fingerprint, study_entries)

REQUIRED = ("case", "formulation", "method", "rtol", "cpu_s", "error_t10", "max_constraint_error", "nfev")


@pytest.fixture(scope="module")
def quick(quick_benchmark):
    return quick_benchmark


def curve(data, key, method="DOP853"):
    rows = [r for r in data["rows"] if r["formulation"] == key and r["method"] == method]
    return {r["rtol"]: r for r in rows}


def test_rows_have_the_promised_fields_and_cover_the_grid(quick):
    data, _, _ = quick
    assert data["rows"]
    for row in data["rows"]:
        for key in REQUIRED:
            assert key in row, key
        # a run may fail (Minimal at rtol 1e-3 meets its branch guard); it says when, and why
        assert row["status"] == "ok" or re.match(r"failed: .*at t = [0-9.]+ s", row["status"]), row["status"]
        assert row["status"] == "ok" or row["rtol"] > 1e-6
        assert row["case"] == 2 and row["method"] in QUICK_SETTINGS.methods and row["atol"] == row["rtol"]
    assert {r["formulation"] for r in data["rows"]} == {e.key for e in study_entries()}
    # every curve ends exactly once, and says why
    for entry in study_entries():
        for method in QUICK_SETTINGS.methods:
            rows = [r for r in data["rows"] if r["formulation"] == entry.key and r["method"] == method]
            if not rows:
                assert method not in entry.methods
                continue
            assert [("curve_end" in r) for r in rows] == [False] * (len(rows) - 1) + [True]
            assert [r["rtol"] for r in rows] == list(QUICK_SETTINGS.rtols[:len(rows)])


def test_the_file_records_what_made_it(quick):
    data, _, _ = quick
    from closedloop import __version__

    assert data["closedloop_version"] == __version__
    assert data["source_fingerprint"] == source_fingerprint()
    assert data["settings"] == QUICK_SETTINGS.as_dict() and data["settings"]["quick"] is True
    assert data["machine"]["cpu_count"] >= 1


def test_the_reference_has_converged(quick):
    data, _, _ = quick
    check = data["references"]["2"]
    # rtol 1e-13 against 1e-12: far below the 1e-8 of the performance target
    assert check["agreement_t10"] < 1e-9 and check["agreement_max"] < 1e-8


@pytest.mark.parametrize("key", ["augmented", "minimal", "projected", "baumgarte-5-5"])
def test_errors_fall_with_rtol_for_convergent_formulations(quick, key):
    rows = curve(quick[0], key)
    errors = [rows[tol]["error_t10"] for tol in (1e-3, 1e-6, 1e-9) if rows[tol]["status"] == "ok"]
    assert len(errors) >= 2 and all(b < a / 10 for a, b in zip(errors, errors[1:]))
    assert rows[1e-9]["max_state_error"] >= rows[1e-9]["error_t10"]


def test_constraint_errors_tell_the_formulations_apart(quick):
    data, _, _ = quick
    for key in ("minimal", "projected"):       # on the manifold to Newton's tolerance at every grid point
        assert max(r["max_constraint_error"] for r in curve(data, key).values() if r["status"] == "ok") < 1e-13
    assert curve(data, "augmented")[1e-3]["max_constraint_error"] > 1e-4   # drift (13) at a loose tolerance
    assert curve(data, BASELINE_KEY)[1e-3]["max_constraint_error"] > 1e-4  # the baseline is (12) too


def test_the_baseline_s_time_is_the_one_of_sympy_s_dynamicsymbols():
    """The baseline spells the time ``sympy.Symbol("t")``: the symbol dynamicsymbols are functions of, so its
    derivatives are the mechanics' own."""
    import sympy as sm
    import sympy.physics.mechanics as me

    phi = me.dynamicsymbols("phi")
    assert phi.args == (sm.Symbol("t"),)
    assert phi.diff(sm.Symbol("t")) == me.dynamicsymbols("phi", 1)
    assert phi.diff(sm.Symbol("t", real=True)) == 0                  # another symbol: the spelling matters


def test_the_sympy_baseline_is_the_same_mechanism(quick):
    """sympy.physics.mechanics' equations, derived independently, converge to the library's reference."""
    rows = curve(quick[0], BASELINE_KEY)
    assert rows[1e-6]["error_t10"] < 1e-3
    assert rows[1e-9]["error_t10"] < rows[1e-6]["error_t10"] / 100
    assert rows[1e-9]["max_state_error"] < 1e-5
    library = curve(quick[0], "augmented")
    # same equations (12), same method and tolerance: errors of the same size
    assert 0.1 < rows[1e-9]["error_t10"] / library[1e-9]["error_t10"] < 10


def test_a_baseline_run_that_never_ends_is_stopped_by_its_evaluation_cap():
    """Integrating through the gas force's switches, LSODA at rtol 1e-10 chatters in case 3 for ever
    (it ran for more than ten minutes in the study); max_nfev stops any run and names where."""
    from closedloop.errors import InputError, IntegrationError
    from closedloop.slider_crank import get_case, initial_state, slider_crank_system
    from closedloop.studies.baseline import LagrangesBaseline

    case = get_case(2)
    state = initial_state(slider_crank_system(), case.phi0, case.dphi0)
    baseline = LagrangesBaseline()
    done = baseline.simulate(state, 1.0, method="RK45", rtol=1e-6, atol=1e-6, max_nfev=10_000)
    with pytest.raises(IntegrationError, match=r"stopped at t = [\d.e-]+ s after max_nfev = 20 evaluations"):
        baseline.simulate(state, 1.0, method="RK45", rtol=1e-6, atol=1e-6, max_nfev=20)
    assert done.nfev > 20 and done.t[-1] == 1.0
    with pytest.raises(InputError, match="max_nfev"):
        baseline.simulate(state, 1.0, max_nfev=0)


def test_the_baseline_refuses_bad_outputs_and_states_before_integrating():
    """Its docstring promised an InputError for a parameter outside its range; t_eval beyond t_end gave
    scipy's ValueError, and a tuple for the state an AttributeError."""
    from closedloop.slider_crank import get_case, initial_state, slider_crank_system
    from closedloop.studies.baseline import LagrangesBaseline

    case = get_case(2)
    state = initial_state(slider_crank_system(), case.phi0, case.dphi0)
    baseline = LagrangesBaseline()
    for t_eval in ([30.0], [0.5, 0.5]):
        with pytest.raises(InputError, match=r"^t_eval: must increase strictly within \[0, 1\]$"):
            baseline.simulate(state, 1.0, t_eval=t_eval)
    with pytest.raises(InputError, match=r"^t_eval: holds no time"):
        baseline.simulate(state, 1.0, t_eval=[])
    with pytest.raises(InputError, match=r"^initial_state: expected an InitialState"):
        baseline.simulate((state.s, state.sd), 1.0)
    run = baseline.simulate(state, 1.0, method="RK45", rtol=1e-6, atol=1e-6, t_eval=[0.25, 1.0])
    assert run.t.tolist() == [0.25, 1.0]


def test_the_two_printers_are_one_baseline():
    """The math printer lambdifies the same expressions as numpy's: the same right-hand side to round-off,
    on both branches of the gas force and on both sides of its law's switch at x_C = 5, and, in the quick
    study, the same errors at the same tolerances."""
    from closedloop.slider_crank import slider_crank_system
    from closedloop.studies.baseline import LagrangesBaseline

    system = slider_crank_system()
    printers = [LagrangesBaseline(system.parameters, system.reading, modules=m) for m in ("numpy", "math")]
    rng = np.random.default_rng(36)
    for x, x_rate in ((2.0, 1.5), (5.3, 0.7), (4.0, -1.0), (1.6, 0.0)):
        y = np.array([rng.uniform(0, 2 * np.pi), rng.uniform(2.5, 3.8), x, rng.normal(), rng.normal(), x_rate])
        t = rng.uniform(0.0, 20.0)
        numpy_rhs, math_rhs = (printer.rhs(t, y) for printer in printers)
        assert np.allclose(math_rhs, numpy_rhs, rtol=1e-12, atol=1e-12), (y, numpy_rhs - math_rhs)
    assert printers[1].rhs(0.0, y).shape == (6,)


def test_the_quick_study_runs_the_baseline_with_both_printers(quick):
    rows = {key: curve(quick[0], key) for key in BASELINE_KEYS}
    for tol in (1e-6, 1e-9):
        numpy_row, math_row = rows[BASELINE_KEY][tol], rows[BASELINE_MATH_KEY][tol]
        assert numpy_row["status"] == math_row["status"] == "ok"
        # the same equations: errors of the same size (round-off may tip a step, not the accuracy)
        assert 0.2 < math_row["error_t10"] / numpy_row["error_t10"] < 5, (numpy_row, math_row)


def fake(case, key, cpu, error):
    return {"case": case, "formulation": key, "label": key, "method": "RK45", "rtol": 1e-6, "status": "ok",
            "cpu_s": cpu, "error_t10": error}


def test_the_library_is_compared_with_the_baseline_at_its_best_printer():
    """The ratio takes the cheaper printer that meets the target: here the math printer's row, not numpy's,
    and not the math printer's cheaper row that misses the target."""
    rows = [fake(1, "closed-form", 0.010, 1e-9), fake(1, BASELINE_KEY, 0.100, 1e-9),
            fake(1, BASELINE_MATH_KEY, 0.040, 1e-9), fake(1, BASELINE_MATH_KEY, 0.020, 1e-6)]
    ratio = performance_ratios(rows, target=1e-8)[1]
    assert ratio["baseline"]["formulation"] == BASELINE_MATH_KEY and ratio["ratio"] == pytest.approx(4.0)
    (level,) = cheapest_choices(rows, levels=(1e-8,))
    assert level["best"]["formulation"] == "closed-form" and level["baseline"]["cpu_s"] == 0.040


def test_cheapest_choice_and_ratio_from_rows():
    rows = [fake(1, "augmented", 0.10, 1e-9), fake(1, "minimal", 0.05, 1e-7), fake(1, "projected", 0.20, 1e-11),
            fake(1, BASELINE_KEY, 0.30, 1e-9), fake(1, BASELINE_KEY, 0.04, 1e-3),
            fake(2, "augmented", 0.10, 1e-5), fake(2, BASELINE_KEY, 0.50, 1e-9)]
    table = {(t["case"], t["level"]): t for t in cheapest_choices(rows, levels=(1e-2, 1e-8, 1e-10))}
    assert table[1, 1e-2]["best"]["formulation"] == BASELINE_KEY          # cheapest overall, whoever it is
    assert table[1, 1e-8]["best"]["formulation"] == "augmented"
    assert table[1, 1e-10]["best"]["formulation"] == "projected" and table[1, 1e-10]["baseline"] is None
    ratios = performance_ratios(rows, target=1e-8)
    assert ratios[1]["ratio"] == pytest.approx(0.30 / 0.10)
    assert ratios[2]["ratio"] is None and ratios[2]["library"] is None


def test_error_t10_comes_from_the_timed_run_whose_cpu_time_is_recorded(quick):
    """The row reports the error of the timed run (outputs at 10 s and 20 s), and a 2001-point grid
    changes neither the steps nor the value at 10 s, for solve_ivp's DOP853 and for ode.dop853
    alike: both interpolate outputs on DOP853's continuous extension of the same steps.

    The rows are those of the quick study; the reference is recomputed here as the study
    computes it (minimal coordinates, REFERENCE_METHOD, rtol = atol = REFERENCE_TOL, on its grid).
    """
    from closedloop import Minimal, simulate
    from closedloop.formulations import ClosedForm
    from closedloop.slider_crank import get_case, initial_state, slider_crank_system

    system = slider_crank_system()
    case = get_case(2)
    state = initial_state(system, case.phi0, case.dphi0)
    grid = np.linspace(0.0, QUICK_SETTINGS.t_end, QUICK_SETTINGS.grid_points)
    at_10 = int(np.argmin(np.abs(grid - QUICK_SETTINGS.t_check)))
    assert (grid.size, at_10, grid[at_10]) == (2001, 1000, 10.0)
    run = simulate(system, state, 20.0, formulation=Minimal(), method=REFERENCE_METHOD, rtol=REFERENCE_TOL,
                   atol=REFERENCE_TOL, t_eval=grid)
    reference = np.concatenate((run.s[:, at_10], run.sd[:, at_10]))
    for method in ("ode.dop853", "DOP853"):
        timed = simulate(system, state, 20.0, formulation=ClosedForm(1, 1), method=method, rtol=1e-6,
                         atol=1e-6, t_eval=(10.0, 20.0))
        on_grid = simulate(system, state, 20.0, formulation=ClosedForm(1, 1), method=method, rtol=1e-6,
                           atol=1e-6, t_eval=grid)
        timed_error = np.abs(np.concatenate((timed.s[:, 0], timed.sd[:, 0])) - reference).max()
        grid_error = np.abs(np.concatenate((on_grid.s[:, at_10], on_grid.sd[:, at_10])) - reference).max()
        row = curve(quick[0], "closed-form", method)[1e-6]
        assert row["error_t10"] == timed_error, method
        assert grid_error == pytest.approx(timed_error, rel=1e-6), method
        assert np.array_equal(on_grid.step_sizes, timed.step_sizes) and row["nfev"] <= on_grid.nfev <= 1.5 * row["nfev"], method


def test_the_baseline_keeps_its_own_methods_in_every_case():
    """The other cases run fewer methods; the baseline keeps LSODA there, its best in case 2,
    so that the library's speed-up in those cases is not measured against a handicapped rival."""
    from closedloop.studies.benchmark import DEFAULT_SETTINGS as settings

    for key in BASELINE_KEYS:
        assert settings.methods_of(settings.main_case, key) == settings.methods
        for case in settings.cases:
            if case != settings.main_case:
                assert "LSODA" in settings.methods_of(case, key)
                assert "LSODA" not in settings.methods_of(case, "closed-form")


@pytest.mark.parametrize("errors, rows_run", [
    # errors that wander near rtol (the compiled DOP853 in case 1) are followed to the end
    ((5.0e-5, 6.7e-5, 2.7e-7, 4.7e-7, 1.5e-7, 3.0e-9), 6),
    # an error stuck far above rtol (drift, or the reference's floor): two flat rows end the curve
    # (at rtol 1e-5 and 1e-6 the error is within 100 rtol, so those rows are not flat yet)
    ((3e-4, 2e-5, 1.9e-5, 1.8e-5, 1.8e-5, 1.8e-5, 1e-9), 6),
])
def test_the_plateau_rule_stops_only_at_an_error_floor(monkeypatch, errors, rows_run):
    """run_study on one contestant whose error at 10 s is prescribed per tolerance.

    ``simulate`` as the study calls it (``closedloop.studies.benchmark.simulate``) is replaced by
    a stand-in: the reference (minimal coordinates) is zero, the contestant is off by the error
    of its rtol, everywhere.
    """
    import closedloop.studies.benchmark
    from closedloop import Baumgarte, Minimal

    rtols = tuple(10.0 ** -k for k in range(3, 3 + len(errors)))
    error_at = dict(zip(rtols, errors))

    def stand_in(system, state, t_end, formulation, method, rtol, atol, t_eval):
        t = np.asarray(t_eval, dtype=float)
        y = np.full((6, t.size), 0.0 if isinstance(formulation, Minimal) else error_at[rtol])
        return SimpleNamespace(t=t, s=y[:3], sd=y[3:], nfev=1, cpu_time=0.0, constraint_error=np.zeros(t.size),
                               velocity_constraint_error=np.zeros(t.size))

    monkeypatch.setattr(closedloop.studies.benchmark, "simulate", stand_in)
    settings = StudySettings(cases=(2,), methods=("DOP853",), rtols=rtols, repeats=1, grid_points=3)
    rows = run_study(settings, entries=[Entry("contestant", "Contestant", Baumgarte())])["rows"]
    assert [row["error_t10"] for row in rows] == list(errors[:len(rows)])
    assert len(rows) == rows_run
    assert rows[-1]["curve_end"] == ("tightest rtol" if rows_run == len(errors) else
                                     f"error plateau: not halved for {settings.plateau} tolerances")


def test_the_runs_use_the_settings_times_and_measure_at_t_check_itself():
    """``t_end`` and ``t_check`` of the settings are the runs' own (they are recorded as provenance),
    and error_t10 is the error at t_check even when the even grid does not hold it (here 0.73 s on a
    0.5 s grid): the same number as a run and a reference computed by themselves at that time."""
    from closedloop import ClosedForm, Minimal, simulate
    from closedloop.slider_crank import get_case, initial_state, slider_crank_system

    settings = StudySettings(cases=(2,), methods=("DOP853",), rtols=(1e-6,), repeats=1, t_end=2.0, t_check=0.73,
                             grid_points=5)
    data = run_study(settings, entries=[Entry("closed-form", "Closed form", ClosedForm(1, 1), ("DOP853",))])
    (row,) = data["rows"]
    system, case = slider_crank_system(), get_case(2)
    state = initial_state(system, case.phi0, case.dphi0)
    run = simulate(system, state, 2.0, formulation=ClosedForm(1, 1), method="DOP853", rtol=1e-6, atol=1e-6,
                   t_eval=(0.73, 2.0))
    grid = [0.0, 0.5, 0.73, 1.0, 1.5, 2.0]                   # the study's: 5 even times and t_check
    reference = simulate(system, state, 2.0, formulation=Minimal(), method=REFERENCE_METHOD, rtol=REFERENCE_TOL,
                         atol=REFERENCE_TOL, t_eval=grid)
    expected = np.abs(np.concatenate((run.s[:, 0] - reference.s[:, 2], run.sd[:, 0] - reference.sd[:, 2]))).max()
    assert row["status"] == "ok", row["status"]
    assert row["error_t10"] == pytest.approx(expected, rel=1e-9)


def test_a_check_time_outside_the_run_is_refused():
    with pytest.raises(InputError, match="t_check"):
        run_study(StudySettings(cases=(2,), methods=("DOP853",), rtols=(1e-3,), repeats=1, t_end=5.0, t_check=10.0))
