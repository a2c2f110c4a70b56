#!/usr/bin/env bash
# Regenerates every number of docs/real-data.md: runs the release binary on the measured records and prints
# the tables (Markdown) with the command behind each row. Nothing is split by hand: estimation and test parts
# come from --rows/--val-rows/--split, separate columns or --merge.
#
#   cargo build --release -p ipa-sysid
#   DATA=/path/to/the/shared/data scripts/real_data.sh [BINARY] > /tmp/real-data.md
#
# DATA (required) is the folder of the shared measured data sets (read only, never copied into the
# repository). Needs jq.
set -euo pipefail
root=$(cd "$(dirname "$0")/.." && pwd)
bin=${1:-$root/target/release/ipa-sysid}
DATA=${DATA:-}
if [ -z "$DATA" ] || [ ! -d "$DATA" ]; then
    echo "real_data.sh: set DATA to the folder of the shared data sets (got '${DATA}')" >&2
    exit 1
fi
command -v jq >/dev/null || { echo "real_data.sh: needs jq" >&2; exit 1; }
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
cd "$DATA"

# 3 significant digits (RMSE) / one decimal, or $3 decimals (fit %); n/a for null.
sig() { local v; v=$(jq -r "$1 // \"n/a\"" "$2"); [ "$v" = n/a ] && printf 'n/a' || printf '%#.3g' "$v"; }
pct() { local v; v=$(jq -r "$1 // \"n/a\"" "$2"); [ "$v" = n/a ] && printf 'n/a' || printf "%.${3:-1}f" "$v"; }

# row LABEL ARGS...: `identify ARGS` and one table row: estimation / test simulation RMSE (estimated initial
# outputs), test fit %, test RMSE from the measured initial outputs, warnings count.
row() {
    local label=$1
    shift
    "$bin" identify "$@" --json "$tmp/j.json" >/dev/null 2>"$tmp/err" || {
        echo "| $label | failed: $(head -c 200 "$tmp/err") |"
        return
    }
    local j=$tmp/j.json
    printf '| %s | `%s` | %s | %s | %s | %s | %s |\n' "$label" "$*" \
        "$(sig .metrics.estimation.rmse_sim "$j")" "$(sig .metrics.validation.rmse_sim "$j")" \
        "$(pct .metrics.validation.fit_sim_percent "$j")" "$(sig .metrics.validation.rmse_sim_measured "$j")" \
        "$(jq -r '.warnings | length' "$j")"
}

header() {
    echo
    echo "| model | flags after \`ipa-sysid identify\` | RMSE sim est. | RMSE sim **test** | fit % test | RMSE sim test (y0 measured) | warnings |"
    echo "|---|---|---|---|---|---|---|"
}

# The benchmark's scoring (nonlinear_benchmarks: a 50-sample state-initialisation window on every test
# record): `validate` of the same model on the test record without and with `--score-from 50`. SCORED_VAL
# holds validate's record flags (--data, columns, rows).
scored_header() {
    echo
    echo "| row | test RMSE, k ≥ k0 | test RMSE, k ≥ 50 (\`validate --score-from 50\`) | y0 measured: k ≥ k0 → k ≥ 50 |"
    echo "|---|---|---|---|"
}

# scored_row LABEL ARGS...: `identify ARGS --save-model M`, then `validate --model M ${SCORED_VAL[@]}`
# and the same with `--score-from 50`: the test simulation RMSE (estimated initial outputs) over
# k >= k0 and over k >= 50, and the same from the measured initial outputs.
scored_row() {
    local label=$1
    shift
    "$bin" identify "$@" --save-model "$tmp/m.json" >/dev/null 2>"$tmp/err" || {
        echo "| $label | failed: $(head -c 200 "$tmp/err") |"
        return
    }
    "$bin" validate --model "$tmp/m.json" "${SCORED_VAL[@]}" --json "$tmp/v0.json" >/dev/null 2>&1
    "$bin" validate --model "$tmp/m.json" "${SCORED_VAL[@]}" --score-from 50 --json "$tmp/v50.json" >/dev/null 2>&1
    printf '| %s | %s | %s | %s → %s |\n' "$label" \
        "$(sig .metrics.validation.rmse_sim "$tmp/v0.json")" "$(sig .metrics.validation.rmse_sim "$tmp/v50.json")" \
        "$(sig .metrics.validation.rmse_sim_measured "$tmp/v0.json")" \
        "$(sig .metrics.validation.rmse_sim_measured "$tmp/v50.json")"
}

