"""Start-up cost of the ``closedloop`` command, before and after the disk cache of generated code (issue 14).

    PYTHONPATH=src python benchmarks/cli_time.py [--before REV] [--repeats 5]

Compares two versions of the package in one run, interleaved, on a noisy machine:

- *before*: the package at git revision ``REV`` (default :data:`BEFORE`, main before the cache),
  unpacked into a temporary folder with ``git archive``;
- *after*: the package beside this script (``src/closedloop``).

It prints, for each version,

1. the top entries of ``python -X importtime -c "import closedloop.cli"`` (by cumulative
   time, from the fastest of three imports) and its self time summed per top-level package;
2. the wall and CPU time of ``closedloop simulate --case 2`` (a new interpreter, import included),
   best of ``--repeats`` runs with a warm cache (one run first fills it), the two versions
   taking turns; and, as floors measured in the same turns, an interpreter that only imports
   ``scipy.integrate`` (which ``solve_ivp`` needs, and, since issue 35, ``ode.dop853`` too: the
   compiled DOP853 through the public ``scipy.integrate.ode``), one that only imports numpy (the
   floor of a run with ``ode.dop853`` from issue 14 to issue 35, which loaded scipy's private
   extension from its file) and one that does nothing.

Then whether the after version's ``simulate --case 2`` imported sympy, matplotlib, and which
modules of scipy.
The cache folder is a temporary one (``CLOSEDLOOP_CACHE_DIR``), removed at the end.

Bytecode: an installed package imports its modules from cached bytecode. So that both versions
are measured that way without writing ``__pycache__`` folders into any source tree, the commands
run with bytecode written to a temporary ``PYTHONPYCACHEPREFIX`` (the warm-up run fills it),
whatever ``PYTHONDONTWRITEBYTECODE`` says; ``--no-bytecode`` compiles every import instead.
"""

from __future__ import annotations

import argparse
import collections
import io
import os
import resource
import subprocess
import sys
import tarfile
import tempfile
import time
from pathlib import Path

#: main before the disk cache: the version the lead's "before" figures refer to.
BEFORE = "0580c6d"
ROOT = Path(__file__).resolve().parents[1]
SIMULATE = "import sys; from closedloop.cli import main; sys.exit(main())"
PACKAGES = ("numpy", "scipy", "sympy", "matplotlib", "closedloop")


def unpack(revision, folder):
    """``src/closedloop`` at ``revision`` into ``folder/src``; returns that ``src`` folder."""
    archive = subprocess.run(["git", "-C", str(ROOT), "archive", revision, "src/closedloop"],
                             check=True, capture_output=True).stdout
    with tarfile.open(fileobj=io.BytesIO(archive)) as tar:
        tar.extractall(folder, filter="data")
    return Path(folder) / "src"


#: Environment of every command (set by main): the cache folder and how bytecode is kept.
ENVIRONMENT = {}


def run(arguments, source, cache, check=True):
    """``(wall [s], CPU [s], stderr)`` of ``python arguments`` with ``source`` first on the path.

    CPU is the child's user + system time: what the command costs, less sensitive than the
    wall time to other processes sharing the cores.
    """
    environment = dict(os.environ, PYTHONPATH=str(source), CLOSEDLOOP_CACHE_DIR=str(cache), **ENVIRONMENT)
    if "PYTHONPYCACHEPREFIX" in ENVIRONMENT:
        environment.pop("PYTHONDONTWRITEBYTECODE", None)
    before = resource.getrusage(resource.RUSAGE_CHILDREN)
    start = time.perf_counter()
    done = subprocess.run([sys.executable, *arguments], env=environment, capture_output=True, text=True,
                          check=check)
    wall = time.perf_counter() - start
    after = resource.getrusage(resource.RUSAGE_CHILDREN)
    return wall, (after.ru_utime - before.ru_utime) + (after.ru_stime - before.ru_stime), done.stderr


def import_times(source, cache):
    """``[(cumulative us, self us, module)]`` of the fastest of three ``import closedloop.cli``."""
    best = None
    for _ in range(3):
        _, _, err = run(["-X", "importtime", "-c", "import closedloop.cli"], source, cache)
        rows = []
        for line in err.splitlines():
            fields = line.split("|")
            if len(fields) == 3 and fields[0].startswith("import time:") and fields[1].strip().isdigit():
                rows.append((int(fields[1]), int(fields[0].split(":")[1]), fields[2].strip()))
        if best is None or max(rows)[0] < max(best)[0]:
            best = rows
    return best


