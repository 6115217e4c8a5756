"""Answer checks for the exercise notebooks: right or wrong, with a hint, never the answer.

Each chapter's module (``ch01`` ... ``ch07``) defines ``CHECKS``, a mapping from an
exercise label to a :class:`Check`. A notebook calls::

    from checking.ch03 import check
    check("3.5", my_answer)

The expected value is computed by the ``closedloop`` library when the check runs
(never typed in), and compared with a tolerance. An answer still left as ``...``
raises :class:`NotAnswered`: the student notebooks stop there, with one clear message.

When the environment variable ``CHECKING_LOG`` names a file, every check also appends its
verdict there as one JSON line, ``{"label", "verdict", "message"}``, with the verdict one of
:data:`VERDICTS` and the message the line the student was shown. ``exercises/grade.py`` grades
from that log, so a grade comes from the same check, and the same words, as the feedback.
"""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from typing import Any, Callable

__all__ = ["Check", "NotAnswered", "WrongKind", "UnknownExercise", "as_numbers", "numeric", "same_angles", "choice", "symbolic",
           "not_an_expression", "scaled", "another_letter", "make_check", "LOG_VARIABLE", "VERDICTS"]

#: The environment variable that names the file the checks log their verdicts to (for grading).
LOG_VARIABLE = "CHECKING_LOG"
#: A check's verdicts: "error" is the check's own failure (the book's), never the student's answer.
VERDICTS = ("right", "not right yet", "wrong kind", "not answered", "error")


class NotAnswered(Exception):
    """The exercise still holds its placeholder ``...``."""


class WrongKind(Exception):
    """The answer is not the kind of thing the exercise asks for (text for a number, say)."""


class UnknownExercise(LookupError):
    """``check(label, answer)`` with a label that names no exercise of the chapter (or is no label at all)."""

    def __str__(self):                      # one plain line (a KeyError would show its message in quotes)
        return str(self.args[0]) if self.args else ""


@dataclass(frozen=True)
class Check:
    """One exercise's answer check.

    Attributes
    ----------
    label : str
        The exercise, e.g. "3.5".
    expected : callable
        Computes the right answer (with the library), once; it is cached.
    compare : callable
        ``compare(answer, expected) -> bool``.
    hint : str
        Shown when the answer is wrong; it must not give the answer away.
    wrong_example : callable
        ``wrong_example(expected) -> a wrong answer``, used by the tests to show
        that this check can fail.
    """

    label: str
    expected: Callable[[], Any]
    compare: Callable[[Any, Any], bool]
    hint: str
    wrong_example: Callable[[Any], Any]
    _cache: dict = field(default_factory=dict, compare=False, repr=False)

    def expected_value(self):
        if "value" not in self._cache:
            self._cache["value"] = self.expected()
        return self._cache["value"]

    def __call__(self, answer) -> bool:
        if answer is Ellipsis:
            message = f"Exercise {self.label} is not yet answered: replace the ... with your answer."
            _log(self.label, "not answered", message)
            raise NotAnswered(message)
        try:
            expected = self.expected_value()    # an error here is the book's, not the student's: it is raised
        except Exception as error:
            _log(self.label, "error", f"Exercise {self.label}: the check itself failed ({type(error).__name__}).")
            raise
        try:
            right = bool(self.compare(answer, expected))
        except WrongKind as wrong:
            return self._tell("wrong kind", f"Exercise {self.label}: {wrong}.")
        except Exception as error:              # the answer broke the comparison: not the kind expected
            return self._tell("wrong kind", f"Exercise {self.label}: this answer can not be compared with the "
                                            f"expected one ({type(error).__name__}); check what kind of answer "
                                            "the exercise asks for.")
        if right:
            return self._tell("right", f"Exercise {self.label}: right.")
        return self._tell("not right yet", f"Exercise {self.label}: not right yet. Hint: {self.hint}")

    def _tell(self, verdict, message) -> bool:
        """Print ``message`` for the student, log ``verdict`` for the grader; True if right."""
        print(message)
        _log(self.label, verdict, message)
        return verdict == "right"


def _log(label, verdict, message):
    """Append one verdict to the file named by ``$CHECKING_LOG``, if it names one (see the module docstring)."""
    path = os.environ.get(LOG_VARIABLE)
    if path:
        with open(path, "a", encoding="utf-8") as log:
            log.write(json.dumps({"label": label, "verdict": verdict, "message": message}) + "\n")


def as_numbers(answer, expected, complex_numbers=False):
    """``answer`` as a float (or, with ``complex_numbers``, complex) array shaped like ``expected``, or
    WrongKind saying what was expected: never text, a bool, an infinity or NaN."""
    import numpy as np

    shape = np.shape(expected)
    wanted = "a number" if shape == () else f"numbers in an array of shape {shape}"
    finite = "a finite number" if shape == () else f"finite numbers in an array of shape {shape}"
    if answer is None or isinstance(answer, (str, bytes, bool, np.bool_)):
        raise WrongKind(f"expected {wanted}, got {answer!r}")
    try:
        raw = np.asarray(answer)
    except (TypeError, ValueError):
        raise WrongKind(f"expected {wanted}, got {type(answer).__name__}") from None
    if raw.dtype.kind not in ("iufc" if complex_numbers else "iuf"):      # before converting: no ComplexWarning
        what = "a complex number" if raw.dtype.kind == "c" and raw.ndim == 0 else (
            "complex numbers" if raw.dtype.kind == "c" else f"{type(answer).__name__} of {raw.dtype}")
        raise WrongKind(f"expected {wanted}, got {what}")
    array = raw.astype(complex if complex_numbers else float)
    if array.shape != shape:
        raise WrongKind(f"expected {wanted}, got shape {array.shape}")
    if not np.all(np.isfinite(array)):
        raise WrongKind(f"expected {finite}, got {answer!r}")
    return array


