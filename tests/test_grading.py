"""Grading a class's exercise notebooks (exercises/grade.py): a generated class and its exact gradebook.

The submissions are made from exercise page 01 with the real tools: its reference solution (the page
converted by jupytext), its student version (make_student.py), and variants of the reference: wrong
answers (each check's own ``wrong_example``), a cell that raises, one that kills its kernel, one that
loops forever, one that deletes files, one that tries the network, printed fake verdicts and
repeated checks; besides them, random bytes and a notebook of chapter 2. Every cell of the
gradebook is asserted.
"""

import hashlib
import importlib
import os
import random
import socket
import sys
import threading
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXERCISES = ROOT / "exercises"
sys.path.insert(0, str(EXERCISES))
grade = importlib.import_module("grade")
make_student = importlib.import_module("make_student")
CHECKS = importlib.import_module("checking.ch01").CHECKS
SOURCE = EXERCISES / "01-closed-loop-systems.md"
LABELS = list(CHECKS)
#: Seconds for all of a notebook's cells: page 01 runs in about two (five with the book building beside
#: the tests); the looping notebook takes all of it, on a core of its own.
TIMEOUT = 10
#: A file a submission tries to create in the instructor's repository (it must never exist).
PLANTED = EXERCISES / ".planted-by-a-submission"


# --- making submissions -----------------------------------------------------------------------------
def reference():
    """Page 01 with its solutions, as a notebook (jupytext), fresh for every variant."""
    import jupytext

    return jupytext.read(SOURCE)


def check_cell(notebook, label):
    """The code cell that runs ``check(label, ...)``, and its number among the code cells (from 1)."""
    code = [cell for cell in notebook.cells if cell.cell_type == "code"]
    number = next(n for n, cell in enumerate(code, 1) if f'check("{label}",' in cell.source)
    return code[number - 1], number


def code_cells(notebook):
    return sum(cell.cell_type == "code" for cell in notebook.cells)


def prepend_code(notebook, source):
    """``notebook`` with a code cell holding ``source`` before its first code cell."""
    import nbformat

    first = next(i for i, cell in enumerate(notebook.cells) if cell.cell_type == "code")
    notebook.cells.insert(first, nbformat.v4.new_code_cell(source))
    return notebook


def with_wrong_answers(notebook, labels):
    """Before each ``check(label, name)`` of ``labels``, ``name`` becomes the check's own wrong example."""
    for label in labels:
        cell, _ = check_cell(notebook, label)
        call = next(line for line in cell.source.splitlines() if line.startswith(f'check("{label}",'))
        name = call.split(",", 1)[1].strip(" )")
        wrong = (f'from checking.ch01 import CHECKS\n'
                 f'{name} = CHECKS["{label}"].wrong_example(CHECKS["{label}"].expected_value())\n')
        cell.source = cell.source.replace(call, wrong + call)
    return notebook


def deleting(instructor, submitted):
    """A submission that first tries to delete and plant files everywhere it should not, its own checks too."""
    return prepend_code(reference(), f"""
import os, shutil
tried = {{}}
def attempt(what, action):
    try:
        action()
        tried[what] = "done"
    except Exception as error:
        tried[what] = type(error).__name__
attempt("instructor's checks", lambda: shutil.rmtree({str(instructor)!r}))
attempt("a submission", lambda: os.remove({str(submitted / "reference.ipynb")!r}))
attempt("every submission", lambda: shutil.rmtree({str(submitted)!r}))
attempt("a file in the repository", lambda: open({str(PLANTED)!r}, "w").write("x"))
attempt("the parent folder", lambda: shutil.rmtree(".."))
attempt("its own checks", lambda: shutil.rmtree("checking"))
print(tried)
""")