def report_imports(label, rows, top):
    print(f"\n{label}: python -X importtime -c 'import closedloop.cli' (fastest of 3)")
    print(f"  {'cumulative':>10}  {'self':>8}  module")
    for cumulative, own, name in sorted(rows, reverse=True)[:top]:
        print(f"  {cumulative / 1e3:8.1f} ms  {own / 1e3:5.1f} ms  {name}")
    sums = collections.Counter()
    for _, own, name in rows:
        top_level = name.split(".")[0]
        sums[top_level if top_level in PACKAGES else "other"] += own
    print("  self time per package: " + ", ".join(f"{name} {value / 1e3:.0f} ms" for name, value in sums.most_common()))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--before", default=BEFORE, help=f"git revision of the 'before' version (default {BEFORE})")
    parser.add_argument("--repeats", type=int, default=5, help="runs of each command, best taken (default 5)")
    parser.add_argument("--top", type=int, default=12, help="importtime entries shown (default 12)")
    parser.add_argument("--no-bytecode", action="store_true", help="compile every import (no bytecode cache)")
    args = parser.parse_args()

    with tempfile.TemporaryDirectory(prefix="cli-time-") as folder:
        cache = Path(folder) / "cache"
        if args.no_bytecode:
            ENVIRONMENT["PYTHONDONTWRITEBYTECODE"] = "1"
        else:
            ENVIRONMENT["PYTHONPYCACHEPREFIX"] = str(Path(folder) / "bytecode")
        print("bytecode: " + ("none, every import compiled" if args.no_bytecode else
                              "cached in a temporary PYTHONPYCACHEPREFIX, as an installed package has it"))
        versions = {f"before ({args.before})": unpack(args.before, Path(folder) / "before"),
                    "after (this checkout)": ROOT / "src"}
        for source in versions.values():       # fill the caches of code and bytecode (the old version has none)
            run(["-c", SIMULATE, "simulate", "--case", "2"], source, cache)
        run(["-c", "import scipy.integrate"], ROOT / "src", cache)

        for label, source in versions.items():
            report_imports(label, import_times(source, cache), args.top)

        commands = {label: (["-c", SIMULATE, "simulate", "--case", "2"], source)
                    for label, source in versions.items()}
        commands["floor: import scipy.integrate"] = (["-c", "import scipy.integrate"], ROOT / "src")
        commands["floor: import numpy"] = (["-c", "import numpy"], ROOT / "src")
        commands["floor: python -c pass"] = (["-c", "pass"], ROOT / "src")
        best = {label: [float("inf"), float("inf")] for label in commands}
        for _ in range(args.repeats):                         # interleaved: every command in every turn
            for label, (arguments, source) in commands.items():
                wall, cpu, _ = run(arguments, source, cache)
                best[label] = [min(best[label][0], wall), min(best[label][1], cpu)]
        print(f"\nclosedloop simulate --case 2, warm cache, best of {args.repeats} (interleaved):")
        print(f"  {'':32s} {'wall':>7s}  {'CPU':>7s}")
        for label, (wall, cpu) in best.items():
            print(f"  {label:32s} {wall:6.3f} s  {cpu:6.3f} s")
        (before_wall, before_cpu), (after_wall, after_cpu) = (best[label] for label in versions)
        print(f"  after / before = {after_wall / before_wall:.2f} (wall), {after_cpu / before_cpu:.2f} (CPU)")
        numpy_wall, numpy_cpu = best["floor: import numpy"]
        print(f"  after - numpy floor = {after_wall - numpy_wall:.3f} s (wall), {after_cpu - numpy_cpu:.3f} s (CPU)")

        probe = ("import sys, io, contextlib\nfrom closedloop.cli import main\n"
                 "with contextlib.redirect_stdout(io.StringIO()): main(['simulate', '--case', '2'])\n"
                 "scipy = sorted(name for name in sys.modules if name.startswith('scipy.'))\n"
                 "print('sympy' in sys.modules, 'matplotlib' in sys.modules, ','.join(scipy) or 'none', "
                 "file=sys.stderr)")
        _, _, err = run(["-c", probe], ROOT / "src", cache)
        sympy_loaded, matplotlib_loaded, scipy_loaded = err.split()[-3:]
        print(f"\nafter, simulate --case 2 with a warm cache: sympy imported: {sympy_loaded}, "
              f"matplotlib imported: {matplotlib_loaded}, scipy's modules: {scipy_loaded}")


if __name__ == "__main__":
    main()
