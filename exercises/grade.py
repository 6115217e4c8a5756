"""Grade a class's exercise notebooks with the checks of ``exercises/checking`` (issue 15).

    python exercises/grade.py SUBMISSIONS [--chapter NN] [--out DIR] [--timeout S] [--jobs N]
    make grade SUBMISSIONS=DIR [CHAPTER=NN] [OUT=DIR] [TIMEOUT=S] [JOBS=N]

One assignment is one chapter's exercise notebook. Every file in SUBMISSIONS is one student's
submission (a folder holding one .ipynb counts as one too). Each is copied into its own fresh
temporary folder, with a fresh copy of the ``checking`` package, and run there top to bottom in a
fresh kernel: cell by cell with errors allowed (a raising cell does not lose the later checks),
with a time limit on all its cells together (the kernel is killed when it is reached), no network,
HOME and the working directory in that folder (:func:`isolation`). Every ``check(label, answer)``
the notebook runs logs its verdict (``$CHECKING_LOG``, see ``checking/__init__.py``): the grade is
read from that log, so it comes from the same check, and the same words, as the student's feedback.
What the notebook prints is never read: a printed "Exercise 1.4: right." scores nothing.

Scoring: one point per exercise whose **last** check said "right" (a student may try again; a
later wrong answer undoes an earlier right one, as the notebook would show it). An exercise whose
check never ran scores 0, "not checked", with the reason (an error in its cell, the time limit).

Output, in ``--out`` (default ``_build/grade``):

- ``gradebook.csv``: one row per submission: ``submission, status, <one column per exercise of the
  chapter, 1 or 0, in the order of checking.chNN.CHECKS>, total, reason``. Status is ``ok`` (ran to
  its end; errors in cells are named in reason), ``timeout``, ``crashed`` (the kernel died) or
  ``invalid`` (not a notebook, not valid JSON, or a notebook of another chapter; not run);
- ``feedback/<submission>.txt``: per exercise, right / not right yet and the check's hint / not
  answered / not checked and why, then how the run ended.

The chapter is ``--chapter``, or else the one most submissions import their checks from
(``checking.chNN``). A submission that imports another chapter's checks and not this one's is
invalid ("a notebook of chapter 02").

Why not otter-grader or nbgrader (evaluated November 2026, each in a throwaway venv):

- otter-grader 7.0.0 (88 packages with its dependencies, 24 of them not in requirements/lock.txt,
  among them pandas, pydantic, nbconvert, python-on-whales): ``otter grade``, the command with a
  timeout and ``--no-network``, runs every submission in a Docker container (python-on-whales
  drives the docker CLI; no daemon runs here). ``otter run``, without Docker, has neither a time
  limit nor network or file isolation and executes in the submission's own folder. Its grades come
  from its own test files (OK format) run against the notebook's variables after execution: each
  exercise would need a test naming the student's answer variable and calling our check, a second
  place that knows every exercise, and the notebooks would need otter's assignment format.
- nbgrader 0.9.6 (100 packages, 51 not in the lock, among them jupyterlab, jupyter_server,
  notebook, alembic): grading needs a course directory (source/release/submitted/autograded), a
  gradebook database (sqlite by default, through SQLAlchemy and alembic; no server) and nbgrader's
  cell metadata with checksums, written by ``nbgrader generate_assignment``, a second student
  version beside make_student.py's. A grade cell scores from its outputs (an error is 0, a number is
  partial credit), so our cells, which hold the answer and its ``check`` together, would have to be
  split into an answer cell and a locked test cell. Its time limit is per cell (``Execute.timeout``),
  with no total limit and no network or file isolation.

Neither fits without Docker or duplicating the checks, so this builds on nbclient, already a
dependency of the book.
"""

from __future__ import annotations

import argparse
import ast
import csv
import io
import json
import math
import os
import re
import shutil
import subprocess
import sys
import tempfile
import time
from collections import Counter
from dataclasses import dataclass
from pathlib import Path

