"""Run one notebook in a plain Jupyter: run by the plain environment's own Python (tests/test_downloads.py).

    PLAIN_PYTHON tests/plain_jupyter.py FOLDER NOTEBOOK OUTPUT [FOLDER NOTEBOOK OUTPUT ...]

The plain environment holds the site's wheel with its ``plot`` extra, ipykernel and nbclient, and
nothing else; so this script imports nothing of the repository and nothing the plain environment
lacks. It runs ``FOLDER/NOTEBOOK`` top to bottom, in FOLDER, in a fresh kernel of the environment's
``python3`` kernel specification (ipykernel's, which starts this same Python), with nbclient,
going on after an error, and writes the executed notebook to ``OUTPUT``; then the next triple, each
notebook in a kernel of its own (one process runs several, so that Python and nbclient start once).
It prints one line of JSON per notebook: the kernel's command and ``sys.prefix``, so that the test can
see that the kernel was the plain environment's, and the error that stopped nbclient itself, if any.
"""

import json
import shutil
import sys
import tempfile
from pathlib import Path

import nbclient
import nbformat
from jupyter_client.manager import KernelManager


def main(folder, name, output):
    folder = Path(folder)
    notebook = nbformat.read(folder / name, as_version=4)
    # Unix sockets, not TCP ports (two kernels started at once can pick the same free port), in a folder of
    # their own with a short path: a socket's path may not be longer than 107 bytes, the notebook's may be
    sockets = tempfile.mkdtemp(prefix="kernel-")
    manager = KernelManager(kernel_name="python3", transport="ipc", connection_file=f"{sockets}/k.json")
    client = nbclient.NotebookClient(notebook, km=manager, timeout=600, allow_errors=True,
                                     resources={"metadata": {"path": str(folder)}})
    report = {"prefix": sys.prefix, "kernel": manager.kernel_spec.argv[:1] + [manager.kernel_spec.resource_dir]}
    try:
        client.execute(cleanup_kc=True)
    except Exception as error:                 # the notebook did not run to its end: reported, not raised
        report["stopped"] = f"{type(error).__name__}: {error}"[:3000]
    finally:
        shutil.rmtree(sockets, ignore_errors=True)
    nbformat.write(notebook, output)
    print(json.dumps(report), flush=True)


if __name__ == "__main__":
    arguments = sys.argv[1:]
    for k in range(0, len(arguments), 3):
        main(*arguments[k:k + 3])
