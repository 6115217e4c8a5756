"""Dead positions of the independent coordinates: every formulation and method is right or says it can not go on.

The rocking slider-crank (l1 = 2 m, l2 = 1.5 m, no torque, no gas force, phi0 = 0, phi0' = 1 rad/s)
passes dead positions of phi, where Phi_z of (20) is singular, at about 2.21 s and 4.79 s. Minimal
coordinates used to turn back there with no error (phi(5) = 0.30 where the mechanism reaches -0.7265).
The reference is independent of the library's formulations: the rod angle psi has no dead position
(sin phi = (l2/l1) sin psi on the crank's branch), so the Lagrangian in psi alone, written here with
sympy, is one smooth ODE; its motion is checked against an energy quadrature with mpmath. A double
pendulum in Cartesian coordinates, whose partition becomes singular where a link lies level, is
checked against its equation in the link angles.
"""

import math
import re
import signal

import mpmath
import numpy as np
import pytest
import sympy as sp
from scipy.integrate import solve_ivp

from closedloop import (Augmented, Baumgarte, ClosedForm, ClosedLoopError, Minimal, MultibodyModel, NullSpace,
                        Orthogonal, Projected, SingularConfigurationError, System, consistent_initial_state,
                        simulate)
from closedloop.four_bar import four_bar_model
from closedloop.simulation.options import methods_taking
from closedloop.slider_crank import SliderCrankParameters, initial_state, slider_crank_system

ROCKING = SliderCrankParameters(l2=1.5, a2=0.75, full_rotation=False)
START, T_END = (0.0, 1.0), 5.0
#: The formulations of the sweep: each on every method it takes, at each tolerance (rtol = atol).
FORMULATIONS = (Augmented(), Baumgarte(5, 5), Orthogonal(5, 5), Minimal(), NullSpace(5, 5), NullSpace(basis="pivoted"),
                ClosedForm(5, 5), ClosedForm(0, 0), Projected())
TOLERANCES = (1e-6, 1e-9)
#: A run that takes longer than this is a hang (Minimal with Radau used to crawl for minutes).
HANG_SECONDS = 60


def slider_crank_energies(p, phi, psi, dphi, dpsi, coordinate, speed):
    """T and Pi of section 3 of the paper, with phi and psi (and their rates) functions of one
    ``coordinate`` whose rate is ``speed``; x_C = l1 cos phi - l2 cos psi."""
    x = p.l1 * sp.cos(phi) - p.l2 * sp.cos(psi)
    dx = sp.diff(x, coordinate) * speed
    T = ((p.I1 + p.m1 * p.a1**2 + p.m2 * p.l1**2) * dphi**2 + (p.I2 + p.m2 * p.a2**2) * dpsi**2 + p.m3 * dx**2) / 2 \
        - p.m2 * p.l1 * p.a2 * dphi * dpsi * sp.cos(phi - psi)
    Pi = (p.m1 * p.a1 + p.m2 * p.l1) * p.g * sp.sin(phi) - p.m2 * p.g * p.a2 * sp.sin(psi)
    return T, Pi


def psi_coordinate_equation(p):
    """The rocking crank's Lagrangian in the rod angle psi alone: ``(psi'', T + Pi, phi(psi))`` as functions.

    On the crank's branch (|phi| < pi/2) sin phi = (l2/l1) sin psi and x_C = l1 cos phi - l2 cos psi,
    smooth in psi for l2 < l1; T and Pi are those of section 3 of the paper.
    """
    psi, dpsi = sp.symbols("psi dpsi")
    phi = sp.asin(p.l2 / p.l1 * sp.sin(psi))
    dphi = sp.diff(phi, psi) * dpsi
    T, Pi = slider_crank_energies(p, phi, psi, dphi, dpsi, psi, dpsi)
    mass = sp.diff(T, dpsi, 2)                           # T = mass(psi) psi'^2 / 2
    acceleration = -(sp.diff(mass, psi) * dpsi**2 / 2 + sp.diff(Pi, psi)) / mass
    return (sp.lambdify((psi, dpsi), acceleration, "math"), sp.lambdify((psi, dpsi), T + Pi, "math"),
            sp.lambdify(psi, phi, "math"), (psi, mass, Pi))


