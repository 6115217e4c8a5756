"""Errors raised by closedloop.

Every error says what went wrong in one line: bad input names the parameter
and its allowed range, and is raised before any integration starts; a failed
integration names the time and the reason.
"""

__all__ = [
    "ClosedLoopError",
    "InputError",
    "ConvergenceError",
    "SingularConfigurationError",
    "IntegrationError",
]


class ClosedLoopError(Exception):
    """Base class of every error raised on purpose by closedloop."""


class InputError(ClosedLoopError, ValueError):
    """A parameter is outside its allowed range; raised before any integration."""


class ConvergenceError(ClosedLoopError, ArithmeticError):
    """Newton's method on the constraints f(s) = 0 did not converge."""


class SingularConfigurationError(ClosedLoopError, ArithmeticError):
    """A Jacobian that must be inverted (Phi_z of (20), or the matrix of (12)) is singular."""


class IntegrationError(ClosedLoopError, RuntimeError):
    """The numerical integration failed; the message names the time and the reason."""


def at_time(t):
    """``" at t = ... s"`` for an error message, or nothing when the time is unknown."""
    return "" if t is None else f" at t = {t:.6g} s"
