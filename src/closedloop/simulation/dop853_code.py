"""Hairer and Wanner's compiled DOP853, and its coefficients, without importing ``scipy.integrate``.

``scipy.integrate.ode`` runs Hairer and Wanner's DOP853 code [Hairer, Nørsett, Wanner,
*Solving ODEs I*, section II.10], compiled into scipy's extension module
``scipy.integrate._dop``.  Importing it the ordinary way runs the package's
``scipy/integrate/__init__.py``, which imports all of scipy.integrate and with it
scipy.optimize, scipy.sparse, scipy.special and scipy.linalg: about 0.3 s, more than
the whole of ``closedloop simulate --case 2`` otherwise costs (issue 14).  The
extension itself needs none of them (only numpy).  So this module loads two files
of scipy directly from scipy's folder, found with :func:`importlib.util.find_spec`
of the top-level ``scipy`` (which runs no ``__init__``):

- the extension ``integrate/_dop`` (:func:`extension`), registered in
  ``sys.modules`` under its real name ``scipy.integrate._dop``, so that a later
  ``import scipy.integrate`` in the same process uses the same module;
- the pure-numpy module ``integrate/_ivp/dop853_coefficients.py``
  (:func:`coefficients`), the coefficients of the pair and of its continuous
  extension that ``scipy.integrate.DOP853`` carries, executed as a module of its own
  (not registered: a second copy that scipy may load later is harmless).

If a module of that name is already imported it is used; if loading a file fails
(another layout of scipy), the ordinary import is the fallback.

:func:`dopri853` calls the compiled code with exactly the arguments that
``ode(f).set_integrator("dop853", ...).set_solout(...)``, ``set_initial_value`` and
``integrate`` pass (scipy's ``_ode.py``, classes ``dopri5`` and ``dop853``), so it takes
the same steps to the last bit.  One difference: without a ``solout`` it still gives
the code one (that lets every step be), since scipy's C translation of the code (``dop.c``,
``dp86co``) leaves its flag ``irtrn`` uninitialised when ``iout`` is 0 and evaluates f at the
start of every step again when that stack garbage happens to be 2 or more: the same values, but
a count of evaluations that depends on what ran before (seen: 13 or 14 evaluations for the same
one-step integration, and so ``nfev`` of a whole run differing between two processes).
"""

from __future__ import annotations

import importlib
import importlib.machinery
import importlib.util
import os
import sys

import numpy as np

from ..loading import one_time

__all__ = ["extension", "coefficients", "dopri853", "EXTENSION_NAME", "COEFFICIENTS_NAME"]

#: The extension's real name (scipy's ``from . import _dop`` in ``scipy/integrate/_ode.py``).
EXTENSION_NAME = "scipy.integrate._dop"
#: The module of DOP853's coefficients (``scipy/integrate/_ivp/dop853_coefficients.py``).
COEFFICIENTS_NAME = "scipy.integrate._ivp.dop853_coefficients"
#: scipy's defaults of ``ode(...).set_integrator("dop853")`` (class ``dop853`` of ``_ode.py``).
SAFETY, IFACTOR, DFACTOR, BETA = 0.9, 6.0, 0.3, 0.0
#: ``verbosity`` of the code: negative, no messages printed.
VERBOSITY = -1

_loaded = {}


def _scipy_folder():
    """scipy's package folder, without importing scipy."""
    spec = importlib.util.find_spec("scipy")
    if spec is None or not spec.submodule_search_locations:
        raise ImportError("scipy not found")
    return list(spec.submodule_search_locations)[0]


def _load_extension():
    """``scipy.integrate._dop`` loaded from its file, registered in ``sys.modules``."""
    folder = os.path.join(_scipy_folder(), "integrate")
    for suffix in importlib.machinery.EXTENSION_SUFFIXES:
        path = os.path.join(folder, "_dop" + suffix)
        if os.path.isfile(path):
            break
    else:
        raise ImportError(f"no compiled _dop in {folder}")
    loader = importlib.machinery.ExtensionFileLoader(EXTENSION_NAME, path)
    spec = importlib.util.spec_from_file_location(EXTENSION_NAME, path, loader=loader)
    module = importlib.util.module_from_spec(spec)
    loader.exec_module(module)
    return sys.modules.setdefault(EXTENSION_NAME, module)


