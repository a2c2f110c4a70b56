#!/usr/bin/env bash
# Opens an ipa-sysid HTML report in headless Chromium (Debian's `chromium` package), the way a reader
# would, and checks what the browser actually built:
#   - the page loads and renders (a screenshot is written: OUT.png, 1200 x 3000 px viewport);
#   - the DOM Chromium produced contains the report's <h1> and every expected section title
#     (by default the <h2> headings found in the file; add more with --expect TEXT);
#   - every <img> has a data: URI (the report is self-contained), and the DOM holds as many inline
#     <svg> figures and <img> figures as the file;
#   - the file references no script and no external resource (no http:, https:, file: URL other
#     than the SVG namespace).
# Nothing is installed by this script. Exit status: 0 all checks pass, 1 a check failed, 2 usage or
# missing browser.
#
# Usage: scripts/check_report_browser.sh REPORT.html [OUT.png] [--expect TEXT]...
set -euo pipefail

usage() {
    echo "usage: $0 REPORT.html [OUT.png] [--expect 'Section title']..." >&2
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
[ -n "$shot" ] || shot="${report%.html}-screenshot.png"

browser=/usr/bin/chromium
if [ ! -x "$browser" ]; then
    echo "error: $browser not found. Install Debian's Chromium first:" >&2
    echo "    apt-get update && apt-get install -y chromium" >&2
    exit 2
fi

report_abs="$(cd "$(dirname "$report")" && pwd)/$(basename "$report")"
shot_dir="$(dirname "$shot")"
mkdir -p "$shot_dir"
shot_abs="$(cd "$shot_dir" && pwd)/$(basename "$shot")"
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
    --hide-scrollbars --window-size=1200,3000
)

# 1. The DOM as Chromium built it.
if ! timeout 120 "$browser" "${common_flags[@]}" --user-data-dir="$(mktemp -d -p "$work")" \
    --dump-dom "file://$report_abs" >"$work/dom.html" 2>"$work/dom.log"; then
    cat "$work/dom.log" >&2
    fail "chromium could not load $report (see its messages above)"
fi

# 2. A screenshot of the first 1200 x 3000 px.
rm -f "$shot_abs"
if ! timeout 120 "$browser" "${common_flags[@]}" --user-data-dir="$(mktemp -d -p "$work")" \
    --screenshot="$shot_abs" "file://$report_abs" >"$work/shot.log" 2>&1; then
    cat "$work/shot.log" >&2
    fail "chromium could not take the screenshot"
fi
if [ -s "$shot_abs" ] && [ "$(head -c 8 "$shot_abs" | od -An -tx1 | tr -d ' \n')" = "89504e470d0a1a0a" ]; then
    size=$(stat -c %s "$shot_abs")
    # A blank white 1200 x 3000 page compresses to a few kB; text and figures make it far larger.
    if [ "$size" -lt 20000 ]; then
        fail "screenshot $shot is only $size bytes: the page looks blank"
    else
        ok "screenshot $shot ($size bytes)"
    fi
else
    fail "no PNG screenshot at $shot"
fi

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
echo "all checks passed for $report (screenshot: $shot)"