HERE = Path(__file__).resolve().parent
#: The kernel's start-up script: an IPython kernel behind an audit hook (see grading_guard.py).
GUARD = HERE / "grading_guard.py"
STATUSES = ("ok", "timeout", "crashed", "invalid")
#: A submission larger than this is not read (bytes).
MAX_SIZE = 50_000_000
#: When the grader is root, each submission's kernel runs as a user of its own, drawn from
#: UID_BASE ... UID_BASE + UID_SPAN (no account has these; see isolation()).
UID_BASE, UID_SPAN = 2_000_000_000, 100_000_000
CHECK_CALL = re.compile(r"""\bcheck\(\s*["'](\d+\.\d+)["']""")
CHAPTER_NAMED = re.compile(r"\bchecking\.ch(\d\d)\b|\bfrom\s+checking\s+import\s+ch(\d\d)\b")


@dataclass(frozen=True)
class Outcome:
    """One exercise of one submission.

    Attributes
    ----------
    label : str
        The exercise, e.g. "1.4".
    verdict : str
        The last verdict its check logged (``checking.VERDICTS``), or "not checked".
    detail : str
        What the student is told: the check's own words, or why it was not checked.
    """

    label: str
    verdict: str
    detail: str

    @property
    def score(self) -> int:
        return int(self.verdict == "right")


@dataclass(frozen=True)
class Graded:
    """The grading of one submission.

    Attributes
    ----------
    name : str
        The submission's file (or folder) name.
    status : str
        One of :data:`STATUSES`.
    reason : str
        Why it is not ``ok``, or which cells raised; empty when there is nothing to say.
    seconds : float
        Wall time spent on it: copying, the kernel's start, its cells, reading the log.
    outcomes : tuple of Outcome
        One per exercise of the chapter, in the order of its CHECKS.
    """

    name: str
    status: str
    reason: str
    seconds: float
    outcomes: tuple

    @property
    def total(self) -> int:
        return sum(outcome.score for outcome in self.outcomes)


@dataclass(frozen=True)
class Isolation:
    """How a submission's kernel is kept from the network and from other files.

    Attributes
    ----------
    name : str
        ``"root"``: its own network namespace (``unshare --net``), run as a user of its own that may
        read every file but write only its folder (``setpriv``, no new privileges); ``"user
        namespace"``: its own network namespace in a user namespace (``unshare -rn``, for a grader
        that is not root; files are then kept by the guard only); ``"guard"``: the audit hook of
        grading_guard.py alone, which every kernel has anyway.
    """

    name: str

    def prefix(self, uid):
        """The command that goes before the kernel's, for the kernel that runs as ``uid`` (root only)."""
        if self.name == "root":
            keep = "-all,+dac_read_search"       # read the interpreter and library wherever they are
            return ["unshare", "--net", "--", "setpriv", f"--reuid={uid}", f"--regid={uid}", "--clear-groups",
                    "--no-new-privs", f"--inh-caps={keep}", f"--ambient-caps={keep}", f"--bounding-set={keep}"]
        if self.name == "user namespace":
            return ["unshare", "--user", "--map-root-user", "--net", "--"]
        return []


def isolation(name=None) -> Isolation:
    """The strongest :class:`Isolation` that works here (or the one named), tried with a Python start-up.

    Parameters
    ----------
    name : str, optional
        "root", "user namespace" or "guard"; by default the first of them that works.
    """
    names = [name] if name else (["root"] if os.geteuid() == 0 else []) + ["user namespace", "guard"]
    for candidate in names:
        chosen = Isolation(candidate)
        command = chosen.prefix(UID_BASE) + [sys.executable, "-c", "pass"]
        try:
            if subprocess.run(command, capture_output=True, timeout=60, cwd="/").returncode == 0:
                return chosen
        except (OSError, subprocess.SubprocessError):
            pass
    raise RuntimeError(f"no isolation of {', '.join(names)} works on this machine")


def labels_of(chapter, checking=HERE / "checking"):
    """The exercise labels of ``checking/chNN.py``, in the order of its CHECKS (read, not imported)."""
    path = Path(checking) / f"ch{chapter}.py"
    if not path.exists():
        known = sorted(p.stem[2:] for p in Path(checking).glob("ch[0-9][0-9].py"))
        raise ValueError(f"no checks for chapter {chapter!r} in {checking}; chapters: {', '.join(known)}")
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, ast.Assign) and [getattr(t, "id", None) for t in node.targets] == ["CHECKS"]:
            return [ast.literal_eval(key) for key in node.value.keys]
    raise ValueError(f"{path} defines no CHECKS")


