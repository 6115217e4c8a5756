"""A result whose own residuals show it is meaningless says so, and is not classified.

The bound is sqrt(max(rtol, atol)) on |f| of (32) and sqrt(tol) (1 + max |s'|) on |f'| of (9),
over the output points and every step end (closedloop.simulation.result.residual_warnings).
"""

import dataclasses
import math

import numpy as np
import pytest

from closedloop import InputError, simulate
from closedloop.cli import main
from closedloop.formulations import formulation_from_name
from closedloop.simulation.result import residual_warnings
from closedloop.slider_crank import CLASSIFY_RTOL_LIMIT, classify_motion, get_case, initial_state, slider_crank_system


@pytest.fixture(scope="module")
def system():
    return slider_crank_system()


def start(system, case):
    chosen = get_case(case)
    return initial_state(system, chosen.phi0, chosen.dphi0)


def test_the_bound_is_the_square_root_of_the_tolerance():
    assert residual_warnings(0.9e-3, 0.0, 0.0, 1e-6, 1e-6) == []
    assert len(residual_warnings(1.1e-3, 0.0, 0.0, 1e-6, 1e-7)) == 1
    assert "max |f'| = 0.05" in residual_warnings(0.0, 0.05, 1.0, 1e-4, 1e-4)[0]     # 0.05 > 0.01 (1 + 1)
    assert residual_warnings(0.0, 0.019, 1.0, 1e-4, 1e-4) == []
    assert len(residual_warnings(math.nan, math.nan, 0.0, 1e-9, 1e-9)) == 2              # NaN is never within


def test_drift_at_a_loose_tolerance_is_flagged_and_not_classified(system):
    """Augmented at rtol 1e-3: the mechanism comes apart by metres, and the result says so."""
    result = simulate(system, start(system, 2), 20.0, formulation=formulation_from_name("augmented"),
                      method="RK45", rtol=1e-3, atol=1e-3)
    assert result.max_constraint_error > 1.0 > math.sqrt(1e-3)
    assert any("max |f| =" in warning and "came apart" in warning for warning in result.warnings)
    with pytest.raises(InputError, match=r"^result: not classified, the constraint error max \|f\|"):
        classify_motion(result)


def test_a_stabilised_run_has_no_warning_and_is_classified(system):
    result = simulate(system, start(system, 2), 20.0, formulation=formulation_from_name("baumgarte"),
                      method="RK45", rtol=1e-9, atol=1e-9)
    assert result.warnings == []
    assert result.max_constraint_error < math.sqrt(1e-9)
    assert classify_motion(result) == "full rotation"


def test_the_largest_residual_covers_every_step_end_not_only_the_outputs(system):
    """Outputs at 0 and 10 s of a 20 s run whose drift grows: the step ends still count."""
    state = start(system, 1)
    formulation = formulation_from_name("augmented")
    sparse = simulate(system, state, 20.0, formulation=formulation, method="DOP853", rtol=1e-6, atol=1e-6,
                      t_eval=[0.0, 10.0])
    every_step = simulate(system, state, 20.0, formulation=formulation, method="DOP853", rtol=1e-6, atol=1e-6)
    assert sparse.n_steps == every_step.n_steps                 # the same steps
    assert np.max(sparse.constraint_error) < 0.5 * np.max(every_step.constraint_error)
    assert sparse.max_constraint_error == pytest.approx(np.max(every_step.constraint_error), rel=1e-9)
    assert sparse.max_velocity_constraint_error == pytest.approx(
        np.max(every_step.velocity_constraint_error), rel=1e-9)


def test_a_result_with_nan_is_not_classified(system):
    result = simulate(system, start(system, 3), 2.0, formulation=formulation_from_name("baumgarte"),
                      method="RK45", rtol=1e-9, atol=1e-9)
    spoiled = result.s.copy()
    spoiled[0, -1] = np.nan
    with pytest.raises(InputError, match="phi is empty or not finite"):
        classify_motion(dataclasses.replace(result, s=spoiled))