# order_line ARGS...: `order ARGS`, the recommended structure, its ranking fit (the worse of estimated and
# measured initial outputs on the selection part) and test fit, and the search's warnings; sets CHOSEN
# (empty when no structure qualifies).
order_line() {
    "$bin" order "$@" --json "$tmp/o.json" >/dev/null 2>&1
    local o=$tmp/o.json
    CHOSEN=$(jq -r '.test.orders // empty | "\(.na) \(.nb) \(.nk)"' "$o")
    local warn
    warn=$(jq -r 'if (.warnings | length) > 0 then "; warning: " + (.warnings | join("; ")) else "" end' "$o")
    if [ -z "$CHOSEN" ]; then
        printf '`ipa-sysid order %s`\n: none recommended%s\n\n' "$*" "$warn"
        return
    fi
    printf '`ipa-sysid order %s`\n: chosen (na, nb, nk) = (%s), selection fit %s %% on %s; test fit %s %% (simulation), test RMSE %s%s\n\n' \
        "$*" "$(echo "$CHOSEN" | tr ' ' ',')" \
        "$(pct '. as $d | [$d.candidates[] | select(.orders == $d.test.orders)][0].ranking_fit' "$o")" \
        "$(jq -r .selection "$o" | sed 's|.*/||')" "$(pct .test.fit_sim_percent "$o")" \
        "$(sig .test.metrics.rmse_sim "$o")" "$warn"
}

# classes_line ARGS...: `order --classes ARGS` (structure search over model classes on the selection part
# of the estimation record), the chosen class and structure and its test RMSE; sets CLASS and CHOSEN.
classes_line() {
    "$bin" order "$@" --json "$tmp/c.json" >/dev/null 2>&1
    local c=$tmp/c.json
    CLASS=$(jq -r '.chosen.class // empty' "$c")
    CHOSEN=$(jq -r '.chosen.orders // empty | "\(.na) \(.nb) \(.nk)"' "$c")
    printf '`ipa-sysid order %s`\n: chosen %s (na, nb, nk) = (%s), selection RMSE %s on %s; test RMSE %s (simulation from measured initial outputs), %s candidates%s\n\n' \
        "$*" "$CLASS" "$(echo "$CHOSEN" | tr ' ' ',')" \
        "$(sig '.candidates[0].selection_rmse' "$c")" "$(jq -r .selection "$c" | sed 's|.*/||')" \
        "$(sig .chosen.rmse_sim "$c")" "$(jq -r '.candidates | length' "$c")" \
        "$(jq -r 'if (.warnings | length) > 0 then "; warnings: " + (.warnings | length | tostring) else "" end' "$c")"
}

delay_line() {
    "$bin" delay "$@" --json "$tmp/d.json" >/dev/null 2>&1
    printf '`ipa-sysid delay %s`\n: nk = %s (%s s)%s\n\n' "$*" "$(jq -r .nk "$tmp/d.json")" \
        "$(jq -r .delay_s "$tmp/d.json")" \
        "$(jq -r '(if (.notes | length) > 0 then "; note: " + (.notes | join("; ")) else "" end) + (if (.warnings | length) > 0 then "; warning: " + (.warnings | join("; ")) else "" end)' "$tmp/d.json")"
}

echo "Generated by scripts/real_data.sh with $("$bin" --version) on $(date -u +%Y-%m-%d); paths relative to \$DATA."

