#!/usr/bin/env python3
"""Tables of a sequence experiment (configs/experiments/dynamic.toml): per source and map
strategy the mean update / map / render time of the steps after the first and the sequence's
frames per second, the scan time per step, and per step the update / map / render cycles.

    vizsim sweep configs/experiments/dynamic.toml --out runs/dynamic
    scripts/dynamic-report.py runs/dynamic   # the tables of reports/dynamic/experiment.md

Reads OUT/results.jsonl (one line per time step, docs/experiments.md "Sequences"); prints
Markdown. fps = clock / mean step cycles (update + map + render, the fence's order): "steady"
over steps 1.. (partial updates), "with the download" over every step. A sequence with steps
missing (a sweep still running or cut short) is reported with the steps it has, and says so.
"""
import json
import os
import sys
from collections import defaultdict

out = sys.argv[1]
lines = [json.loads(l) for l in open(os.path.join(out, "results.jsonl")) if l.strip()]
resolved = json.load(open(os.path.join(out, "experiment.resolved.json")))
experiment = resolved.get("experiment", {})
steps_wanted = (experiment.get("sequence") or {}).get("steps")
clock_mhz = 100.0  # the lines carry fps and frame_time_ns; the clock from one line:
for l in lines:
    clock_mhz = l["total_cycles"] / (l["frame_time_ns"] / 1e3)
    break
ms = lambda cycles: cycles / (clock_mhz * 1e3)
MAPS = ["during-update", "rescan", "scan", "none"]

seqs = defaultdict(dict)
for l in lines:
    seqs[(l["dataset"], l["tf"], l["view"], l["map"])][l["time_step"]] = l
sources = sorted({k[0] for k in seqs}, key=lambda s: (int(s.rsplit(":", 1)[-1]) if s.rsplit(":", 1)[-1].isdigit() else 0, s))
maps = [m for m in MAPS if any(k[3] == m for k in seqs)]


print(f"Experiment `{experiment.get('name', '?')}`: {len(lines)} result lines"
      f" ({steps_wanted} time steps per sequence wanted). Clock {clock_mhz:.0f} MHz.")
print()
print("| source | view | map | steps | update ms | map ms | render ms | step ms | fps (steps 1..) | fps (with the download) | stale sub-cubes at the last step | empty sub-cubes at the last step |")
print("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|")
for s in sources:
    for key in sorted((k for k in seqs if k[0] == s), key=lambda k: (k[1], k[2], MAPS.index(k[3]))):
        _, tf, view, m = key
        if key[3] not in maps:
            continue
        steps = seqs[key]
        have = sorted(steps)
        contiguous = have == list(range(len(have)))
        later = [steps[k] for k in have if k > 0] or [steps[k] for k in have]
        mean = lambda f: sum(x[f] for x in later) / len(later)
        u, mp, r, t = mean("update_cycles"), mean("map_cycles"), mean("render_cycles"), mean("total_cycles")
        every = [steps[k] for k in have]
        fps_all = len(every) * clock_mhz * 1e6 / sum(x["total_cycles"] for x in every)
        last = steps[have[-1]]
        note = "" if contiguous and (steps_wanted is None or len(have) == steps_wanted) else " (partial)"
        print(f"| {s} | {view} | {m} | {len(have)}{note} | {ms(u):.2f} | {ms(mp):.3f} | {ms(r):.2f} | {ms(t):.2f} | "
              f"{clock_mhz * 1e6 / t:.1f} | {fps_all:.1f} | "
              f"{last['stale_subcubes'] if m != 'none' else '—'} | "
              f"{'%.1f %%' % last['skippable_subcubes_percent'] if m != 'none' else '—'} |")

print()
print("Scan pass per step (map strategy `scan`: map cycles = the scan through the read path + one cycle per map bit):")
print()
print("| source | sub-cubes (map bits) | scan cycles, mean over the steps | scan time | published |")
print("|---|---:|---:|---:|---|")
for s in sources:
    for key in sorted(k for k in seqs if k[0] == s and k[3] == "scan"):
        steps = seqs[key]
        first = next(iter(steps.values()))
        n = int(s.rsplit(":", 1)[-1]) if s.rsplit(":", 1)[-1].isdigit() else None
        sub = first["subcube"]
        bits = (n // sub) ** 3 if n else 0
        scan = sum(x["map_cycles"] for x in steps.values()) / len(steps) - bits
        print(f"| {s} | {bits:,} | {scan:,.0f} | {ms(scan):.2f} ms | {'about 20 ms (256³)' if n == 256 else '—'} |")

for s in sources:
    keys = [k for k in sorted(seqs) if k[0] == s]
    for view in sorted({k[2] for k in keys}):
        row_keys = [k for k in keys if k[2] == view]
        row_keys.sort(key=lambda k: MAPS.index(k[3]))
        print()
        print(f"Per step, {s}, view {view} (cycles: update / map / render; "
              + " vs ".join(k[3] for k in row_keys) + "):")
        print()
        print("| step | volume | voxels written | " + " | ".join(k[3] for k in row_keys) + " |")
        print("|---:|---|---:|" + "---:|" * len(row_keys))
        all_steps = sorted(set().union(*(seqs[k].keys() for k in row_keys)))
        for k in all_steps:
            cells = []
            ref = None
            for key in row_keys:
                st = seqs[key].get(k)
                if st is None:
                    cells.append("—")
                    continue
                ref = ref or st
                cells.append(f"{st['update_cycles']:,} / {st['map_cycles']:,} / {st['render_cycles']:,}")
            print(f"| {k} | {ref['volume']} | {ref['voxels_written']:,} | " + " | ".join(cells) + " |")
