#!/bin/sh
# Throughput of `ipa-sysid track` from standard input (docs/benchmarks.md, docs/online.md):
# simulates N samples of the paper's plant (default 2 000 000), pipes them through
# `track --data - --every N` (one JSON line at the end) and prints samples per second.
#   scripts/bench_track.sh [N]
set -eu
N=${1:-2000000}
B=${IPA_SYSID:-target/release/ipa-sysid}
DIR=$(mktemp -d)
trap 'rm -rf "$DIR"' EXIT
"$B" simulate --plant paper --input aprbs --samples "$N" --noise-std 0.01 --seed 1 --out "$DIR/big.csv" 2>/dev/null
for args in "" "--windup none --no-detect"; do
    start=$(date +%s.%N)
    cat "$DIR/big.csv" | "$B" track --data - --every "$N" $args >/dev/null 2>&1
    end=$(date +%s.%N)
    awk -v n="$N" -v a="$start" -v b="$end" -v args="$args" \
        'BEGIN { printf "track %s: %d samples in %.3f s = %.3g samples/s\n", args, n, b - a, n / (b - a) }'
done
echo "load: $(uptime)"
