#!/usr/bin/env bash
# Opens an ipa-sysid HTML report in headless Chromium (Debian's `chromium` package), the way a reader
# would, and checks what the browser actually built:
#   - at window widths of 800 and 1400 px (scripts/report_browser.py, the DevTools protocol over a pipe):
#     full-page screenshots SHOTS/report-800.png and SHOTS/report-1400.png (pages taller than 16000 px
#     are cut into report-W-1.png, -2.png, ...), and a failure on horizontal page overflow (a table
#     wider than the window must scroll inside its own box), a broken image, a figure without alt text
#     or a console error;
#   - the DOM Chromium produced contains the report's <h1> and every expected section title
#     (by default the <h2> headings found in the file; add more with --expect TEXT);
#   - every <img> has a data: URI (the report is self-contained), and the DOM holds as many inline
#     <svg> figures and <img> figures as the file;
#   - the file references no script and no external resource (no http:, https:, file: URL other
#     than the SVG namespace).
# Nothing is installed by this script. Exit status: 0 all checks pass, 1 a check failed, 2 usage or
# missing browser.
#
# Usage: scripts/check_report_browser.sh REPORT.html [SHOTS_DIR] [--expect TEXT]...
# (SHOTS_DIR defaults to the report's folder + /screenshots.)
set -euo pipefail

usage() {
    echo "usage: $0 REPORT.html [SHOTS_DIR] [--expect 'Section title']..." >&2
    exit 2
}

report=""
shot=""
expects=()
while [ $# -gt 0 ]; do
    case "$1" in
        --expect)
            [ $# -ge 2 ] || usage
            expects+=("$2")
            shift 2
            ;;
        -h | --help) usage ;;
        *)
            if [ -z "$report" ]; then
                report="$1"
            elif [ -z "$shot" ]; then
                shot="$1"
            else
                usage
            fi
            shift
            ;;
    esac
done
[ -n "$report" ] || usage
if [ ! -f "$report" ]; then
    echo "error: $report: no such file (expected the report.html written by ipa-sysid reproduce)" >&2
    exit 2
fi
[ -n "$shot" ] || shot="$(dirname "$report")/screenshots"

browser=/usr/bin/chromium
if [ ! -x "$browser" ]; then
    echo "error: $browser not found. Install Debian's Chromium first:" >&2
    echo "    apt-get update && apt-get install -y chromium" >&2
    exit 2
fi

report_abs="$(cd "$(dirname "$report")" && pwd)/$(basename "$report")"
mkdir -p "$shot"
work="$(mktemp -d)"
trap 'rm -rf "$work"' EXIT

failures=0
fail() {
    echo "FAIL: $*" >&2
    failures=$((failures + 1))
}
ok() { echo "ok:   $*"; }

common_flags=(
    --headless --no-sandbox --disable-gpu --disable-quic --no-first-run
    --disable-background-networking --disable-component-update --disable-sync
    --hide-scrollbars --window-size=1200,900
)

# 1. The DOM as Chromium built it.
if ! timeout 120 "$browser" "${common_flags[@]}" --user-data-dir="$(mktemp -d -p "$work")" \
    --dump-dom "file://$report_abs" >"$work/dom.html" 2>"$work/dom.log"; then
    cat "$work/dom.log" >&2
    fail "chromium could not load $report (see its messages above)"
fi

# 2. Full-page screenshots at 800 and 1400 px; overflow, broken images, alt text, console errors.
here="$(cd "$(dirname "$0")" && pwd)"
if timeout 300 python3 "$here/report_browser.py" "$report_abs" "$shot" 800 1400 >"$work/widths.json" 2>"$work/widths.log"; then
    ok "widths 800 and 1400 px: no horizontal overflow, no broken image, alt text on every figure, no console error"
else
    cat "$work/widths.log" >&2
    fail "layout check at 800/1400 px: $(grep -o '"failures": \[[^]]*\]' "$work/widths.json" | tr '\n' ' ')"
