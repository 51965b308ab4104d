//! Experiments with a time axis (`[sequence]`, docs/experiments.md "Sequences"): expansion
//! into one run per time step, a sweep whose per-step cycles equal `vizsim sequence`'s,
//! resuming without duplicate lines, and clear errors for bad input. Tiny volumes and images.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::process::Command;

use serde_json::Value;
use vizsim::experiment::spec::expand;

const BIN: &str = env!("CARGO_BIN_EXE_vizsim");

const SEQ: &str = r#"
name = "ci-sequence"
datasets = ["phantom:metaballs:32", "phantom:tsdf:32"]
tf = ["class"]
modes = ["ert+leap8"]
models = ["cycle"]
[frames]
orbit = 1
size = "32x32"
[sequence]
steps = 3
map = ["update", "scan", "none"]
"#;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-seqexp-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn vizsim(args: &[&str]) -> std::process::Output {
    Command::new(BIN).args(args).output().unwrap()
}

fn lines(path: &Path) -> Vec<Value> {
    std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect()
}

/// `SEQ` on the metaballs alone with the map built during the update, changed by `edit`, swept
/// into `dir/out`; returns the folder.
fn sweep_metaballs(dir: &Path, edit: impl Fn(String) -> String) -> PathBuf {
    let exp = dir.join("seq.toml");
    let text = SEQ
        .replace(
            r#"datasets = ["phantom:metaballs:32", "phantom:tsdf:32"]"#,
            r#"datasets = ["phantom:metaballs:32"]"#,
        )
        .replace(r#"map = ["update", "scan", "none"]"#, r#"map = ["update"]"#);
    std::fs::write(&exp, edit(text)).unwrap();
    let out = dir.join("out");
    let o = vizsim(&[
        "sweep",
        exp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    out
}

#[test]
fn a_sequence_experiment_expands_into_one_run_per_time_step() {
    let e = expand(SEQ, "seq", None).unwrap();
    // 2 sources x 3 map strategies x 3 steps
    assert_eq!(e.runs.len(), 2 * 3 * 3);
    let keys: std::collections::HashSet<_> = e.runs.iter().map(|r| r.key.clone()).collect();
    assert_eq!(keys.len(), e.runs.len(), "keys are distinct");
    for run in &e.runs {
        let step = run.sequence.as_ref().expect("a time step");
        assert_eq!(step.source, run.run.dataset);
        assert!(step.time_step < 3);
        // Without leaping the run renders without a map, and says so.
        let none = step.map == vizsim::dynamic::MapMode::None;
        assert_eq!(run.mode.subcube, if none { 0 } else { 8 });
        assert_eq!(run.run.hardware.occupancy.subcube, run.mode.subcube);
    }
    // A longer sequence repeats the shorter one's steps under the same keys.
    let longer = expand(&SEQ.replace("steps = 3", "steps = 5"), "seq", None).unwrap();
    assert_eq!(longer.runs.len(), 2 * 3 * 5);
    let long_keys: std::collections::HashSet<_> =
        longer.runs.iter().map(|r| r.key.clone()).collect();
    assert!(keys.is_subset(&long_keys));
    // Experiments without `[sequence]` have no time step.
    let plain = SEQ
        .split("[sequence]")
        .next()
        .unwrap()
        .replace("phantom:tsdf:32", "phantom:shells:24");
    let e = expand(&plain, "plain", None).unwrap();
    assert_eq!(e.runs.len(), 2);
    assert!(e.runs.iter().all(|r| r.sequence.is_none()));
}

#[test]
fn a_sequence_sweep_equals_vizsim_sequence_and_resumes_without_duplicates() {
    let dir = temp_dir("sweep");
    let exp = dir.join("seq.toml");
    std::fs::write(&exp, SEQ).unwrap();
    let out = dir.join("out");
    // First a partial sweep: the first two steps only (same keys as the longer sequence).
    let partial = dir.join("partial.toml");
    std::fs::write(&partial, SEQ.replace("steps = 3", "steps = 2")).unwrap();
    let o = vizsim(&[
        "sweep",
        partial.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let results = out.join("results.jsonl");
    assert_eq!(lines(&results).len(), 2 * 3 * 2);
    // Resume with all three steps: only the third step of each sequence is written.
    let o = vizsim(&[
        "sweep",
        exp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    let stdout = String::from_utf8_lossy(&o.stdout).to_string();
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    assert!(stdout.contains("12 were already done"), "{stdout}");
    let all = lines(&results);
    assert_eq!(all.len(), 2 * 3 * 3, "no duplicate lines");
    // Re-running writes nothing.
    let o = vizsim(&[
        "sweep",
        exp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(o.status.success());
    assert_eq!(lines(&results).len(), 2 * 3 * 3);
    // The per-step cycles are those `vizsim sequence` prints for the same sequence.
    let mut by_run: BTreeMap<(String, String, u64), &Value> = BTreeMap::new();
    for line in &all {
        let k = (
            line["dataset"].as_str().unwrap().to_string(),
            line["map"].as_str().unwrap().to_string(),
            line["time_step"].as_u64().unwrap(),
        );
        assert!(by_run.insert(k, line).is_none());
        assert_eq!(
            line["total_cycles"].as_u64().unwrap(),
            line["update_cycles"].as_u64().unwrap()
                + line["map_cycles"].as_u64().unwrap()
                + line["render_cycles"].as_u64().unwrap()
        );
        assert_eq!(line["cycles"], line["render_cycles"]);
    }
    let mut rates = BTreeMap::new();
    for source in ["phantom:metaballs:32", "phantom:tsdf:32"] {
        for map in ["during-update", "scan", "none"] {
            let o = vizsim(&[
                "sequence",
                "--source",
                source,
                "--steps",
                "3",
                "--subcube",
                "8",
                "--map",
                map,
                "--view",
                "orbit:0/1",
                "--size",
                "32x32",
                "--json",
            ]);
            assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
            let report: Value = serde_json::from_slice(&o.stdout).unwrap();
            for step in report["steps"].as_array().unwrap() {
                let k = step["step"].as_u64().unwrap();
                let line = by_run[&(source.to_string(), map.to_string(), k)];
                for field in [
                    "update_cycles",
                    "map_cycles",
                    "render_cycles",
                    "total_cycles",
                ] {
                    assert_eq!(line[field], step[field], "{source} {map} step {k} {field}");
                }
                // The tables the strategy keeps on chip: only `update` keeps them here.
                assert_eq!(
                    line["table_on_chip_bits"], report["table_on_chip_bits"],
                    "{source} {map} step {k}"
                );
                assert_eq!(
                    line["table_on_chip_bits"].is_null(),
                    map != "during-update",
                    "{source} {map}"
                );
            }
            rates.insert((source, map), report["fps"].as_f64().unwrap());
        }
    }
    // Tabulated, a cell is a mean over time steps and says so; the clock over the mean
    // `total-cycles` is the sequence's frame rate as `vizsim sequence` gives it.
    let tables = dir.join("tables");
    let o = vizsim(&[
        "table",
        out.to_str().unwrap(),
        "--rows",
        "dataset,map",
        "--columns",
        "mode",
        "--metric",
        "total-cycles,fps",
        "--out",
        tables.to_str().unwrap(),
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let md = std::fs::read_to_string(tables.join("cycle-fps.md")).unwrap();
    assert!(md.contains("mean over 3 time steps"), "{md}");
    assert!(md.contains("The sequence's frame rate is the clock over the mean `total-cycles`"));
    let csv = std::fs::read_to_string(tables.join("cycle-total-cycles.csv")).unwrap();
    for ((source, map), fps) in rates {
        let row = csv
            .lines()
            .find(|l| l.starts_with(&format!("{source},{map},")))
            .unwrap_or_else(|| panic!("no row {source} {map}: {csv}"));
        // One mode per row (the `none` map renders without its map: mode ERT).
        let mean: f64 = row
            .split(',')
            .skip(2)
            .find(|c| !c.is_empty())
            .unwrap()
            .parse()
            .unwrap();
        assert!(
            (1e8 / mean - fps).abs() < 1e-6 * fps,
            "{source} {map}: {mean} {fps}"
        );
    }
}

#[test]
fn bad_sequence_input_gives_clear_errors() {
    let err = |text: &str| match expand(text, "seq", None) {
        Ok(_) => panic!("accepted:\n{text}"),
        Err(e) => e.to_string(),
    };
    let e = err(&SEQ.replace("steps = 3", "steps = 0"));
    assert!(
        e.contains("sequence.steps") && e.contains("at least one"),
        "{e}"
    );
    let e = err(&SEQ.replace("\"scan\"", "\"sweep\""));
    assert!(
        e.contains("sequence.map") && e.contains("`sweep`: unknown map strategy"),
        "{e}"
    );
    let e = err(&SEQ.replace("map = [\"update\", \"scan\", \"none\"]", "map = []"));
    assert!(e.contains("sequence.map") && e.contains("empty"), "{e}");
    let e = err(&SEQ.replace("phantom:tsdf:32", "phantom:shells:24"));
    assert!(
        e.contains("phantom:shells:24") && e.contains("does not change with time"),
        "{e}"
    );
    let e = err(&SEQ.replace("models = [\"cycle\"]", "models = [\"step\"]"));
    assert!(e.contains("models") && e.contains("cycle model"), "{e}");
    let e = err(&SEQ.replace("\"ert+leap8\"", "\"ert+distance8\""));
    assert!(e.contains("modes") && e.contains("ert+distance8"), "{e}");
    let e = err(&SEQ.replace("steps = 3", "steps = 3\nbrick = 0"));
    assert!(e.contains("sequence.brick"), "{e}");
}

/// A sequence seen from two views: a table cell that holds both says it mixes their sequences;
/// with the frame a row, each cell is one view's time steps.
#[test]
fn a_sequence_table_says_when_its_cells_mix_views() {
    let dir = temp_dir("views");
    let out = sweep_metaballs(&dir, |t| {
        t.replace("orbit = 1", "orbit = 4\nselect = [0, 1]")
    });
    assert_eq!(lines(&out.join("results.jsonl")).len(), 2 * 3);
    let table = |rows: &str, name: &str| {
        let tables = dir.join(name);
        let o = vizsim(&[
            "table",
            out.to_str().unwrap(),
            "--rows",
            rows,
            "--columns",
            "mode",
            "--metric",
            "total-cycles",
            "--out",
            tables.to_str().unwrap(),
        ]);
        assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
        std::fs::read_to_string(tables.join("cycle-total-cycles.md")).unwrap()
    };
    let mixed = table("dataset,map", "mixed");
    assert!(
        mixed.contains("mean over 6 time steps of every view"),
        "{mixed}"
    );
    assert!(
        mixed.contains("these cells mix several views' sequences"),
        "{mixed}"
    );
    let apart = table("dataset,map,frame", "apart");
    assert!(apart.contains("mean over 3 time steps\n"), "{apart}");
    assert!(!apart.contains("mix several views"), "{apart}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A sequence experiment takes the map's hierarchy (`ert+leap4+hier`), as `vizsim sequence
/// --hierarchy` does: the same cycles per step, and other cycles than without it.
#[test]
fn a_sequence_experiment_with_the_hierarchy_equals_vizsim_sequence() {
    let dir = temp_dir("hier");
    let out = sweep_metaballs(&dir, |t| {
        t.replace(
            r#"modes = ["ert+leap8"]"#,
            r#"modes = ["ert+leap4", "ert+leap4+hier"]"#,
        )
    });
    let all = lines(&out.join("results.jsonl"));
    assert_eq!(all.len(), 2 * 3);
    let o = vizsim(&[
        "sequence",
        "--source",
        "phantom:metaballs:32",
        "--steps",
        "3",
        "--subcube",
        "4",
        "--hierarchy",
        "--view",
        "orbit:0/1",
        "--size",
        "32x32",
        "--json",
    ]);
    assert!(o.status.success(), "{}", String::from_utf8_lossy(&o.stderr));
    let report: Value = serde_json::from_slice(&o.stdout).unwrap();
    let mut differs = false;
    for step in report["steps"].as_array().unwrap() {
        let of = |mode: &str| {
            all.iter()
                .find(|l| l["mode"] == mode && l["time_step"] == step["step"])
                .unwrap_or_else(|| panic!("no {mode} line of step {}", step["step"]))
        };
        assert_eq!(of("ert+leap4+hier")["render_cycles"], step["render_cycles"]);
        assert_eq!(of("ert+leap4+hier")["total_cycles"], step["total_cycles"]);
        differs |= of("ert+leap4")["render_cycles"] != step["render_cycles"];
    }
    assert!(differs, "the hierarchy changes no step's render cycles");
    let _ = std::fs::remove_dir_all(&dir);
}
