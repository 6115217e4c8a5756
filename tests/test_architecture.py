"""The package's architecture: its layers, one home for each list of names, and the old homes that still answer.

The layers: the engine knows no mechanism, study, figure or command; studies draw nothing.

An ``ast`` scan of every module of src/closedloop finds each import, absolute or relative, at
module level or inside a function, and resolves it to the full module name it reaches.

- The engine (every module except ``slider_crank.py``, ``four_bar.py``, ``studies/``,
  ``plotting/``, ``cli.py``, ``output.py`` and the package's ``__init__.py``) never imports
  ``slider_crank``, ``four_bar``, ``studies``, ``plotting`` or ``cli``.
- ``studies/`` never imports ``plotting``, ``cli`` or matplotlib: a study computes, a figure
  draws, so a figure change never touches the benchmark's source fingerprint.
- No module imports sympy, matplotlib or bokeh when it is imported (only inside the functions
  that derive or draw): ``import closedloop`` and a run with cached generated code need none.
- Nor any subpackage of scipy (scipy.integrate imports scipy.optimize, scipy.sparse, scipy.special,
  scipy.linalg: about 0.3 s): a run imports them on first use.

No module reaches a private part of a dependency (a module or name below its top-level package that
starts with ``_``) by an import, an importlib loader or an attribute of an imported module.

Every installed package that the library imports is declared in pyproject.toml's dependencies or its
``plot``/``interactive`` extras, and every one the tests and benchmarks import, in its ``test`` extra.
"""

import ast
import functools
from pathlib import Path

import pytest

import closedloop
import closedloop.methods as methods
from closedloop import simulation
from closedloop.formulations.projected import PROJECTABLE_METHODS
from closedloop.simulation import dop853
from closedloop.studies import baseline, benchmark

PACKAGE_ROOT = Path(closedloop.__file__).resolve().parent
PACKAGE = "closedloop"
NOT_ENGINE = ("slider_crank.py", "slider_crank_gas_law.py", "four_bar.py", "studies", "plotting", "cli.py", "output.py",
              "__init__.py")
ENGINE_MAY_NOT_IMPORT = ("slider_crank", "slider_crank_gas_law", "four_bar", "studies", "plotting", "cli", "output")
STUDIES_MAY_NOT_IMPORT = ("plotting", "cli")


def module_name(path):
    """``closedloop.studies.basin`` for src/closedloop/studies/basin.py; a package is its ``__init__``."""
    parts = path.relative_to(PACKAGE_ROOT).with_suffix("").parts
    if parts[-1] == "__init__":
        parts = parts[:-1]
    return ".".join((PACKAGE, *parts))


def _nodes(tree, at_import):
    """Every node below ``tree`` (``ast.walk``); with ``at_import``, none inside a function body."""
    pending = [tree]
    while pending:
        node = pending.pop()
        yield node
        if at_import and isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef, ast.Lambda)):
            continue
        pending.extend(ast.iter_child_nodes(node))


def imports_of(source, module, is_package=False, at_import=False):
    """Every import in ``source`` as ``(line, statement, full names reached)``, wherever it stands.

    A relative import is resolved against ``module``; ``from X import a`` reaches ``X`` and
    ``X.a`` (a may be a submodule); ``importlib.import_module("...")`` with a constant counts too.
    With ``at_import``, only the imports that run when the module is imported (none in a function).
    """
    package = module if is_package else module.rpartition(".")[0]
    found = []
    for node in _nodes(ast.parse(source), at_import):
        if isinstance(node, ast.Import):
            found.append((node.lineno, ast.unparse(node), [alias.name for alias in node.names]))
        elif isinstance(node, ast.ImportFrom):
            if node.level:
                base = package.split(".")[:len(package.split(".")) - (node.level - 1)]
                origin = ".".join(base + ([node.module] if node.module else []))
            else:
                origin = node.module
            found.append((node.lineno, ast.unparse(node),
                          [origin] + [f"{origin}.{alias.name}" for alias in node.names]))
        elif (isinstance(node, ast.Call) and isinstance(node.func, ast.Attribute)
              and node.func.attr == "import_module" and node.args and isinstance(node.args[0], ast.Constant)):
            found.append((node.lineno, ast.unparse(node), [str(node.args[0].value)]))
    return sorted(found)


