"""Output files of the command line: checked before any computation, written atomically.

:func:`check_file`, :func:`check_folder`, :func:`check_distinct` and
:func:`require_matplotlib` raise :class:`~closedloop.errors.InputError` with a
one-line message that names the option (``--png: the folder of /nope/map.png
does not exist``), so that a run is refused before it starts rather than failing at
the end. :func:`atomic_write` writes into a temporary file in the target's
folder and moves it over the target only once complete: a failed write leaves
the previous file as it was and no temporary behind; it reports failure as
:class:`WriteError`, whose message names the file.
"""

from __future__ import annotations

import contextlib
import os
import stat
import tempfile

from .errors import ClosedLoopError, InputError

__all__ = ["STDOUT", "WriteError", "check_file", "check_folder", "check_distinct", "require_matplotlib",
           "atomic_write", "save_figure"]

#: The file name that means standard output (``--json -``).
STDOUT = "-"


class WriteError(ClosedLoopError, OSError):
    """An output file could not be written (the run itself went well)."""


def _writable_folder(folder):
    return os.access(folder, os.W_OK | os.X_OK)


def check_file(option, path):
    """Refuse ``path`` for ``option`` unless a file can be written there; returns ``path``.

    Besides the permissions, the folder is tried: a temporary file is opened in it, as
    :func:`atomic_write` will, and removed.  Permissions alone do not tell (root may write
    anywhere, yet not into /proc).
    """
    if not isinstance(path, (str, os.PathLike)):
        raise InputError(f"{option}: expected a file name, got {path!r}")
    path = os.fspath(path)
    if path == "":
        raise InputError(f"{option}: expected a file name, got ''")
    if os.path.isdir(path) or path.endswith(os.sep):
        raise InputError(f"{option}: {path} is a folder; give a file name")
    folder = os.path.dirname(os.path.abspath(path))
    if not os.path.isdir(folder):
        raise InputError(f"{option}: the folder of {path} does not exist")
    if not _writable_folder(folder):
        raise InputError(f"{option}: the folder {folder} is not writable")
    if os.path.exists(path) and not os.access(path, os.W_OK):
        raise InputError(f"{option}: {path} exists and is not writable")
    try:
        with tempfile.NamedTemporaryFile("wb", dir=folder, prefix=f".{os.path.basename(path)}.", suffix=".tmp"):
            pass
    except OSError as error:
        raise InputError(f"{option}: cannot write {path}: {error.strerror or error}") from None
    return path


def check_folder(option, path):
    """Refuse ``path`` for ``option`` unless it is a writable folder or one that can be created."""
    if path == "":
        raise InputError(f"{option}: expected a folder name, got ''")
    if os.path.exists(path):
        if not os.path.isdir(path):
            raise InputError(f"{option}: {path} exists and is not a folder")
        if not _writable_folder(path):
            raise InputError(f"{option}: the folder {path} is not writable")
        return path
    ancestor = os.path.dirname(os.path.abspath(path))
    while not os.path.exists(ancestor):
        ancestor = os.path.dirname(ancestor)
    if not os.path.isdir(ancestor):
        raise InputError(f"{option}: cannot create {path}: {ancestor} is not a folder")
    if not _writable_folder(ancestor):
        raise InputError(f"{option}: cannot create {path}: the folder {ancestor} is not writable")
    return path


def _same(a, b):
    if os.path.realpath(a) == os.path.realpath(b):
        return True
    with contextlib.suppress(OSError):
        return os.path.samefile(a, b)
    return False


def check_distinct(named):
    """Refuse two options that name the same file; ``named`` is a list of (option, path), None skipped."""
    named = [(option, path) for option, path in named if path is not None and path != STDOUT]
    for i, (first, a) in enumerate(named):
        for second, b in named[i + 1:]:
            if _same(a, b):
                raise InputError(f"{first}, {second}: both name {b}; give two different files")


def require_matplotlib(option):
    """Refuse a figure when matplotlib cannot be imported."""
    try:
        import matplotlib  # noqa: F401
    except ImportError:
        raise InputError(f"{option}: writing a figure needs matplotlib, which is not installed "
                         "(pip install 'closedloop[plot]')") from None


def _new_file_mode(path):
    """The permissions the written file gets: those of the file it replaces, else 0666 less the umask."""
    try:
        return stat.S_IMODE(os.stat(path).st_mode)
    except OSError:
        umask = os.umask(0)
        os.umask(umask)
        return 0o666 & ~umask


@contextlib.contextmanager
def atomic_write(path, binary=False, option=None):
    """``with atomic_write(path) as handle:`` write into ``handle``; ``path`` is replaced only at the end.

    Text is UTF-8. On any failure (an exception in the block, a full disk, an
    interrupt) the temporary file is removed and ``path`` keeps its previous
    content; an OSError becomes :class:`WriteError` naming ``path`` (and the
    command's ``option`` that named it, if given).
    """
    where = f"{option}: " if option else ""
    folder, name = os.path.split(os.path.abspath(path))
    try:
        handle = tempfile.NamedTemporaryFile("wb" if binary else "w", dir=folder, prefix=f".{name}.",
                                             suffix=".tmp", delete=False,
                                             **({} if binary else {"encoding": "utf-8"}))
    except OSError as error:
        raise WriteError(f"{where}cannot write {path}: {error.strerror or error}") from None
    try:
        with handle:
            yield handle
            handle.flush()
            os.fsync(handle.fileno())
        os.chmod(handle.name, _new_file_mode(path))
        os.replace(handle.name, path)
    except BaseException as error:
        with contextlib.suppress(OSError):
            os.unlink(handle.name)
        if isinstance(error, OSError) and not isinstance(error, WriteError):
            raise WriteError(f"{where}cannot write {path}: {error.strerror or error}") from None
        raise


def save_figure(figure, path, dpi, option=None):
    """Write a matplotlib figure as PNG, atomically (``option``: the command's option that named ``path``)."""
    with atomic_write(path, binary=True, option=option) as handle:
        figure.savefig(handle, format="png", dpi=dpi)