echo
echo "## Cascaded tanks"
T=cascaded_tanks/dataBenchmark.csv
TANKS=(--data $T --u-col uEst --y-col yEst --ts 4 --validation $T --val-u-col uVal --val-y-col yVal --offset)
header
row "ARX + offset, ls" "${TANKS[@]}" --na 2 --nb 2 --nk 1 --structure arx --method ls
row "ARX + offset, rls" "${TANKS[@]}" --na 2 --nb 2 --nk 1 --structure arx --method rls
row "ARX + offset, oe" "${TANKS[@]}" --na 2 --nb 2 --nk 1 --structure arx --method oe
row "Hammerstein + offset, ls" "${TANKS[@]}" --na 2 --nb 2 --nk 1 --structure hammerstein --method ls
row "Hammerstein + offset, oe" "${TANKS[@]}" --na 2 --nb 2 --nk 1 --structure hammerstein --method oe
echo
order_line "${TANKS[@]}" --na 1..5 --nb 1..3 --nk 0..5
read -r na nb nk <<<"$CHOSEN"
CH_LS=("$na" "$nb" "$nk")
order_line "${TANKS[@]}" --na 1..4 --nb 1..3 --nk 0..2 --method oe
read -r na nb nk <<<"$CHOSEN"
CH_OE=("$na" "$nb" "$nk")
header
row "ARX + offset, ls, chosen by \`order\`" "${TANKS[@]}" --na "${CH_LS[0]}" --nb "${CH_LS[1]}" --nk "${CH_LS[2]}" --structure arx --method ls
row "ARX + offset, oe, chosen by \`order --method oe\`" "${TANKS[@]}" --na "${CH_OE[0]}" --nb "${CH_OE[1]}" --nk "${CH_OE[2]}" --structure arx --method oe
row "ARX + offset + output saturation (Wiener)" "${TANKS[@]}" --na 2 --nb 2 --nk 1 --structure arx --method ls --output-nonlinearity saturation
row "ARX + offset + output piecewise-linear K = 2 (Wiener), smallest estimation AIC of 27" "${TANKS[@]}" --na 4 --nb 4 --nk 1 --structure arx --method ls --output-nonlinearity piecewise-linear --breakpoints 2
row "polynomial D = 2 + ARX + offset + output saturation (Hammerstein–Wiener)" "${TANKS[@]}" --na 2 --nb 2 --nk 1 --nonlinearity polynomial --degree 2 --method ls --output-nonlinearity saturation
echo
delay_line --data $T --u-col uEst --y-col yEst --ts 4
classes_line "${TANKS[@]}" --classes arx,hammerstein,narx2,narx3 --na 1..4 --nb 1..4 --nk 0..1
read -r na nb nk <<<"$CHOSEN"
header
row "Polynomial NARX, degree 3 + constant, chosen by \`order --classes\`" "${TANKS[@]}" --structure narx --degree "${CLASS#narx}" --na "$na" --nb "$nb" --nk "$nk"
row "the same, number of terms by BIC" "${TANKS[@]}" --structure narx --degree 3 --na 2 --nb 2 --nk 0 --stop bic
row "the same, no simulation-error refinement" "${TANKS[@]}" --structure narx --degree 3 --na 2 --nb 2 --nk 0 --no-refine
echo
echo "Scored as the benchmark scores (from sample 50 of the test record on):"
SCORED_VAL=(--data $T --u-col uVal --y-col yVal)
scored_header
scored_row "ARX + offset, ls (2, 2, 1)" "${TANKS[@]}" --na 2 --nb 2 --nk 1 --structure arx --method ls
scored_row "ARX + offset, oe (2, 2, 1)" "${TANKS[@]}" --na 2 --nb 2 --nk 1 --structure arx --method oe
scored_row "Hammerstein + offset, oe" "${TANKS[@]}" --na 2 --nb 2 --nk 1 --structure hammerstein --method oe
scored_row "ARX + offset, oe (${CH_OE[0]}, ${CH_OE[1]}, ${CH_OE[2]}), chosen by \`order --method oe\`" "${TANKS[@]}" --na "${CH_OE[0]}" --nb "${CH_OE[1]}" --nk "${CH_OE[2]}" --structure arx --method oe
scored_row "Polynomial NARX degree 3 (2, 2, 0)" "${TANKS[@]}" --structure narx --degree 3 --na 2 --nb 2 --nk 0

echo
echo "## Hair dryer"
H=hair_dryer_pt326/dryer.csv
header
row "ARX + offset, ls" --data $H --rows 0..500 --val-rows 500.. --ts 0.08 --offset --na 2 --nb 2 --nk 3 --structure arx --method ls
row "the same by --split 0.5" --data $H --split 0.5 --ts 0.08 --offset --na 2 --nb 2 --nk 3 --structure arx --method ls
row "ARX + offset, oe" --data $H --rows 0..500 --val-rows 500.. --ts 0.08 --offset --na 2 --nb 2 --nk 3 --structure arx --method oe
row "Hammerstein + offset, ls" --data $H --rows 0..500 --val-rows 500.. --ts 0.08 --offset --na 2 --nb 2 --nk 3 --structure hammerstein --method ls
row "ARX, --detrend mean, ls" --data $H --rows 0..500 --val-rows 500.. --ts 0.08 --detrend mean --na 2 --nb 2 --nk 3 --structure arx --method ls
echo
order_line --data $H --rows 0..500 --val-rows 500.. --ts 0.08 --offset
read -r na nb nk <<<"$CHOSEN"
header
row "ARX + offset, ls, chosen by \`order\`" --data $H --rows 0..500 --val-rows 500.. --ts 0.08 --offset --na "$na" --nb "$nb" --nk "$nk" --structure arx --method ls
echo
delay_line --data $H --rows 0..500 --ts 0.08
"$bin" identify --data $H --rows 0..500 --ts 0.08 --detrend mean --na 2 --nb 2 --nk 3 --structure arx --method ls \
    --json "$tmp/dt.json" >/dev/null 2>&1