def submissions(folder):
    """The submissions in ``folder``: (name, path of its notebook, or None with the reason), by name."""
    found = []
    for entry in sorted(Path(folder).iterdir()):
        if entry.name.startswith("."):
            continue
        if entry.is_dir():
            notebooks = sorted(entry.glob("*.ipynb"))
            if len(notebooks) == 1:
                found.append((entry.name, notebooks[0], None))
            else:
                found.append((entry.name, None, f"a folder with {len(notebooks)} notebooks, not one"))
        elif entry.is_file():
            found.append((entry.name, entry, None))
    return found


def read_notebook(path):
    """``(notebook, "")`` for a readable notebook at ``path``, else ``(None, why not)``."""
    import nbformat

    if path.stat().st_size > MAX_SIZE:
        return None, f"larger than {MAX_SIZE // 1_000_000} MB"
    raw = path.read_bytes()
    try:
        text = raw.decode("utf-8")
        json.loads(text)
    except (UnicodeDecodeError, ValueError) as error:
        return None, f"not a notebook: not valid JSON ({type(error).__name__})"
    try:
        notebook = nbformat.reads(text, as_version=4)
        if not isinstance(notebook.get("cells"), list):
            raise ValueError("it has no list of cells")
        nbformat.validate(notebook)
    except Exception as error:                # noqa: BLE001 - whatever it is, it is not a notebook we can run
        first = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
        return None, f"not a valid notebook ({first[:120]})"
    return notebook, ""


def chapters_named(notebook):
    """The chapters whose checks ``notebook``'s code imports ("01", ...)."""
    code = "\n".join(cell.source for cell in notebook.cells if cell.cell_type == "code")
    return {a or b for a, b in CHAPTER_NAMED.findall(code)}


def kernel_environment(folder, checking):
    """The kernel's environment: HOME, temporary files and caches in ``folder``, the checks' log there."""
    env = {key: value for key, value in os.environ.items()
           if not key.startswith(("JUPYTER", "IPYTHON", "XDG_", "MPLCONFIG")) and key != "CHECKING_LOG"}
    paths = [os.path.abspath(p) for p in env.get("PYTHONPATH", "").split(os.pathsep) if p]
    instructor = os.path.realpath(Path(checking).parent)
    from closedloop.codecache import cache_folder

    (folder / "tmp").mkdir()
    env.update(HOME=str(folder), TMPDIR=str(folder / "tmp"), PYTHONDONTWRITEBYTECODE="1", MPLBACKEND="Agg",
               PYTHONPATH=os.pathsep.join(p for p in paths if os.path.realpath(p) != instructor),
               CHECKING_LOG=str(folder / ".checks.jsonl"),
               # the grader's generated code, read only: a submission can not leave code there for another
               CLOSEDLOOP_CACHE_DIR=str(cache_folder()))
    return env


def _kernel_manager(prefix, connection_file):
    from jupyter_client.manager import AsyncKernelManager

    class Kernel(AsyncKernelManager):
        """The submission's kernel: grading_guard.py, behind ``prefix``, talking through Unix sockets."""

        def format_kernel_cmd(self, extra_arguments=None):
            return [*prefix, sys.executable, str(GUARD), "-f", self.connection_file, *(extra_arguments or [])]

    return Kernel(kernel_name="python3", transport="ipc", connection_file=str(connection_file))


def execute(notebook, folder, env, timeout, prefix):
    """Run ``notebook``'s code cells in ``folder``, errors allowed, ``timeout`` seconds for all of them.

    Returns
    -------
    status : str
        "ok", "timeout" or "crashed".
    stopped : int or None
        The code cell (numbered from 1) that was running when the run stopped, or None.
    why : str
        What stopped it, for the reason column.
    """
    import nbclient
    from nbclient.exceptions import CellTimeoutError, DeadKernelError

    client = nbclient.NotebookClient(notebook, km=_kernel_manager(prefix, folder / ".kernel.json"),
                                     allow_errors=True, shutdown_kernel="immediate", startup_timeout=120,
                                     resources={"metadata": {"path": str(folder)}})
    number = 0
    try:
        with client.setup_kernel(env=env, cleanup_kc=True):     # shut the kernel down (km is ours)
            deadline = time.monotonic() + timeout
            for index, cell in enumerate(notebook.cells):
                if cell.cell_type != "code":
                    continue
                number += 1
                left = deadline - time.monotonic()
                if left <= 0:
                    raise CellTimeoutError("no time left")
                client.timeout = max(1, math.ceil(left))
                client.execute_cell(cell, index)
    except CellTimeoutError:
        return "timeout", number, f"time limit of {timeout:g} s reached in code cell {number}"
    except DeadKernelError:
        return "crashed", number, f"the kernel died in code cell {number}"
    except Exception as error:                      # noqa: BLE001 - the kernel did not start or answer
        where = f" in code cell {number}" if number else " (it did not start)"
        return "crashed", number or None, f"the kernel failed{where}: {type(error).__name__}: {error}"[:300]
    return "ok", None, ""


