#!/usr/bin/env bash
# The image-quality table of reports/leaping-structures/quality.md: homogeneous leap values
# (lossy) against the non-leaping float reference, and the lossless structures for comparison,
# 256x256, orthographic orbit frame 12/72, ERT on, each dataset of the leaping-structures
# experiment with '0' and class. Columns: PSNR and max error (8-bit levels, any channel) of the
# fixed-point image with no leaping (the baseline: fixed-point error alone), with empty-region
# leap values (must equal the baseline) and with homogeneous leap values; then the float
# reference that follows the same homogeneous protocol, the steps each fixed-point run took,
# the flagged voxels and the preprocessing wall time (steps 1-4, one thread, this machine's load).
#   scripts/leaping-structures-quality.sh [VIZSIM] > reports/leaping-structures/quality.md
set -euo pipefail
vizsim=${1:-target/release/vizsim}
tmp=$(mktemp -d)
trap 'rm -rf "$tmp"' EXIT
datasets=${DATASETS:-"fuel neghip aneurism foot-lossy tooth_103x94x161 phantom:cast:256 engine"}
view="--view orbit:12/72 --size 256x256"
lv="--set occupancy.structure=leap-values"
psnr_and_max() { # reference.png image.png -> "PSNR dB, max M"
    "$vizsim" compare "$1" "$2" --json "$tmp/c.json" > /dev/null
    python3 -c 'import json,sys; c=json.load(open(sys.argv[1])); p=c["psnr_db"]; print(("%.1f dB" % p if p is not None and p != float("inf") else "∞") + ", max %d" % max(c["max_abs_error"]))' "$tmp/c.json"
}
steps() { python3 -c 'import json,sys; print("%.2f M" % (json.load(open(sys.argv[1]))["steps"] / 1e6))' "$1"; }
prep() { # run.json -> "leap voxels | preprocessing s"
    python3 -c 'import json,sys; l=json.load(open(sys.argv[1]))["leap_values"]; print("%.2f M | %.2f s" % (l["leap_voxels"] / 1e6, l["preprocessing_seconds"]))' "$1"
}
echo "### Image quality of the leaping structures against the non-leaping float reference"
echo
echo "PSNR in dB and max error in 8-bit levels; ∞ = identical. Fixed point: the step model at the default widths."
echo
echo "| dataset | tf | fixed, no leaping | fixed, LV | fixed, LV-h | float, LV-h | steps none | steps LV | steps LV-h | leap voxels LV | preprocessing LV | leap voxels LV-h | preprocessing LV-h |"
echo "|---|---|---|---|---|---|---:|---:|---:|---:|---:|---:|---:|"
for d in $datasets; do
    for tf in zero class; do
        "$vizsim" render --dataset "$d" --tf "$tf" $view -o "$tmp/float.png" > /dev/null
        "$vizsim" render --dataset "$d" --tf "$tf" $view --model fixed -o "$tmp/fixed.png" --json "$tmp/fixed.json" > /dev/null
        "$vizsim" render --dataset "$d" --tf "$tf" $view --model fixed $lv -o "$tmp/lv.png" --json "$tmp/lv.json" > /dev/null
        "$vizsim" render --dataset "$d" --tf "$tf" $view --model fixed $lv --set leap_values.regions=homogeneous -o "$tmp/lvh.png" --json "$tmp/lvh.json" > /dev/null
        "$vizsim" render --dataset "$d" --tf "$tf" $view $lv --set leap_values.regions=homogeneous -o "$tmp/flvh.png" > /dev/null
        echo "| $d | $tf | $(psnr_and_max "$tmp/float.png" "$tmp/fixed.png") | $(psnr_and_max "$tmp/float.png" "$tmp/lv.png") | $(psnr_and_max "$tmp/float.png" "$tmp/lvh.png") | $(psnr_and_max "$tmp/float.png" "$tmp/flvh.png") | $(steps "$tmp/fixed.json") | $(steps "$tmp/lv.json") | $(steps "$tmp/lvh.json") | $(prep "$tmp/lv.json") | $(prep "$tmp/lvh.json") |"
    done
done
echo
echo "Made by \`scripts/leaping-structures-quality.sh > reports/leaping-structures/quality.md\`."
