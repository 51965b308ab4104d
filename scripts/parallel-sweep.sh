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
if ! parallel "${SSH[@]}" -j "$N" "$VIZSIM" --threads 1 sweep "$EXPERIMENT" \
    --out "$OUT/shard-{}" --shard "{}/$N" --quiet ::: $(seq 0 $((N - 1))); then
    # parallel's exit status is the number of failed shards; the finished runs are kept
    echo "parallel-sweep: a shard failed, not merged; run the same command again: it resumes" >&2
    exit 1
fi
"$VIZSIM" merge "$OUT"/shard-* --out "$OUT/merged"
