#!/bin/sh
# Iso-surface hitpoint refinement quality (issue 15, part 5): PSNR, largest error and samples
# per ray of float and fixed-point iso images at spacings 1 to 5, with and without 6
# refinement steps, against a float iso reference at spacing 1/8; writes
# reports/iso-refinement/{table.md,*-side-by-side.png}.
#   scripts/iso-refinement-quality.sh [OUT_DIR] [VIEW]   (default: reports/iso-refinement orbit:5/72)
set -eu
cd "$(dirname "$0")/.."
cargo run --release --quiet --example iso_refinement_quality -- \
    "${1:-reports/iso-refinement}" "${2:-orbit:5/72}" \
    phantom:sphere:64 phantom:metaballs:64 neghip fuel