def rocking_solution():
    """The psi equation's motion of the rocking crank over T_END, with the times where the rod stands upright.

    The slider starts to the right of the crank (psi0 = pi, as initial_state places it); dead positions of
    phi are where the rod stands upright, cos psi = 0 (its ``t_events[0]``).
    """
    p = ROCKING
    acceleration = psi_coordinate_equation(p)[0]
    psi0 = math.pi - math.asin(p.l1 / p.l2 * math.sin(START[0]))
    dpsi0 = START[1] * p.l1 * math.cos(START[0]) / (p.l2 * math.cos(psi0))

    def upright(t, y):
        return math.cos(y[0])

    return solve_ivp(lambda t, y: [y[1], acceleration(y[0], y[1])], (0.0, T_END), [psi0, dpsi0],
                     method="DOP853", rtol=1e-13, atol=1e-13, dense_output=True, events=upright)


@pytest.fixture(scope="module")
def reference():
    """phi(t) of the rocking crank from the psi equation: ``(solution, phi of psi, energy, dead position times)``."""
    _, energy, phi_of, _ = psi_coordinate_equation(ROCKING)
    solution = rocking_solution()
    return solution, phi_of, energy, solution.t_events[0]


def test_the_reference_keeps_its_energy_and_matches_the_quadrature(reference):
    """T + Pi stays constant, and since psi' keeps its sign the time to psi(5) is the quadrature
    t = int sqrt(mass(psi) / (2 (E - Pi(psi)))) dpsi, computed with mpmath at 30 digits."""
    solution, phi_of, energy, dead = reference
    psi, dpsi = solution.y
    assert np.all(dpsi < 0)
    values = [energy(a, b) for a, b in zip(psi, dpsi)]
    assert np.ptp(values) < 1e-11 * abs(values[0])
    _, _, _, (symbol, mass, Pi) = psi_coordinate_equation(ROCKING)
    mass_of = sp.lambdify(symbol, mass, "mpmath")
    Pi_of = sp.lambdify(symbol, Pi, "mpmath")
    with mpmath.workdps(30):
        E = mpmath.mpf(values[0])
        elapsed = mpmath.quad(lambda a: mpmath.sqrt(mass_of(a) / (2 * (E - Pi_of(a)))),
                              [mpmath.mpf(psi[-1]), -mpmath.pi / 2, -3 * mpmath.pi / 2 + 2 * mpmath.pi,
                               mpmath.mpf(psi[0])])
    assert float(elapsed) == pytest.approx(T_END, abs=1e-9)
    assert len(dead) == 2 and 2.2 < dead[0] < 2.22                        # the t of about 2.21 s
    assert phi_of(psi[-1]) == pytest.approx(-0.7265, abs=1e-4)


class Hang(BaseException):
    """Raised by the alarm of a run that takes longer than HANG_SECONDS."""


def _alarm(signum, frame):
    raise Hang


def outcome(system, state, formulation, method, tolerance, phi_exact):
    """``("right", None)``, ``("refused", error)`` or ``("wrong", what)`` for one run of the sweep.

    Right: phi(5) within 100 times the solver's own error unit, atol + rtol |phi(5)| (LSODA's global
    error at 1e-9 is 79 of them here, 136 of rtol alone: its ordinary error, grown from t = 0 on).
    Refused: a ClosedLoopError whose one-line message names the time.
    """
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(HANG_SECONDS)
    try:
        result = simulate(system, state, T_END, formulation=formulation, method=method, rtol=tolerance,
                          atol=tolerance)
    except Hang:
        return "wrong", f"no answer in {HANG_SECONDS} s"
    except ClosedLoopError as error:
        message = str(error)
        names_a_time = re.search(r"\bt = [-+0-9.e]+ s", message) is not None
        return ("refused", error) if names_a_time and "\n" not in message else ("wrong", message)
    except Exception as error:                     # numpy's LinAlgError and the like: never
        return "wrong", f"{type(error).__name__}: {error}"
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)
    error = abs(result.coordinate("phi")[-1] - phi_exact)
    if error <= 100 * (tolerance + tolerance * abs(phi_exact)):
        return "right", None
    return "wrong", f"phi(5) = {result.coordinate('phi')[-1]:.6g}, off by {error:.3g}"


