#!/usr/bin/env python3
"""Best-of and median ns per update of the last `cargo bench -p ipa-embedded --bench rls` run.

Criterion's mean is the mean over all its samples, and on a shared machine many samples are
interrupted by other processes; docs/benchmarks.md reports the *best* sample (the run least disturbed)
with the median beside it. This reads target/criterion/<group>/<bench>/new/sample.json (per sample: the
iteration count and the total time in ns) and prints one markdown row per benchmark, with the ratio of
each best time to the peer's (oxictl) best in the same group.

Usage: python3 crates/embedded/benches/best_of.py [TARGET_DIR]
"""

import json
import statistics
import sys
from pathlib import Path

GROUPS = ["f64-n4", "f64-n9", "f32-n4", "f32-n9", "hammerstein"]


def per_iteration(sample_json: Path) -> list[float]:
    d = json.loads(sample_json.read_text())
    return [t / i for t, i in zip(d["times"], d["iters"])]


def main() -> None:
    root = Path(sys.argv[1] if len(sys.argv) > 1 else "target") / "criterion"
    print("| group | benchmark | best ns | median ns | best / oxictl best |")
    print("|---|---|---|---|---|")
    for group in GROUPS:
        rows = []
        for sample in sorted((root / group).glob("*/*/new/sample.json")):
            bench = f"{sample.parent.parent.parent.name}/{sample.parent.parent.name}"
            ns = per_iteration(sample)
            rows.append((bench, min(ns), statistics.median(ns)))
        peer = next((best for bench, best, _ in rows if bench.startswith("oxictl")), None)
        for bench, best, median in rows:
            ratio = f"{best / peer:.2f}" if peer else "—"
            print(f"| {group} | {bench} | {best:.1f} | {median:.1f} | {ratio} |")


if __name__ == "__main__":
    main()