def _load_coefficients():
    """``scipy/integrate/_ivp/dop853_coefficients.py`` executed as a module (not registered)."""
    path = os.path.join(_scipy_folder(), "integrate", "_ivp", "dop853_coefficients.py")
    spec = importlib.util.spec_from_file_location(COEFFICIENTS_NAME, path)
    if spec is None or spec.loader is None:
        raise ImportError(f"cannot load {path}")
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _module(name, load):
    """The module ``name``: imported already, else loaded by ``load``, else imported the ordinary way
    (once per process: :func:`closedloop.loading.one_time` leaves it out of a run's cpu_time)."""
    if name not in _loaded:
        with one_time():
            module = sys.modules.get(name)
            if module is None:
                try:
                    module = load()
                except Exception:           # another layout of scipy: import it (and scipy.integrate)
                    module = importlib.import_module(name)
            _loaded[name] = module
    return _loaded[name]


def extension():
    """scipy's compiled DOP853 and DOPRI5 (``scipy.integrate._dop``), without scipy.integrate's ``__init__``."""
    return _module(EXTENSION_NAME, _load_extension)


def coefficients():
    """The module of DOP853's coefficients (``N_STAGES``, ``A``, ``B``, ``C``, ``D``, ...), as scipy's."""
    return _module(COEFFICIENTS_NAME, _load_coefficients)


def dopri853(f, t0, y0, t_end, *, rtol, atol, nsteps, first_step=0.0, max_step=0.0, solout=None,
             dfactor=DFACTOR, beta=BETA):
    """Integrate ``y' = f(t, y)`` from ``t0`` to ``t_end`` with the compiled DOP853: ``(t, y, code)``.

    The same call as ``solver = ode(f).set_integrator("dop853", rtol=rtol, atol=atol,
    nsteps=nsteps, first_step=first_step, max_step=max_step)``, ``solver.set_solout(solout)``,
    ``solver.set_initial_value(y0, t0)``, ``solver.integrate(t_end)``, with ``solver.t``,
    ``solver.y`` and ``solver.get_return_code()`` returned, except that a failure (a
    negative code) is not also announced by a warning, and that without ``solout`` the
    code gets one that returns 0 (so that it evaluates ``f`` a fixed number of times; see the
    module's docstring).

    Parameters
    ----------
    f : callable
        ``f(t, y) -> sequence`` of length ``y0.size``.
    t0, t_end : float
    y0 : array_like, shape (n,)
        Not changed (the code works on a copy).
    rtol, atol : float
    nsteps : int
        Steps allowed.
    first_step, max_step : float, optional
        0 lets the code choose.
    solout : callable, optional
        ``solout(t, y) -> int`` after every accepted step (and once at ``t0``); -1 stops the code.
    dfactor : float, optional
        The code's ``fac1`` (scipy's ``dfactor``), the smallest ratio of a new step to the
        last: scipy's default :data:`DFACTOR` takes scipy's steps.  In scipy's C translation
        (``dop.c``, scipy 1.17) it is also the ratio of every retry to a rejected step: see
        :data:`closedloop.simulation.dop853.REJECTION_FACTOR`.
    beta : float, optional
        The code's ``beta`` (Hairer's ``WORK(5)``): the weight of the last accepted step's error
        in the choice of the next step (stabilised step size control); scipy's default
        :data:`BETA` = 0 leaves it out.  See :data:`closedloop.simulation.dop853.STEP_CONTROL_BETA`.

    Returns
    -------
    t : float
        Where the code stopped (``t_end``, or the end of the step where ``solout`` stopped it).
    y : ndarray, shape (n,)
    code : int
        1 done, 2 stopped by ``solout``; -1 inconsistent input, -2 more than ``nsteps``
        steps needed, -3 step size too small, -4 probably stiff.
    """
    y = np.asarray(y0, dtype=float).copy()  # the code changes y in place
    n = len(y)
    work = np.zeros((11 * n + 21,), float)
    work[1], work[2], work[3], work[4] = SAFETY, dfactor, IFACTOR, beta
    work[5], work[6] = max_step, first_step
    iwork = np.zeros((21,), dtype=np.int32)
    try:
        t, y, code = extension().dopri853(f, t0, y, t_end, rtol, atol, solout or _no_solout, 1, work, iwork,
                                          nsteps, VERBOSITY, ())
    except SystemError as error:            # as ode.integrate: f2py's trouble with a tuple returned by f
        raise ValueError("Function to integrate must not return a tuple.") from error
    return t, y, code


def _no_solout(t, y):
    """The ``solout`` of a call without one: go on (0), and the code's flag ``irtrn`` is set."""
    return 0
