#!/usr/bin/env bash
# Feasibility oracle for issue 25's |e_ss| targets (docs/control.md, "Can any command land within
# 0.02 mm?"): the smallest move from rest and the landing precision of any per-sample command sequence
# (pulses, ramp + cut at any sample, ramp + cut + reverse brake pulse) on the physics plant, nominal
# (variant 0) and the verification's variants 1..20 (±30 %). Arguments: variant numbers (default all).
# Usage: scripts/stiction_oracle.sh [VARIANT...]
set -euo pipefail
cd "$(dirname "$0")/.."
exec cargo run --quiet --release -p ipa --example stiction_oracle -- "$@"
