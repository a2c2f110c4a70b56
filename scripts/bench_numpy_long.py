#!/usr/bin/env python3
"""The numpy peer of `ipa-sysid bench long`: ARX(na, nb, nk) least squares on a long CSV record.

Reads the columns u and y of a CSV file with a header row (numpy.loadtxt), builds the same regression as
`ipa-sysid identify --structure arx --method ls` (rows k = k0..N-1, k0 = max(na, nk + nb - 1),
phi(k) = [-y(k-1) .. -y(k-na), u(k-nk) .. u(k-nk-nb+1)], target y(k)) and solves it with
numpy.linalg.lstsq (LAPACK gelsd). Prints and, with --json OUT, writes: the numpy and Python versions,
seconds to read, to build the regression and to solve, the peak resident memory of this process
(getrusage ru_maxrss) and theta = [a1..a_na, b1..b_nb].

Usage: python3 scripts/bench_numpy_long.py --data FILE [--na 3 --nb 1 --nk 1] [--json OUT]
"""

import argparse
import json
import platform
import resource
import sys
import time

import numpy as np


def main():
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--data", required=True)
    ap.add_argument("--na", type=int, default=3)
    ap.add_argument("--nb", type=int, default=1)
    ap.add_argument("--nk", type=int, default=1)
    ap.add_argument("--u-col", default="u")
    ap.add_argument("--y-col", default="y")
    ap.add_argument("--json")
    a = ap.parse_args()

    t0 = time.perf_counter()
    with open(a.data) as f:
        header = [h.strip() for h in f.readline().split(",")]
    cols = (header.index(a.u_col), header.index(a.y_col))
    uy = np.loadtxt(a.data, delimiter=",", skiprows=1, usecols=cols, dtype=np.float64)
    u, y = uy[:, 0], uy[:, 1]
    t1 = time.perf_counter()

    n = len(y)
    k0 = max(a.na, a.nk + a.nb - 1)
    rows = n - k0
    phi = np.empty((rows, a.na + a.nb))
    for i in range(1, a.na + 1):
        phi[:, i - 1] = -y[k0 - i : n - i]
    for j in range(a.nb):
        phi[:, a.na + j] = u[k0 - a.nk - j : n - a.nk - j]
    target = y[k0:]
    t2 = time.perf_counter()

    theta, _, rank, _ = np.linalg.lstsq(phi, target, rcond=None)
    t3 = time.perf_counter()

    out = {
        "rows": n,
        "numpy": np.__version__,
        "python": platform.python_version(),
        "read_s": t1 - t0,
        "build_s": t2 - t1,
        "solve_s": t3 - t2,
        "total_s": t3 - t0,
        "rank": int(rank),
        # ru_maxrss is in KiB on Linux (bytes on macOS).
        "peak_rss_bytes": resource.getrusage(resource.RUSAGE_SELF).ru_maxrss
        * (1 if sys.platform == "darwin" else 1024),
        "theta": theta.tolist(),
    }
    print(
        f"numpy {out['numpy']}: {n} rows, read {out['read_s']:.2f} s, regression {out['build_s']:.2f} s, "
        f"lstsq {out['solve_s']:.2f} s, peak RSS {out['peak_rss_bytes'] / 2**20:.0f} MiB"
    )
    if a.json:
        with open(a.json, "w") as f:
            json.dump(out, f, indent=2)


if __name__ == "__main__":
    main()