def read_log(path, labels):
    """The last logged verdict of each label in ``labels``: {label: (verdict, message)}; bad lines skipped."""
    last = {}
    try:
        lines = Path(path).read_text(encoding="utf-8", errors="replace").splitlines()
    except OSError:
        return last
    for line in lines:
        try:
            entry = json.loads(line)
            label, verdict, message = entry["label"], entry["verdict"], str(entry["message"])
        except (ValueError, KeyError, TypeError):
            continue
        if label in labels:
            last[label] = (verdict, message)
    return last


def cell_errors(notebook):
    """{code cell number (from 1): the exception's name} for every code cell that raised."""
    errors, number = {}, 0
    for cell in notebook.cells:
        if cell.cell_type == "code":
            number += 1
            names = [o.get("ename") for o in cell.get("outputs", []) if o.get("output_type") == "error"]
            if names:
                errors[number] = names[0]
    return errors


def outcomes(labels, logged, notebook, errors, stopped, why):
    """One :class:`Outcome` per label, from the log, else from where its check call is and what happened there."""
    cells = {}                                       # label -> the code cells that call its check
    number = 0
    for cell in notebook.cells:
        if cell.cell_type == "code":
            number += 1
            for label in CHECK_CALL.findall(cell.source):
                cells.setdefault(label, []).append(number)
    result = []
    for label in labels:
        if label in logged:
            verdict, message = logged[label]
            detail = message.split(f"Exercise {label}: ", 1)[-1]
            if verdict == "not answered":
                detail = "not answered: replace the ... with your answer."
            elif verdict == "error":
                detail += " Tell your instructor: this is the book's error, not yours."
            result.append(Outcome(label, verdict, detail))
            continue
        where = cells.get(label, [])
        raised = [n for n in where if n in errors]
        if raised:
            detail = f"not checked: error in code cell {raised[0]} ({errors[raised[0]]})."
        elif where and stopped is not None and stopped <= where[0]:
            detail = f"not checked: the run was stopped ({why})."
        elif where:
            detail = f"not checked: code cell {where[0]} ran without reaching check(\"{label}\", ...)."
        else:
            detail = f"not checked: the notebook has no check(\"{label}\", ...)."
        result.append(Outcome(label, "not checked", detail))
    return tuple(result)


def error_summary(errors):
    """The cells that raised, NotAnswered aside (an unanswered exercise is its own verdict)."""
    real = {n: name for n, name in errors.items() if name != "NotAnswered"}
    if not real:
        return ""
    first = min(real)
    more = f" and {len(real) - 1} more cell{'s' if len(real) > 2 else ''}" if len(real) > 1 else ""
    return f"error in code cell {first} ({real[first]}){more}"