def reaches(name, target):
    """True if the full module name ``name`` is ``target`` or lies below it."""
    return name == target or name.startswith(target + ".")


def violations(path, forbidden):
    """``"module, line N: statement"`` for each import of ``path`` that reaches a forbidden layer."""
    module = module_name(path)
    targets = [f"{PACKAGE}.{name}" if name != "matplotlib" else name for name in forbidden]
    return [f"{module}, line {line}: {statement}"
            for line, statement, names in imports_of(path.read_text(encoding="utf-8"), module,
                                                     path.name == "__init__.py")
            if any(reaches(name, target) for name in names for target in targets)]


def is_engine(path):
    relative = path.relative_to(PACKAGE_ROOT)
    return not (relative.parts[0] in NOT_ENGINE or relative.as_posix() == "__init__.py")


MODULES = sorted(PACKAGE_ROOT.rglob("*.py"))
ENGINE = [p for p in MODULES if is_engine(p)]
STUDIES = [p for p in MODULES if p.relative_to(PACKAGE_ROOT).parts[0] == "studies"]


def test_the_layers_are_where_the_rule_says():
    names = {module_name(p) for p in ENGINE}
    assert {"closedloop.model", "closedloop.simulation", "closedloop.simulation.dop853",
            "closedloop.formulations", "closedloop.formulations.minimal", "closedloop.linalg"} <= names
    assert not names & {"closedloop", "closedloop.slider_crank", "closedloop.cli", "closedloop.plotting",
                         "closedloop.output"}
    assert {module_name(p) for p in STUDIES} >= {"closedloop.studies.basin", "closedloop.studies.benchmark",
                                                 "closedloop.studies.readings"}


@pytest.mark.parametrize("path", ENGINE, ids=module_name)
def test_the_engine_imports_no_mechanism_study_figure_or_command(path):
    found = violations(path, ENGINE_MAY_NOT_IMPORT)
    assert not found, "the engine imports an outer layer: " + "; ".join(found)


@pytest.mark.parametrize("path", STUDIES, ids=module_name)
def test_studies_import_no_figure_and_no_command(path):
    found = violations(path, STUDIES_MAY_NOT_IMPORT + ("matplotlib",))
    assert not found, "a study imports figures or the command line: " + "; ".join(found)


@pytest.mark.parametrize("source, module, reached", [
    ("from .slider_crank import CASES", "closedloop.simulation", "closedloop.slider_crank"),
    ("from ..studies.basin import basin_map", "closedloop.formulations.minimal", "closedloop.studies.basin"),
    ("def f():\n    from .. import plotting\n", "closedloop.simulation.dop853", "closedloop.plotting"),
    ("import closedloop.cli as cli", "closedloop.model", "closedloop.cli"),
    ("from closedloop import four_bar", "closedloop.model", "closedloop.four_bar"),
    ("import importlib\nimportlib.import_module('closedloop.plotting.basin')", "closedloop.model",
     "closedloop.plotting.basin"),
])
def test_the_scan_resolves_every_form_of_import(source, module, reached):
    names = {name for _, _, names in imports_of(source, module) for name in names}
    assert reached in names
    assert not any(reaches(name, "closedloop.linalg") for name in names)      # and nothing it does not reach


def test_the_scan_resolves_relative_imports_in_a_package_init():
    """In a package's __init__, ``.`` is the package itself, not its parent."""
    [(line, statement, names)] = imports_of("from .dop853 import run", "closedloop.simulation", is_package=True)
    assert (line, statement, names[0]) == (1, "from .dop853 import run", "closedloop.simulation.dop853")
    [(_, _, names)] = imports_of("from .dop853 import run", "closedloop.simulation.runner")
    assert names[0] == "closedloop.simulation.dop853"


#: Imported only inside the functions that need them, never when a module is imported: sympy (a
#: derivation; the generated code is cached, see closedloop.codecache), matplotlib and bokeh (a figure).
IMPORTED_ONLY_WHEN_NEEDED = ("sympy", "matplotlib", "bokeh")


