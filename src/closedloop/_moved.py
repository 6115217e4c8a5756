"""The import paths of modules that moved in the redesign of 0.2, kept working for readers' code.

``from closedloop.basin import basin_map`` still works: :func:`install` puts a
module object under each old name whose first attribute look-up imports the
new home and warns (DeprecationWarning), as scipy does for its moved modules.
The book and the tests import the new homes.
"""

from __future__ import annotations

import importlib
import sys
import types
import warnings

#: Old module name -> new home, both relative to the package.
MOVED = {
    "basin": "studies.basin",
    "benchmark": "studies.benchmark",
    "baseline": "studies.baseline",
    "energy": "studies.energy",
    "examples": "four_bar",
    "projection": "formulations.projected",
    "closed_form": "formulations.closed_form",
    "ode_dop853": "simulation.dop853",
}


class _MovedModule(types.ModuleType):
    """A stand-in for a moved module: attributes come from its new home, with a warning."""

    def __init__(self, old, new):
        super().__init__(old, f"Moved to {new}.")
        self.__new_home = new

    def __getattr__(self, name):
        if name.startswith("__"):
            raise AttributeError(name)
        warnings.warn(f"{self.__name__} moved to {self.__new_home}; import it from there",
                      DeprecationWarning, stacklevel=2)
        return getattr(importlib.import_module(self.__new_home), name)


def install(package):
    """Register the stand-ins of :data:`MOVED` under ``package`` (called once by ``closedloop``)."""
    for old, new in MOVED.items():
        sys.modules.setdefault(f"{package}.{old}", _MovedModule(f"{package}.{old}", f"{package}.{new}"))
