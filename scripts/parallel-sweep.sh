#!/bin/bash
# Runs a vizsim sweep as N shards with GNU parallel, then merges them.
#   scripts/parallel-sweep.sh EXPERIMENT.toml OUT_DIR N [HOSTS]
# HOSTS: optional comma-separated ssh logins for parallel --sshlogin (shared file system).
set -euo pipefail
EXPERIMENT=${1:?experiment file}
OUT=${2:?output folder}
N=${3:?number of shards}
HOSTS=${4:-}
VIZSIM=${VIZSIM:-vizsim}
SSH=()
if [ -n "$HOSTS" ]; then SSH=(--sshlogin "$HOSTS"); fi
parallel "${SSH[@]}" -j "$N" "$VIZSIM" --threads 1 sweep "$EXPERIMENT" \
    --out "$OUT/shard-{}" --shard "{}/$N" --quiet ::: $(seq 0 $((N - 1)))
"$VIZSIM" merge "$OUT"/shard-* --out "$OUT/merged"
