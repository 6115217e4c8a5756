"""The basin map on any executor, and local workers that end with their parent.

A map split into the same parts gives the same numbers wherever the parts run: on this process's own
workers, on a ``concurrent.futures`` pool, or on a Dask ``distributed`` cluster through
``client.get_executor()``.  The local workers end with their parent even when it is killed by SIGKILL,
which no handler can see.
"""

import math
import os
import signal
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor

import numpy as np
import psutil
import pytest

from closedloop import InputError
from closedloop.studies.basin import basin_map, grid_values

from ._processes import started_workers

#: A 10 x 6 grid across the basin boundary, 6 s long: both outcomes, and cells that stick.
PHI0 = grid_values(0.0, 2 * math.pi, 10)
DPHI0 = grid_values(0.0, 3.0, 6)
T_END = 6.0


@pytest.fixture(scope="module")
def local_map():
    """The map on this machine's own worker processes, in two parts."""
    return basin_map(PHI0, DPHI0, T_END, workers=2)


def same_cells(a, b):
    """Every cell's outcome, excursion, decision and sticking time the same to the bit (nan where both are)."""
    np.testing.assert_array_equal(a.outcome, b.outcome)
    for name in ("excursion", "decided_at", "stuck_at"):
        np.testing.assert_array_equal(getattr(a, name), getattr(b, name), err_msg=name)


def test_the_grid_holds_both_outcomes_and_sticking(local_map):
    assert 0.2 < local_map.fraction_rotating < 0.8
    assert np.any(np.isfinite(local_map.stuck_at))


def test_a_map_on_a_dask_local_cluster_is_the_local_map_cell_by_cell(local_map):
    from distributed import Client, LocalCluster

    with LocalCluster(n_workers=1, threads_per_worker=2, processes=False, dashboard_address=None) as cluster, \
            Client(cluster) as client:
        remote = basin_map(PHI0, DPHI0, T_END, workers=2, executor=client.get_executor())
    same_cells(remote, local_map)
    assert remote.workers == 2 and remote.evaluations == local_map.evaluations


def test_any_executor_gives_the_same_map_and_a_single_part_is_the_same_too(local_map):
    with ThreadPoolExecutor(2) as pool:
        threads = basin_map(PHI0, DPHI0, T_END, workers=2, executor=pool)
        one_part = basin_map(PHI0, DPHI0, T_END, workers=1, executor=pool)
    same_cells(threads, local_map)
    np.testing.assert_array_equal(one_part.outcome, local_map.outcome)
    np.testing.assert_allclose(one_part.excursion, local_map.excursion, rtol=1e-12, atol=0)


def test_an_executor_must_be_an_executor():
    with pytest.raises(InputError, match=r"^executor: must be a concurrent.futures.Executor, got list$"):
        basin_map(PHI0, DPHI0, T_END, workers=2, executor=[])


#: The child: a map long enough (a 60 x 60 grid over 20 s, tens of seconds on two workers) to be killed in.
KILLED = ("import math\n"
          "from closedloop.studies.basin import basin_map, grid_values\n"
          "basin_map(grid_values(0, 2 * math.pi, 60), grid_values(0, 3, 60), 20.0, workers=2)\n")
#: The same child as on a system without prctl: its workers watch their parent's pid instead.
WITHOUT_PRCTL = ("import types\nimport closedloop.simulation.batch_pool as pool\n"
                 "pool.sys = types.SimpleNamespace(platform='elsewhere')\n" + KILLED)


def running(processes):
    """Those of ``processes`` still alive (a zombie, dead but not yet reaped, is not)."""
    alive = []
    for process in processes:
        try:
            if process.status() != psutil.STATUS_ZOMBIE:
                alive.append(process)
        except psutil.NoSuchProcess:
            pass
    return alive


@pytest.mark.parametrize("child", [KILLED, WITHOUT_PRCTL], ids=["prctl", "watching thread"])
def test_no_worker_outlives_its_parent_killed_by_sigkill(child):
    parent = subprocess.Popen([sys.executable, "-c", child])
    try:
        deadline = time.monotonic() + 60
        workers = started_workers(parent, timeout=60, poll=0.05)
        start = [sum(worker.cpu_times()[:2]) for worker in workers]
        while min(sum(w.cpu_times()[:2]) - s for w, s in zip(workers, start)) < 0.5:   # and they compute
            assert time.monotonic() < deadline and parent.poll() is None
            time.sleep(0.05)
        os.kill(parent.pid, signal.SIGKILL)
        parent.wait(timeout=10)
    finally:
        if parent.poll() is None:
            parent.kill()
    assert parent.returncode == -signal.SIGKILL
    deadline = time.monotonic() + 5.0
    while running(workers) and time.monotonic() < deadline:
        time.sleep(0.05)
    left = running(workers)
    for worker in left:                      # a failing test does not leave them computing
        worker.kill()
    assert not left, f"workers outlived their parent by 5 s: {left}"
