//! The fields of a result line are the ones docs/experiments.md documents ("Results", and a
//! sequence step's in "Sequences"): a sweep of every kind of run (both models, every leaping
//! structure, bricks with traversal and table, iso, blocking with the float reference,
//! sampled, a sequence) writes no field the reference lacks, and every documented field is
//! written by one of them. A statistic added or renamed without its line in the reference
//! fails here (DRAMsim3's docs drifted from its counters; house style).
//!
//! The same for the `--json` report of `render` and `sim`: its fields that are not a result
//! line's have their row in "The --json report of render and sim", and reports of every kind
//! (both memories, sampled, each leaping structure, iso, bricks, blocking, the bound check)
//! write every field that table documents.

use std::collections::BTreeSet;
use std::path::Path;
use std::process::Command;

use vizsim::experiment::{self, spec};

/// One experiment on small phantoms; `extra` goes at the end (axes, sequence, sampling).
fn experiment(name: &str, dataset: &str, modes: &str, models: &str, extra: &str) -> String {
    format!(
        r#"name = "{name}"
datasets = ["{dataset}"]
tf = ["class"]
modes = [{modes}]
models = [{models}]
{extra}
"#
    )
}

/// Field paths of a result line: its top-level fields, and one level into objects (not into
/// `axes`, whose keys are configuration paths).
fn field_paths(line: &serde_json::Value, into: &mut BTreeSet<String>) {
    for (key, value) in line.as_object().expect("a result is an object") {
        into.insert(key.clone());
        if let (Some(inner), false) = (value.as_object(), key == "axes") {
            for sub in inner.keys() {
                into.insert(format!("{key}.{sub}"));
            }
        }
    }
}

/// The backticked names of a piece of the reference; `name{a, b}` documents `name`,
/// `name.a` and `name.b`.
fn names_in(text: &str, into: &mut BTreeSet<String>) {
    for name in text.split('`').skip(1).step_by(2) {
        match name.split_once('{') {
            Some((object, fields)) => {
                into.insert(object.to_string());
                for f in fields.trim_end_matches('}').split(',') {
                    into.insert(format!("{object}.{}", f.trim()));
                }
            }
            None => {
                into.insert(name.to_string());
            }
        }
    }
}

/// The rows of the first `| field | meaning |` table after the line `heading` of
/// docs/experiments.md, as (first column, second column).
fn table_rows(heading: &str) -> Vec<(String, String)> {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/experiments.md"))
        .expect("docs/experiments.md");
    doc.lines()
        .skip_while(|l| *l != heading)
        .skip_while(|l| !l.starts_with("| field | meaning |"))
        .skip(2)
        .take_while(|l| l.starts_with('|'))
        .map(|row| {
            let mut cells = row.split('|').skip(1);
            let field = cells.next().unwrap_or_default().to_string();
            (field, cells.next().unwrap_or_default().to_string())
        })
        .collect()
}

