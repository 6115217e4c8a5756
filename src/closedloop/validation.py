"""Input checks, written once: every :class:`~closedloop.errors.InputError` about a number or a name.

Each check returns the value it accepted (as a float, an int or a float array)
and otherwise raises an InputError whose one line names the parameter, says
what is allowed and shows the value given, e.g. ``step: must be a finite
number > 0 s, got -0.1``.  Python and numpy numbers are accepted alike
(``5``, ``5.0``, ``np.int64(5)``, ``np.float64(5.0)``); ``True``, ``"5"`` and
``None`` are refused, with the parameter named.
"""

from __future__ import annotations

import math
import numbers
import sys

import numpy as np

from .errors import InputError

__all__ = ["finite_number", "positive_number", "integer", "positive_integer", "one_of", "finite_array", "instance_of",
           "flag", "is_real", "shown", "shown_array"]


def shown(value):
    """``value`` as an error message shows it: numpy scalars like the Python numbers they hold."""
    if isinstance(value, np.generic):
        value = value.item()
    if isinstance(value, np.ndarray) and value.ndim:
        return shown_array(value)
    try:
        text = repr(value)
    except ValueError:                     # an int (or Fraction) beyond Python's limit of digits for str
        return f"{type(value).__name__} of more than {sys.get_int_max_str_digits()} digits"
    return " ".join(line.strip() for line in text.splitlines()) if "\n" in text else text


def shown_array(values):
    """An array as an error message shows it: on one line, at most a dozen entries (``[1. nan ... 3.]``)."""
    text = np.array2string(np.asarray(values), max_line_width=sys.maxsize, threshold=12, edgeitems=3)
    return text.replace("\n", "")                # the rows of a 2-d array: "[[1. 2.] [3. 4.]]"


def is_real(value):
    """True for a real number (numpy scalars included), never for bool, str or None."""
    return isinstance(value, numbers.Real) and not isinstance(value, (bool, np.bool_))


def _range_text(minimum, maximum, strict, unit):
    """``"> 0 s"``, ``">= 0"``, ``"from 1 to 8"``: the allowed range in words."""
    suffix = f" {unit}" if unit else ""
    if minimum is not None and maximum is not None:
        return f" from {minimum:g} to {maximum:g}{suffix}"
    if minimum is not None:
        return f" {'>' if strict else '>='} {minimum:g}{suffix}"
    if maximum is not None:
        return f" {'<' if strict else '<='} {maximum:g}{suffix}"
    return f" [{unit}]" if unit else ""


def finite_number(name, value, *, minimum=None, maximum=None, strict=False, unit=None):
    """``value`` as a float, if it is a finite real number within the bounds.

    Parameters
    ----------
    name : str
        The parameter's name, as the user wrote it.
    value : object
    minimum, maximum : float, optional
        Bounds; with both, the range is closed (``strict`` is ignored).
    strict : bool, optional
        With one bound: exclude it (``> minimum``, ``< maximum``).
    unit : str, optional
        Shown after the range (``"s"``, ``"kg m^2"``).

    Returns
    -------
    float

    Raises
    ------
    InputError
        ``"{name}: must be a finite number{range}, got {value}"``.
    """
    if is_real(value):
        try:
            number = float(value)
        except OverflowError:              # an integer or Fraction beyond float's range (10**400)
            number = math.inf
        inside = np.isfinite(number)
        if inside and minimum is not None:
            inside = number > minimum if strict and maximum is None else number >= minimum
        if inside and maximum is not None:
            inside = number < maximum if strict and minimum is None else number <= maximum
        if inside:
            return number
    raise InputError(f"{name}: must be a finite number{_range_text(minimum, maximum, strict, unit)}, "
                     f"got {shown(value)}")


def positive_number(name, value, *, unit=None):
    """``value`` as a float, if it is a finite number > 0 (a time, a step, a tolerance)."""
    return finite_number(name, value, minimum=0.0, strict=True, unit=unit)


