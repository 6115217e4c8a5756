"""Golden master for refactorings: record what the engine computes, or compare with a record.

Run as ``python benchmarks/golden_master.py record FILE`` before a change and
``python benchmarks/golden_master.py compare FILE`` after it; and
``python benchmarks/golden_master.py compare-study OLD.json NEW.json`` to compare two
error-against-run-time studies (``closedloop benchmark --json``) row by row.  The record holds,
for each of the paper's four cases and every formulation with each method it
takes, the final state, nfev, the step count and the switch events of a 20 s
run, and the outcome of every cell of a 100 x 100 basin map.  ``compare``
prints the largest differences and exits 1 when a final state moves by more
than 1e-12 (relative), an nfev, step count or switch action changes, or a
basin cell changes its outcome.  The record is a generated artefact: it is
never committed.
"""

from __future__ import annotations

import json
import math
import sys

import numpy as np

import closedloop
from closedloop.slider_crank import CASES, initial_state, slider_crank_system

try:                                       # the layout after the redesign, then before it
    from closedloop.studies.basin import basin_map, grid_values
except ImportError:                        # pragma: no cover - the layout before
    from closedloop.basin import basin_map, grid_values

RUNS = [
    ("Augmented", (), ("RK45", "DOP853", "Radau")),
    ("Baumgarte", (5.0, 5.0), ("RK45", "DOP853", "LSODA")),
    ("Orthogonal", (5.0, 5.0), ("DOP853", "ode.dop853")),
    ("Minimal", (), ("DOP853", "ode.dop853", "BDF")),
    ("NullSpace", (5.0, 5.0), ("DOP853",)),
    ("ClosedForm", (1.0, 1.0), ("DOP853", "ode.dop853")),
    ("Projected", (), ("DOP853",)),
]


def record():
    system = slider_crank_system()
    runs = {}
    for case in CASES:
        state = initial_state(system, CASES[case].phi0, CASES[case].dphi0)
        for name, args, methods in RUNS:
            for method in methods:
                formulation = getattr(closedloop, name)(*args)
                result = closedloop.simulate(system, state, 20.0, formulation=formulation, method=method,
                                             rtol=1e-9, atol=1e-9)
                runs[f"case {case} {name} {method}"] = {
                    "s": result.s[:, -1].tolist(), "sd": result.sd[:, -1].tolist(),
                    "nfev": int(result.nfev), "n_steps": int(result.n_steps),
                    "events": [[e.t, e.switch, e.action] for e in result.switch_events],
                    "sticking": [list(map(float, i)) for i in result.sticking_intervals],
                }
    phi, dphi = grid_values(0.0, 2 * math.pi, 100), grid_values(0.0, 3.0, 100)
    basin = basin_map(phi, dphi, 20.0, workers=2)
    stuck = np.where(np.isnan(basin.stuck_at), -1.0, basin.stuck_at)
    return {"runs": runs, "basin": np.asarray(basin.outcome).tolist(), "basin_stuck_at": stuck.tolist()}


def compare(old, new):
    worst_state, changed = 0.0, []
    for key, a in old["runs"].items():
        b = new["runs"].get(key)
        if b is None:
            changed.append(f"{key}: missing")
            continue
        x, y = np.array(a["s"] + a["sd"]), np.array(b["s"] + b["sd"])
        worst_state = max(worst_state, float(np.max(np.abs(x - y) / (1.0 + np.abs(x)))))
        for field in ("nfev", "n_steps"):
            if a[field] != b[field]:
                changed.append(f"{key}: {field} {a[field]} -> {b[field]}")
        if [e[1:] for e in a["events"]] != [e[1:] for e in b["events"]]:
            changed.append(f"{key}: switch events differ")
        elif a["events"]:
            dt = max(abs(p[0] - q[0]) for p, q in zip(a["events"], b["events"]))
            if dt > 1e-12:
                changed.append(f"{key}: switch times move by {dt:.3g} s")
    cells = np.array(old["basin"]) != np.array(new["basin"])
    stuck = float(np.max(np.abs(np.array(old["basin_stuck_at"]) - np.array(new["basin_stuck_at"]))))
    print(f"basin: largest change of a sticking time: {stuck:.3g} s")
    print(f"runs compared: {len(old['runs'])}; largest relative change of a final state: {worst_state:.3g}")
    print(f"basin cells that changed outcome: {int(cells.sum())} of {cells.size}")
    for line in changed:
        print("changed:", line)
    return worst_state <= 1e-12 and not changed and not cells.any()


def compare_study(old, new):
    """nfev and error_t10 of every row present in both studies (same case, formulation, method, rtol)."""
    def key(row):
        return row["case"], row["formulation"], row["method"], row["rtol"]

    rows = {key(r): r for r in new["rows"]}
    both = [(r, rows[key(r)]) for r in old["rows"] if key(r) in rows]
    nfev = [(key(a), a["nfev"], b["nfev"]) for a, b in both if a.get("nfev") != b.get("nfev")]
    errors = [abs(a["error_t10"] - b["error_t10"]) / max(abs(a["error_t10"]), 1e-300)
              for a, b in both if a.get("error_t10") is not None and b.get("error_t10") is not None]
    print(f"rows: {len(old['rows'])} before, {len(new['rows'])} after, {len(both)} in both")
    print(f"rows whose nfev changed: {len(nfev)}")
    for line in nfev[:20]:
        print("  nfev changed:", line)
    print(f"largest relative change of error_t10: {max(errors, default=0.0):.3g}")
    return not nfev and max(errors, default=0.0) <= 1e-9


def main(argv):
    if len(argv) == 4 and argv[1] == "compare-study":
        with open(argv[2]) as a, open(argv[3]) as b:
            return 0 if compare_study(json.load(a), json.load(b)) else 1
    if len(argv) != 3 or argv[1] not in ("record", "compare"):
        print(__doc__.splitlines()[2])
        return 2
    if argv[1] == "record":
        with open(argv[2], "w") as handle:
            json.dump(record(), handle)
        return 0
    with open(argv[2]) as handle:
        old = json.load(handle)
    return 0 if compare(old, record()) else 1


if __name__ == "__main__":
    sys.exit(main(sys.argv))
