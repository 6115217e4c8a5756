"""Generated numeric code kept on disk, so that a run does not derive it again.

The numeric functions of a model (:func:`closedloop.model.model_functions`, behind
:func:`~closedloop.model.derive`), the two branches of the gas law and the period of a
system's forcing are made by sympy (the derivation, ``lambdify`` and its code printers).
Importing sympy and generating them costs about a second, far more than a run of the
command line. The first run writes each generated set as the source of a small Python
module into a cache folder; later runs execute that source and need no sympy at all.

Folder
    ``$CLOSEDLOOP_CACHE_DIR`` if set, else ``$XDG_CACHE_HOME/closedloop``, else
    ``~/.cache/closedloop``. It may be deleted at any time.

Key
    sha256 of the kind of code, the source of the whole package (every ``*.py`` below it,
    :func:`source_fingerprint`), the versions of sympy, Python and numpy, and the caller's own
    parts (the model's definition, the force's data, the parameter values). The key names
    the file, and the file states its key and the sha256 of its text, both checked at
    every load: a change of any of them is a different file, so a cached function is never
    stale.

Failures
    A missing, unreadable or corrupt file (text not matching its checksum, another key,
    a name missing, any error while it runs) is generated again and rewritten. A folder
    that cannot be written only means that the code generated in this run is used from
    memory. Neither is an error, and neither gives a wrong function: what is written is
    the text that the run itself executes.

The generated text is Python; its only imports are the ``math``/``numpy`` functions that
the generated code calls (and, for the closed form, the library's own error helper). The
folder should be writable by its owner only, like any place Python code is loaded from.
"""

from __future__ import annotations

import builtins
import dis
import hashlib
import inspect
import math
import os
import re
import sys
import textwrap
import types
from functools import lru_cache
from pathlib import Path

import numpy

from .loading import one_time

__all__ = ["ENVIRONMENT_VARIABLE", "cache_folder", "package_fingerprint", "source_fingerprint", "sympy_version", "cache_key",
           "cached_code", "module_text"]

#: The environment variable that names the cache folder.
ENVIRONMENT_VARIABLE = "CLOSEDLOOP_CACHE_DIR"
#: First words of a cached file's first line, which carries the checksum of the rest.
_HEADER = "# closedloop generated code, do not edit; sha256 of the lines below:"
#: The package's root folder (its source is part of every key).
_PACKAGE_ROOT = Path(__file__).resolve().parent
#: Modules a generated function's global names may come from (besides the one that made it).
_HOMES = ("math", "numpy", "builtins")


def cache_folder():
    """The folder of the cache: ``$CLOSEDLOOP_CACHE_DIR``, ``$XDG_CACHE_HOME/closedloop`` or ``~/.cache/closedloop``."""
    named = os.environ.get(ENVIRONMENT_VARIABLE)
    if named:
        return Path(named).expanduser()
    xdg = os.environ.get("XDG_CACHE_HOME")
    if xdg and os.path.isabs(xdg):
        return Path(xdg) / "closedloop"
    return Path.home() / ".cache" / "closedloop"


def package_fingerprint(leave_out=()):
    """sha256 of the package's source: every ``*.py`` below its root, in path order, as path and bytes.

    Parameters
    ----------
    leave_out : sequence of str, optional
        Paths relative to the package root (``"cli.py"``) to leave out; a folder
        named here (``"plotting"``) leaves out everything below it.

    Returns
    -------
    str
        The hexadecimal digest.  A new module, or a module moved to another
        folder, changes it too; line endings do not.
    """
    digest = hashlib.sha256()
    for path in sorted(_PACKAGE_ROOT.rglob("*.py")):
        relative = path.relative_to(_PACKAGE_ROOT)
        if relative.as_posix() in leave_out or relative.parts[0] in leave_out:
            continue
        digest.update(relative.as_posix().encode() + b"\0" + path.read_bytes().replace(b"\r\n", b"\n") + b"\0")
    return digest.hexdigest()


@lru_cache(maxsize=None)
def source_fingerprint():
    """:func:`package_fingerprint` of the whole package, part of every key; read once per process.

    An edit anywhere in the package changes every key, so no cached function can
    outlive the code that generated it.
    """
    return package_fingerprint()


