"""The slider-crank written the usual way, as a baseline for closedloop's formulations.

Most readers who meet a closed-loop mechanism in Python write it with
``sympy.physics.mechanics`` and integrate it with ``scipy.integrate.solve_ivp``.
This module does exactly that, with nothing taken from closedloop's own
derivation or simulation loop, so that the benchmark (:mod:`closedloop.studies.benchmark`)
can compare the library with what a reader would otherwise have:

- ``dynamicsymbols`` phi, psi, x_C; T and Pi typed in from section 3 of the
  paper; the loop constraints (27)-(28) as ``hol_coneqs``;
- ``LagrangesMethod(L, [phi, psi, x], hol_coneqs=..., forcelist=..., frame=N)``,
  with the drive torque as ``(A, M(t) N.z)`` on the crank frame A and the gas
  force as ``(P, F N.x)`` on the slider point P = O + x_C N.x;
- the gas force as a sympy ``Piecewise`` in (x_C, x_C'), the printed law of
  :func:`closedloop.slider_crank_gas_law.printed_law` (the one source of the law in the
  library) with the same reading of the data as :class:`closedloop.slider_crank.GasForce`;
  the usual user integrates straight through its switches (no events);
- Table 1 values substituted, and the rows of (12) below the kinematic
  identity, ``mass_matrix_full[3:, 3:]`` and ``forcing_full[3:, :]`` (5 x 5 and
  5 x 1: s'' and lambda), turned into ONE function by ``lambdify(..., cse=True)``
  with sympy's default (numpy) printer, the way the sympy.physics.mechanics
  tutorials do it; the right-hand side is ``y' = [s', s'']`` with s'' from one
  ``numpy.linalg.solve`` of that 5 x 5 system at every call.  This is the
  unstabilised augmented (index-1) system (12).

``modules="math"`` prints the same expressions for Python's ``math`` module
(the gas force's ``Piecewise`` becomes a conditional expression instead of
``numpy.select``): a lambdify setting that a user tuning for speed picks,
about twice as fast per evaluation.  The benchmark runs both printers, and
compares the library with the cheaper of the two.
"""

from __future__ import annotations

import time
from dataclasses import dataclass

import numpy as np

from .. import slider_crank_gas_law as gas_law
from ..errors import IntegrationError
from ..methods import SOLVE_IVP_METHODS
from ..slider_crank import DEFAULT_READING, OMEGA, TORQUE_RIPPLE, SliderCrankParameters, get_reading
from ..kinematics import initial_state_arrays
from ..validation import instance_of, one_of, output_times, positive_integer, positive_number

__all__ = ["LagrangesBaseline", "BaselineResult"]

#: The solve_ivp methods the baseline accepts.
BASELINE_METHODS = SOLVE_IVP_METHODS
#: Evaluations a baseline run may take (the longest run of the benchmark study takes about 10 000).
DEFAULT_MAX_NFEV = 200_000


class _TooManyEvaluations(Exception):
    """Raised inside solve_ivp's loop when a baseline run exceeds its max_nfev."""
#: The printers of lambdify the baseline can use (see the module's notes).
BASELINE_MODULES = ("numpy", "math")


@dataclass
class BaselineResult:
    """What :meth:`LagrangesBaseline.simulate` computed.

    Attributes
    ----------
    t : ndarray, shape (N,)
    s, sd : ndarray, shape (3, N)
        ``[phi, psi, x_C]`` and their rates.
    nfev : int
        Right-hand-side evaluations reported by solve_ivp.
    cpu_time : float
        Process time of the ``solve_ivp`` call [s].
    method : str
    rtol, atol : float
    """

    t: np.ndarray
    s: np.ndarray
    sd: np.ndarray
    nfev: int
    cpu_time: float
    method: str
    rtol: float
    atol: float


