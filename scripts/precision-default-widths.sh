#!/usr/bin/env bash
# The "Default widths: every dataset" table of docs/precision.md: fixed point at the default
# widths against the float reference, 256x256, class transfer functions, ERT on, orthographic at
# orbit 7/72 and perspective at orbit 50/72. Prints the Markdown table.
#   scripts/precision-default-widths.sh [VIZSIM] > table.md     (VIZSIM default: target/release/vizsim)
set -euo pipefail
source "$(dirname "$0")/precision-common.sh"
psnr_and_max() { # float.png fixed.png -> "PSNR | max"
    "$vizsim" compare "$1" "$2" --json "$tmp/c.json" > /dev/null
    python3 -c 'import json,sys; c=json.load(open(sys.argv[1])); print("%.2f | %d" % (c["psnr_db"], max(c["max_abs_error"])))' "$tmp/c.json"
}
echo "| dataset | ortho PSNR dB | ortho max error | persp PSNR dB | persp max error |"
echo "|---|---:|---:|---:|---:|"
for d in $datasets; do
    row="| $d"
    for view in "orbit:7/72 ortho" "orbit:50/72 persp"; do
        set -- $view
        for model in float fixed; do
            "$vizsim" render --dataset "$d" --tf class --view "$1" --projection "$2" --model "$model" \
                -o "$tmp/$model.png" > /dev/null
        done
        row="$row | $(psnr_and_max "$tmp/float.png" "$tmp/fixed.png")"
    done
    echo "$row |"
done
