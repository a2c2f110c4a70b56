#!/bin/sh
# Throughput of `ipa-sysid track` from standard input (docs/online.md, docs/benchmarks.md): simulates N
# samples of the paper's plant (default 2 000 000, 63 MB of CSV), pipes them R times (default 5)
# through `track --data - --every N` (one JSON line at the end) and prints the best run in samples/s,
# for the defaults (trace windup guard, change detector), with --guard --restart-on-change, and for the
# plain paper RLS.
#   scripts/bench_track.sh [N [R]]      (IPA_SYSID=path/to/ipa-sysid to use another binary)
set -eu
N=${1:-2000000}
R=${2:-5}
B=${IPA_SYSID:-target/release/ipa-sysid}
DIR=$(mktemp -d)
trap 'rm -rf "$DIR"' EXIT
"$B" simulate --plant paper --input aprbs --samples "$N" --noise-std 0.01 --seed 1 --out "$DIR/big.csv" 2>/dev/null
for args in "" "--guard --restart-on-change" "--windup none --no-detect"; do
    best=""
    i=0
    while [ "$i" -lt "$R" ]; do
        start=$(date +%s.%N)
        cat "$DIR/big.csv" | "$B" track --data - --every "$N" $args >/dev/null 2>&1
        end=$(date +%s.%N)
        best=$(awk -v a="$start" -v b="$end" -v best="$best" 'BEGIN { d = b - a; if (best == "" || d < best) print d; else print best }')
        i=$((i + 1))
    done
    awk -v n="$N" -v d="$best" -v args="${args:-(defaults)}" \
        'BEGIN { printf "track %s: %d samples, best of runs %.3f s = %.3g samples/s\n", args, n, d, n / d }'
done
echo "load: $(uptime)"
