#!/usr/bin/env bash
# reports/dynamic/: the frame loop of dynamic sequences (issue 16, part 4). For each source, 30
# time steps at 128³, 8³ sub-cubes, 8³ bricks, 256×256 front view, class transfer function,
# the calibrated default hardware; maps built during the update (widened), during the update
# with a rescan, by a scan pass per step, and no leaping. Runs
#   VIZSIM sequence --source SOURCE --steps 30 --subcube 8 --map MODE --json
# into OUT/json/ (a JSON already there is kept: rerun after deleting it) and prints the tables.
#   [SOURCES="..."] scripts/dynamic-sequences.sh OUT [VIZSIM]   (VIZSIM default: target/release/vizsim)
# SOURCES defaults to "phantom:metaballs:128 phantom:tsdf:128".
set -euo pipefail
out=${1:?output folder}
vizsim=${2:-target/release/vizsim}
mkdir -p "$out/json"
sources=${SOURCES:-"phantom:metaballs:128 phantom:tsdf:128"}
modes="during-update rescan scan none"
for source in $sources; do
    for mode in $modes; do
        file="$out/json/$(echo "$source" | tr ':' '-')-$mode.json"
        if [ ! -s "$file" ]; then
            "$vizsim" sequence --source "$source" --steps 30 --subcube 8 --map "$mode" --json \
                > "$file.tmp"
            mv "$file.tmp" "$file"
        fi
    done
done
python3 - "$out/json" $sources <<'PY'
import json, sys, os
folder, sources = sys.argv[1], sys.argv[2:]
modes = ["during-update", "rescan", "scan", "none"]
ms = lambda c, mhz: c / (mhz * 1e3)
print("| source | map | update ms | map ms | render ms | step ms | fps (steps 1–29) | fps (with the download) | stale sub-cubes at step 29 | empty sub-cubes at step 29 |")
print("|---|---|---:|---:|---:|---:|---:|---:|---:|---:|")
runs = {}
for s in sources:
    for m in modes:
        r = json.load(open(os.path.join(folder, f"{s.replace(':', '-')}-{m}.json")))
        runs[(s, m)] = r
        f = r["clock_mhz"]
        u, mp, rd = r["mean_update_cycles"], r["mean_map_cycles"], r["mean_render_cycles"]
        last = r["steps"][-1]
        print(f"| {s} | {m} | {ms(u, f):.2f} | {ms(mp, f):.3f} | {ms(rd, f):.2f} | {ms(u + mp + rd, f):.2f} | "
              f"{r['steady_fps']:.1f} | {r['fps']:.1f} | {last['stale_subcubes'] if m != 'none' else '—'} | {'%.1f %%' % last['empty_subcubes_percent'] if m != 'none' else '—'} |")
for s in sources:
    print()
    print(f"Per step, {s} (cycles: update / map / render; map during-update vs rescan vs scan vs none):")
    print()
    print("| step | voxels written | " + " | ".join(modes) + " |")
    print("|---:|---:|" + "---:|" * len(modes))
    n = len(runs[(s, modes[0])]["steps"])
    for k in range(n):
        cells = []
        for m in modes:
            st = runs[(s, m)]["steps"][k]
            cells.append(f"{st['update_cycles']:,} / {st['map_cycles']:,} / {st['render_cycles']:,}")
        w = runs[(s, modes[0])]["steps"][k]["voxels_written"]
        print(f"| {k} | {w:,} | " + " | ".join(cells) + " |")
PY
