"""The slider-crank mechanism of section 3, its data (Table 1) and the four cases of section 4.

Coordinates ``s = [phi, psi, x]`` = ``[q1, q2, q3]`` of the paper: the crank
angle phi (independent), the connecting-rod angle psi and the slider position
x_C (dependent).  The mechanism moves in a vertical plane.

Reading the data
----------------
The paper prints ``M = 41,450`` and ``F = -282,857/(6 - x_C) + 62,857`` with
a Vietnamese decimal comma, and its virtual work ``dA = M dq1 - F dq3``
leaves the sign of the gas force loose.  :data:`READINGS` names the four
readings; only ``"decimal-opposing"`` (the default) reproduces the paper's
findings (see ``shared/paper/NOTES.md`` and the book).
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field, fields
from functools import lru_cache

import numpy as np

from . import slider_crank_gas_law as gas_law
from .errors import InputError
from .forces import SwitchedForce
from .kinematics import InitialState, consistent_initial_state
from .model import MultibodyModel, System
from .simulation import SimulationResult
from .simulation.batch import full_turn
from .validation import finite_number, flag, instance_of, one_of, shown

__all__ = [
    "check_classification_tolerance",
    "SliderCrankParameters",
    "Reading",
    "READINGS",
    "DEFAULT_READING",
    "CASES",
    "Case",
    "points",
    "slider_crank_model",
    "slider_crank_system",
    "SliderCrankSystem",
    "GasForce",
    "gas_force",
    "drive_torque",
    "initial_state",
    "classify_motion",
    "MOTIONS",
    "motion_codes",
    "COORDINATES",
    "get_case",
    "get_reading",
]

#: Names of the coordinates in s, in order: q1 = phi, q2 = psi, q3 = x_C.
COORDINATES = ("phi", "psi", "x")


@dataclass(frozen=True)
class SliderCrankParameters:
    """Geometry and masses of the slider-crank, Table 1 (after Haug 1989).

    Parameters
    ----------
    l1, l2 : float
        Lengths of crank and connecting rod [m], > 0, with l1 < l2 unless
        ``full_rotation`` is False.
    a1, a2 : float
        Centre-of-mass positions OC1 and AC2 [m], >= 0.
    m1, m2, m3 : float
        Masses of crank, rod and slider [kg], > 0.
    I1, I2 : float
        Moments of inertia of crank and rod about their centres of mass [kg m^2], > 0.
    g : float
        Gravitational acceleration [m/s^2], >= 0 (the paper does not print it).
    full_rotation : bool, optional, keyword only
        True (default): require l1 < l2, the paper's crank that turns full
        circle.  False: require l2 < l1, a crank that can only rock between
        the two dead positions ``sin(phi) = +-l2/l1`` where the rod stands
        perpendicular to the slider's axis and Phi_z of (20) is singular (for
        the study of singular configurations).  l1 = l2 is refused either way:
        there Phi_s loses rank at phi = pi/2 and the two assembly branches meet.
    """

    l1: float = 2.0
    a1: float = 0.0
    m1: float = 200.0
    I1: float = 450.0
    l2: float = 3.5
    a2: float = 1.75
    m2: float = 35.0
    I2: float = 35.0
    m3: float = 25.0
    g: float = 9.81
    full_rotation: bool = field(default=True, kw_only=True)

    def __post_init__(self):
        units = {"l1": "m", "l2": "m", "a1": "m", "a2": "m", "m1": "kg", "m2": "kg", "m3": "kg",
                 "I1": "kg m^2", "I2": "kg m^2", "g": "m/s^2"}
        if not isinstance(self.full_rotation, bool):
            raise InputError(f"full_rotation: must be True or False, got {shown(self.full_rotation)}")
        checked = {item.name: finite_number(item.name, getattr(self, item.name), minimum=0.0,
                                            strict=item.name not in ("a1", "a2", "g"), unit=units[item.name])
                   for item in fields(self) if item.name != "full_rotation"}
        l1, l2, a2 = checked["l1"], checked["l2"], checked["a2"]      # floats: a Fraction has no :g before 3.12
        if self.full_rotation and l1 >= l2:
            raise InputError(
                f"l1: must be < l2 = {l2:g} m, got {l1:g} m: with l1 >= l2 the crank cannot "
                "turn a full revolution (the rod cannot reach the slider's axis); pass "
                "full_rotation=False to study a rocking crank with l2 < l1"
            )
        if not self.full_rotation and l2 >= l1:
            raise InputError(
                f"l2: must be < l1 = {l1:g} m with full_rotation=False, got {l2:g} m (at l2 = l1 "
                "the two assembly branches meet at phi = pi/2, where Phi_s loses rank: a bifurcation)"
            )
        if a2 > l2:
            raise InputError(f"a2: must lie on the rod, 0 <= a2 <= l2 = {l2:g} m, got {a2:g} m")

    def as_dict(self):
        """Values keyed by the model's parameter names (without ``full_rotation``)."""
        values = asdict(self)
        del values["full_rotation"]
        return values


