#!/usr/bin/env bash
# Records the outputs of a fixed set of commands into DIR, so that a refactoring can be shown to change
# nothing but timing: run it before and after, then `scripts/golden.sh --compare BEFORE AFTER`.
# Usage: scripts/golden.sh DIR [BIN]        (BIN defaults to target/release/ipa-sysid)
#        scripts/golden.sh --compare A B
set -euo pipefail
if [ "${1:-}" = "--compare" ]; then
  # Timing fields are the only ones allowed to differ.
  strip() { sed -E 's/("(elapsed|seconds|wall|time_s|duration_s|runtime_s)[a-z_]*": *)[0-9.eE+-]+/\1T/g; s/[0-9.]+ ?(ms|µs|s) \(wall\)/T (wall)/g; s/in [0-9.]+ ?(s|ms)\b/in T/g; s/Elapsed: [0-9.]+ s/Elapsed: T/g' "$1"; }
  status=0
  for f in $(cd "$2" && find . -type f | sort); do
    if [ ! -f "$3/$f" ]; then echo "missing in $3: $f"; status=1; continue; fi
    if ! diff -q <(strip "$2/$f") <(strip "$3/$f") >/dev/null; then
      # (`|| true`: diff exits 1 on a difference, which pipefail and -e would turn into an exit here)
      echo "differs: $f"; diff <(strip "$2/$f") <(strip "$3/$f") | head -20 || true; status=1
    fi
  done
  [ $status = 0 ] && echo "identical: $(cd "$2" && find . -type f | wc -l) files"
  exit $status
fi
out=$1; bin=${2:-target/release/ipa-sysid}
bin=$(cd "$(dirname "$bin")" && pwd)/$(basename "$bin")
mkdir -p "$out"; out=$(cd "$out" && pwd)
cd "$(mktemp -d)"
run() { local name=$1; shift; "$bin" "$@" >"$out/$name.out" 2>"$out/$name.err" || echo "exit $?" >>"$out/$name.err"; }
# README worked example
run sim1 simulate --plant ipa --seed 1 --out est.csv
run sim2 simulate --plant ipa --seed 2 --out val.csv
cp est.csv val.csv "$out/"
run readme_identify identify --data est.csv --validation val.csv --method oe --save-model model.json
cp model.json "$out/readme_model.json"
run readme_validate validate --model model.json --data val.csv
run readme_validate_json validate --model model.json --data val.csv --json -
run readme_control control --plant model:model.json --setpoint 50 --duration 10
# identify --json for each method and structure
for kind in arx hammerstein; do
  for m in ls rls oe iv; do
    run "identify_${kind}_${m}" identify --data est.csv --validation val.csv --model $kind --method $m --json - --save-model "m_${kind}_${m}.json"
    cp "m_${kind}_${m}.json" "$out/" 2>/dev/null || true
  done
done
run identify_rls_passes identify --data est.csv --method rls --passes 5 --forgetting 0.99 --json -
run identify_rls_ud identify --data est.csv --method rls --rls-form ud --windup trace --json -
run identify_offset identify --data est.csv --model arx --na 2 --nb 2 --nk 1 --method ls --offset --json -
run identify_text_ls identify --data est.csv --method ls
run simulate_paper simulate --plant paper --seed 3 --samples 500 --out paper.csv
cp paper.csv "$out/"
run identify_paper identify --data paper.csv --method rls --passes 20 --json -
# control
run control_json control --plant ipa --setpoint 50 --duration 5 --json -
run control_paper control --plant paper --profile staircase:50,120@2 --json -
run control_comp control --plant ipa --setpoint 50 --duration 5 --compensate-deadzone m_hammerstein_oe.json --json -
# validate
run validate_ls validate --model m_hammerstein_ls.json --data val.csv
# order
run order order --data est.csv --validation val.csv --na 1..3 --nb 1..2 --nk 1..2 --model arx --json -
# reproduce
run reproduce reproduce --out rep
cp rep/summary.json "$out/reproduce_summary.json"
for f in rep/data/*.csv; do cp "$f" "$out/reproduce_$(basename "$f")"; done
# errors
run err_missing identify --data nonexistent.csv
printf 't,u,y\n0,1,2\n0.01,x,3\n' > bad.csv
run err_bad identify --data bad.csv
echo "recorded $(ls "$out" | wc -l) files in $out"