@lru_cache(maxsize=None)
def sympy_version():
    """The installed sympy's version, read without importing sympy (which takes half a second).

    From the imported module if it is loaded, else from ``sympy/release.py`` beside its
    ``__init__``, else from the package metadata; ``"absent"`` without sympy.
    """
    if "sympy" in sys.modules:
        return sys.modules["sympy"].__version__
    import importlib.util

    spec = importlib.util.find_spec("sympy")
    if spec is None or spec.origin is None:
        return "absent"
    try:
        found = re.search(r"""^__version__\s*=\s*["']([^"']+)["']""",
                          Path(spec.origin).with_name("release.py").read_text(encoding="utf-8"), re.MULTILINE)
    except OSError:
        found = None
    if found:
        return found.group(1)
    from importlib import metadata

    return metadata.version("sympy")


def cache_key(kind, parts):
    """sha256 (hex) naming the code of ``kind`` for ``parts``, this package's source, sympy, Python and numpy.

    Parameters
    ----------
    kind : str
        What is generated (``"model"``, ``"gas_law"``, ...); a valid file-name word.
    parts : tuple of str
        Everything else the generated code depends on.
    """
    digest = hashlib.sha256()
    for part in (kind, source_fingerprint(), sympy_version(), sys.version, numpy.__version__, *parts):
        digest.update(str(part).encode() + b"\0")
    return digest.hexdigest()


def cached_code(kind, parts, generate, names):
    """The generated functions and constants of ``kind`` for ``parts``: from the cache, or generated now.

    Parameters
    ----------
    kind : str
    parts : tuple of str
        See :func:`cache_key`.  A part None says that the code cannot be named by a
        key (it depends on something outside the key): it is generated, not cached.
    generate : callable
        ``generate() -> dict`` of name to generated function (made by ``lambdify``, or
        with its source text as attribute ``source``) or constant (None, bool, int,
        float, str, or tuples of these). Called only when the cache has no valid entry;
        this is where sympy is imported.
    names : sequence of str
        The names ``generate`` returns, all of which a cached entry must define.

    Returns
    -------
    dict
        Name to function or constant. On a miss, the functions come from the very text
        that is written to the cache (or, if some function cannot be written as a
        module, straight from ``generate``, and nothing is cached).
    """
    with one_time():                        # once per system: left out of a run's cpu_time
        return _cached_code(kind, parts, generate, names)


def _cached_code(kind, parts, generate, names):
    if any(part is None for part in parts):
        made = generate()
        return {name: made[name] for name in names}
    key = cache_key(kind, parts)
    folder = cache_folder()
    path = folder / f"{kind}-{key[:32]}.py"
    loaded = _load(path, key, names)
    if loaded is not None:
        return loaded
    made = generate()
    text = module_text(key, made)
    try:
        namespace = None if text is None else _execute(text, path, key)
    except Exception:                   # noqa: BLE001 - the text does not run: use what generate() made
        namespace = None
    if namespace is None or any(name not in namespace for name in names):
        return {name: made[name] for name in names}
    _write(folder, path, text)
    return {name: namespace[name] for name in names}


def _load(path, key, names):
    """The names defined by the cached file at ``path``, or None if it is missing or not valid for ``key``."""
    try:
        text = path.read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError):
        return None
    first, _, body = text.partition("\n")
    if first != f"{_HEADER} {hashlib.sha256(body.encode()).hexdigest()}":
        return None
    try:
        namespace = _execute(text, path, key)
    except Exception:                   # noqa: BLE001 - whatever is wrong with the file, generate it again
        return None
    if namespace.get("KEY") != key or any(name not in namespace for name in names):
        return None
    return {name: namespace[name] for name in names}


def _execute(text, path, key):
    """Run the module text and return its namespace."""
    namespace = {"__name__": f"closedloop.codecache.{path.stem.replace('-', '_')}", "__file__": str(path),
                 "__builtins__": builtins}
    exec(compile(text, str(path), "exec"), namespace)      # noqa: S102 - our own generated code, checked above
    return namespace