def numeric(rtol=1e-6, atol=0.0):
    """Compare numbers (or arrays, element by element) with a tolerance."""
    import numpy as np

    def compare(answer, expected):
        answer, expected = as_numbers(answer, expected), np.asarray(expected, dtype=float)
        return bool(np.allclose(answer, expected, rtol=rtol, atol=atol))
    return compare


def same_angles(rtol=1e-9, atol=1e-12, angles=None):
    """Compare numbers of which those at ``angles`` (an index; default all) are angles, taken modulo 2 pi:
    their cosines and sines are compared, the other numbers as they are, with :func:`numeric`'s tolerance.

    The answer is first taken as every numeric answer is (finite numbers shaped like the expected ones), so
    that an infinite angle or ``True`` is the wrong kind of answer, said so, not a NaN cosine or 1 rad.
    """
    import numpy as np

    def on_circle(values):
        chosen = np.zeros(values.shape, dtype=bool)
        chosen[slice(None) if angles is None else angles] = True
        return np.concatenate((np.cos(values[chosen]), np.sin(values[chosen]), values[~chosen]))

    def compare(answer, expected):
        answer, expected = as_numbers(answer, expected), np.asarray(expected, dtype=float)
        return bool(np.allclose(on_circle(answer), on_circle(expected), rtol=rtol, atol=atol))
    return compare


def not_an_expression(answer):
    """WrongKind if ``answer`` cannot be a sympy expression the student wrote (text, a bool, None)."""
    if answer is None or isinstance(answer, (str, bytes, bool)):
        raise WrongKind(f"expected a sympy expression or matrix, got {answer!r}")


def choice(answer, expected):
    """Compare a short text answer (a letter, a word), ignoring case and spaces."""
    if not isinstance(answer, str):
        raise WrongKind(f"expected a letter or a word in quotes, such as 'a', got {answer!r}")
    return answer.strip().lower() == str(expected).strip().lower()


def symbolic(rtol=1e-9, points=5, seed=2018):
    """Compare sympy expressions or matrices by their values at random points.

    Symbols are matched by name, so a student's own ``sp.symbols("l1 ...")`` work;
    the answer may not use a symbol the expected value does not have.
    """
    import warnings

    import numpy as np
    import sympy as sp
    from sympy.utilities.exceptions import SymPyDeprecationWarning

    def compare(answer, expected):
        not_an_expression(answer)
        with warnings.catch_warnings():     # entries that are not expressions (a dict, None, a set ...)
            warnings.simplefilter("error", SymPyDeprecationWarning)
            try:
                matrix = sp.Matrix([answer]) if not hasattr(answer, "shape") else sp.Matrix(answer)
            except SymPyDeprecationWarning:
                raise WrongKind(f"expected a sympy expression or matrix, got {answer!r}") from None
        answer = matrix
        expected = sp.Matrix([expected]) if not hasattr(expected, "shape") else sp.Matrix(expected)
        names = sorted({str(symbol) for symbol in expected.free_symbols})
        if answer.shape != expected.shape or not {str(s) for s in answer.free_symbols} <= set(names):
            return False
        rng = np.random.default_rng(seed)
        for _ in range(points):
            point = dict(zip(names, rng.uniform(0.3, 2.5, len(names))))
            a, e = (np.array(m.subs({s: point[str(s)] for s in m.free_symbols}), dtype=float)
                    for m in (answer, expected))
            if not np.allclose(a, e, rtol=rtol, atol=1e-12 * (1.0 + np.abs(e).max())):
                return False
        return True
    return compare


def scaled(factor=1.5, shift=1.0):
    """A wrong numeric answer near the right one (no value maps onto itself)."""
    import numpy as np

    def wrong(expected):
        expected = np.asarray(expected, dtype=float)
        return expected * factor + shift + np.abs(expected)
    return wrong


def another_letter(letters="abc"):
    """A wrong multiple-choice answer: the first of ``letters`` that is not the right one."""
    def wrong(expected):
        return next(letter for letter in letters if letter != str(expected).strip().lower())
    return wrong


def make_check(checks: dict):
    """The ``check(label, answer)`` function of one chapter's module.

    It prints the verdict and returns None, so that a notebook cell ending in ``check(...)``
    shows the verdict alone (``Check.__call__`` returns it as a bool, for graders).
    """
    def check(label, answer):
        if not isinstance(label, str):
            raise UnknownExercise(f"check(label, answer): the label is the exercise's number in quotes, such as "
                                  f"{next(iter(checks))!r}, got {label!r} ({type(label).__name__})")
        if label not in checks:
            raise UnknownExercise(f"no exercise {label!r} here; the exercises are {', '.join(checks)}")
        checks[label](answer)
    return check