def networking(port, c_level):
    """The reference, unless it reaches ``port`` on 127.0.0.1: then 1.4's answer is wrong (1.5's from C)."""
    notebook = prepend_code(reference(), f"""
import socket
try:
    socket.create_connection(("127.0.0.1", {port}), timeout=5).close()
    reached = True
except OSError:
    reached = False
reached_from_c = False
if {c_level}:                          # around Python's socket module, and so around the audit hook
    import ctypes, struct
    libc = ctypes.CDLL(None, use_errno=True)
    address = struct.pack("=H", socket.AF_INET) + struct.pack("!H", {port}) + socket.inet_aton("127.0.0.1") + bytes(8)
    reached_from_c = libc.connect(libc.socket(socket.AF_INET, socket.SOCK_STREAM, 0), address, len(address)) == 0
print(reached, reached_from_c)
""")
    for label, flag in (("1.4", "reached"), ("1.5", "reached_from_c")):
        cell, _ = check_cell(notebook, label)
        name = cell.source.split(f'check("{label}", ', 1)[1].split(")")[0]
        cell.source = cell.source.replace(f'check("{label}", {name})',
                                          f'check("{label}", {name} if not {flag} else "wrong")')
    return notebook


def faking(notebook):
    """1.4 prints a fake verdict instead of checking; 1.5 is checked right then wrong; 1.6 wrong then right."""
    cell, _ = check_cell(notebook, "1.4")
    cell.source = cell.source.replace('check("1.4", f)', 'print("Exercise 1.4: right.")')
    for label, (first, last) in {"1.5": ("right", "wrong"), "1.6": ("wrong", "right")}.items():
        cell, _ = check_cell(notebook, label)
        call = next(line for line in cell.source.splitlines() if line.startswith(f'check("{label}",'))
        name = call.split(",", 1)[1].strip(" )")
        answer = {"right": name, "wrong": f'CHECKS["{label}"].wrong_example(CHECKS["{label}"].expected_value())'}
        cell.source = cell.source.replace(call, f'from checking.ch01 import CHECKS\ncheck("{label}", {answer[first]})\n'
                                                f'check("{label}", {answer[last]})')
    return notebook


def planted():
    """Whether a submission could create PLANTED; it is removed, so that a failed run leaves nothing."""
    found = PLANTED.exists()
    PLANTED.unlink(missing_ok=True)
    return found


def write(notebook, path):
    import jupytext

    jupytext.write(notebook, path, fmt="ipynb")


class Listener:
    """A TCP server on 127.0.0.1 that counts the connections it accepts."""

    def __init__(self):
        self.server = socket.create_server(("127.0.0.1", 0))
        self.server.settimeout(0.2)
        self.port, self.accepted, self.stop = self.server.getsockname()[1], 0, threading.Event()
        self.thread = threading.Thread(target=self.serve, daemon=True)
        self.thread.start()

    def serve(self):
        while not self.stop.is_set():
            try:
                connection, _ = self.server.accept()
            except OSError:
                continue
            self.accepted += 1
            connection.close()

    def close(self):
        self.stop.set()
        self.thread.join()
        self.server.close()


LEAVE_A_PROCESS = """import os, time
if os.fork() == 0:
    os.setsid()
    time.sleep(3600)
"""


def graders_users():
    """The live processes (not zombies) that run as one of the users the grader gives submissions."""
    found = []
    for status in Path("/proc").glob("[0-9]*/status"):
        try:
            fields = dict(line.split(":", 1) for line in status.read_text().splitlines() if ":" in line)
            uid, state = int(fields["Uid"].split()[0]), fields["State"].strip()
        except (OSError, KeyError, ValueError):
            continue
        if grade.UID_BASE <= uid < grade.UID_BASE + grade.UID_SPAN and not state.startswith("Z"):
            found.append(int(status.parent.name))
    return found


def snapshot(folder):
    """{relative path: sha256} of every file below ``folder``."""
    return {str(p.relative_to(folder)): hashlib.sha256(p.read_bytes()).hexdigest()
            for p in sorted(Path(folder).rglob("*")) if p.is_file()}


@pytest.fixture(scope="module")
def isolated():
    return grade.isolation()


@pytest.fixture
def instructor(tmp_path):
    """A copy of the instructor's checks, which the grader copies from and a submission tries to delete."""
    import shutil

    copy = tmp_path / "instructor" / "checking"
    shutil.copytree(EXERCISES / "checking", copy, ignore=shutil.ignore_patterns("__pycache__"))
    return copy


