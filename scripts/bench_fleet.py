#!/usr/bin/env python3
"""Fleet monitoring on Dask: throughput, scaling, Dask's overhead per actuator, and detection
(docs/benchmarks.md, section "Fleet on Dask"; docs/fleet.md).

1. A fleet of --actuators physics IPAs (--worn fraction worn, --windows windows of 2000 samples each) is
   simulated by `ipa-sysid simulate --fleet` into target/bench-fleet/records (kept between runs of the
   same settings).
2. In this process, without Dask: `identify_partition` on one Parquet file (the identification's own
   time per window).
3. `ipa_sysid.fleet.run` on a LocalCluster of 1 worker, then of 2 (one thread per worker process), each
   after a warm-up task on every worker: wall time, actuator-windows per second, scaling, and Dask's
   overhead per actuator = (1-worker wall time - in-process time of all partitions) / actuators.
4. Detection: `fleet.worn(results)` against truth.csv: worn found, worn missed, healthy flagged.
5. The worn-valve report (target/bench-fleet/worn.html) and the fleet-at-a-glance figure (--figure,
   docs/fleet-glance.svg).

Usage (from the repository root; the package built in release mode with the extra):

    python3 -m venv target/fleet-venv
    target/fleet-venv/bin/pip install "./python[fleet]"
    cargo build --release -p ipa-sysid
    target/fleet-venv/bin/python scripts/bench_fleet.py --cli target/release/ipa-sysid
"""

import argparse
import glob
import os
import platform
import shutil
import subprocess
import time
from importlib import metadata

import pandas as pd
from dask.distributed import Client, LocalCluster

from ipa_sysid import fleet


def simulate(cli, out, actuators, worn, windows, seed):
    stamp = os.path.join(out, ".settings")
    settings = f"{actuators} {worn} {windows} {seed}"
    if os.path.exists(stamp) and open(stamp).read() == settings:
        return 0.0
    if os.path.exists(out):
        shutil.rmtree(out)
    t0 = time.perf_counter()
    subprocess.run(
        [cli, "simulate", "--fleet", str(actuators), "--worn", str(worn), "--windows", str(windows),
         "--seed", str(seed), "--out", out],
        check=True,
    )
    seconds = time.perf_counter() - t0
    with open(stamp, "w") as f:
        f.write(settings)
    return seconds


def on_cluster(workers, records, results_dir):
    with LocalCluster(
        n_workers=workers, threads_per_worker=1, processes=True, dashboard_address=":0"
    ) as cluster, Client(cluster) as client:
        # Warm-up: import the package on every worker.
        client.run(lambda: __import__("ipa_sysid.fleet"))
        t0 = time.perf_counter()
        results = fleet.run(records, results_dir, client=client)
        return time.perf_counter() - t0, results


def main():
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--cli", default="target/release/ipa-sysid")
    ap.add_argument("--actuators", type=int, default=1000)
    ap.add_argument("--worn", type=float, default=0.05)
    ap.add_argument("--windows", type=int, default=10)
    ap.add_argument("--seed", type=int, default=1)
    ap.add_argument("--out", default="target/bench-fleet")
    ap.add_argument("--figure", default=None, help="write the fleet-at-a-glance SVG here too")
    args = ap.parse_args()

    records = os.path.join(args.out, "records")
    os.makedirs(args.out, exist_ok=True)
    sim = simulate(args.cli, records, args.actuators, args.worn, args.windows, args.seed)
    files = sorted(glob.glob(os.path.join(records, "*.parquet")))
    windows_total = args.actuators * args.windows

    print(f"machine: {platform.processor() or platform.machine()}, {os.cpu_count()} CPUs, "
          f"load average at start {os.getloadavg()[0]:.2f}")
    print(f"versions: python {platform.python_version()}, ipa-sysid {metadata.version('ipa-sysid')}, "
          f"dask {metadata.version('dask')}, distributed {metadata.version('distributed')}, "
          f"pandas {pd.__version__}, pyarrow {metadata.version('pyarrow')}")
    print(f"fleet: {args.actuators} actuators x {args.windows} windows of 2000 samples "
          f"({windows_total} actuator-windows) in {len(files)} Parquet files"
          + (f"; simulated in {sim:.1f} s" if sim else " (already simulated)"))

    # In-process, no Dask: read + identify every partition once.
    t_read = t_ident = cpu_ident = 0.0
    for f in files:
        t0 = time.perf_counter()
        part = pd.read_parquet(f)
        t1 = time.perf_counter()
        c1 = time.process_time()
        fleet.identify_partition(part)
        cpu_ident += time.process_time() - c1
        t2 = time.perf_counter()
        t_read += t1 - t0
        t_ident += t2 - t1
    serial = t_read + t_ident
    print(f"in-process, no Dask: identify_partition {1e3 * t_ident / windows_total:.3f} ms per window "
          f"(CPU time {1e3 * cpu_ident / windows_total:.3f} ms), "
          f"reading {1e3 * t_read / windows_total:.3f} ms per window; all partitions {serial:.2f} s "
          f"({windows_total / serial:.0f} windows/s)")

    timings = {}
    for workers in (1, 2):
        seconds, results = on_cluster(workers, records, os.path.join(args.out, f"results-{workers}"))
        timings[workers] = seconds
        print(f"Dask LocalCluster, {workers} worker(s) x 1 thread: {seconds:.2f} s, "
              f"{windows_total / seconds:.0f} actuator-windows/s")
    print(f"scaling 1 -> 2 workers: {timings[1] / timings[2]:.2f} x")
    overhead = (timings[1] - serial) / args.actuators
    print(f"Dask overhead per actuator (1 worker wall time - in-process time) / actuators: "
          f"{1e3 * overhead:.3f} ms, against {1e3 * t_ident / args.actuators:.3f} ms of identification "
          f"per actuator")

    truth = pd.read_csv(os.path.join(records, "truth.csv"))
    worn_ids = set(truth[truth["worn"]]["actuator_id"])
    flagged = fleet.report(results, os.path.join(args.out, "worn.html"))
    found = set(flagged["actuator_id"])
    tr = fleet.trends(results)
    print(f"detection (alpha = {fleet.ALPHA}, threshold p < {tr['threshold'].iloc[0]:.2e}): "
          f"{len(found & worn_ids)} of {len(worn_ids)} worn flagged, {len(worn_ids - found)} missed, "
          f"{len(found - worn_ids)} of {args.actuators - len(worn_ids)} healthy flagged")
    healthy = tr[~tr["actuator_id"].isin(worn_ids)]
    worn_tr = tr[tr["actuator_id"].isin(worn_ids)]
    print(f"  smallest p among healthy: {healthy['p_value'].min():.3e}; largest p among worn: "
          f"{worn_tr['p_value'].max():.3e}")
    print(f"  windows with a warning: {(results['warnings'] != '').sum()} of {len(results)}; "
          f"windows with a tracker change point: {(results['changes'] > 0).sum()}; "
          f"windows not identified: {(results['error'] != '').sum()}")
    print(f"report: {os.path.join(args.out, 'worn.html')}")
    if args.figure:
        with open(args.figure, "w", encoding="utf-8") as f:
            f.write(fleet.glance_svg(tr) + "\n")
        print(f"figure: {args.figure}")


if __name__ == "__main__":
    main()
