"""Waiting for the worker processes of a command or a script the tests start and then stop."""

import time

import psutil


def started_workers(process, count=2, timeout=30.0, poll=0.1):
    """The processes below ``process`` (a ``subprocess.Popen``) once there are ``count`` of them;
    fails if ``process`` ends first or they take more than ``timeout`` seconds to start."""
    parent, deadline = psutil.Process(process.pid), time.monotonic() + timeout
    while len(children := parent.children(recursive=True)) < count:
        assert time.monotonic() < deadline and process.poll() is None, "the workers did not start"
        time.sleep(poll)
    return children
