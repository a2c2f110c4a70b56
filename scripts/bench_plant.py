#!/usr/bin/env python3
"""Real-time factor of the physics plant: `ipa-sysid bench plant --reference` (the production
Dormand-Prince integrator and the previous RK4 integrator timed in the same run) and the end-to-end
`ipa-sysid simulate --plant ipa --samples N` (input design, simulation and CSV writing; per wall-clock
second and per CPU second of the process, which a loaded machine does not inflate), and `bench plant`
per CPU second, repeated in rounds; prints the median over the rounds (the machine is shared: single
runs are noisy).

    python3 scripts/bench_plant.py [--bin target/release/ipa-sysid] [--before OLD_BINARY] [--rounds 5]

--before times an older build of ipa-sysid (e.g. the commit before the change) in the same rounds.
"""
import argparse
import json
import resource
import statistics
import subprocess
import tempfile
import time
from pathlib import Path


def bench_plant(binary, reference, reps, samples):
    cmd = [binary, "bench", "plant", "--repetitions", str(reps), "--samples", str(samples), "--json", "-"]
    if reference:
        cmd.append("--reference")
    out = subprocess.run(cmd, check=True, capture_output=True, text=True).stdout
    return json.loads(out)


def cpu_seconds():
    r = resource.getrusage(resource.RUSAGE_CHILDREN)
    return r.ru_utime + r.ru_stime


def simulate_rtf(binary, samples, out_csv):
    """Real-time factors of one `simulate` run: per wall-clock second and per CPU second (user + system)."""
    cpu = cpu_seconds()
    start = time.perf_counter()
    subprocess.run(
        [binary, "simulate", "--plant", "ipa", "--samples", str(samples), "--out", str(out_csv)],
        check=True,
        capture_output=True,
    )
    wall = time.perf_counter() - start
    cpu = cpu_seconds() - cpu
    return samples * 0.01 / wall, samples * 0.01 / cpu


def bench_plant_cpu(binary, samples):
    """Real-time factor of `bench plant` per CPU second: the CPU time of a run with 5 timed repetitions
    minus that of a run with 1 (input design, warm-up and start-up cancel), over the 4 extra runs."""
    def cpu_of(reps):
        c = cpu_seconds()
        subprocess.run([binary, "bench", "plant", "--repetitions", str(reps), "--samples", str(samples)],
                       check=True, capture_output=True)
        return cpu_seconds() - c
    per_run = (cpu_of(5) - cpu_of(1)) / 4
    return samples * 0.01 / per_run


def main():
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--bin", default="target/release/ipa-sysid")
    ap.add_argument("--before", help="an older ipa-sysid binary, timed in the same rounds")
    ap.add_argument("--rounds", type=int, default=5)
    ap.add_argument("--repetitions", type=int, default=5, help="timed runs inside each bench plant call")
    ap.add_argument("--bench-samples", type=int, default=6000)
    ap.add_argument("--simulate-samples", type=int, default=200000)
    ap.add_argument("--cpu-samples", type=int, default=200000,
                    help="samples of the bench plant runs timed per CPU second (0: skip)")
    a = ap.parse_args()
    rows = {}

    def add(key, value):
        rows.setdefault(key, []).append(value)

    with tempfile.TemporaryDirectory() as tmp:
        csv = Path(tmp) / "x.csv"
        for _ in range(a.rounds):
            r = bench_plant(a.bin, True, a.repetitions, a.bench_samples)
            add("bench plant: Dormand-Prince (median of its runs)", r["median_real_time_factor"])
            add("bench plant: RK4 reference, same run (median of its runs)", r["reference"]["median_real_time_factor"])
            add("bench plant: speed-up (median/median)", r["reference"]["median_speedup"])
            wall, cpu = simulate_rtf(a.bin, a.simulate_samples, csv)
            add(f"simulate --samples {a.simulate_samples}: end-to-end", wall)
            add(f"simulate --samples {a.simulate_samples}: end-to-end per CPU second", cpu)
            if a.cpu_samples:
                add(f"bench plant --samples {a.cpu_samples}: per CPU second", bench_plant_cpu(a.bin, a.cpu_samples))
            if a.before:
                if a.cpu_samples:
                    add(f"before: bench plant --samples {a.cpu_samples}: per CPU second",
                        bench_plant_cpu(a.before, a.cpu_samples))
                rb = bench_plant(a.before, False, a.repetitions, a.bench_samples)
                add("before: bench plant (median of its runs)", rb["median_real_time_factor"])
                wall, cpu = simulate_rtf(a.before, a.simulate_samples, csv)
                add(f"before: simulate --samples {a.simulate_samples}: end-to-end", wall)
                add(f"before: simulate --samples {a.simulate_samples}: per CPU second", cpu)
    print(f"real-time factor, median of {a.rounds} rounds (min..max):")
    for key, vals in rows.items():
        print(f"  {key:<62} {statistics.median(vals):8.2f}  ({min(vals):.2f}..{max(vals):.2f})")


if __name__ == "__main__":
    main()
