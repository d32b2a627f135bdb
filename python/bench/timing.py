"""What both benchmark scripts time with: calls per second of a step, over a number of seconds that the
scripts' first argument sets (default 3)."""

import sys
import time

SECONDS = float(sys.argv[1]) if len(sys.argv) > 1 else 3.0


def rate(step, seconds=SECONDS):
    """Calls of `step` per second, called repeatedly for `seconds` of wall time."""
    n, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds:
        step()
        n += 1
    return n / (time.perf_counter() - start)
