#!/usr/bin/env bash
# Time oracle for issue 25's settling and rise-time targets (docs/control.md, "How fast can any command
# settle? (the time oracle)"): on the verification's 168 runs (physics plant nominal + variants 1..20,
# ±30 %; steps 10/30/70/150 mm both ways, 3 s), the lower bounds of the 2 % settling and 10–90 % rise
# times (full command), the best settling time of the bang-bang open-loop family, and the settling
# times of a controller file and of the paper's PI; then Table V's nominal 50 mm step.
# Without a CONTROLLER.json argument the (B) controller of docs/control.md's Results is made first
# (its commands: simulate, calibrate, tune on the twin with the defaults) in a temporary directory.
# Usage: scripts/time_oracle.sh [CONTROLLER.json] [VARIANT...]   (ROWS=1: a line per run)
set -euo pipefail
cd "$(dirname "$0")/.."
if [[ "${1:-}" != *.json ]]; then
    dir=$(mktemp -d)
    trap 'rm -rf "$dir"' EXIT
    cli=(cargo run --quiet --release -p ipa-sysid --)
    "${cli[@]}" simulate --input calibration --samples 3000 --seed 1 --out "$dir/rec.csv" >/dev/null
    "${cli[@]}" calibrate --data "$dir/rec.csv" --out "$dir/twin.toml" --no-baseline >/dev/null
    "${cli[@]}" tune --plant-config "$dir/twin.toml" --check-physics --out "$dir/c5.json" >/dev/null
    set -- "$dir/c5.json" "$@"
fi
cargo run --quiet --release -p control --example time_oracle -- "$@"