printf 'Operating point stored by `--detrend mean`: u0 = %s, y0 = %s\n' \
    "$(sig '.model.operating_point.u[0]' "$tmp/dt.json")" "$(sig .model.operating_point.y "$tmp/dt.json")"

echo
echo "## Hydraulic actuator"
A=hydraulic_actuator/actuator.csv
HYD=(--data $A --rows 0..512 --val-rows 512.. --y-col p --ts 1 --offset)
header
row "ARX + offset, ls" "${HYD[@]}" --na 3 --nb 2 --nk 1 --structure arx --method ls
row "ARX + offset, oe" "${HYD[@]}" --na 3 --nb 2 --nk 1 --structure arx --method oe
row "Hammerstein + offset, ls" "${HYD[@]}" --na 3 --nb 2 --nk 1 --structure hammerstein --method ls
row "Hammerstein + offset, rls" "${HYD[@]}" --na 3 --nb 2 --nk 1 --structure hammerstein --method rls
row "Hammerstein + offset, oe" "${HYD[@]}" --na 3 --nb 2 --nk 1 --structure hammerstein --method oe
echo
order_line "${HYD[@]}"
classes_line "${HYD[@]}" --classes arx,hammerstein,narx2,narx3 --na 1..4 --nb 1..4 --nk 0..2
read -r na nb nk <<<"$CHOSEN"
header
row "Polynomial NARX + constant, chosen by \`order --classes\`" "${HYD[@]}" --structure narx --degree "${CLASS#narx}" --na "$na" --nb "$nb" --nk "$nk"
delay_line --data $A --rows 0..512 --y-col p --ts 1

echo
echo "## Gas furnace"
G=gas_furnace_box_jenkins/gas_furnace.csv
header
row "ARX + offset, ls" --data $G --u-col InputGasRate --y-col CO2 --ts 9 --split 0.5 --offset --na 2 --nb 2 --nk 3 --structure arx --method ls
row "ARX + offset, oe" --data $G --u-col InputGasRate --y-col CO2 --ts 9 --split 0.5 --offset --na 2 --nb 2 --nk 3 --structure arx --method oe
echo
order_line --data $G --u-col InputGasRate --y-col CO2 --ts 9 --split 0.5 --offset
delay_line --data $G --u-col InputGasRate --y-col CO2 --ts 9 --rows 0..148

echo
echo "## Silverbox"
S=silverbox/SNLS80mV.csv
header
row "ARX, --detrend mean, ls" --data $S --u-col V1 --y-col V2 --ts 0.0016384 --rows 40650..105712 --validation $S --val-rows 105712..127400 --detrend mean --na 2 --nb 2 --nk 0 --structure arx --method ls
row "ARX, --detrend mean, oe" --data $S --u-col V1 --y-col V2 --ts 0.0016384 --rows 40650..105712 --validation $S --val-rows 105712..127400 --detrend mean --na 2 --nb 2 --nk 0 --structure arx --method oe
SB=(--data $S --u-col V1 --y-col V2 --ts 0.0016384 --rows 40650..105712 --validation $S --val-rows 105712..127400 --offset)
echo
classes_line "${SB[@]}" --classes arx,narx2,narx3 --na 2..3 --nb 2..3 --nk 0..1
read -r na nb nk <<<"$CHOSEN"
header
row "Polynomial NARX + constant, chosen by \`order --classes\`" "${SB[@]}" --structure narx --degree "${CLASS#narx}" --na "$na" --nb "$nb" --nk "$nk"
row "the same, number of terms by BIC" "${SB[@]}" --structure narx --degree "${CLASS#narx}" --na "$na" --nb "$nb" --nk "$nk" --stop bic
row "Polynomial NARX (2, 2, 0), degree 3 + constant" "${SB[@]}" --structure narx --degree 3 --na 2 --nb 2 --nk 0
echo
echo "Scored as the benchmark scores (from sample 50 of the test rows on):"
SCORED_VAL=(--data $S --u-col V1 --y-col V2 --rows 105712..127400)
scored_header
scored_row "ARX, --detrend mean, ls" --data $S --u-col V1 --y-col V2 --ts 0.0016384 --rows 40650..105712 --detrend mean --na 2 --nb 2 --nk 0 --structure arx --method ls
scored_row "ARX, --detrend mean, oe" --data $S --u-col V1 --y-col V2 --ts 0.0016384 --rows 40650..105712 --detrend mean --na 2 --nb 2 --nk 0 --structure arx --method oe

