#!/usr/bin/env bash
# The "predicted bound" table of docs/precision.md: invariant (c) at the default widths, fixed
# point against the float reference and the error bound the widths predict, 256x256, class
# transfer functions, ERT on, orthographic at orbit 7/72 and perspective at orbit 50/72.
# Prints the Markdown table; fails if any pixel is over its bound.
#   scripts/precision-bound.sh [VIZSIM] > table.md     (VIZSIM default: target/release/vizsim)
set -euo pipefail
source "$(dirname "$0")/precision-common.sh"
echo "| dataset | ortho max error | ortho max bound | ortho mean error | ortho mean bound | persp max error | persp max bound | persp mean error | persp mean bound |"
echo "|---|---:|---:|---:|---:|---:|---:|---:|---:|"
for d in $datasets; do
    row="| $d"
    for view in "orbit:7/72 ortho" "orbit:50/72 persp"; do
        set -- $view
        "$vizsim" render --dataset "$d" --tf class --view "$1" --projection "$2" --model fixed \
            --check-bound -o "$tmp/fixed.png" --json "$tmp/r.json" > /dev/null
        row="$row | $(python3 -c 'import json,sys; b=json.load(open(sys.argv[1]))["error_bound"]; print("%d | %d | %.3f | %.2f" % (max(b["max_error"][:3]), max(b["max_bound"][:3]), b["mean_error"], b["mean_bound"]))' "$tmp/r.json")"
    done
    echo "$row |"
done
