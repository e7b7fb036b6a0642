"""CPU timing shared by the benchmark scripts (imported from their own folder)."""

import math
import time


def best_wall(func, repeats=3):
    """Best wall-clock time (time.perf_counter, s) of `func()` over `repeats` runs."""
    best = math.inf
    for _ in range(repeats):
        start = time.perf_counter()
        func()
        best = min(best, time.perf_counter() - start)
    return best


def best_cpu(func, repeats=3):
    """Best CPU time (time.process_time, s) of `func()` over `repeats` runs, and its result.

    CPU time rather than wall time, and the best of several runs, so that other load on the
    machine distorts the figures less.
    """
    best, result = math.inf, None
    for _ in range(repeats):
        start = time.process_time()
        result = func()
        best = min(best, time.process_time() - start)
    return max(best, 1e-9), result
