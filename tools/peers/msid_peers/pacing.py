"""The pacing and statistics of the peers' tick loops (tick_peer.py, can_tick_peer.py): time.sleep to each
deadline of time.monotonic(), as a user's script would, and nearest-rank quantiles."""
import json
import math
import time


def quantiles(x):
    """Median, p99 and maximum of x (zeros when x is empty)."""
    x = sorted(x)
    if not x:
        return {"median": 0.0, "p99": 0.0, "max": 0.0}
    q = lambda p: x[min(len(x) - 1, max(0, math.ceil(p * len(x)) - 1))]
    return {"median": q(0.5), "p99": q(0.99), "max": x[-1]}


def sleep_until(deadline, late, wake):
    """time.sleep to the deadline; appends the lateness of the wake-up to `late`, and to `wake` when the loop
    slept (the pacing's own precision, without the ticks it was already late for). Returns the wake-up instant."""
    d = deadline - time.monotonic()
    if d > 0:
        time.sleep(d)
    w = time.monotonic()
    late.append(w - deadline)
    if d > 0:
        wake.append(w - deadline)
    return w


def report(ticks, late, wake, rtt, cpu0, cpu1, **counts):
    """The JSON line a peer prints at its end: ticks, its own counts (`counts`), the quantiles of lateness, wake-up
    lateness and round trip, and the loop's CPU seconds between the getrusage() results cpu0 and cpu1."""
    user = cpu1.ru_utime - cpu0.ru_utime
    return json.dumps({"ticks": ticks, **counts, "lateness_s": quantiles(late), "wake_lateness_s": quantiles(wake),
                       "round_trip_s": quantiles(rtt), "cpu_s": user + (cpu1.ru_stime - cpu0.ru_stime),
                       "cpu_user_s": user})