@dataclass(frozen=True)
class Reading:
    """One way to read the paper's printed numbers.

    Attributes
    ----------
    name : str
    scale : float
        1 for the decimal reading (41.450 N m), 1000 for thousands (41 450 N m).
    force_sign : int
        +1: the generalised force on x_C is +F, which opposes outward motion;
        -1: it is -F, as printed in dA = M dq1 - F dq3.
    description : str
    """

    name: str
    scale: float
    force_sign: int
    description: str

    @property
    def torque_mean(self):
        """Mean drive torque [N m]: 41.450 read as decimal or as thousands."""
        return 41.450 * self.scale

    @property
    def gas_coefficients(self):
        """``(282.857, 62.857, 110.000)`` of the gas force (:data:`closedloop.slider_crank_gas_law.PRINTED_COEFFICIENTS`),
        scaled by the reading."""
        return tuple(c * self.scale for c in gas_law.PRINTED_COEFFICIENTS)


#: The readings of Table 1 by name (:class:`Reading`): which printed numbers mean what.
READINGS = {
    r.name: r
    for r in (
        Reading("decimal-opposing", 1.0, +1,
                "decimal comma (M = 41.45 N m), gas force opposing outward motion: reproduces the paper"),
        Reading("decimal-as-printed", 1.0, -1,
                "decimal comma (M = 41.45 N m), generalised force -F as printed"),
        Reading("thousands-opposing", 1000.0, +1,
                "thousands (M = 41 450 N m), gas force opposing outward motion"),
        Reading("thousands-as-printed", 1000.0, -1,
                "thousands (M = 41 450 N m), generalised force -F as printed"),
    )
}
#: The reading that reproduces the paper's four findings.
DEFAULT_READING = "decimal-opposing"


def get_reading(name):
    """The :class:`Reading` called ``name``, or a clear error."""
    if isinstance(name, Reading):
        return name
    return READINGS[one_of("reading", name, READINGS)]


OMEGA = 2.0 * math.pi          # rad/s, the torque's ripple frequency
TORQUE_RIPPLE = 0.01           # N m, printed with a decimal point in every reading


def drive_torque(t, reading=DEFAULT_READING):
    """Drive torque ``M(t) = 41.450 + 0.01 sin(Omega t)`` [N m], Omega = 2 pi rad/s.

    The mean is scaled by the reading (41 450 N m when read as thousands).
    """
    return get_reading(reading).torque_mean + TORQUE_RIPPLE * np.sin(OMEGA * t)