def is_scipy_subpackage(name):
    """``scipy.integrate``, ``scipy.linalg.lapack``, ...: anything below scipy (scipy itself is cheap)."""
    return name.startswith("scipy.")


def imported_with_the_module(path):
    """``(line, statement)`` of each import of ``path`` that runs when it is imported and reaches sympy,
    matplotlib, bokeh or a subpackage of scipy."""
    return [(line, statement)
            for line, statement, names in imports_of(path.read_text(encoding="utf-8"), module_name(path),
                                                     path.name == "__init__.py", at_import=True)
            if any(is_scipy_subpackage(name) or any(reaches(name, heavy) for heavy in IMPORTED_ONLY_WHEN_NEEDED)
                   for name in names)]


@pytest.mark.parametrize("path", MODULES, ids=module_name)
def test_no_module_imports_sympy_a_figure_library_or_a_scipy_subpackage_when_it_is_imported(path):
    found = [f"line {line}: {statement}" for line, statement in imported_with_the_module(path)]
    assert not found, "imported with the module (import it inside the function that needs it): " + "; ".join(found)


def test_the_scan_finds_a_scipy_subpackage_imported_with_the_module():
    source = ("import scipy\nfrom scipy.integrate import ode\nimport scipy.linalg as la\nfrom scipy import optimize\n"
              "def f():\n    from scipy.optimize import brentq\n")
    found = [statement for _, statement, names in imports_of(source, "closedloop.simulation.dop853", at_import=True)
             if any(is_scipy_subpackage(name) for name in names)]
    assert found == ["from scipy.integrate import ode", "import scipy.linalg as la", "from scipy import optimize"]


def test_the_scan_at_import_leaves_out_function_bodies_only():
    source = ("import sympy\nclass A:\n    import matplotlib\n    def f(self):\n        import bokeh\n"
              "def g():\n    import numpy\n")
    names = {name for _, _, names in imports_of(source, "closedloop.model", at_import=True) for name in names}
    assert names == {"sympy", "matplotlib"}
    assert {name for _, _, names in imports_of(source, "closedloop.model") for name in names} == \
        {"sympy", "matplotlib", "bokeh", "numpy"}


# -- dependencies through their public interfaces only --------------------------------------------
#: Calls that load a module by name: the name is their first argument (a constant, or a module-level name
#: bound to one).
LOADERS = ("import_module", "__import__", "find_spec", "spec_from_file_location", "ExtensionFileLoader",
           "SourceFileLoader", "SourcelessFileLoader")

#: Private parts of dependencies the package reaches: ``(module, name) -> why``; none since issue 35 (the compiled
#: DOP853 through scipy.integrate.ode and DOP853's public class attributes, the time symbol as sympy.Symbol("t")).
#: A new entry needs a reason that no public interface serves.
KNOWN_PRIVATE = {}


def is_private(name):
    """True if ``name`` reaches a private part of an installed dependency: a component after the top-level package
    that starts with ``_`` (dunder names such as ``__version__`` aside).  The standard library and the package's
    own modules are not dependencies."""
    import sys

    top, *rest = name.split(".")
    if not rest or top in sys.stdlib_module_names or top == PACKAGE:
        return False
    return any(part.startswith("_") and not (part.startswith("__") and part.endswith("__")) for part in rest)


def _dotted(node):
    """``a.b.c`` for a chain of attributes on a name, else None."""
    parts = []
    while isinstance(node, ast.Attribute):
        parts.append(node.attr)
        node = node.value
    return ".".join([node.id, *reversed(parts)]) if isinstance(node, ast.Name) else None


