#!/usr/bin/env python3
"""Speed of the Python package (docs/benchmarks.md, section "Python package").

1. RLS: ipa_sysid.Rls.update_many with n = 9 against padasip's FilterRLS (pure Python/numpy), the
   same regressors and measurements, in the same run; the two estimates are compared as a check that
   both did the same computation (rho = 1, P(0) = 1e6 I, i.e. padasip eps = 1e-6).
2. identify: ipa_sysid.identify (Hammerstein, na = 3, nb = 1, nk = 1, method rls and ls, 2000 samples of
   the paper model, including the metrics and the JSON report) against the same identification inside
   the command line, `ipa-sysid bench identify` (estimation only, timed in-process, on the paper
   model's own 2000-sample staircase record, so LS iteration counts may differ), and against the whole
   `ipa-sysid identify` process on the very record Python used.

Usage (from the repository root, in a venv with the package built in release mode and padasip):

    python -m venv target/bench-venv
    target/bench-venv/bin/pip install ./python padasip
    cargo build --release -p ipa-sysid
    target/bench-venv/bin/python scripts/bench_python.py [--cli target/release/ipa-sysid]

Timings are the best of several repetitions (wall clock, time.perf_counter).
"""

import argparse
import json
import platform
import subprocess
import sys
import time
from importlib import metadata

import numpy as np

import ipa_sysid


def best_of(reps, f):
    best = float("inf")
    for _ in range(reps):
        t0 = time.perf_counter()
        f()
        best = min(best, time.perf_counter() - t0)
    return best


def bench_rls(n, n_ours, n_peer, reps):
    import padasip as pa

    rng = np.random.default_rng(1)
    Phi = rng.normal(size=(n_ours, n))
    theta = rng.normal(size=n)
    y = Phi @ theta + rng.normal(0, 0.01, n_ours)

    def ours():
        ipa_sysid.Rls(n, forgetting=1.0, p0=1e6).update_many(Phi, y)

    t_ours = best_of(reps, ours)

    def peer():
        f = pa.filters.FilterRLS(n=n, mu=1.0, eps=1e-6, w="zeros")
        f.run(y[:n_peer], Phi[:n_peer])
        return f

    t_peer = best_of(max(1, reps // 2), peer)
    # The same computation: both estimates after n_peer samples.
    r = ipa_sysid.Rls(n, forgetting=1.0, p0=1e6)
    r.update_many(Phi[:n_peer], y[:n_peer])
    f = peer()
    diff = float(np.max(np.abs(r.theta - f.w)))
    return {
        "n": n,
        "ours_samples": n_ours,
        "ours_updates_per_s": n_ours / t_ours,
        "padasip_samples": n_peer,
        "padasip_updates_per_s": n_peer / t_peer,
        "speedup": (n_ours / t_ours) / (n_peer / t_peer),
        "max_abs_theta_difference": diff,
    }


def bench_identify(cli, reps):
    doc = json.loads(
        subprocess.run(
            [cli, "bench", "identify", "--repetitions", str(reps), "--json", "-"],
            capture_output=True, text=True, check=True,
        ).stdout
    )
    _, u, y, _ = ipa_sysid.simulate_plant("paper", input="staircase", samples=2000, seed=1,
                                          noise_std=0.01)
    import os
    import tempfile

    tmp = tempfile.mkdtemp()
    csv_path = os.path.join(tmp, "paper.csv")
    with open(csv_path, "w") as f:
        f.write("u,y\n" + "".join(f"{float(a)!r},{float(b)!r}\n" for a, b in zip(u, y)))
    out = {}
    for method in ("rls", "ls"):
        fit = ipa_sysid.identify(u, y, 0.01, method=method)
        t = best_of(reps, lambda: ipa_sysid.identify(u, y, 0.01, method=method))
        cli_t = doc[method]["seconds_per_identification"]
        # The whole command on the same record: process start, CSV parsing, identification, metrics.
        cmd = [cli, "identify", "--data", csv_path, "--ts", "0.01", "--method", method,
               "--json", os.path.join(tmp, "fit.json")]
        proc_t = best_of(reps, lambda: subprocess.run(cmd, capture_output=True, check=True))
        out[method] = {
            "python_s": t,
            "python_iterations": fit.estimation["iterations"],
            "cli_s": cli_t,
            "cli_iterations": doc[method]["iterations"],
            "ratio_python_over_cli": t / cli_t,
            "cli_process_same_record_s": proc_t,
        }
    return out


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--cli", default="target/release/ipa-sysid")
    ap.add_argument("--reps", type=int, default=7)
    ap.add_argument("--rls-samples", type=int, default=1_000_000)
    ap.add_argument("--padasip-samples", type=int, default=20_000)
    args = ap.parse_args()

    env = {
        "python": sys.version.split()[0],
        "platform": platform.platform(),
        "machine": platform.machine(),
        "processor": platform.processor() or "n/a",
        "ipa_sysid": ipa_sysid.__version__,
        "numpy": np.__version__,
        "padasip": metadata.version("padasip"),
    }
    print("environment:", json.dumps(env))
    rls = bench_rls(9, args.rls_samples, args.padasip_samples, args.reps)
    print(
        f"RLS n = 9: ipa_sysid.Rls.update_many {rls['ours_updates_per_s']:.3e} updates/s "
        f"({rls['ours_samples']} samples), padasip FilterRLS {rls['padasip_updates_per_s']:.3e} "
        f"updates/s ({rls['padasip_samples']} samples): {rls['speedup']:.0f}x; "
        f"max |theta difference| {rls['max_abs_theta_difference']:.2e}"
    )
    ident = bench_identify(args.cli, args.reps)
    for m, r in ident.items():
        print(
            f"identify {m}: Python {r['python_s'] * 1e3:.3f} ms ({r['python_iterations']} iterations), "
            f"CLI bench {r['cli_s'] * 1e3:.3f} ms ({r['cli_iterations']} iterations): "
            f"ratio {r['ratio_python_over_cli']:.2f}; whole CLI process on the same record "
            f"{r['cli_process_same_record_s'] * 1e3:.3f} ms"
        )
    print(json.dumps({"environment": env, "rls": rls, "identify": ident}))


if __name__ == "__main__":
    main()