def gas_force(x, xdot, reading=DEFAULT_READING):
    """The gas force F(x_C, x_C') as printed in section 4 [N].

    For ``x_C' > 0``: ``-282.857/(6 - x) + 62.857`` on 1.5 <= x <= 5 and
    ``-110 [1 - sin 2 pi (x - 5.25)]`` on 5 <= x <= 5.5; zero for x_C' <= 0 and
    outside the stroke [1.5, 5.5].  The coefficients scale with the reading.
    The sign here is the printed one (F <= 0); how F enters the equations is
    the reading's ``force_sign``.  The law is that of :mod:`closedloop.slider_crank_gas_law`.
    """
    reading = get_reading(reading)
    x = np.asarray(x, dtype=float)
    xdot = np.asarray(xdot, dtype=float)
    low, high = gas_law.STROKE
    value = gas_law.law_many(x, x > gas_law.CHANGE_POINT, reading.gas_coefficients)
    value = np.where((xdot > 0) & (x >= low) & (x <= high), value, 0.0)
    return value if value.ndim else float(value)


class GasForce(SwitchedForce):
    """The gas force on the slider as a switched generalised force on x_C.

    Switches: ``x_C' = 0`` (the force acts only while the slider moves
    outward; the slider may stick there) and ``x_C = 5`` (the formula changes).
    Every form of the force here (one state, K states, sympy) comes from the
    expressions of :mod:`closedloop.slider_crank_gas_law`.
    """

    switch_names = ("x_C' = 0", "x_C = 5")
    can_stick = (True, False)

    def __init__(self, reading=DEFAULT_READING):
        self.reading = get_reading(reading)
        self._a, self._b, self._c = self.reading.gas_coefficients
        self._sign = float(self.reading.force_sign)
        self._inner, self._outer = gas_law.numeric_branches("math")

    def switching_functions(self, t, s, sd):
        return np.array([sd[2], s[2] - gas_law.CHANGE_POINT])

    def switching_values(self, t, s, sd):
        """:meth:`switching_functions` as Python floats (the same numbers, no array built)."""
        return [float(sd[2]), float(s[2]) - gas_law.CHANGE_POINT]

    def __call__(self, t, s, sd, mode):
        return np.array(self.components(t, s, sd, mode))

    def components(self, t, s, sd, mode):
        """The force as ``[0, 0, F]`` of Python floats (see SwitchedForce.components)."""
        moving_out, beyond_five = mode
        x = float(s[2])
        value = 0.0
        low, high = gas_law.STROKE
        if moving_out and low <= x <= high:
            branch = self._outer if beyond_five else self._inner
            value = branch(x, self._a, self._b, self._c, gas_law.WAVENUMBER)
        return [0.0, 0.0, self._sign * value]

    def switching_functions_many(self, t, s, sd):
        return np.array([sd[2], s[2] - gas_law.CHANGE_POINT])

    def expressions(self, mode, time, coordinates, velocities):
        """The force of :meth:`components` on branch ``mode`` as sympy expressions ``[0, 0, F]``."""
        import sympy as sp

        moving_out, beyond_five = mode
        if not moving_out:
            return [0, 0, 0]
        x = coordinates[2]
        formula = gas_law.branch_expression(beyond_five, x, (self._a, self._b, self._c))
        low, high = gas_law.STROKE
        value = sp.Piecewise((sp.Float(self._sign) * formula, (x >= low) & (x <= high)), (0, True))
        return [0, 0, value]

    def cache_key(self, mode):
        """The class and what :meth:`expressions` uses on ``mode``: the branch of the law, the coefficients, the sign."""
        moving_out, beyond_five = mode
        law = (f"{'outer' if beyond_five else 'inner'} {(self._a, self._b, self._c, self._sign)!r}" if moving_out
               else "zero")
        return f"{type(self).__module__}.{type(self).__qualname__} {law}"

    def many(self, t, s, sd, mode):
        """The force at K states at once, each on its own branch ``mode[:, j]`` (same formula as a call)."""
        moving_out, beyond_five = mode
        x = s[2]
        low, high = gas_law.STROKE
        stroke = moving_out & (x >= low) & (x <= high)
        value = np.where(stroke, gas_law.law_many(x, beyond_five, (self._a, self._b, self._c)), 0.0)
        out = np.zeros(s.shape)
        out[2] = self._sign * value
        return out