class LagrangesBaseline:
    """The slider-crank by ``sympy.physics.mechanics.LagrangesMethod``, lambdified.

    Parameters
    ----------
    parameters : SliderCrankParameters, optional
        Table 1 by default.
    reading : str, optional
        How to read the paper's data (see :data:`closedloop.slider_crank.READINGS`);
        the default reproduces the paper.
    modules : {"numpy", "math"}, optional
        The printer of ``lambdify``: sympy's default ``"numpy"``, or ``"math"``
        (scalar code, faster per call; see the module's notes).

    Attributes
    ----------
    derivation_cpu_time : float
        Process time from the first symbol to the lambdified functions [s].
    """

    def __init__(self, parameters=None, reading=DEFAULT_READING, modules="numpy"):
        self.parameters = instance_of("parameters", SliderCrankParameters() if parameters is None else parameters,
                                      SliderCrankParameters)
        self.reading = get_reading(reading)
        self.modules = one_of("modules", modules, BASELINE_MODULES)
        start = time.process_time()
        self._matrices = self._derive()
        self.derivation_cpu_time = time.process_time() - start

    def _derive(self):
        import sympy as sm
        import sympy.physics.mechanics as me

        phi, psi, x = me.dynamicsymbols("phi psi x")
        dphi, dpsi, dx = me.dynamicsymbols("phi psi x", 1)
        t = sm.Symbol("t")                                 # dynamicsymbols' time: phi is phi(t)
        l1, a1, m1, I1, l2, a2, m2, I2, m3, g = sm.symbols("l1 a1 m1 I1 l2 a2 m2 I2 m3 g")

        N = me.ReferenceFrame("N")
        A = N.orientnew("A", "Axis", (phi, N.z))           # the crank: the drive torque acts here
        O = me.Point("O")
        O.set_vel(N, 0)
        P = O.locatenew("P", x * N.x)                      # the slider: the gas force acts here

        T = (sm.Rational(1, 2) * (I1 + m1 * a1**2 + m2 * l1**2) * dphi**2
             + sm.Rational(1, 2) * (I2 + m2 * a2**2) * dpsi**2 + sm.Rational(1, 2) * m3 * dx**2
             - m2 * l1 * a2 * dphi * dpsi * sm.cos(phi - psi))
        Pi = m1 * g * a1 * sm.sin(phi) + m2 * g * l1 * sm.sin(phi) - m2 * g * a2 * sm.sin(psi)
        f1 = l1 * sm.cos(phi) - l2 * sm.cos(psi) - x                       # (27)
        f2 = l1 * sm.sin(phi) - l2 * sm.sin(psi)                           # (28)

        reading = self.reading
        torque = reading.torque_mean + TORQUE_RIPPLE * sm.sin(OMEGA * t)
        gas = reading.force_sign * gas_law.printed_law(x, dx, reading.gas_coefficients)

        method = me.LagrangesMethod(T - Pi, [phi, psi, x], hol_coneqs=[f1, f2],
                                    forcelist=[(A, torque * N.z), (P, gas * N.x)], frame=N)
        method.form_lagranges_equations()
        values = {sm.Symbol(name): value for name, value in self.parameters.as_dict().items()}
        arguments = [phi, psi, x, dphi, dpsi, dx, t]
        # (12) without its kinematic rows s' = s': the 5 x 5 matrix of [s''; lambda] and its right side
        mass = method.mass_matrix_full[3:, 3:].subs(values)
        forcing = method.forcing_full[3:, :].subs(values)
        if self.modules == "math":          # the math printer takes lists, not matrices
            return sm.lambdify(arguments, [mass.tolist(), list(forcing)], modules="math", cse=True)
        return sm.lambdify(arguments, [mass, forcing], cse=True)

    def rhs(self, t, y):
        """``y' = F(t, y)`` for ``y = [phi, psi, x_C, phi', psi', x_C']``.

        ``mass_matrix_full[3:, 3:] [s''; lambda] = forcing_full[3:]``, solved by numpy.
        """
        mass, forcing = self._matrices(*y, t)
        accelerations = np.linalg.solve(mass, forcing)[:3]
        return np.concatenate((y[3:], np.ravel(accelerations)))

    def simulate(self, initial_state, t_end=20.0, method="RK45", rtol=1e-9, atol=1e-9, t_eval=None,
                 max_nfev=DEFAULT_MAX_NFEV):
        """Integrate from ``initial_state`` (an InitialState) with solve_ivp, as a user would.

        Parameters
        ----------
        initial_state : InitialState
            Consistent ``(s0, s0')``, e.g. from :func:`closedloop.slider_crank.initial_state`.
        t_end : float, optional
            Final time [s], > 0.
        method : str, optional
            One of :data:`BASELINE_METHODS`.
        rtol, atol : float, optional
            > 0.
        t_eval : array_like, optional
            Output times; default: the solver's own steps.
        max_nfev : int, optional
            Right-hand-side evaluations allowed. Integrating straight through the gas force's
            switches, as the usual way does, a method can chatter at a switch for ever (LSODA at
            rtol 1e-10 in case 3 did, for more than ten minutes, while rtol 1e-9 takes 1 592
            evaluations); the run then stops with an IntegrationError.

        Returns
        -------
        BaselineResult

        Raises
        ------
        InputError
            For a parameter outside its range, before integrating.
        IntegrationError
            If solve_ivp fails; the message names the time reached.
        """
        t_end = positive_number("t_end", t_end, unit="s")
        one_of("method", method, BASELINE_METHODS)
        positive_number("rtol", rtol)
        positive_number("atol", atol)
        positive_integer("max_nfev", max_nfev)
        y0 = np.concatenate(initial_state_arrays(initial_state, 3))
        t_eval = output_times(t_eval, 0.0, t_end)
        from scipy.integrate import solve_ivp   # here, before the clock starts (not when the command line starts)

        calls = [0]

        def rhs(t, y):
            calls[0] += 1
            if calls[0] > max_nfev:
                raise _TooManyEvaluations(t)
            return self.rhs(t, y)

        start = time.process_time()
        try:
            sol = solve_ivp(rhs, (0.0, t_end), y0, method=method, rtol=rtol, atol=atol, t_eval=t_eval)
        except _TooManyEvaluations as stop:
            raise IntegrationError(f"baseline {method} at rtol {rtol:g} stopped at t = {stop.args[0]:.6g} s after "
                                   f"max_nfev = {max_nfev} evaluations: it chatters at a switch of the gas "
                                   "force, which it integrates through") from None
        cpu_time = time.process_time() - start
        if sol.status != 0:
            reached = sol.t[-1] if sol.t.size else 0.0
            raise IntegrationError(f"baseline {method} at rtol {rtol:g} failed after t = {reached:.6g} s: "
                                   f"{sol.message}")
        return BaselineResult(t=sol.t, s=sol.y[:3], sd=sol.y[3:], nfev=sol.nfev, cpu_time=cpu_time,
                              method=method, rtol=rtol, atol=atol)
