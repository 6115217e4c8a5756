"""A run's cpu_time leaves out the modules and generated code the process loads on first use
(closedloop.loading): the first run of a process is timed like the same run after it."""

import subprocess
import sys
import time

from closedloop import loading

_FRESH_PROCESS = """
import sys, time
from closedloop import Augmented, loading, simulate
from closedloop.slider_crank import get_case, initial_state, slider_crank_system
system = slider_crank_system()
case = get_case(2)
state = initial_state(system, case.phi0, case.dphi0)
assert "scipy.integrate" not in sys.modules and "scipy.linalg" not in sys.modules
process, loads = time.process_time(), loading.load_time()
first = simulate(system, state, 20.0, formulation=Augmented(), method="RK45")
process, loads = time.process_time() - process, loading.load_time() - loads
assert "scipy.integrate" in sys.modules and "scipy.linalg" in sys.modules
second = simulate(system, state, 20.0, formulation=Augmented(), method="RK45")
print(first.cpu_time, second.cpu_time, process, loads)
"""


def test_the_first_run_of_a_process_leaves_its_imports_out():
    """In a fresh process, the first solve_ivp run with the augmented system imports scipy.integrate and
    scipy.linalg's LAPACK (0.3 to 0.5 s here): the loads are counted, and the first run's cpu_time is
    that of the same run after it (within a factor of 2: one process, one machine), not the process
    time of the call.  (A load block that also covered the run's own work would make it far smaller.)"""
    done = subprocess.run([sys.executable, "-c", _FRESH_PROCESS], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr[-2000:]
    first, second, process, loads = map(float, done.stdout.split())
    assert loads > 0.05                               # the imports happened inside the run, and were counted
    assert second > 0.02                              # a run long enough to be timed
    assert 0.5 * second < first < 2.0 * second + 0.005
    assert first < process - loads + 0.005


def _busy(seconds):
    end = time.process_time() + seconds
    while time.process_time() < end:
        pass


def test_nested_one_time_blocks_count_once():
    before, start = loading.load_time(), time.process_time()
    with loading.one_time():
        _busy(0.02)
        with loading.one_time():
            _busy(0.02)
    counted, spent = loading.load_time() - before, time.process_time() - start
    assert 0.04 <= counted <= spent + 1e-9            # the inner block is not counted a second time


def test_first_use_loads_once_and_counts_its_time():
    calls = []

    @loading.first_use
    def load():
        calls.append(1)
        _busy(0.02)
        return object()

    before = loading.load_time()
    first, second = load(), load()
    assert first is second and len(calls) == 1
    assert loading.load_time() - before >= 0.02
    clock = loading.run_clock()
    _busy(0.01)
    assert loading.run_clock() - clock >= 0.01        # outside a block, the run clock is the process time