def names_reached(source, module, is_package=False):
    """Every dotted name ``source`` reaches, as ``(line, name)``: its imports (:func:`imports_of`), the module
    names given to importlib's loaders (:data:`LOADERS`) as constants or module-level names of constants, and the
    attributes it reads on a module it imported (``mpl._api``, ``me.dynamicsymbols._t``)."""
    tree = ast.parse(source)
    found = [(line, name) for line, _, names in imports_of(source, module, is_package) for name in names]
    constants = {target.id: node.value.value for node in tree.body if isinstance(node, ast.Assign)
                 and isinstance(node.value, ast.Constant) and isinstance(node.value.value, str)
                 for target in node.targets if isinstance(target, ast.Name)}
    aliases = {}
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for alias in node.names:
                aliases[alias.asname or alias.name.partition(".")[0]] = alias.name if alias.asname else \
                    alias.name.partition(".")[0]
        elif isinstance(node, ast.ImportFrom) and not node.level:
            for alias in node.names:
                aliases[alias.asname or alias.name] = f"{node.module}.{alias.name}"
    for node in ast.walk(tree):
        if isinstance(node, ast.Call) and node.args:
            callee = node.func.attr if isinstance(node.func, ast.Attribute) else getattr(node.func, "id", None)
            first = node.args[0]
            if callee in LOADERS:
                if isinstance(first, ast.Constant) and isinstance(first.value, str):
                    found.append((node.lineno, first.value))
                elif isinstance(first, ast.Name) and first.id in constants:
                    found.append((node.lineno, constants[first.id]))
        elif isinstance(node, ast.Attribute) and isinstance(node.ctx, ast.Load):
            dotted = _dotted(node)
            head, _, rest = (dotted or "").partition(".")
            if head in aliases:
                found.append((node.lineno, f"{aliases[head]}.{rest}"))
    return sorted(set(found))


def private_parts(path):
    """``{(module, name): [line, ...]}``: the private parts of dependencies the module at ``path`` reaches."""
    module = module_name(path)
    found = {}
    for line, name in names_reached(path.read_text(encoding="utf-8"), module, path.name == "__init__.py"):
        if is_private(name):
            found.setdefault((module, name), []).append(line)
    return found


@functools.cache
def private_parts_of_the_package():
    found = {}
    for path in MODULES:
        found.update(private_parts(path))
    return found


@pytest.mark.parametrize("source, reached", [
    ("import matplotlib._animation_data", "matplotlib._animation_data"),
    ("from matplotlib._animation_data import JS_INCLUDE", "matplotlib._animation_data"),
    ("from matplotlib.animation import _embedded_frames", "matplotlib.animation._embedded_frames"),
    ("def f():\n    from scipy.integrate import _dop\n", "scipy.integrate._dop"),
    ("import importlib\nimportlib.import_module('scipy.integrate._ode')", "scipy.integrate._ode"),
    ("import importlib.util\nNAME = 'scipy.integrate._dop'\nspec = importlib.util.spec_from_file_location(NAME, p)",
     "scipy.integrate._dop"),
    ("from importlib.machinery import ExtensionFileLoader\nNAME = 'scipy.integrate._dop'\n"
     "loader = ExtensionFileLoader(NAME, path)", "scipy.integrate._dop"),
    ("import matplotlib as mpl\nmpl._api.check_in_list([1], x=1)", "matplotlib._api.check_in_list"),
    ("import sympy.physics.mechanics as me\nt = me.dynamicsymbols._t", "sympy.physics.mechanics.dynamicsymbols._t"),
    ("import numpy\nx = numpy._core.multiarray", "numpy._core.multiarray"),
])
def test_the_scan_finds_every_way_to_reach_a_private_part(source, reached):
    names = [name for _, name in names_reached(source, "closedloop.plotting.player")]
    assert reached in names and is_private(reached)


def test_the_scan_leaves_public_names_the_standard_library_and_the_package_alone():
    source = ("import numpy as np\nfrom scipy.integrate import solve_ivp\nimport scipy\nv = scipy.__version__\n"
              "from __future__ import annotations\nimport importlib\nimportlib.import_module('scipy.integrate')\n"
              "from ._local import install\nfrom .redundant import _Stabilised\nimport os\nos._exit\n"
              "x = np.linalg.solve\nclass A(solve_ivp):\n    def f(self):\n        return self._g\n")
    names = [name for _, name in names_reached(source, "closedloop.formulations.closed_form")]
    assert {"scipy.integrate.solve_ivp", "scipy.__version__", "closedloop.formulations._local.install",
            "numpy.linalg.solve",
            "os._exit", "scipy.integrate"} <= set(names)
    assert [name for name in names if is_private(name)] == []