def test_a_run_too_loose_to_classify_is_refused(system):
    """Minimal at rtol 1e-2 calls case 4 (a full rotation) an oscillation: refused, not answered."""
    result = simulate(system, start(system, 4), 20.0, formulation=formulation_from_name("minimal"),
                      method="RK45", rtol=1e-2, atol=1e-2)
    assert result.warnings == []                                # its residuals are exact: no help there
    with pytest.raises(InputError, match=rf"not classified, rtol = 0.01 is too loose .* rerun with rtol <= {CLASSIFY_RTOL_LIMIT:g}"):
        classify_motion(result)
    tight = simulate(system, start(system, 4), 20.0, formulation=formulation_from_name("minimal"),
                     method="RK45", rtol=CLASSIFY_RTOL_LIMIT, atol=CLASSIFY_RTOL_LIMIT)
    assert classify_motion(tight) == "full rotation"            # the advice works


def test_the_command_line_prints_the_warning_and_fails(capsys):
    status = main(["simulate", "--case", "2", "--formulation", "augmented", "--method", "RK45", "--rtol", "1e-3",
                   "--atol", "1e-3", "--t-end", "20"])
    out, err = capsys.readouterr()
    assert status == 1
    assert "motion: not classified (see the warning)" in out
    assert err.startswith("closedloop: warning: the constraint error max |f| =")


@pytest.mark.parametrize("option, value, limit", [("--phi0", "1e308", "-1000 to 1000 rad"),
                                                  ("--dphi0", "1e200", "-1000 to 1000 rad/s")])
def test_absurd_magnitudes_are_refused_before_any_work(capsys, option, value, limit):
    other = "--dphi0" if option == "--phi0" else "--phi0"
    status = main(["simulate", option, value, other, "1"])
    err = capsys.readouterr().err
    assert status == 2
    assert err == f"closedloop: error: {option[2:]}: must be a finite number from {limit}, got {float(value):g}\n"


def test_the_residuals_at_the_outputs_are_computed_when_first_read_and_are_those_of_the_states(system,
                                                                                               monkeypatch):
    """simulate leaves |f| and |f'| at the outputs to the first reader (as lambda, only when asked for);
    they are then those of the states returned, checked one column at a time with (6) and (9)."""
    calls = []
    many = system.constraint_errors

    def counted(s, sd):
        calls.append(s.shape[1])
        return many(s, sd)

    monkeypatch.setattr(system, "constraint_errors", counted)
    result = simulate(system, start(system, 2), 2.0, formulation=formulation_from_name("closed-form"),
                      method="ode.dop853", rtol=1e-6, atol=1e-6, t_eval=np.linspace(0.0, 2.0, 201))
    assert calls == []                                          # the run itself computed none
    f_norm, fd_norm = result.constraint_error, result.velocity_constraint_error
    assert calls == [201]                                       # both at once, at the first read, once
    assert result.velocity_constraint_error is fd_norm and calls == [201]
    for k in range(0, 201, 20):
        f, Phi = system.constraints_and_jacobian(result.s[:, k])
        # to the round-off of the sums, whose terms (lengths, and lengths times speeds) are far larger
        assert f_norm[k] == pytest.approx(np.linalg.norm(f), rel=0, abs=16 * np.finfo(float).eps)
        scale = np.max(np.abs(Phi) @ np.abs(result.sd[:, k]))
        assert fd_norm[k] == pytest.approx(np.linalg.norm(Phi @ result.sd[:, k]), rel=0,
                                           abs=16 * np.finfo(float).eps * scale)
        assert fd_norm[k] > 1e3 * np.finfo(float).eps * scale or k == 0      # not round-off itself
    assert result.max_constraint_error == max(float(f_norm.max()), result.step_constraint_error)
    assert result.warnings == []                                # 1e-6: drift far below sqrt(tol)
    assert 1e-12 < result.max_constraint_error < 1e-4
