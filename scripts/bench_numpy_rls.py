#!/usr/bin/env python3
"""The baseline of docs/benchmarks.md: RLS (paper eqs. 9-12) as a plain per-sample numpy loop.

The same equations and data layout as `ipa-sysid bench rls`: n parameters (default 9), regressors
uniform in [-1, 1] cycled from a ring of 1024, y = phi' theta* + 0.01 e, forgetting factor rho
(default 0.99), P(0) = 1e3 I. Each update:

    eps   = y - phi @ theta
    Pphi  = P @ phi
    d     = rho + phi @ Pphi
    L     = Pphi / d
    theta = theta + L * eps
    P     = (P - np.outer(Pphi, Pphi) / d) / rho     # = (P - L (P phi)') / rho, kept exactly symmetric

(Written as np.outer(L, Pphi) the update lets P drift from symmetry, and with rho < 1 the antisymmetric
part grows like rho^-k until P overflows after a few thousand samples; the Rust code keeps P exactly
symmetric too.)

Prints samples/s (best of --repetitions) and, with --json OUT, writes them as JSON.
Usage: python3 scripts/bench_numpy_rls.py [--params 9] [--samples 200000] [--repetitions 5] [--json OUT]
"""

import argparse
import json
import time

import numpy as np


def run(n, samples, rho, phi, y):
    theta = np.zeros(n)
    P = np.eye(n) * 1e3
    ring = len(y)
    t0 = time.perf_counter()
    for k in range(samples):
        f = phi[k % ring]
        eps = y[k % ring] - f @ theta
        pphi = P @ f
        d = rho + f @ pphi
        L = pphi / d
        theta = theta + L * eps
        P = (P - np.outer(pphi, pphi) / d) / rho
    return time.perf_counter() - t0, theta


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--params", type=int, default=9)
    ap.add_argument("--samples", type=int, default=200_000)
    ap.add_argument("--repetitions", type=int, default=5)
    ap.add_argument("--forgetting", type=float, default=0.99)
    ap.add_argument("--json", default=None)
    a = ap.parse_args()
    if a.params < 1 or a.samples < 1 or a.repetitions < 1 or not (0 < a.forgetting <= 1):
        ap.error("--params, --samples, --repetitions must be >= 1 and --forgetting in (0, 1]")
    rng = np.random.default_rng(42)
    truth = rng.uniform(-1, 1, a.params)
    phi = rng.uniform(-1, 1, (1024, a.params))
    y = phi @ truth + 0.01 * rng.standard_normal(1024)
    best = min(run(a.params, a.samples, a.forgetting, phi, y)[0] for _ in range(a.repetitions))
    sps = a.samples / best
    print(f"numpy per-sample RLS, n = {a.params}, rho = {a.forgetting}: {sps:.4e} samples/s "
          f"({1e9 / sps:.0f} ns/update, best of {a.repetitions}, numpy {np.__version__})")
    if a.json:
        with open(a.json, "w") as fh:
            json.dump({"benchmark": "numpy_rls", "params": a.params, "samples": a.samples,
                       "forgetting": a.forgetting, "samples_per_second": sps,
                       "numpy": np.__version__}, fh, indent=2)
            fh.write("\n")


if __name__ == "__main__":
    main()
