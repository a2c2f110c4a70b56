"""Time from a signal to the end of a long ipa_sysid call (docs/python.md "Threads and Ctrl-C").

Each long computation below is started, a SIGALRM handler that raises is armed to fire `DELAY_S` into
it (signal.setitimer), and the time from the timer's expiry to the moment the exception reaches the
caller is printed, with the time the same call takes uninterrupted. Run:

    python python/examples/interrupt_latency.py [WORD ...]

(with words, only the calls whose name contains one of them: `simulate_plant control`).

A measurement, not a test: the figures depend on the machine and its load.
"""

import signal
import sys
import time

import numpy as np

import ipa_sysid
from ipa_sysid import _core

DELAY_S = 1.0


class Alarm(Exception):
    """The handler's own exception."""


def handler(signum, frame):
    raise Alarm()


def main():
    _, u, y, _ = ipa_sysid.simulate_plant("ipa", samples=300_000, seed=1, noise_std=0.05)
    calls = {
        "identify(method='oe', max_iterations=100000), 300 000 samples": dict(
            method="oe", max_iterations=100_000
        ),
        "identify(structure='narx', degree=3, na=4, nb=4, max_terms=60), 300 000 samples": dict(
            structure="narx", degree=3, na=4, nb=4, max_terms=60
        ),
        "identify(method='rls', forgetting=0.999, passes=1000), 300 000 samples": dict(
            method="rls", forgetting=0.999, passes=1000
        ),
    }
    calls = {name: (lambda kw=kw: ipa_sysid.identify(u, y, 0.01, **kw)) for name, kw in calls.items()}
    # The fleet's window identification (ipa_sysid.fleet's per-partition call): 300 windows by OE.
    calls["fleet_windows(method='oe'), 300 windows of 1000 samples"] = lambda: _core.fleet_windows(
        u, y, [0, len(u)], 0.01, 1000, method="oe"
    )
    # One simulation each, polled every 4 096 samples of the plant: 5 million samples of the physics
    # plant; 40 000 s of the loop following a square wave (20 / 100 mm, a level per second).
    calls["simulate_plant('ipa', samples=5_000_000)"] = lambda: ipa_sysid.simulate_plant(
        "ipa", samples=5_000_000
    )
    t = np.arange(0.0, 40_000.0)
    square = np.column_stack([t, np.where(t % 2 == 0, 20.0, 100.0)])
    calls["control('ipa', profile=square wave, duration=40_000)"] = lambda: ipa_sysid.control(
        "ipa", profile=square, duration=40_000
    )
    words = sys.argv[1:]
    signal.signal(signal.SIGALRM, handler)
    for name, call in calls.items():
        if words and not any(w in name for w in words):
            continue
        start = time.perf_counter()
        ipa_sysid_warnings_off(call)
        whole = time.perf_counter() - start
        signal.setitimer(signal.ITIMER_REAL, DELAY_S)
        start = time.perf_counter()
        try:
            ipa_sysid_warnings_off(call)
            outcome = "returned a result (the alarm came too late)"
        except Alarm:
            outcome = f"Alarm raised {time.perf_counter() - start - DELAY_S:.3f} s after the signal"
        signal.setitimer(signal.ITIMER_REAL, 0)
        print(f"{name}: uninterrupted {whole:.2f} s; {outcome}", flush=True)


def ipa_sysid_warnings_off(call):
    import warnings

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        return call()


if __name__ == "__main__":
    main()