def _write(folder, path, text):
    """Write ``text`` to ``path`` atomically; a folder or file that cannot be written is left alone."""
    temporary = path.with_name(f".{path.name}.{os.getpid()}.tmp")
    try:
        folder.mkdir(parents=True, exist_ok=True)
        descriptor = os.open(temporary, os.O_WRONLY | os.O_CREAT | os.O_EXCL, 0o644)
        with os.fdopen(descriptor, "w", encoding="utf-8") as handle:
            handle.write(text)
        os.replace(temporary, path)
    except OSError:
        try:
            temporary.unlink()
        except OSError:
            pass


# -- writing generated code as a module -------------------------------------------------------------
def module_text(key, values):
    """The text of a module that defines ``values`` (see :func:`cached_code`) and ``KEY = key``, or None.

    Each function keeps its own namespace: its source is wrapped in a maker that first
    imports, under the names the function uses, the very objects it found in its own
    globals (``math.sin`` for one, ``numpy.sin`` for another). None if some value is
    neither a literal nor a function whose source and globals can be written so.
    """
    lines = [f"KEY = {key!r}"]
    for name, value in values.items():
        if not name.isidentifier() or name.startswith("_") or name == "KEY":
            return None
        if isinstance(value, types.FunctionType):
            made = _function_text(name, value)
            if made is None:
                return None
            lines.append(made)
        else:
            literal = _literal(value)
            if literal is None:
                return None
            lines.append(f"{name} = {literal}")
    body = "\n".join(lines) + "\n"
    return f"{_HEADER} {hashlib.sha256(body.encode()).hexdigest()}\n{body}"


def _literal(value):
    """Python text for a constant that evaluates to an equal (for floats: identical) value, or None."""
    if value is None or isinstance(value, (bool, int, str)):
        return repr(value)
    if isinstance(value, float):
        return repr(value) if math.isfinite(value) else f"float.fromhex({value.hex()!r})"
    if isinstance(value, (tuple, list)):
        items = [_literal(item) for item in value]
        return None if any(item is None for item in items) else f"({', '.join(items)}{',' if len(items) == 1 else ''})"
    return None


def _function_text(name, function):
    """``_make_name()``, which imports what ``function`` uses and defines it, then ``name = _make_name()``."""
    source = getattr(function, "source", None)
    if source is None:
        try:
            source = inspect.getsource(function)
        except (OSError, TypeError):
            return None
    source = textwrap.dedent(source)
    if not re.match(r"def \w+\(", source) or function.__closure__ or function.__defaults__:
        return None
    source = re.sub(r"\Adef \w+\(", f"def {name}(", source)
    imports = []
    for used in sorted(_global_names(function.__code__)):
        if used not in function.__globals__:
            if not hasattr(builtins, used):
                return None                 # a name the function itself cannot find: do not cache it
            continue
        line = _import_line(used, function.__globals__[used])
        if line is None:
            return None
        imports.append(line)
    inner = "\n".join(imports + [source.rstrip("\n"), f"return {name}"])
    return f"\n\ndef _make_{name}():\n{textwrap.indent(inner, '    ')}\n\n\n{name} = _make_{name}()"


def _global_names(code):
    """Every global name that ``code`` (and the code nested in it) loads."""
    found = {instruction.argval for instruction in dis.get_instructions(code)
             if instruction.opname in ("LOAD_GLOBAL", "LOAD_NAME")}
    for constant in code.co_consts:
        if isinstance(constant, types.CodeType):
            found |= _global_names(constant)
    return found


def _import_line(name, value):
    """A line that binds ``name`` to this very ``value`` (an import or an exact literal), or None."""
    if isinstance(value, (float, int)) and not isinstance(value, bool):
        return f"{name} = {_literal(value)}"
    if isinstance(value, types.ModuleType):
        return f"import {value.__name__} as {name}" if sys.modules.get(value.__name__) is value else None
    homes = [getattr(value, "__module__", None), *_HOMES]
    for home in dict.fromkeys(h for h in homes if isinstance(h, str)):
        module = sys.modules.get(home)
        if module is None:
            continue
        for attribute in dict.fromkeys((getattr(value, "__name__", None), name)):
            if isinstance(attribute, str) and getattr(module, attribute, None) is value:
                return f"from {home} import {attribute} as {name}"
    return None
