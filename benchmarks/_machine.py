"""A fixed reference workload, so speed figures from different machines can be compared.

Sessions run on machines whose CPUs differ by 2x or more (the same code's fresh calibrate took
3.7 s on one and 6.8 s on another): each speed benchmark prints how long this reference takes
beside its own figures.
"""

from __future__ import annotations

import os
import time

import numpy as np


def reference_seconds() -> tuple[float, float]:
    """CPU seconds of (a 1e7-step pure-Python loop, 20 products of a 600x600 float64 matrix with
    itself), each the fastest of three runs. The products run in numpy's BLAS threads: their CPU
    time is summed over those threads."""
    def py_loop():
        s = 0
        for i in range(10_000_000):
            s += i
        return s

    a = np.random.default_rng(0).random((600, 600))

    def np_work():
        for _ in range(20):
            a @ a

    out = []
    for work in (py_loop, np_work):
        best = float("inf")
        for _ in range(3):
            t = time.process_time()
            work()
            best = min(best, time.process_time() - t)
        out.append(best)
    return out[0], out[1]


def machine_line() -> str:
    """One line naming the machine's speed: cores, load, and the reference workload's CPU s."""
    py_s, np_s = reference_seconds()
    return (f"machine: {os.cpu_count()} cores, load average {os.getloadavg()[0]:.2f}; reference workload "
            f"(benchmarks/_machine.py) CPU s: Python loop {py_s:.2f}, numpy {np_s:.2f}")
