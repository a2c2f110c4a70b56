#!/usr/bin/env python3
"""One worker thread against two, in the same run: `ipa-sysid order --method oe` and batch `identify`
(several files, no --merge) with RAYON_NUM_THREADS=1 and =2, alternating, in rounds; prints the median
wall time and CPU time (all threads) of each and the speed-up, and checks that both thread counts print
byte-identical results. CPU / wall above 1 shows the work running on both cores at once; on a machine
shared by other sessions, Linux's autogroup scheduler may hold the whole session to its share of the CPUs
whatever its thread count, and then the wall time cannot fall.

    python3 scripts/bench_threads.py [--bin target/release/ipa-sysid] [--rounds 3] [--files 100]

The records are simulated by the binary itself into a temporary folder (physics plant, staircase input,
2000 samples per batch file; one 10 000-sample record for the order search), so nothing outside the
repository is needed.
"""
import argparse
import os
import resource
import statistics
import subprocess
import tempfile
import time
from pathlib import Path


def cpu_seconds():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def timed(binary, args, threads):
    """Wall time, CPU time (user + system, all threads) and standard output of one run."""
    env = dict(os.environ, RAYON_NUM_THREADS=str(threads))
    c = cpu_seconds()
    t = time.perf_counter()
    r = subprocess.run([binary, *args], env=env, capture_output=True, check=True)
    return time.perf_counter() - t, cpu_seconds() - c, r.stdout


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="target/release/ipa-sysid")
    ap.add_argument("--rounds", type=int, default=3)
    ap.add_argument("--files", type=int, default=100, help="files of the batch identification")
    a = ap.parse_args()
    binary = str(Path(a.bin).resolve())
    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        files = []
        for i in range(a.files):
            f = tmp / f"rec{i:04}.csv"
            subprocess.run([binary, "simulate", "--plant", "ipa", "--seed", str(i + 1), "--out", str(f)],
                           check=True, capture_output=True)
            files.append(str(f))
        long = tmp / "long.csv"
        subprocess.run([binary, "simulate", "--plant", "ipa", "--seed", "1", "--samples", "10000",
                        "--out", str(long)], check=True, capture_output=True)
        work = {
            f"batch identify, {a.files} files x 2000 samples, Hammerstein LS":
                ["identify", "--data", *files, "--method", "ls"],
            f"batch identify, {a.files} files x 2000 samples, Hammerstein OE":
                ["identify", "--data", *files, "--method", "oe"],
            "order --method oe, ARX, na 1..4 nb 1..3 nk 1..2 (24 structures), 10 000 samples":
                ["order", "--data", str(long), "--model", "arx", "--method", "oe",
                 "--na", "1..4", "--nb", "1..3", "--nk", "1..2", "--json", "-"],
        }
        print(f"median wall time of {a.rounds} rounds, RAYON_NUM_THREADS = 1 | 2 (alternating):")
        for name, args in work.items():
            times = {1: [], 2: []}
            cpu = {1: [], 2: []}
            outputs = {}
            for _ in range(a.rounds):
                for threads in (1, 2):
                    t, c, out = timed(binary, args, threads)
                    times[threads].append(t)
                    cpu[threads].append(c)
                    outputs.setdefault(threads, out)
                    if out != outputs[threads]:
                        raise SystemExit(f"{name}: output changed between rounds")
            same = outputs[1] == outputs[2]
            m1, m2 = statistics.median(times[1]), statistics.median(times[2])
            c1, c2 = statistics.median(cpu[1]), statistics.median(cpu[2])
            print(f"  {name}\n    1 thread {m1:.3f} s ({min(times[1]):.3f}..{max(times[1]):.3f}), "
                  f"2 threads {m2:.3f} s ({min(times[2]):.3f}..{max(times[2]):.3f}), speed-up {m1 / m2:.2f}; "
                  f"outputs {'identical' if same else 'DIFFER'}\n"
                  f"    CPU time (all threads) {c1:.3f} s | {c2:.3f} s, CPUs used (CPU / wall) {c1 / m1:.2f} | {c2 / m2:.2f}")
            if not same:
                raise SystemExit(1)


if __name__ == "__main__":
    main()
