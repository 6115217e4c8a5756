"""Where a study's numbers came from: the library, its source, the settings and the machine.

A study written to JSON (``closedloop benchmark --json``, ``closedloop long-runs --json``)
carries this provenance, and reading it back says whether the library imported now
would compute the same numbers (its :func:`source_fingerprint` is the study's).
"""

from __future__ import annotations

import json
import os
import sys

import numpy as np

from .. import __version__
from ..codecache import package_fingerprint, sympy_version
from ..errors import InputError

__all__ = ["NOT_IN_FINGERPRINT", "source_fingerprint", "provenance", "read_with_provenance"]

#: Paths in the package, relative to its root, that cannot change a number of a study (the
#: command line, output files, figures and the four-bar); a folder named here leaves out
#: everything below it.
NOT_IN_FINGERPRINT = ("cli.py", "output.py", "plotting", "four_bar.py")


def source_fingerprint():
    """sha256 of the library's sources that can change a study's numbers.

    Returns
    -------
    str
        :func:`closedloop.codecache.package_fingerprint` without :data:`NOT_IN_FINGERPRINT`.
    """
    return package_fingerprint(NOT_IN_FINGERPRINT)


def provenance(settings):
    """The provenance of a study run now with ``settings``.

    Parameters
    ----------
    settings : object
        The study's settings, with a method ``as_dict()``.

    Returns
    -------
    dict
        ``closedloop_version``, ``source_fingerprint``, ``settings`` (as a dict) and
        ``machine`` (platform, processor, cores, the versions of Python, numpy, scipy
        and sympy).
    """
    import platform                         # here: the command line builds its parser from the studies
    import scipy

    return {
        "closedloop_version": __version__,
        "source_fingerprint": source_fingerprint(),
        "settings": settings.as_dict(),
        "machine": {"platform": platform.platform(), "machine": platform.machine(),
                    "cpu_count": os.cpu_count(), "python": sys.version.split()[0],
                    "numpy": np.__version__, "scipy": scipy.__version__, "sympy": sympy_version()},
    }


def read_with_provenance(path, parts, what, command):
    """A study's JSON file with its provenance and parts checked.

    Parameters
    ----------
    path : str or path-like
        The file that ``closedloop COMMAND --json`` wrote.
    parts : sequence of str
        The keys the study has besides its provenance.
    what : str
        What the file holds, for error messages ("a study").
    command : str
        The command that writes it, for error messages ("benchmark").

    Returns
    -------
    dict
        The file's content, with one more key, ``"current"``: True when its
        ``source_fingerprint`` is that of the library imported now.

    Raises
    ------
    InputError
        If the file cannot be read as JSON, or lacks a part.
    """
    try:
        with open(path, encoding="utf-8") as stream:
            data = json.load(stream)
    except (OSError, ValueError) as error:
        raise InputError(f"path: cannot read {what} from {str(path)!r}: {error}") from None
    missing = {"closedloop_version", "source_fingerprint", "settings", "machine", *parts} - set(data)
    if missing:
        raise InputError(f"path: {str(path)!r} lacks {sorted(missing)}; write it with closedloop {command} --json")
    data["current"] = data["source_fingerprint"] == source_fingerprint()
    return data
