"""Two writers of one output racing to its final step, for the tests of atomic writes."""

import os
import threading


def race(monkeypatch, step, write):
    """Run ``write(0)`` and ``write(1)`` in two threads, each held at ``os.<step>`` (the final
    step of an atomic write: "replace" or "link") until both have reached it with all their
    bytes written; return {variant: None where it finished, else the exception it raised}."""
    barrier = threading.Barrier(2, timeout=60)
    real = getattr(os, step)

    def together(*args, **kwargs):
        barrier.wait()
        return real(*args, **kwargs)

    monkeypatch.setattr(os, step, together)
    outcomes = {}

    def run(variant):
        try:
            write(variant)
            outcomes[variant] = None
        except BaseException as error:  # reported by the caller
            outcomes[variant] = error
            barrier.abort()  # a writer that failed before the step must not hold the other

    threads = [threading.Thread(target=run, args=(variant,)) for variant in (0, 1)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join(120)
    monkeypatch.setattr(os, step, real)
    return outcomes
