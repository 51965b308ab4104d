#!/usr/bin/env python3
"""Compares a sampled sweep with the exact sweep of the same runs (docs/sampling.md).

    scripts/sampling-validation.py EXACT_DIR SAMPLED_DIR [--csv OUT.csv] [--md OUT.md]

Runs are matched by (dataset, tf, mode, frame, axes). Prints the coverage of the 95 %
intervals (share of runs whose exact cycles lie within cycles ± cycles_ci95), the median and
largest relative error, per mode and overall, and the summed wall times of both folders
(timing.jsonl: the sum of per-run wall times, not the sweep's elapsed time)."""
import json
import statistics
import sys
from pathlib import Path


def lines(folder):
    with open(Path(folder) / "results.jsonl") as f:
        return [json.loads(l) for l in f if l.strip()]


def wall(folder):
    path = Path(folder) / "timing.jsonl"
    if not path.exists():
        return None
    with open(path) as f:
        return sum(json.loads(l)["wall_seconds"] or 0 for l in f if l.strip())


def identity(line):
    return (line["dataset"], line["tf"], line["mode"], line["frame"],
            json.dumps(line.get("axes", {}), sort_keys=True))


def main():
    args = sys.argv[1:]
    options = {}
    while len(args) > 2 and args[-2].startswith("--"):
        options[args[-2]] = args[-1]
        args = args[:-2]
    exact_dir, sampled_dir = args
    exact = {identity(l): l for l in lines(exact_dir) if l["model"] == "cycle"}
    sampled = [l for l in lines(sampled_dir) if l.get("sampled")]
    rows = []
    for s in sampled:
        e = exact.get(identity(s))
        if e is None:
            continue
        true, est, half = e["cycles"], s["cycles"], s["cycles_ci95"]
        rows.append({
            "dataset": s["dataset"], "tf": s["tf"], "mode": s["mode"], "frame": s["frame"],
            "exact_cycles": true, "sampled_cycles": est, "ci95": half,
            "relative_error": (est - true) / true,
            "relative_ci95": half / true,
            "covered": abs(est - true) <= half,
        })
    if not rows:
        sys.exit("no sampled run has an exact counterpart")

    def summary(group):
        errors = [abs(r["relative_error"]) for r in group]
        return (len(group), 100 * sum(r["covered"] for r in group) / len(group),
                100 * statistics.median(errors), 100 * max(errors),
                100 * statistics.mean(r["relative_error"] for r in group),
                100 * statistics.median(r["relative_ci95"] for r in group))

    header = ("| group | runs | coverage of the 95 % interval | median abs. error | "
              "max abs. error | mean signed error | median interval half-width |")
    table = [header, "|---|---:|---:|---:|---:|---:|---:|"]
    fmt = "| {} | {} | {:.1f} % | {:.2f} % | {:.2f} % | {:+.2f} % | {:.2f} % |"
    table.append(fmt.format("all", *summary(rows)))
    for key in ["mode", "dataset", "tf"]:
        for value in sorted({r[key] for r in rows}):
            table.append(fmt.format(f"{key} {value}", *summary([r for r in rows if r[key] == value])))
    text = "\n".join(table)
    we, ws = wall(exact_dir), wall(sampled_dir)
    text += (f"\n\n{len(rows)} sampled runs matched with exact ones "
             f"({len(sampled)} sampled, {len(exact)} exact cycle runs).")
    if we is not None and ws is not None:
        text += (f"\nSummed per-run wall time: exact {we:.0f} s, sampled {ws:.0f} s "
                 f"(all runs of each folder).")
    print(text)
    if "--md" in options:
        Path(options["--md"]).write_text(text + "\n")
    if "--csv" in options:
        keys = list(rows[0])
        with open(options["--csv"], "w") as f:
            f.write(",".join(keys) + "\n")
            for r in sorted(rows, key=lambda r: (r["dataset"], r["tf"], r["mode"], r["frame"])):
                f.write(",".join(str(r[k]) for k in keys) + "\n")


if __name__ == "__main__":
    main()
