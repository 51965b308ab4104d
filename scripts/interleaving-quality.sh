#!/bin/sh
# Interleaved sampling quality (issue 15, part 4): PSNR and structured-error figures at sample
# spacings 1, 2 and 4 with and without interleaving, against a float reference at spacing 1/8;
# writes reports/interleaving/{table.md,side-by-side.png,*.png}.
#   scripts/interleaving-quality.sh [DATASET] [VIEW] [N]    (default: bonsai orbit:0/72 4)
set -eu
cd "$(dirname "$0")/.."
cargo run --quiet --example interleaving_quality -- \
    "${1:-bonsai}" "${2:-orbit:0/72}" "${3:-4}" reports/interleaving