def points(s, values, module=np):
    """The named points of the slider-crank at ``s = [phi, psi, x_C]``: its one home for positions.

    The model's constraints (27)-(28) and potential energy (5.b) are made from these points
    (:func:`slider_crank_model`), and the drawings of :mod:`closedloop.plotting` draw them.

    Parameters
    ----------
    s : sequence of 3
        ``[phi, psi, x_C]`` [rad, rad, m]: numbers, arrays of one shape (a point per entry), or
        sympy expressions.
    values : mapping
        ``l1``, ``l2``, ``a1``, ``a2`` [m] (other keys are ignored), e.g.
        :meth:`SliderCrankParameters.as_dict`; numbers or sympy symbols.
    module : module, optional
        Where ``cos`` and ``sin`` come from: numpy (default), math or sympy.

    Returns
    -------
    dict of str to (x, y)
        ``"O"``, the crank's pivot; ``"A"``, the crank pin; ``"C"``, the slider's pin;
        ``"C1"`` and ``"C2"``, the centres of mass of crank and rod (OC1 = a1 along the crank,
        AC2 = a2 along the rod); ``"rod end"``, the end of the rod reached from A along psi,
        which (27)-(28) put at C.
    """
    phi, psi, x = s[0], s[1], s[2]
    l1, l2, a1, a2 = values["l1"], values["l2"], values["a1"], values["a2"]
    zero = 0 * x
    crank = (module.cos(phi), module.sin(phi))
    rod = (module.cos(psi), module.sin(psi))                    # from C towards A
    pin = (l1 * crank[0], l1 * crank[1])
    return {
        "O": (zero, zero),
        "A": pin,
        "C": (x, zero),
        "C1": (a1 * crank[0], a1 * crank[1]),
        "C2": (pin[0] - a2 * rod[0], pin[1] - a2 * rod[1]),
        "rod end": (pin[0] - l2 * rod[0], pin[1] - l2 * rod[1]),
    }


@lru_cache(maxsize=None)
def slider_crank_model() -> MultibodyModel:
    """The symbolic slider-crank of section 3: T (5.a), Pi (5.b), (27)-(28) and the drive torque.

    Pi and (27)-(28) are made from the positions of :func:`points`; T is (5.a) as printed.

    The gas force is not here: it switches, so it is a :class:`GasForce`.
    A :class:`SliderCrankSystem` does not call this function when the model's
    numeric functions are cached (:func:`closedloop.model.model_functions`).
    """
    import sympy as sp

    phi, psi, x = sp.symbols("phi psi x")
    dphi, dpsi, dx = sp.symbols("dphi dpsi dx")
    l1, a1, m1, I1, l2, a2, m2, I2, m3, g = sp.symbols("l1 a1 m1 I1 l2 a2 m2 I2 m3 g")
    torque_mean, ripple, omega, t = sp.symbols("torque_mean torque_ripple omega t")
    T = (sp.Rational(1, 2) * (I1 + m1 * a1**2 + m2 * l1**2) * dphi**2
         + sp.Rational(1, 2) * (I2 + m2 * a2**2) * dpsi**2
         + sp.Rational(1, 2) * m3 * dx**2
         - m2 * l1 * a2 * dphi * dpsi * sp.cos(phi - psi))
    at = points((phi, psi, x), {"l1": l1, "l2": l2, "a1": a1, "a2": a2}, sp)
    Pi = sp.expand(g * (m1 * at["C1"][1] + m2 * at["C2"][1] + m3 * at["C"][1]))        # (5.b)
    constraints = tuple(end - pin for end, pin in zip(at["rod end"], at["C"]))         # (27)-(28)
    torque = torque_mean + ripple * sp.sin(omega * t)
    return MultibodyModel(
        coordinates=(phi, psi, x), velocities=(dphi, dpsi, dx), kinetic_energy=T,
        potential_energy=Pi, constraints=constraints, independent=(phi,),
        parameters=(l1, a1, m1, I1, l2, a2, m2, I2, m3, g, torque_mean, ripple, omega),
        generalized_forces=(torque, 0, 0), time=t,
    )