def grade_submission(name, path, why_not, chapter, labels, timeout, isolated, checking, uid=UID_BASE):
    """Grade one submission: copy it and the checks into a fresh folder, run it there, read its log.

    Parameters
    ----------
    name : str
        The submission's name (its row).
    path : Path or None
        Its notebook; None when ``why_not`` says why there is none.
    chapter : str
        The assignment's chapter ("01").
    labels : list of str
        The chapter's exercise labels.
    timeout : float
        Seconds for all the notebook's cells together.
    isolated : Isolation
    checking : Path
        The instructor's ``checking`` package, copied afresh for this submission.
    uid : int
        The user its kernel runs as when ``isolated`` is "root", no other submission's; whatever
        runs as that user when the notebook is done is killed.

    Returns
    -------
    Graded
    """
    start = time.perf_counter()

    def invalid(reason):
        return Graded(name, "invalid", reason, time.perf_counter() - start,
                      tuple(Outcome(label, "not checked", "not checked: the file could not be run.")
                            for label in labels))

    if path is None:
        return invalid(why_not)
    notebook, problem = read_notebook(path)
    if notebook is None:
        return invalid(problem)
    named = chapters_named(notebook)
    if named and chapter not in named:
        return invalid(f"a notebook of chapter {', '.join(sorted(named))} (it imports "
                       f"{', '.join('checking.ch' + n for n in sorted(named))}), not of chapter {chapter}")
    run = Path(tempfile.mkdtemp(prefix="closedloop-grade-"))
    try:
        os.chmod(run, 0o711)                         # its kernel's user may pass, not look around
        folder = run / "submission"
        folder.mkdir(mode=0o700)
        shutil.copyfile(path, folder / path.name)
        shutil.copytree(checking, folder / "checking", ignore=shutil.ignore_patterns("__pycache__"))
        env = kernel_environment(folder, checking)
        if isolated.name == "root":
            for entry in [folder, *folder.rglob("*")]:
                os.lchown(entry, uid, uid)
        try:
            status, stopped, why = execute(notebook, folder, env, timeout, isolated.prefix(uid))
        finally:
            if isolated.name == "root":
                kill_user(uid)                       # what the notebook started and left behind
        logged = read_log(folder / ".checks.jsonl", labels)
    finally:
        shutil.rmtree(run, ignore_errors=True)
    errors = cell_errors(notebook)
    reason = "; ".join(part for part in (why, error_summary(errors)) if part)
    return Graded(name, status, reason, time.perf_counter() - start,
                  outcomes(labels, logged, notebook, errors, stopped, why))


def kill_user(uid):
    """Kill every process that runs as ``uid`` (a submission's own user: see :func:`grade_submission`).

    Waits until none is left (zombies aside: they are dead, waiting for their parent), up to 5 s.
    """
    import signal

    for _ in range(50):
        alive = []
        for status in Path("/proc").glob("[0-9]*/status"):
            try:
                fields = dict(line.split(":", 1) for line in status.read_text().splitlines() if ":" in line)
                if int(fields["Uid"].split()[0]) == uid and not fields["State"].strip().startswith("Z"):
                    alive.append(int(status.parent.name))
            except (OSError, KeyError, ValueError):
                pass                                 # gone meanwhile
        if not alive:
            return
        for pid in alive:
            try:
                os.kill(pid, signal.SIGKILL)
            except OSError:
                pass
        time.sleep(0.1)


def assignment_chapter(found):
    """The chapter most of the ``found`` submissions import their checks from, or ValueError."""
    votes = Counter()
    for _, path, _ in found:
        if path is not None:
            notebook, _ = read_notebook(path)
            named = chapters_named(notebook) if notebook is not None else set()
            if len(named) == 1:
                votes.update(named)
    ranked = votes.most_common()
    if not ranked or (len(ranked) > 1 and ranked[0][1] == ranked[1][1]):
        raise ValueError("can not tell the chapter from the submissions "
                         f"({dict(ranked) or 'none imports checking.chNN'}); name it with --chapter")
    return ranked[0][0]


def gradebook_csv(results, labels):
    """The gradebook's text (see the module docstring)."""
    buffer = io.StringIO()
    writer = csv.writer(buffer, lineterminator="\n")
    writer.writerow(["submission", "status", *labels, "total", "reason"])
    for graded in results:
        writer.writerow([graded.name, graded.status, *(o.score for o in graded.outcomes), graded.total,
                         graded.reason])
    return buffer.getvalue()


def feedback_text(graded, chapter):
    """The student's feedback file: one line per exercise, then how the run ended."""
    lines = [f"Exercise notebook {chapter}: {graded.name}", f"Score: {graded.total} of {len(graded.outcomes)}", ""]
    lines += [f"{o.label}: {o.detail}" for o in graded.outcomes]
    ending = {"ok": "The notebook ran to its end" + (f", with an {graded.reason}." if graded.reason else "."),
              "timeout": f"The notebook was stopped: {graded.reason}.",
              "crashed": f"The notebook was stopped: {graded.reason}.",
              "invalid": f"The file could not be graded: {graded.reason}."}[graded.status]
    return "\n".join(lines + ["", ending]) + "\n"