def integer(name, value, *, minimum=None, maximum=None):
    """``value`` as an int, if it is an integer (Python or numpy, not bool) within the closed bounds.

    Raises
    ------
    InputError
        ``"{name}: must be an integer{range}, got {value}"``.
    """
    if isinstance(value, (numbers.Integral, np.integer)) and not isinstance(value, (bool, np.bool_)):
        number = int(value)
        if (minimum is None or number >= minimum) and (maximum is None or number <= maximum):
            return number
    raise InputError(f"{name}: must be an integer{_range_text(minimum, maximum, False, None)}, got {shown(value)}")


def positive_integer(name, value, *, maximum=None):
    """``value`` as an int, if it is an integer >= 1 (and <= ``maximum``)."""
    return integer(name, value, minimum=1, maximum=maximum)


def one_of(name, value, choices):
    """``value``, if it is one of ``choices`` (a sequence, or a mapping whose keys are the choices).

    Raises
    ------
    InputError
        ``"{name}: unknown {value}; choose one of {choices}"``.
    """
    try:                                   # a bool is no choice (True == 1 would pass for a case number)
        known = not isinstance(value, (bool, np.bool_)) and bool(value in choices)
    except (TypeError, ValueError):        # an unhashable value is no key of a mapping; an array no choice
        known = False
    if not known:
        raise InputError(f"{name}: unknown {shown(value)}; choose one of {', '.join(map(str, choices))}")
    if isinstance(value, np.ndarray):      # a 0-d array equal to a choice: the choice itself, hashable
        return next(choice for choice in choices if choice == value)
    return value


def instance_of(name, value, kind):
    """``value``, if it is an instance of the class ``kind``.

    Raises
    ------
    InputError
        ``"{name}: expected a {kind}, got {type}"``.
    """
    if not isinstance(value, kind):
        raise InputError(f"{name}: expected a {kind.__name__}, got {type(value).__name__}")
    return value


def flag(name, value):
    """``value`` as a bool, if it is True or False (numpy's too).

    Raises
    ------
    InputError
        ``"{name}: must be True or False, got {value}"`` (an array's truth is ambiguous, a text's always true).
    """
    if isinstance(value, (bool, np.bool_)):
        return bool(value)
    raise InputError(f"{name}: must be True or False, got {shown(value)}")


def output_times(t_eval, t_start, t_end):
    """``t_eval`` checked as output times: a flat list of finite times increasing strictly within
    ``[t_start, t_end]`` (a float array), or None.

    Raises
    ------
    InputError
        Naming ``t_eval`` and the interval.
    """
    if t_eval is None:
        return None
    t_eval = finite_array("t_eval", t_eval)
    if t_eval.size == 0:
        raise InputError("t_eval: holds no time; give at least one, or None for the step ends")
    if np.any(np.diff(t_eval) <= 0) or t_eval[0] < t_start or t_eval[-1] > t_end:
        raise InputError(f"t_eval: must increase strictly within [{t_start:g}, {t_end:g}]")
    return t_eval


def finite_array(name, value, *, size=None):
    """``value`` as a 1-d float array of finite numbers (of ``size`` entries, if given).

    Raises
    ------
    InputError
        ``"{name}: must be a flat list of numbers, got an array of shape {shape}"``,
        ``"{name}: need {size} values, got {k}"`` or ``"{name}: must be finite, got {values}"``.
    """
    if value is None or isinstance(value, (str, bytes, bool, np.bool_)):
        raise InputError(f"{name}: must be finite numbers, got {shown(value)}")
    try:
        array = np.atleast_1d(np.asarray(value, dtype=float))
    except OverflowError:                  # an integer beyond float's range (2**1024), alone or in a list
        raise InputError(f"{name}: must be finite, got {shown(value)}") from None
    except (TypeError, ValueError):
        raise InputError(f"{name}: must be finite numbers, got {shown(value)}") from None
    if array.ndim != 1:
        raise InputError(f"{name}: must be a flat list of numbers, got an array of shape {array.shape}")
    if size is not None and array.size != size:
        raise InputError(f"{name}: need {size} values, got {array.size}")
    if not np.all(np.isfinite(array)):
        raise InputError(f"{name}: must be finite, got {shown_array(array)}")
    return array