/// The fields docs/experiments.md documents: the first column of the "Results" table, and the
/// backticked names of the "Result line of a step" paragraph that are written as fields.
fn documented() -> (BTreeSet<String>, BTreeSet<String>) {
    let doc = std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/docs/experiments.md"))
        .expect("docs/experiments.md");
    let mut table = BTreeSet::new();
    for (field, _) in table_rows("## Results") {
        names_in(&field, &mut table);
    }
    let paragraph: String = doc
        .lines()
        .skip_while(|l| !l.starts_with("**Result line of a step**"))
        .take_while(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join(" ");
    let mut sequence = BTreeSet::new();
    names_in(&paragraph, &mut sequence);
    (table, sequence)
}

#[test]
fn every_result_field_is_documented_and_every_documented_field_is_written() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-results-fields-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    let frames = "[frames]\norbit = 8\nselect = [0]\nsize = \"8x8\"";
    let experiments = [
        experiment(
            "structures",
            "phantom:sphere:16",
            r#""none", "ert+leap4+hier", "distance8", "leapvalues", "bricks8", "iso2", "ert+leap4+bricks8+table""#,
            r#""step", "cycle""#,
            frames,
        ),
        experiment(
            "blocking",
            "phantom:sphere:16",
            r#""none""#,
            r#""step", "cycle""#,
            // With the image against the float reference in every line.
            &format!(
                "float_reference = true\n{frames}\n[axes]\n\"blocking.enabled\" = [true]\n\"blocking.block_size\" = [8]"
            ),
        ),
        experiment(
            "sampled",
            "phantom:sphere:32",
            r#""none""#,
            r#""cycle""#,
            "sample = 0.5\n[frames]\norbit = 8\nselect = [0]\nsize = \"32x32\"",
        ),
        experiment(
            "sequence",
            "phantom:metaballs:16",
            r#""ert+leap4""#,
            r#""cycle""#,
            "[frames]\norbit = 1\nsize = \"8x8\"\n[sequence]\nsteps = 2\nmap = [\"update\"]",
        ),
    ];
    let (mut written, mut written_by_steps) = (BTreeSet::new(), BTreeSet::new());
    for text in &experiments {
        let expansion = spec::expand(text, "fields.toml", None).expect("a valid experiment");
        let name = &expansion.experiment.name;
        let out = dir.join(name);
        experiment::sweep(&expansion, &out, None, None, false).expect("the sweep runs");
        let lines = std::fs::read_to_string(out.join("results.jsonl")).unwrap();
        assert!(!lines.is_empty(), "{name}: no results");
        for line in lines.lines() {
            let line: serde_json::Value = serde_json::from_str(line).unwrap();
            let into = if line.get("time_step").is_some() {
                &mut written_by_steps
            } else {
                &mut written
            };
            field_paths(&line, into);
        }
    }
    let (table, sequence) = documented();
    assert!(
        table.len() > 40,
        "the Results table was not found: {table:?}"
    );
    let undocumented: Vec<&String> = written.difference(&table).collect();
    assert!(
        undocumented.is_empty(),
        "result fields missing from docs/experiments.md's Results table: {undocumented:?}"
    );
    // A step of a sequence: the run's fields and its own.
    let all: BTreeSet<String> = table.union(&sequence).cloned().collect();
    let undocumented: Vec<&String> = written_by_steps.difference(&all).collect();
    assert!(
        undocumented.is_empty(),
        "sequence step fields missing from docs/experiments.md: {undocumented:?}"
    );
    let never_written: Vec<&String> = table.difference(&written).collect();
    assert!(
        never_written.is_empty(),
        "docs/experiments.md documents result fields no run writes: {never_written:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// The `--json` report of `vizsim ARGS` on a small phantom (8×8 pixels of a sphere of 16³),
/// written into `dir` as `name.json`.
fn report(dir: &Path, name: &str, args: &[&str]) -> serde_json::Value {
    let json = dir.join(format!("{name}.json"));
    let mut command = Command::new(env!("CARGO_BIN_EXE_vizsim"));
    command
        .args(args)
        .args(["--dataset", "phantom:sphere:16", "--size", "8x8", "--json"])
        .arg(&json);
    if args[0] == "render" {
        command.arg("--output").arg(dir.join(format!("{name}.png")));
    }
    let out = command.output().expect("vizsim runs");
    assert!(
        out.status.success(),
        "{name}: vizsim {args:?} failed: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    serde_json::from_str(&std::fs::read_to_string(&json).expect("the report")).expect("JSON")
}

#[test]
fn every_json_report_field_is_documented_and_every_documented_field_is_written() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-report-fields-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let runs: [(&str, &[&str]); 9] = [
        ("float", &["render"]),
        ("fixed", &["render", "--model", "fixed", "--check-bound"]),
        ("sdram-map", &["sim", "--subcube", "4", "--hierarchy"]),
        ("ideal", &["sim", "--memory", "ideal"]),
        ("sampled", &["sim", "--sample", "0.5"]),
        (
            "leap-values",
            &[
                "sim",
                "--set",
                "occupancy.structure=leap-values",
                "--check-bound",
            ],
        ),
        (
            "distance",
            &["sim", "--set", "occupancy.structure=distance"],
        ),
        (
            "iso-bricks",
            &["sim", "--set", "iso.enabled=true", "--bricks", "4"],
        ),
        (
            "blocking",
            &[
                "sim",
                "--set",
                "blocking.enabled=true",
                "--set",
                "blocking.block_size=8",
            ],
        ),
    ];
    let (mut written, mut module_fields) = (BTreeSet::new(), BTreeSet::new());
    for (name, args) in runs {
        let report = report(&dir, name, args);
        // One level into every object: `run.hardware` is the configuration (docs/config.md),
        // and the Measurements' objects are the Results table's.
        field_paths(&report, &mut written);
        for module in report["memory_stats"]["modules"]
            .as_array()
            .into_iter()
            .flatten()
        {
            module_fields.extend(module.as_object().expect("a module").keys().cloned());
        }
    }
    let (mut json_table, mut memory_meaning) = (BTreeSet::new(), String::new());
    for (field, meaning) in table_rows("## The --json report of render and sim") {
        names_in(&field, &mut json_table);
        if field.trim().starts_with("`memory_stats{") {
            memory_meaning = meaning;
        }
    }
    assert!(
        json_table.len() > 60,
        "the --json report's table was not found: {json_table:?}"
    );
    let (results_table, _) = documented();
    let documented: BTreeSet<String> = json_table.union(&results_table).cloned().collect();
    let undocumented: Vec<&String> = written.difference(&documented).collect();
    assert!(
        undocumented.is_empty(),
        "--json report fields missing from docs/experiments.md (\"The --json report of render \
         and sim\", or the Results table for the Measurements): {undocumented:?}"
    );
    let never_written: Vec<&String> = json_table.difference(&written).collect();
    assert!(
        never_written.is_empty(),
        "docs/experiments.md documents --json report fields no report writes: {never_written:?}"
    );
    // An entry of `memory_stats.modules` is described in the meaning of the `memory_stats` row.
    assert!(
        !module_fields.is_empty(),
        "no report wrote memory_stats.modules"
    );
    let mut described = BTreeSet::new();
    names_in(&memory_meaning, &mut described);
    let undescribed: Vec<&String> = module_fields.difference(&described).collect();
    assert!(
        undescribed.is_empty(),
        "fields of a memory_stats.modules entry missing from the memory_stats row: \
         {undescribed:?}"
    );
    let _ = std::fs::remove_dir_all(&dir);
}
