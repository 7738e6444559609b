#!/usr/bin/env python3
"""SciPy baseline for benches/benches/kalman.rs: the same DARE problems
(the same SplitMix64 sequence as kestrel_benches::pseudo_random and the
dare_cpu_time example), timed with process CPU time and with wall-clock
time.

    python3 crates/kalman/scripts/scipy_dare.py
"""
import time
import numpy as np
from scipy.linalg import solve_discrete_are

MASK = (1 << 64) - 1


def pseudo_random(seed, n):
    """SplitMix64 seeded with the state `seed` (rand_xoshiro's
    `SplitMix64::seed_from_u64`), mapped to [-1, 1) as rand's
    `random::<f64>() * 2.0 - 1.0`: (next >> 11) / 2^53 * 2 - 1."""
    s = seed & MASK
    out = []
    for _ in range(n):
        s = (s + 0x9E3779B97F4A7C15) & MASK
        z = s
        z = ((z ^ (z >> 30)) * 0xBF58476D1CE4E5B9) & MASK
        z = ((z ^ (z >> 27)) * 0x94D049BB133111EB) & MASK
        z ^= z >> 31
        out.append((z >> 11) / float(1 << 53) * 2.0 - 1.0)
    return out


def problem(n):
    m, p = 1 + n // 4, 1 + n // 3
    scale = 1.1 * np.sqrt(3.0) / np.sqrt(n)
    a = np.array(pseudo_random(11 + n, n * n)).reshape(n, n) * scale
    b = np.array(pseudo_random(23 + n, n * m)).reshape(n, m)
    c = np.array(pseudo_random(37 + n, p * n)).reshape(p, n)
    return a, b, c.T @ c, np.eye(m)


for n in (5, 20, 60):
    a, b, q, r = problem(n)
    x = solve_discrete_are(a, b, q, r)
    reps = 2000 if n < 60 else 50
    for clock, name in ((time.process_time, "cpu"), (time.perf_counter, "wall")):
        best = float("inf")
        for _ in range(3):
            t = clock()
            for _ in range(reps):
                solve_discrete_are(a, b, q, r)
            best = min(best, (clock() - t) / reps)
        print(f"n={n}: scipy solve_discrete_are {name} {best * 1e6:.1f} us")
    np.save(f"/tmp/scipy_dare_x_{n}.npy", x)