def read_rows(path):
    import csv

    with open(path, newline="") as handle:
        return list(csv.reader(handle))


# --- the class --------------------------------------------------------------------------------------
def test_a_class_is_graded_exactly(tmp_path, instructor, isolated):
    submitted = tmp_path / "submitted"
    submitted.mkdir()
    listener = Listener()
    c_level = isolated.name != "guard"                 # the guard alone does not stop C code
    write(reference(), submitted / "reference.ipynb")
    write(make_student.student_notebook(SOURCE), submitted / "student.ipynb")
    write(with_wrong_answers(reference(), ["1.5", "1.7"]), submitted / "wrong.ipynb")
    raising = reference()
    cell, raises_in = check_cell(raising, "1.6")
    cell.source = 'raise ValueError("a student\'s bug")\n' + cell.source
    write(raising, submitted / "raises.ipynb")
    crashing = reference()
    cell, crashes_in = check_cell(crashing, "1.6")
    cell.source = "import os\nos._exit(3)\n" + cell.source     # the kernel dies
    write(crashing, submitted / "crashes.ipynb")
    looping = reference()
    cell, loops_in = check_cell(looping, "1.7")
    cell.source = "while True:\n    pass\n" + cell.source
    if isolated.name == "root":                        # and leaves a process of its own, out of its group
        cell.source = LEAVE_A_PROCESS + cell.source
    write(looping, submitted / "loops.ipynb")
    deletes = deleting(instructor, submitted)
    write(deletes, submitted / "deletes.ipynb")
    write(networking(listener.port, c_level), submitted / "network.ipynb")
    write(faking(reference()), submitted / "fake.ipynb")
    (submitted / "garbage.ipynb").write_bytes(random.Random(2018).randbytes(300))
    write(make_student.student_notebook(EXERCISES / "02-lagrange-multipliers.md"), submitted / "chapter2.ipynb")
    before = snapshot(instructor), snapshot(submitted)

    try:
        results = grade.grade(submitted, tmp_path / "out", timeout=TIMEOUT, jobs=2, isolated=isolated,
                              checking=instructor)
    finally:
        listener.close()

    assert (snapshot(instructor), snapshot(submitted)) == before
    assert not planted(), "a submission wrote into the repository"
    assert listener.accepted == 0, "a submission reached the network"
    assert graders_users() == [], "a submission's process outlived its grading"
    timeout_reason = f"time limit of {TIMEOUT} s reached in code cell {loops_in}"
    expected = [
        ["submission", "status", *LABELS, "total", "reason"],
        ["chapter2.ipynb", "invalid", "0", "0", "0", "0", "0", "0",
         "a notebook of chapter 02 (it imports checking.ch02), not of chapter 01"],
        ["crashes.ipynb", "crashed", "1", "1", "0", "0", "0", "2", f"the kernel died in code cell {crashes_in}"],
        ["deletes.ipynb", "ok", "0", "0", "0", "0", "0", "0",
         f"error in code cell 2 (ModuleNotFoundError) and {code_cells(deletes) - 2} more cells"],
        ["fake.ipynb", "ok", "0", "0", "1", "1", "1", "3", ""],
        ["garbage.ipynb", "invalid", "0", "0", "0", "0", "0", "0", "not a notebook: not valid JSON (UnicodeDecodeError)"],
        ["loops.ipynb", "timeout", "1", "1", "1", "0", "0", "3", timeout_reason],
        ["network.ipynb", "ok", "1", "1", "1", "1", "1", "5", ""],
        ["raises.ipynb", "ok", "1", "1", "0", "1", "1", "4", f"error in code cell {raises_in} (ValueError)"],
        ["reference.ipynb", "ok", "1", "1", "1", "1", "1", "5", ""],
        ["student.ipynb", "ok", "0", "0", "0", "0", "0", "0", ""],
        ["wrong.ipynb", "ok", "1", "0", "1", "0", "1", "3", ""],
    ]
    assert read_rows(tmp_path / "out" / "gradebook.csv") == expected
    assert [r.name for r in results] == [row[0] for row in expected[1:]]

    feedback = {p.name: p.read_text() for p in (tmp_path / "out" / "feedback").iterdir()}
    assert sorted(feedback) == sorted(f"{row[0]}.txt" for row in expected[1:])
    wrong = feedback["wrong.ipynb.txt"].splitlines()
    assert wrong[:3] == ["Exercise notebook 01: wrong.ipynb", "Score: 3 of 5", ""]
    assert wrong[3:8] == [f"{label}: " + ("right." if label not in ("1.5", "1.7")
                                          else f"not right yet. Hint: {CHECKS[label].hint}") for label in LABELS]
    assert wrong[-1] == "The notebook ran to its end."
    assert f"1.6: not checked: error in code cell {raises_in} (ValueError)." in feedback["raises.ipynb.txt"]
    assert f"1.8: not checked: the run was stopped ({timeout_reason})." in feedback["loops.ipynb.txt"]
    assert feedback["loops.ipynb.txt"].endswith(f"The notebook was stopped: {timeout_reason}.\n")
    assert "1.4: not checked: the notebook has no check(\"1.4\", ...)." in feedback["fake.ipynb.txt"]
    assert "1.7: not answered: replace the ... with your answer." in feedback["student.ipynb.txt"]
    assert next(r for r in results if r.name == "loops.ipynb").seconds >= TIMEOUT   # the limit was waited for