echo
echo "## Coupled electric drives (PRBS record u1 -> z1, first 250 / last 250 samples)"
CE=coupled_electric_drives_prbs/DATAPRBS.csv
CED=(--data $CE --u-col u1 --y-col z1 --ts 0.02 --rows 0..250 --val-rows 250..500 --offset)
header
row "ARX + offset, oe" "${CED[@]}" --na 2 --nb 2 --nk 1 --structure arx --method oe
echo
classes_line "${CED[@]}" --classes arx,hammerstein,narx2,narx3 --na 1..4 --nb 1..4 --nk 0..2
read -r na nb nk <<<"$CHOSEN"
header
row "Polynomial NARX + constant, chosen by \`order --classes\`" "${CED[@]}" --structure narx --degree "${CLASS#narx}" --na "$na" --nb "$nb" --nk "$nk"
row "Polynomial NARX (2, 3, 1), degree 2 + constant" "${CED[@]}" --structure narx --degree 2 --na 2 --nb 3 --nk 1

echo
echo "## EMPS: two experiments, one model (--merge)"
E1=emps/DATA_EMPS.csv
E2=emps/DATA_EMPS_PULSES.csv
header
row "ARX + offset, ls, estimated on DATA_EMPS" --data $E1 --validation $E2 --u-col vir --y-col qm --offset --na 2 --nb 2 --nk 1 --structure arx --method ls
"$bin" identify --data $E1 $E2 --merge --u-col vir --y-col qm --offset --na 2 --nb 2 --nk 1 --structure arx --method ls \
    --json "$tmp/merged.json" >/dev/null 2>&1
echo
echo '`ipa-sysid identify --data '"$E1 $E2"' --merge --u-col vir --y-col qm --offset --na 2 --nb 2 --nk 1 --structure arx --method ls`'
echo
echo "| record | fit % sim | fit % sim (y0 measured) | fit % 1-step |"
echo "|---|---|---|---|"
for i in 0 1; do
    # The merged document: each record's metrics under records[i].metrics, the pooled ones as metrics.estimation.
    printf '| %s | %s | %s | %s |\n' "$(jq -er ".records[$i].data" "$tmp/merged.json")" \
        "$(pct ".records[$i].metrics.fit_sim_percent" "$tmp/merged.json")" \
        "$(pct ".records[$i].metrics.fit_sim_measured_percent" "$tmp/merged.json")" \
        "$(pct ".records[$i].metrics.fit_pred_percent" "$tmp/merged.json" 4)"
done
printf '| pooled | %s | %s | %s |\n' "$(pct .metrics.estimation.fit_sim_percent "$tmp/merged.json")" \
    "$(pct .metrics.estimation.fit_sim_measured_percent "$tmp/merged.json")" "$(pct .metrics.estimation.fit_pred_percent "$tmp/merged.json" 4)"

echo
echo "## Pneumatic cylinder friction record, read as logged"
P=pneumatic_cylinder_friction_tudelft/NAPN_1bar.csv
echo
echo '`ipa-sysid delay --data '"$P"' --no-header --t-col 1 --time-unit ms --resample 0.01 --u-col 6 --y-col 5`'
echo
echo '```text'
"$bin" delay --data $P --no-header --t-col 1 --time-unit ms --resample 0.01 --u-col 6 --y-col 5 2>&1 | sed "s|$DATA/||g"
echo '```'

echo
echo "## Ball and beam"
BB=(--data ball_and_beam/ballbeam.csv --rows 0..500 --val-rows 500.. --ts 0.1 --offset)
header
row "ARX + offset, ls" "${BB[@]}" --na 2 --nb 2 --nk 1 --structure arx --method ls
row "ARX + offset, oe" "${BB[@]}" --na 2 --nb 2 --nk 1 --structure arx --method oe
row "Hammerstein + offset, ls" "${BB[@]}" --na 2 --nb 2 --nk 1 --structure hammerstein --method ls
echo
order_line "${BB[@]}"
delay_line --data ball_and_beam/ballbeam.csv --rows 0..500 --ts 0.1

echo
echo "## Flexible robot arm"
RA=(--data robot_arm_flexible/robot_arm.csv --rows 0..512 --val-rows 512.. --ts 1 --offset)
header
row "ARX + offset, ls" "${RA[@]}" --na 4 --nb 4 --nk 1 --structure arx --method ls
row "ARX + offset, oe" "${RA[@]}" --na 4 --nb 4 --nk 1 --structure arx --method oe
echo
order_line "${RA[@]}"
delay_line --data robot_arm_flexible/robot_arm.csv --rows 0..512 --ts 1
