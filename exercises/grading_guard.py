"""The kernel that runs a submission while it is graded: an IPython kernel behind an audit hook.

    python grading_guard.py -f CONNECTION_FILE [kernel options]     (started by exercises/grade.py)

The hook (``sys.addaudithook``, which Python code cannot remove) refuses, with a PermissionError
that says why:

- network connections (``socket.connect``, ``sendto``, name look-ups), except through Unix sockets;
- writing, creating, deleting, renaming or changing files outside the submission's folder (the
  kernel's working directory at start) and ``/dev``;
- starting programs (``subprocess``, ``os.system``, ``os.exec*``, ``os.spawn*``, ``posix_spawn``)
  and signalling any process but the kernel itself.

This is a guard against accidents and plain code, not a sandbox: a C extension or ``ctypes`` can
go around it. When it can, ``grade.py`` also runs the kernel in its own network namespace as a user
that may write nothing but the submission's folder (see ``grade.isolation``).
"""

import os
import sys

#: Audit events that change the file named by their first argument (``os.rename``: both the first two).
CHANGES = {"os.remove", "os.rmdir", "os.mkdir", "os.chmod", "os.chown", "os.truncate", "os.utime",
           "os.symlink", "os.link", "os.rename", "shutil.rmtree", "shutil.move", "os.mkfifo", "os.mknod"}
#: Audit events that start a program.
PROGRAMS = {"subprocess.Popen", "os.system", "os.exec", "os.spawn", "os.posix_spawn", "pty.spawn",
            "os.startfile"}
WRITING = os.O_WRONLY | os.O_RDWR | os.O_CREAT | os.O_TRUNC | os.O_APPEND


def make_hook(folder):
    """The audit hook that keeps a kernel to ``folder`` (see the module docstring)."""
    import socket

    allowed = (os.path.realpath(folder), "/dev")

    def inside(path, dir_fd=None, follow=True):
        """Whether ``path`` lies in the folder (or /dev); with ``follow`` False, a change of the entry
        itself: its last part is not followed, and the folder itself may not be removed or renamed."""
        if isinstance(path, int):                     # an open descriptor: already allowed when opened
            return True
        path = os.fsdecode(path)
        if dir_fd is not None and not os.path.isabs(path):
            path = os.path.join(os.readlink(f"/proc/self/fd/{dir_fd}"), path)
        path = os.path.abspath(path)
        real = os.path.realpath(path) if follow else os.path.join(os.path.realpath(os.path.dirname(path)),
                                                                   os.path.basename(path))
        return any(real.startswith(root + os.sep) or (follow and real == root) for root in allowed)

    def refuse(what):
        raise PermissionError(f"{what} is not allowed while a notebook is graded")

    def hook(event, args):
        if event == "open":
            path, _, flags = args
            if flags & WRITING and not inside(path):
                refuse(f"writing {path!r}")
        elif event in CHANGES:
            dir_fd = args[-1] if event in ("os.remove", "os.rmdir", "os.mkdir", "shutil.rmtree") else None
            paths = args[:2] if event in ("os.rename", "os.symlink", "os.link", "shutil.move") else args[:1]
            if event == "os.symlink":
                paths = args[1:2]                         # the link made; its target may be anywhere
            if not all(inside(p, dir_fd if isinstance(dir_fd, int) else None, follow=False) for p in paths):
                refuse(f"{event} of {paths[0]!r}")
        elif event in ("socket.connect", "socket.sendto", "socket.sendmsg", "socket.bind"):
            if getattr(args[0], "family", None) != socket.AF_UNIX:
                refuse("the network")
        elif event in ("socket.getaddrinfo", "socket.gethostbyname", "socket.gethostbyname_ex",
                       "socket.gethostbyaddr"):
            if args[0] not in (None, "localhost", "127.0.0.1", "::1", b"localhost"):
                refuse("the network")
        elif event in PROGRAMS:
            refuse("starting a program")
        elif event in ("os.kill", "os.killpg"):
            if args[0] != os.getpid():
                refuse("signalling another process")

    return hook


if __name__ == "__main__":
    folder = os.getcwd()
    sys.path[0] = folder                  # the submission's folder (its checking), not this script's
    sys.addaudithook(make_hook(folder))
    import runpy

    runpy.run_module("ipykernel_launcher", run_name="__main__", alter_sys=True)