def test_the_guard_alone_keeps_files_and_network(tmp_path, instructor):
    """Without namespaces or another user (a grader that is not root), the audit hook still refuses."""
    submitted = tmp_path / "submitted"
    submitted.mkdir()
    listener = Listener()
    write(reference(), submitted / "reference.ipynb")
    deletes = deleting(instructor, submitted)
    write(deletes, submitted / "deletes.ipynb")
    write(networking(listener.port, c_level=False), submitted / "network.ipynb")
    before = snapshot(instructor), snapshot(submitted)
    try:
        grade.grade(submitted, tmp_path / "out", chapter="1", timeout=TIMEOUT, jobs=2,
                    isolated=grade.Isolation("guard"), checking=instructor)
    finally:
        listener.close()
    assert (snapshot(instructor), snapshot(submitted)) == before
    assert not planted() and listener.accepted == 0
    assert read_rows(tmp_path / "out" / "gradebook.csv")[1:] == [
        ["deletes.ipynb", "ok", "0", "0", "0", "0", "0", "0",
         f"error in code cell 2 (ModuleNotFoundError) and {code_cells(deletes) - 2} more cells"],
        ["network.ipynb", "ok", "1", "1", "1", "1", "1", "5", ""],
        ["reference.ipynb", "ok", "1", "1", "1", "1", "1", "5", ""],
    ]


def test_the_chapter_is_the_one_most_submissions_import_or_named(tmp_path):
    for name, page in (("a", "01-closed-loop-systems"), ("b", "02-lagrange-multipliers")):
        write(make_student.student_notebook(EXERCISES / f"{page}.md"), tmp_path / f"{name}.ipynb")
    with pytest.raises(ValueError, match="can not tell the chapter .* name it with --chapter"):
        grade.assignment_chapter(grade.submissions(tmp_path))
    write(make_student.student_notebook(SOURCE), tmp_path / "c.ipynb")
    assert grade.assignment_chapter(grade.submissions(tmp_path)) == "01"
    assert grade.labels_of("01") == LABELS
    with pytest.raises(ValueError, match="no checks for chapter '99'"):
        grade.labels_of("99")


def test_the_command_refuses_bad_arguments_before_grading(tmp_path, capsys):
    with pytest.raises(SystemExit) as stop:
        grade.main([str(tmp_path / "missing"), "--out", str(tmp_path / "out"), "--isolation", "guard"])
    assert stop.value.code == 2
    assert "SUBMISSIONS must be a folder" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        grade.main([str(tmp_path), "--timeout", "0", "--isolation", "guard"])
    assert "timeout must be a positive number" in capsys.readouterr().err
    with pytest.raises(SystemExit):
        grade.main([str(tmp_path), "--chapter", "1; rm", "--isolation", "guard"])
    assert "chapter must be a chapter's number such as 03, got '1; rm'" in capsys.readouterr().err
    assert not (tmp_path / "out").exists()