def test_every_formulation_method_and_tolerance_is_right_or_refused(reference):
    """The sweep of the issue: formulations x methods x tolerances, counted right, refused, wrong.

    Wrong must be 0. Only Minimal may refuse (q alone can not pass a dead position of its partition),
    and it must do so at the first dead position, naming the NullSpace remedy.
    """
    solution, phi_of, _, dead = reference
    phi_exact = phi_of(solution.y[0, -1])
    system = slider_crank_system(ROCKING, torque=False, gas=False)
    state = initial_state(system, *START)
    counts, wrong, refusals = {"right": 0, "refused": 0, "wrong": 0}, [], []
    for formulation in FORMULATIONS:
        for method in methods_taking(formulation):
            for tolerance in TOLERANCES:
                kind, detail = outcome(system, state, formulation, method, tolerance, phi_exact)
                counts[kind] += 1
                label = f"{formulation!r} {method} {tolerance:g}"
                if kind == "wrong":
                    wrong.append(f"{label}: {detail}")
                elif kind == "refused":
                    refusals.append((label, formulation, detail))
    assert counts["wrong"] == 0, wrong
    assert counts["right"] + counts["refused"] == 118 and counts["right"] >= 104
    for label, formulation, error in refusals:
        message = str(error)
        assert isinstance(formulation, Minimal), f"{label}: {message}"
        assert isinstance(error, SingularConfigurationError) and "NullSpace" in message, f"{label}: {message}"
        t = float(message.split("at t = ")[1].split(" s")[0])
        assert abs(t - dead[0]) < 5e-3, f"{label}: {message}"


@pytest.mark.parametrize("method", ["RK45", "BDF", "LSODA"])
def test_minimal_that_turned_back_on_its_branch_says_so(reference, method):
    """The runs that returned phi(5) = 0.30 or -0.62 with no warning: the turning point is located on the
    step's interpolant, at the dead position, and the branch does not go on beyond it."""
    _, _, _, dead = reference
    system = slider_crank_system(ROCKING, torque=False, gas=False)
    with pytest.raises(SingularConfigurationError, match=r"^minimal coordinates turned back at a dead position of q "
                       r"at t = ([0-9.]+) s \(phi = 0\.84806[0-9]*, psi = [0-9.]+, x = [0-9.]+; \|Phi_s\| "
                       r"\|Phi_z\^-1\| = .*use the NullSpace formulation, which passes dead positions$") as error:
        simulate(system, initial_state(system, *START), T_END, formulation=Minimal(), method=method, rtol=1e-6,
                 atol=1e-6)
    t = float(str(error.value).split("at t = ")[1].split(" s")[0])
    assert abs(t - dead[0]) < 1e-3
    assert math.asin(ROCKING.l2 / ROCKING.l1) == pytest.approx(0.848062, abs=1e-6)   # the crank's limit


def crank_angle_equation(p):
    """The paper's crank (l1 < l2) in phi alone, which has no dead position there: ``phi''(phi, phi')``.

    On the paper's branch psi = pi - asin((l1/l2) sin phi), x_C = l1 cos phi - l2 cos psi.
    """
    phi, dphi = sp.symbols("phi dphi")
    psi = sp.pi - sp.asin(p.l1 / p.l2 * sp.sin(phi))
    dpsi = sp.diff(psi, phi) * dphi
    T, Pi = slider_crank_energies(p, phi, psi, dphi, dpsi, phi, dphi)
    mass = sp.diff(T, dphi, 2)
    return sp.lambdify((phi, dphi), -(sp.diff(mass, phi) * dphi**2 / 2 + sp.diff(Pi, phi)) / mass, "math")