def test_the_package_reaches_dependencies_through_public_names_only():
    """No module imports, loads or reads a private part of numpy, scipy, matplotlib, sympy, bokeh or any other
    installed dependency, but those of :data:`KNOWN_PRIVATE`, each of which is still needed."""
    found = private_parts_of_the_package()
    new = {f"{module}: {name} (line {', '.join(map(str, lines))})" for (module, name), lines in found.items()
           if (module, name) not in KNOWN_PRIVATE}
    assert not new, "private parts of dependencies reached (use their public interface): " + "; ".join(sorted(new))
    gone = set(KNOWN_PRIVATE) - set(found)
    assert not gone, f"no longer reached, take them out of KNOWN_PRIVATE: {sorted(gone)}"


def test_no_private_part_of_a_dependency_is_reached():
    assert KNOWN_PRIVATE == {}
    assert private_parts_of_the_package() == {}


# -- one home for each list of names ------------------------------------------------------------
def test_every_list_of_methods_comes_from_one_place():
    assert simulation.SOLVER_METHODS == methods.SOLVER_METHODS
    assert methods.SOLVER_METHODS == ("RK45", "RK23", "DOP853", "Radau", "BDF", "LSODA", "ode.dop853")
    assert dop853.METHOD == methods.COMPILED_METHOD
    assert list(PROJECTABLE_METHODS) == ["RK23", "RK45", "DOP853"]
    assert baseline.BASELINE_METHODS == methods.SOLVE_IVP_METHODS
    assert benchmark.ALL_METHODS == ("RK45", "DOP853", "Radau", "BDF", "LSODA", "ode.dop853")
    assert benchmark.EXPLICIT_RK == ("RK45", "DOP853")


def formulation_names_typed(path):
    """The registry names of formulations (``"closed-form"``) typed as a string in the module at ``path``."""
    from closedloop.formulations import REGISTRY

    return sorted((node.lineno, node.value) for node in ast.walk(ast.parse(path.read_text(encoding="utf-8")))
                  if isinstance(node, ast.Constant) and isinstance(node.value, str) and node.value in REGISTRY)


def test_no_formulation_name_is_typed_outside_its_own_file():
    """A formulation's name is typed once, as its class attribute: everything else asks the registry or the class."""
    from closedloop.formulations import REGISTRY

    own = {}
    for name, cls in REGISTRY.items():
        own.setdefault(Path(__import__(cls.__module__, fromlist=["_"]).__file__).resolve(), set()).add(name)
    typed = {}
    for path in MODULES:
        found = [(line, value) for line, value in formulation_names_typed(path)
                 if value not in own.get(path.resolve(), set())]
        if found:
            typed[path.relative_to(PACKAGE_ROOT).as_posix()] = found
    assert typed == {}
    assert len(formulation_names_typed(PACKAGE_ROOT / "formulations" / "redundant.py")) == 4     # the scan sees them


def test_the_solver_classes_are_made_on_first_use_and_are_scipy_s():
    import scipy.integrate

    from closedloop.formulations import projected
    from closedloop.simulation import solve_ivp_runner

    assert methods.solver_classes() is methods.SOLVER_CLASSES is solve_ivp_runner.SOLVER_CLASSES
    assert list(methods.SOLVER_CLASSES) == list(methods.SOLVE_IVP_METHODS)
    assert methods.SOLVER_CLASSES["DOP853"] is scipy.integrate.DOP853
    assert methods.SOLVER_CLASSES["LSODA"] is scipy.integrate.LSODA
    assert projected.PROJECTABLE_METHODS is PROJECTABLE_METHODS
    assert PROJECTABLE_METHODS["RK23"] is scipy.integrate.RK23
    assert solve_ivp_runner.solve_ivp is scipy.integrate.solve_ivp        # tests/test_validation.py replaces it
    assert "SOLVER_CLASSES" in dir(methods)
    for module in (methods, solve_ivp_runner, projected):
        with pytest.raises(AttributeError, match="no_such_name"):
            module.no_such_name


