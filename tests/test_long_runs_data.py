"""book/data/long_runs.json, which chapter 9's study 3 shows, must come from the current code and settings."""

import json
from pathlib import Path

import numpy as np
import pytest

from closedloop import __version__, simulate
from closedloop.balance import energy_balance
from closedloop.slider_crank import CASES, initial_state, slider_crank_system
from closedloop.studies.benchmark import source_fingerprint
from closedloop.studies.long_runs import DEFAULT_LONG_RUN_SETTINGS, load_long_runs, long_run_formulations

DATA = Path(__file__).resolve().parents[1] / "book" / "data" / "long_runs.json"
REGENERATE = "regenerate it with `make long-runs-data` (closedloop long-runs --json book/data/long_runs.json)"


@pytest.fixture(scope="module")
def data():
    assert DATA.exists(), f"{DATA} is missing; {REGENERATE}"
    return load_long_runs(DATA)


def test_data_file_is_not_stale(data):
    assert data["source_fingerprint"] == source_fingerprint(), (
        f"{DATA.name} was made by other library sources than these (fingerprint "
        f"{data['source_fingerprint'][:12]} != {source_fingerprint()[:12]}): {REGENERATE}")
    assert data["current"]
    assert data["closedloop_version"] == __version__, f"made by closedloop {data['closedloop_version']}: {REGENERATE}"


def test_data_file_is_the_default_study(data):
    settings = DEFAULT_LONG_RUN_SETTINGS
    assert data["settings"] == settings.as_dict(), f"not the default settings of the code: {REGENERATE}"
    assert list(data["runs"]) == [f.name for f in long_run_formulations()], REGENERATE
    assert np.array_equal(data["t"], np.linspace(0.0, settings.t_end, settings.samples))
    for run in data["runs"].values():
        assert run["constraint_error"].shape == run["balance_residual"].shape == data["t"].shape
        assert run["max_constraint_error"] == pytest.approx(run["constraint_error"].max(), rel=1e-5)
        assert run["max_balance_residual"] == pytest.approx(np.abs(run["balance_residual"]).max(), rel=1e-5)


def test_first_seconds_recomputed_match_the_file(data):
    """The first 20 s of the augmented run, computed now, are the file's first 20 s (same steps, same switches)."""
    settings = DEFAULT_LONG_RUN_SETTINGS
    system = slider_crank_system()
    case = CASES[settings.case]
    state = initial_state(system, case.phi0, case.dphi0)
    formulation = long_run_formulations()[0]
    grid = data["t"][data["t"] <= 20.0]
    result = simulate(system, state, 25.0, formulation=formulation, method=settings.method, rtol=settings.rtol,
                      atol=settings.rtol, t_eval=grid, work=True)
    stored = data["runs"][formulation.name]
    n = grid.size
    # The drift of the augmented run is the integrator's truncation error, and the step sizes that make it follow
    # the error estimates continuously: a last-bit difference in a linear solve (OpenBLAS picks its kernels per
    # processor) moves it by up to 0.2 % between two x86-64 machines with the same wheels. Another formulation,
    # method or tolerance moves it by a factor.
    np.testing.assert_allclose(result.constraint_error, stored["constraint_error"][:n], rtol=1e-2, atol=1e-300)
    np.testing.assert_allclose(energy_balance(system, result).residual, stored["balance_residual"][:n],
                               rtol=1e-2, atol=1e-13)


def test_a_short_study_keeps_what_the_chapter_says(tmp_path):
    """The study's own numbers over 20 s: the augmented system drifts far more than Baumgarte's, the minimal
    formulation stays closed to round-off, every run follows the reference's crank angle, and the file it
    makes is read back by load_long_runs."""
    import json

    from closedloop.errors import InputError
    from closedloop.studies.long_runs import LongRunSettings, run_long_runs

    data = run_long_runs(LongRunSettings(t_end=20.0, samples=41, phase_check_time=10.0))
    runs = data["runs"]
    assert runs["augmented"]["max_constraint_error"] > 10 * runs["baumgarte"]["max_constraint_error"]
    assert runs["minimal"]["max_constraint_error"] < 1e-10
    for run in runs.values():
        assert run["early_phase_error"] <= run["max_phase_error"] < 1e-4
        assert run["max_balance_residual"] < 1e-2
    path = tmp_path / "short.json"
    path.write_text(json.dumps(data))
    again = load_long_runs(path)
    assert again["current"] and again["t"].shape == (41,)
    with pytest.raises(InputError, match="settings"):
        run_long_runs({"t_end": 20.0})