def test_an_ordinary_turning_point_is_passed():
    """The paper's crank without torque and gas force, started at phi = pi with 1 rad/s, swings: phi turns back
    (at about 4.7 s) where the whole mechanism comes to rest, with Phi_z regular. Minimal goes on there, on every runner, and
    agrees with the equation in phi alone."""
    acceleration = crank_angle_equation(SliderCrankParameters())
    exact = solve_ivp(lambda t, y: [y[1], acceleration(y[0], y[1])], (0.0, T_END), [math.pi, 1.0],
                      method="DOP853", rtol=1e-13, atol=1e-13)
    assert np.sum(np.diff(np.sign(exact.y[1])) != 0) == 1                # it turns back, once
    system = slider_crank_system(torque=False, gas=False)
    for method in ("DOP853", "LSODA", "ode.dop853"):
        result = simulate(system, initial_state(system, math.pi, 1.0), T_END, formulation=Minimal(), method=method,
                          rtol=1e-10, atol=1e-10)
        assert result.coordinate("phi")[-1] == pytest.approx(exact.y[0, -1], abs=1e-6)


def test_radau_ends_at_the_rocking_four_bar_s_toggle_and_the_remedy_passes_it():
    """The rocking four-bar (l0 = 3.2, not Grashof) reaches a toggle of theta1 at about 0.3725 s, where Radau's
    steps shrank to 1e-15 s with no answer in minutes. It stops there now, naming the cause; NullSpace, the
    remedy it names, passes and keeps T + Pi (the linkage has no force but gravity)."""
    data = {"l0": 3.2, "l1": 1.0, "l2": 3.0, "l3": 1.0, "m1": 1.0, "m2": 2.0, "m3": 1.0, "g": 9.81}
    system = System(four_bar_model(), data)
    start = consistent_initial_state(system, [np.pi / 2], [2.0], [0.0, np.pi / 2])
    with pytest.raises(SingularConfigurationError, match=r"at t = 0\.3724[0-9]* s.*use the NullSpace formulation"):
        simulate(system, start, 3.0, formulation=Minimal(), method="Radau", rtol=1e-9, atol=1e-9)
    remedy = simulate(system, start, 3.0, formulation=NullSpace(), method="Radau", rtol=1e-9, atol=1e-9,
                      t_eval=np.linspace(0.0, 3.0, 301))
    assert remedy.partition_singularities[0] == pytest.approx(0.3725, abs=1e-3)
    energy = system.energy(remedy.s, remedy.sd)
    assert np.ptp(energy) < 1e-6 * np.max(np.abs(energy))


# -- a double pendulum in Cartesian coordinates ------------------------------------------------------

def double_pendulum_model():
    """Two point masses on massless links, in Cartesian coordinates (x1, y1, x2, y2), x1 and x2 independent:
    Phi_z is singular where a link lies level (y1 = 0, or y2 = y1)."""
    x1, y1, x2, y2 = sp.symbols("x1 y1 x2 y2")
    dx1, dy1, dx2, dy2 = sp.symbols("dx1 dy1 dx2 dy2")
    m1, m2, l1, l2, g = sp.symbols("m1 m2 l1 l2 g")
    return MultibodyModel(
        coordinates=(x1, y1, x2, y2), velocities=(dx1, dy1, dx2, dy2),
        kinetic_energy=m1 * (dx1**2 + dy1**2) / 2 + m2 * (dx2**2 + dy2**2) / 2,
        potential_energy=m1 * g * y1 + m2 * g * y2,
        constraints=(x1**2 + y1**2 - l1**2, (x2 - x1)**2 + (y2 - y1)**2 - l2**2),
        independent=(x1, x2), parameters=(m1, m2, l1, l2, g))


DOUBLE = {"m1": 1.0, "m2": 1.0, "l1": 1.0, "l2": 1.0, "g": 9.81}
DOUBLE_T_END = 0.6