# -- every package imported is declared -----------------------------------------------------------
REPOSITORY = PACKAGE_ROOT.parents[1]


def declared_distributions():
    """``(library, tests)``: the normalised names of the distributions pyproject.toml declares for the library
    (its dependencies and its ``plot`` and ``interactive`` extras), and those its ``test`` extra adds."""
    import tomllib

    from packaging.requirements import Requirement
    from packaging.utils import canonicalize_name

    project = tomllib.loads((REPOSITORY / "pyproject.toml").read_text(encoding="utf-8"))["project"]
    extras = project["optional-dependencies"]

    def names(requirements):
        return {canonicalize_name(Requirement(text).name) for text in requirements}

    return names(project["dependencies"] + extras["plot"] + extras["interactive"]), names(extras["test"])


@functools.cache
def _owners():
    """``{top-level module: [distribution, ...]}`` of the environment, read once (it reads every installed
    distribution's file list, 0.1 s a time: called per scanned file, it took 28 s of the tests)."""
    from importlib.metadata import packages_distributions

    return packages_distributions()


def distributions_imported(source):
    """``{distribution: [line, ...]}`` for every installed distribution that ``source`` imports, at any level."""
    import sys

    from packaging.utils import canonicalize_name

    owners = _owners()
    found = {}
    for line, _, names in imports_of(source, "script"):
        for top in {name.partition(".")[0] for name in names}:     # `import a, b` reaches both
            if top and top not in sys.stdlib_module_names and top != PACKAGE:
                for distribution in owners.get(top, ()):
                    found.setdefault(canonicalize_name(distribution), []).append(line)
    return found


def third_party_imports(paths):
    """``{distribution: ["path:line", ...]}`` for every installed distribution that ``paths`` import."""
    found = {}
    for path in paths:
        for distribution, lines in distributions_imported(path.read_text(encoding="utf-8")).items():
            found.setdefault(distribution, []).extend(f"{path.relative_to(REPOSITORY)}:{line}" for line in lines)
    return found


def test_the_dependency_scan_finds_every_name_of_an_import_and_skips_the_standard_library_and_local_modules():
    source = "import json, psutil\nfrom .conftest import x\nfrom numpy.linalg import solve\nimport closedloop\n"
    assert distributions_imported(source) == {"psutil": [1], "numpy": [3]}


def test_every_package_the_library_imports_is_declared_for_it():
    library, _ = declared_distributions()
    undeclared = {name: where for name, where in third_party_imports(MODULES).items() if name not in library}
    assert not undeclared, f"imported by the library but not in pyproject.toml's dependencies: {undeclared}"


def test_every_package_the_tests_and_benchmarks_import_is_declared_for_them():
    """psutil, for one, came in only as ipykernel's dependency until the test extra named it."""
    library, tests = declared_distributions()
    scripts = sorted((REPOSITORY / "tests").glob("*.py")) + sorted((REPOSITORY / "benchmarks").glob("*.py"))
    used = third_party_imports(scripts)
    assert {"psutil", "hypothesis", "numpy"} <= set(used)          # the scan finds them
    undeclared = {name: where for name, where in used.items() if name not in library | tests}
    assert not undeclared, f"imported by the tests or benchmarks but not in the test extra: {undeclared}"


# -- old homes ----------------------------------------------------------------------------------
def test_the_old_home_of_reading_outcomes_warns_and_gives_the_study():
    """Readers' code of 0.1 imported the study from the mechanism; it still works, with a warning."""
    import closedloop.slider_crank as slider_crank
    from closedloop.studies.readings import reading_outcomes

    with pytest.warns(DeprecationWarning, match=r"moved to closedloop\.studies\.readings"):
        old = slider_crank.reading_outcomes
    assert old is reading_outcomes
    assert "reading_outcomes" not in slider_crank.__all__ and "ReadingOutcome" not in slider_crank.__all__
    with pytest.raises(AttributeError, match="no_such_name"):
        slider_crank.no_such_name