def slider_crank_system(parameters=None, reading=DEFAULT_READING, torque=True, gas=True) -> System:
    """The slider-crank bound to Table 1 (or ``parameters``) and a reading of the data.

    Parameters
    ----------
    parameters : SliderCrankParameters, optional
        Default: Table 1.
    reading : str or Reading, optional
        One of :data:`READINGS`; default :data:`DEFAULT_READING`.
    torque, gas : bool, optional
        Switch the drive torque or the gas force off (for energy checks).
    """
    parameters = instance_of("parameters", SliderCrankParameters() if parameters is None else parameters,
                             SliderCrankParameters)
    torque, gas = flag("torque", torque), flag("gas", gas)
    reading = get_reading(reading)
    values = parameters.as_dict()
    values.update(torque_mean=reading.torque_mean if torque else 0.0,
                  torque_ripple=TORQUE_RIPPLE if torque else 0.0, omega=OMEGA)
    return SliderCrankSystem(parameters, reading, values, GasForce(reading) if gas else None)


class SliderCrankSystem(System):
    """A :class:`~closedloop.model.System` that also remembers its Table 1 data and reading."""

    def __init__(self, parameters, reading, values, force):
        super().__init__(slider_crank_model, values, force)      # the model itself only when asked for
        self.parameters = parameters
        self.reading = reading


@dataclass(frozen=True)
class Case:
    """One of the paper's initial-condition cases (section 4)."""

    number: int
    phi0: float
    dphi0: float
    finding: str


#: The four cases of section 4 and the paper's finding for each.
CASES = {
    1: Case(1, math.pi, 1.0, "oscillation"),
    2: Case(2, math.pi / 2, 1.0, "full rotation"),
    3: Case(3, math.pi, 0.5, "oscillation"),
    4: Case(4, math.pi, 1.5, "full rotation"),
}


def get_case(number):
    """The :class:`Case` numbered ``number`` (1-4), or a clear error."""
    return CASES[one_of("case", number, CASES)]


#: |phi0| above this is refused: a start angle is meant within a few turns (1000 rad is 159 turns,
#: and sin phi0 keeps 13 digits there; at 1e308 rad it keeps none).
ANGLE_LIMIT = 1e3
#: |dphi0| above this is refused: the paper's speeds are below 10 rad/s, and 1000 rad/s (9550 rpm)
#: already needs some 1e5 steps for 20 s.
SPEED_LIMIT = 1e3


def initial_state(system, phi0, dphi0) -> InitialState:
    """Consistent initial values for crank angle phi0 and speed dphi0.

    psi(0) and x_C(0) solve (27)-(28) on the branch with the slider to the
    right of the crank (psi near pi; at phi0 = pi the slider is at the inner
    dead centre x_C = l2 - l1), then psi'(0), x_C'(0) follow from (9).
    |phi0| <= :data:`ANGLE_LIMIT` and |dphi0| <= :data:`SPEED_LIMIT`.
    """
    instance_of("system", system, SliderCrankSystem)
    phi0 = finite_number("phi0", phi0, minimum=-ANGLE_LIMIT, maximum=ANGLE_LIMIT, unit="rad")
    dphi0 = finite_number("dphi0", dphi0, minimum=-SPEED_LIMIT, maximum=SPEED_LIMIT, unit="rad/s")
    p = system.parameters
    if abs(p.l1 * math.sin(phi0)) > p.l2:
        raise InputError(
            f"phi0: the mechanism does not assemble at phi0 = {phi0:g} rad: with l2 < l1 the crank rocks "
            f"within |sin phi| <= l2/l1 = {p.l2 / p.l1:g}"
        )
    psi_guess = math.pi - math.asin(p.l1 * math.sin(phi0) / p.l2)       # exact on this branch
    x_guess = p.l1 * math.cos(phi0) - p.l2 * math.cos(psi_guess)
    return consistent_initial_state(system, [phi0], [dphi0], [psi_guess, x_guess])