def angle_equation():
    """The double pendulum in its link angles (from the downward vertical), which have no dead position."""
    a, b, da, db = sp.symbols("a b da db")
    m1, m2, l1, l2, g = (DOUBLE[k] for k in ("m1", "m2", "l1", "l2", "g"))
    x1, y1 = l1 * sp.sin(a), -l1 * sp.cos(a)
    x2, y2 = x1 + l2 * sp.sin(b), y1 - l2 * sp.cos(b)
    speed = {a: da, b: db}

    def rate(expression):
        return sum(sp.diff(expression, q) * v for q, v in speed.items())

    L = (m1 * (rate(x1)**2 + rate(y1)**2) + m2 * (rate(x2)**2 + rate(y2)**2)) / 2 - g * (m1 * y1 + m2 * y2)
    q, v = [a, b], [da, db]
    mass = sp.Matrix(2, 2, lambda i, j: sp.diff(L, v[i], v[j]))
    force = sp.Matrix([sp.diff(L, q[i]) - sum(sp.diff(L, v[i], q[j]) * v[j] for j in range(2)) for i in range(2)])
    accelerations = sp.lambdify((a, b, da, db), list(mass.LUsolve(force)), "math")
    positions = sp.lambdify((a, b), [x1, y1, x2, y2], "math")
    return accelerations, positions


@pytest.fixture(scope="module")
def double_pendulum():
    """The system, a start whose first link passes level at about 0.225 s, and the angle equation's positions."""
    system = System(double_pendulum_model(), DOUBLE)
    start = consistent_initial_state(system, [0.5, 1.2], [5.0, 5.0], [-0.8, -1.5])
    x1, y1, x2, y2 = start.s
    dx1, dy1, dx2, dy2 = start.sd
    a, b = math.atan2(x1, -y1), math.atan2(x2 - x1, -(y2 - y1))
    da = (x1 * dy1 - y1 * dx1) / (x1**2 + y1**2)                      # the angle's rate from the velocities
    db = ((x2 - x1) * (dy2 - dy1) - (y2 - y1) * (dx2 - dx1)) / ((x2 - x1)**2 + (y2 - y1)**2)
    accelerations, positions = angle_equation()
    exact = solve_ivp(lambda t, y: [y[2], y[3], *accelerations(*y)], (0.0, DOUBLE_T_END), [a, b, da, db],
                      method="DOP853", rtol=1e-13, atol=1e-13)
    return system, start, np.array(positions(*exact.y[:2, -1])), exact


def test_the_double_pendulum_passes_level_links(double_pendulum):
    _, _, _, exact = double_pendulum
    first = -np.cos(exact.y[0])                            # y1 / l1
    assert first[0] < 0 < first.max()                      # the first link swings above level


@pytest.mark.parametrize("formulation", [Minimal(), ClosedForm(), Orthogonal()], ids=lambda f: f.name)
def test_no_linear_algebra_error_escapes_at_a_singular_partition(double_pendulum, formulation):
    """Minimal leaked numpy's LinAlgError('Singular matrix') here (RK45, RK23), and ClosedForm with Radau crept
    on for minutes before blaming the step size. Every run is now right against the angle equation, or
    refused with an error that names a nearly singular Phi_z (or the dead position) and the NullSpace remedy,
    never stiffness."""
    system, start, exact, _ = double_pendulum
    for method in methods_taking(formulation):
        kind, detail = _double_outcome(system, start, formulation, method, exact)
        assert kind != "wrong", f"{method}: {detail}"
        if kind == "refused":
            message = str(detail)
            assert isinstance(detail, SingularConfigurationError) and "NullSpace" in message, f"{method}: {message}"
            assert "stiff" not in message
    remedy = simulate(system, start, DOUBLE_T_END, formulation=NullSpace(), method="DOP853", rtol=1e-10, atol=1e-10)
    assert np.max(np.abs(remedy.s[:, -1] - exact)) < 1e-7


def _double_outcome(system, start, formulation, method, exact):
    try:
        result = simulate(system, start, DOUBLE_T_END, formulation=formulation, method=method, rtol=1e-9, atol=1e-9)
    except ClosedLoopError as error:
        return "refused", error
    except Exception as error:
        return "wrong", f"{type(error).__name__}: {error}"
    distance = np.max(np.abs(result.s[:, -1] - exact))
    return ("right", None) if distance < 1e-5 else ("wrong", f"off by {distance:.3g}")
