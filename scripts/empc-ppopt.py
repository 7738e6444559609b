#!/usr/bin/env python3
"""PPOPT on a kestrel.mpqp.v1 problem: the comparison of BENCHMARKS.md
"Explicit MPC at scale" (not part of CI).

    pip install ppopt daqp cvxopt      # free backends: GLPK (LP), DAQP (QP)
    python3 scripts/empc-ppopt.py PROBLEM.mpqp.json [ALGORITHM ...]

kestrel.mpqp.v1 is  min 1/2 z'Hz + (F'theta + f)'z  s.t.  G z <= W + E theta,
theta in [theta_lb, theta_ub]; PPOPT's MPQP_Program is
min 1/2 x'Qx + (H theta + c)'x  s.t.  A x <= b + F theta,  A_t theta <= b_t,
so Q = H, H = F', c = f, A = G, b = W, F = E and the box as A_t, b_t.
Prints one line per algorithm: regions and wall seconds of solve_mpqp.
Gurobi (PPOPT's default) is not used: its pip licence is size-limited and
not available for a fair comparison here; LPs run on GLPK, QPs on DAQP.
"""
import json
import sys
import time

import numpy as np
from ppopt.mpqp_program import MPQP_Program
from ppopt.mp_solvers.solve_mpqp import mpqp_algorithm, solve_mpqp
from ppopt.solver import Solver


def program(path, solver):
    d = json.load(open(path))
    g = np.array(d["G"], dtype=float)
    n, p = g.shape[1], len(d["theta_lb"])
    q = np.array(d["H"], dtype=float)
    ft = np.array(d["F"], dtype=float).reshape(p, n)
    f = np.array(d.get("f", [0.0] * n), dtype=float).reshape(n, 1)
    w = np.array(d["W"], dtype=float).reshape(-1, 1)
    e = np.array(d["E"], dtype=float).reshape(-1, p)
    # Exact duplicate rows (kestrel's test problems write the bounds once
    # per step of a move-blocking block) are dropped, as kestrel's solver
    # does: PPOPT's combinatorial search would count their active sets.
    keep, seen = [], set()
    for i in range(g.shape[0]):
        key = tuple(g[i]) + (w[i, 0],) + tuple(e[i])
        if key not in seen:
            seen.add(key)
            keep.append(i)
    g, w, e = g[keep], w[keep], e[keep]
    lb, ub = np.array(d["theta_lb"], dtype=float), np.array(d["theta_ub"], dtype=float)
    a_t = np.vstack([np.eye(p), -np.eye(p)])
    b_t = np.concatenate([ub, -lb]).reshape(-1, 1)
    return MPQP_Program(g, w, f, ft.T, q, a_t, b_t, e, solver=solver)


def main():
    path = sys.argv[1]
    algos = sys.argv[2:] or ["combinatorial", "geometric"]
    solver = Solver({"lp": "glpk", "qp": "daqp", "milp": "gurobi", "miqp": "gurobi"})
    for name in algos:
        prog = program(path, solver)
        t = time.perf_counter()
        sol = solve_mpqp(prog, mpqp_algorithm[name])
        dt = time.perf_counter() - t
        print(f"{path}: PPOPT {name} (GLPK LPs, DAQP QPs): {len(sol.critical_regions)} regions in {dt:.2f} s",
              flush=True)


if __name__ == "__main__":
    main()
