"""How the basin map scales: a Dask LocalCluster against the local processes, and the cost per cell.

Run as ``python benchmarks/basin_scale.py [--size 400] [--sizes 50,100,200,400] [--cores N] [--t-end 20]``.
Every figure printed comes from this run; nothing is read from earlier runs.
This is a benchmark script, not a test: it asserts nothing.

What is measured
----------------
engine overhead
    One ``basin_map`` of a size x size grid (phi0 in [0, 2 pi), phi0' in [0, 3) rad/s,
    t = 0 .. t_end) split into ``--cores`` parts, once on the map's own worker processes and
    on a Dask ``distributed.LocalCluster`` of ``--cores`` single-threaded worker processes
    (``client.get_executor()``): first with Dask's default worker environment, then with
    glibc's thresholds raised (``MALLOC_TRIM_THRESHOLD_`` 128 MiB, ``MALLOC_MMAP_THRESHOLD_``
    32 MiB).  Dask sets the first to 64 KiB, which also fixes glibc's mmap threshold at 128 KiB,
    so every temporary array of a part above that size is mapped and unmapped afresh, each
    time at the cost of page faults.  The ratios of their wall times to the local one are what
    the engine costs beside the local pool.  A cluster's start-up is timed apart.  The maps
    are compared cell by cell.
cost per cell
    The same map, on the local processes, at each grid size of ``--sizes``: wall and CPU
    seconds (summed over the workers) per cell, and each size's CPU per cell over the
    smallest's.  A flat ratio says the map's cost grows with its cells and nothing else.
"""

from __future__ import annotations

import argparse
import math
import os
import time

import numpy as np

from closedloop.studies.basin import DEFAULT_STEP, basin_map, grid_values


def grid(size):
    return grid_values(0.0, 2 * math.pi, size), grid_values(0.0, 3.0, size)


def same_cells(a, b):
    """Whether two maps agree in every cell's outcome, excursion and sticking time, to the bit."""
    return (np.array_equal(a.outcome, b.outcome) and np.array_equal(a.excursion, b.excursion)
            and np.array_equal(a.stuck_at, b.stuck_at, equal_nan=True))


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=400, help="grid of the local-against-cluster comparison")
    parser.add_argument("--sizes", default="50,100,200,400", help="grids of the cost per cell, comma-separated")
    parser.add_argument("--cores", type=int, default=os.cpu_count() or 1)
    parser.add_argument("--t-end", type=float, default=20.0)
    args = parser.parse_args()
    sizes = [int(text) for text in args.sizes.split(",")]
    import dask
    from distributed import Client, LocalCluster

    print(f"basin map, t = 0 .. {args.t_end:g} s, step {DEFAULT_STEP:g} s, {args.cores} cores, "
          f"{args.cores} parts a map")
    basin_map(*grid(4), 1.0, workers=1)                 # derive and cache the generated code first
    maps = {}
    local = maps[args.size] = basin_map(*grid(args.size), args.t_end, workers=args.cores)
    cells = args.size ** 2
    print(f"\n{args.size} x {args.size} cells ({cells}), {cells // args.cores} cells a part")
    print(f"  local processes                           wall {local.wall_time:8.2f} s   CPU {local.cpu_time:8.2f} s")
    # glibc reads them when a worker starts, so they go in the environment Dask spawns it with
    # (pre-spawn-environ, where this process's own environment takes precedence), not in its env=
    raised = {"MALLOC_TRIM_THRESHOLD_": str(2 ** 27), "MALLOC_MMAP_THRESHOLD_": str(2 ** 25)}
    for label, settings in (("Dask's default environment", {}), ("glibc's thresholds raised", raised)):
        for name in raised:
            os.environ.pop(name, None)
        os.environ.update(settings)
        started = time.perf_counter()
        spawned = {f"distributed.nanny.pre-spawn-environ.{name}": value for name, value in settings.items()}
        with dask.config.set(spawned), LocalCluster(n_workers=args.cores, threads_per_worker=1, processes=True,
                                                    dashboard_address=None) as cluster, Client(cluster) as client:
            start_up = time.perf_counter() - started
            trim = set(client.run(lambda: (os.environ.get("MALLOC_TRIM_THRESHOLD_"),
                                           os.environ.get("MALLOC_MMAP_THRESHOLD_"))).values())
            remote = basin_map(*grid(args.size), args.t_end, workers=args.cores, executor=client.get_executor())
        print(f"  LocalCluster, {label:<27} wall {remote.wall_time:8.2f} s   CPU {remote.cpu_time:8.2f} s   "
              f"(workers' MALLOC_TRIM_THRESHOLD_, MALLOC_MMAP_THRESHOLD_: {', '.join(map(str, trim))}; "
              f"start-up {start_up:.2f} s, apart)")
        print(f"    LocalCluster / local, wall: {remote.wall_time / local.wall_time:.3f}; CPU: "
              f"{remote.cpu_time / local.cpu_time:.3f}; the maps equal cell by cell: "
              f"{'yes' if same_cells(local, remote) else 'NO'}")

    print("\ncost per cell as the grid grows (local processes)")
    print(f"  {'grid':>9}  {'cells':>7}  {'wall [s]':>9}  {'CPU [s]':>9}  {'wall/cell [ms]':>14}  "
          f"{'CPU/cell [ms]':>13}  {'CPU/cell ratio':>14}")
    first = None
    for size in sizes:
        basin = maps.get(size) or basin_map(*grid(size), args.t_end, workers=args.cores)
        per_cell = basin.cpu_time / size ** 2
        first = per_cell if first is None else first
        print(f"  {f'{size} x {size}':>9}  {size ** 2:>7}  {basin.wall_time:>9.2f}  {basin.cpu_time:>9.2f}  "
              f"{1e3 * basin.wall_time / size ** 2:>14.3f}  {1e3 * per_cell:>13.3f}  {per_cell / first:>14.3f}")


if __name__ == "__main__":
    main()