#: The two outcomes of a run, indexed by their codes 0 and 1 (see :func:`motion_codes`).
MOTIONS = ("oscillation", "full rotation")


def motion_codes(excursion):
    """The rule behind :func:`classify_motion`, on the largest excursion ``max |phi(t) - phi0|``.

    Parameters
    ----------
    excursion : float or ndarray
        ``max |phi(t) - phi0|`` over a run [rad], phi unwrapped.

    Returns
    -------
    int or ndarray of int
        1 (``MOTIONS[1]``, "full rotation") where the crank turned at least
        2 pi away from its start, else 0 (``MOTIONS[0]``, "oscillation").
    """
    codes = full_turn(excursion).astype(int)
    return codes if codes.ndim else int(codes)


#: The loosest relative tolerance whose motion classify_motion accepts: at rtol = 1e-2 the minimal
#: formulation (RK45) calls case 4 an oscillation, and at 1e-1 minimal and projected get case 1
#: wrong; at 1e-3 every formulation gets all four cases right.
CLASSIFY_RTOL_LIMIT = 1e-3


def check_classification_tolerance(name, rtol, prefix=""):
    """Refuse a relative tolerance too loose for :func:`classify_motion`.

    Parameters
    ----------
    name : str
        The parameter's name in the message (``"--rtol"``, ``"result"``).
    rtol : float
        The relative tolerance, or the largest of several.
    prefix : str, optional
        Words before the rule in the message (``"not classified, "``).

    Raises
    ------
    InputError
        If ``rtol`` is above :data:`CLASSIFY_RTOL_LIMIT`.
    """
    if rtol > CLASSIFY_RTOL_LIMIT:
        raise InputError(f"{name}: {prefix}rtol = {rtol:g} is too loose to tell a full rotation from an "
                         f"oscillation; rerun with rtol <= {CLASSIFY_RTOL_LIMIT:g}")


def classify_motion(result, phi0=None) -> str:
    """``"full rotation"`` if the crank ever turns 2 pi beyond its start, else ``"oscillation"``.

    Parameters
    ----------
    result : SimulationResult
        Its phi must be unwrapped (continuous), as simulate() returns it.
    phi0 : float, optional
        Starting angle; default the first output value.

    Raises
    ------
    InputError
        If the result can not be classified: it carries warnings (its own
        residuals say it is meaningless), its phi is not finite, or it was
        integrated with rtol above :data:`CLASSIFY_RTOL_LIMIT`.
    """
    instance_of("result", result, SimulationResult)
    if phi0 is not None:
        phi0 = finite_number("phi0", phi0, unit="rad")
    warnings = result.warnings
    if warnings:
        raise InputError(f"result: not classified, {warnings[0]}")
    check_classification_tolerance("result", float(np.max(result.rtol)), "not classified, ")
    phi = result.coordinate("phi")
    start = phi[0] if phi0 is None else phi0
    if phi.size == 0 or not (np.all(np.isfinite(phi)) and np.isfinite(start)):
        raise InputError("result: not classified, its crank angle phi is empty or not finite")
    return MOTIONS[motion_codes(np.max(np.abs(phi - start)))]


#: Names that moved to a study; the old import path still works, with a DeprecationWarning.
_MOVED_TO_STUDIES = {"ReadingOutcome": "readings", "reading_outcomes": "readings"}


def __getattr__(name):
    """``closedloop.slider_crank.reading_outcomes`` of 0.1: found in :mod:`closedloop.studies.readings`."""
    if name not in _MOVED_TO_STUDIES:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    import importlib
    import warnings

    home = f"closedloop.studies.{_MOVED_TO_STUDIES[name]}"
    warnings.warn(f"{__name__}.{name} moved to {home}; import it from there", DeprecationWarning, stacklevel=2)
    return getattr(importlib.import_module(home), name)