def grade(folder, out, chapter=None, timeout=300.0, jobs=1, isolated=None, checking=HERE / "checking"):
    """Grade every submission in ``folder``; write ``out``/gradebook.csv and ``out``/feedback/.

    Parameters
    ----------
    folder : path
        The submissions (see :func:`submissions`).
    out : path
        The output folder; its gradebook.csv and feedback/ are replaced.
    chapter : str, optional
        The assignment's chapter ("01" or "1"); by default the one most submissions import.
    timeout : float
        Seconds for all of one notebook's cells together.
    jobs : int
        Submissions graded at once.
    isolated : Isolation, optional
        By default :func:`isolation`'s choice.
    checking : path
        The instructor's ``checking`` package.

    Returns
    -------
    list of Graded
        In the gradebook's order (by submission name).
    """
    if not (timeout > 0 and math.isfinite(timeout)):
        raise ValueError(f"timeout must be a positive number of seconds, got {timeout!r}")
    if chapter is not None and not (str(chapter).isdigit() and len(str(chapter)) <= 2):
        raise ValueError(f"chapter must be a chapter's number such as 03, got {chapter!r}")
    if not (isinstance(jobs, int) and jobs >= 1):
        raise ValueError(f"jobs must be a whole number >= 1, got {jobs!r}")
    folder, out, checking = Path(folder), Path(out), Path(checking).resolve()
    if not folder.is_dir():
        raise ValueError(f"SUBMISSIONS must be a folder, got {str(folder)!r}")
    found = submissions(folder)
    chapter = f"{int(chapter):02d}" if chapter is not None else assignment_chapter(found)
    labels = labels_of(chapter, checking)
    isolated = isolated or isolation()
    import random

    uids = random.SystemRandom().sample(range(UID_BASE, UID_BASE + UID_SPAN), len(found))
    tasks = [(name, path, why, chapter, labels, timeout, isolated, checking, uid)
             for (name, path, why), uid in zip(found, uids)]
    if jobs == 1:
        results = [grade_submission(*task) for task in tasks]
    else:
        from concurrent.futures import ProcessPoolExecutor

        with ProcessPoolExecutor(max_workers=jobs) as pool:
            results = list(pool.map(grade_submission, *zip(*tasks))) if tasks else []
    out.mkdir(parents=True, exist_ok=True)
    feedback = out / "feedback"
    shutil.rmtree(feedback, ignore_errors=True)
    feedback.mkdir()
    for graded in results:
        (feedback / f"{graded.name}.txt").write_text(feedback_text(graded, chapter), encoding="utf-8")
    partial = out / ".gradebook.csv.partial"
    partial.write_text(gradebook_csv(results, labels), encoding="utf-8")
    partial.replace(out / "gradebook.csv")
    return results


def main(argv=None):
    parser = argparse.ArgumentParser(prog="grade.py", description=__doc__.split("\n\n")[0],
                                     formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("submissions", help="folder with one notebook (or one folder holding one) per student")
    parser.add_argument("--chapter", help="the assignment's chapter, e.g. 03 (default: the one the notebooks "
                                          "import their checks from)")
    parser.add_argument("--out", default=str(HERE.parent / "_build" / "grade"),
                        help="output folder for gradebook.csv and feedback/ (default: _build/grade)")
    parser.add_argument("--timeout", type=float, default=300.0,
                        help="seconds for all of one notebook's cells together (default: 300)")
    parser.add_argument("--jobs", type=int, default=1, help="submissions graded at once (default: 1)")
    parser.add_argument("--isolation", choices=["root", "user namespace", "guard"],
                        help="force an isolation (default: the strongest that works, see grade.isolation)")
    args = parser.parse_args(argv)
    try:
        isolated = isolation(args.isolation)
        results = grade(args.submissions, args.out, args.chapter, args.timeout, args.jobs, isolated)
    except (ValueError, RuntimeError) as error:
        parser.exit(2, f"grade.py: error: {error}\n")
    for graded in results:
        print(f"{graded.name}: {graded.status}, {graded.total} of {len(graded.outcomes)}, {graded.seconds:.1f} s"
              + (f" ({graded.reason})" if graded.reason else ""))
    print(f"{len(results)} submissions graded (isolation: {isolated.name}); "
          f"wrote {Path(args.out) / 'gradebook.csv'} and {Path(args.out) / 'feedback'}/")
    return 0


if __name__ == "__main__":
    sys.exit(main())