fi
for f in "$shot"/report-800*.png "$shot"/report-1400*.png; do
    [ -e "$f" ] || continue
    size=$(stat -c %s "$f")
    # A blank page compresses to a few kB; text and figures make a full page far larger.
    if [ "$size" -lt 20000 ] && [[ "$f" != *-[2-9].png ]]; then
        fail "screenshot $f is only $size bytes: the page looks blank"
    else
        ok "screenshot $f ($size bytes)"
    fi
done
[ -e "$shot/report-800.png" ] || [ -e "$shot/report-800-1.png" ] || fail "no screenshot at 800 px in $shot"
[ -e "$shot/report-1400.png" ] || [ -e "$shot/report-1400-1.png" ] || fail "no screenshot at 1400 px in $shot"

dom="$work/dom.html"
if [ ! -s "$dom" ]; then
    fail "chromium produced an empty DOM"
    echo "$failures check(s) failed" >&2
    exit 1
fi

# Text as both the file and Chromium's serialiser may spell it: undo the quote escapes.
norm() { sed -e 's/&quot;/"/g' -e "s/&#39;/'/g" -e 's/&#x27;/'"'"'/g'; }
# One element per line so that grep -o works on multi-line tags. (Never pipe into `grep -q`: with
# pipefail, grep's early exit would turn a match into a failure through SIGPIPE.)
flat() { tr '\n' ' ' <"$1" | sed -e 's/</\n</g'; }

# 3. Title and section headings.
title=$(flat "$report" | grep -o '^<h1[^>]*>[^<]*' | sed -n '1p' | sed -e 's/^<h1[^>]*>//' | norm || true)
if [ -z "$title" ]; then
    fail "$report has no <h1> title"
elif grep -qF -- ">$title" <<<"$(flat "$dom" | norm)"; then
    ok "title: $title"
else
    fail "title \"$title\" not in the rendered DOM"
fi
while IFS= read -r h; do
    [ -n "$h" ] && expects+=("$h")
done < <(flat "$report" | grep -o '^<h2[^>]*>[^<]*' | sed -e 's/^<h2[^>]*>//' | norm || true)
if [ ${#expects[@]} -eq 0 ]; then
    fail "no section heading to look for (no <h2> in $report and no --expect)"
fi
dom_text="$(flat "$dom" | norm)"
for e in "${expects[@]}"; do
    if grep -qF -- "$e" <<<"$dom_text"; then
        ok "section: $e"
    else
        fail "section \"$e\" not in the rendered DOM"
    fi
done

# 4. Self-contained figures.
imgs=$(flat "$dom" | grep -c '^<img' || true)
data_imgs=$(flat "$dom" | grep '^<img' | grep -c 'src="data:' || true)
if [ "$imgs" -ne "$data_imgs" ]; then
    fail "$((imgs - data_imgs)) of $imgs <img> elements have no data: URI"
else
    ok "$imgs <img> elements, all with data: URIs"
fi
for tag in svg img figure table; do
    in_file=$(flat "$report" | grep -c "^<$tag[ >/]" || true)
    in_dom=$(flat "$dom" | grep -c "^<$tag[ >/]" || true)
    if [ "$in_file" -ne "$in_dom" ]; then
        fail "<$tag>: $in_file in the file but $in_dom in the rendered DOM"
    else
        ok "<$tag>: $in_dom"
    fi
done
if grep -qi '^<script' <<<"$(flat "$report")"; then
    fail "the report contains a <script>"
fi
external=$(grep -oiE '(src|href)="(https?|file|ftp):[^"]*"|url\((https?|file):[^)]*\)|@import' "$report" | sed -n '1,5p' || true)
if [ -n "$external" ]; then
    fail "external resources referenced: $external"
else
    ok "no script, no external resource"
fi

if [ "$failures" -gt 0 ]; then
    echo "$failures check(s) failed for $report" >&2
    exit 1
fi
echo "all checks passed for $report (screenshots in $shot)"
