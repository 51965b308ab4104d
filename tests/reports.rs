//! Reports regenerate: the small committed reports (precision on fuel and neghip with their
//! charts, the quick and bit-widths experiments' tables) are made again here, by the command each names, and
//! must equal the committed copies byte for byte. A stale report (after a transfer function, a
//! model, a table format or the chart layout changed) fails this test; regenerate it with the
//! command it names.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;

fn repo() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// Runs vizsim in `cwd` with the data folder in the environment, so that the command line,
/// and with it the provenance line of the report, is the one the committed report names.
fn vizsim_in(cwd: &Path, data: &Path, args: &[&str]) {
    let out = Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(args)
        .current_dir(cwd)
        .env("VIZSIM_DATA", data)
        .output()
        .expect("run vizsim");
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-reports-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Every file of `committed` with one of `extensions` has an identical twin in `fresh`, and
/// `fresh` has no such file that is not committed.
fn assert_same_files(committed: &Path, fresh: &Path, extensions: &[&str], only_stems: &[&str]) {
    let list = |dir: &Path| -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .filter(|n| extensions.iter().any(|x| n.ends_with(x)))
            .filter(|n| only_stems.is_empty() || only_stems.iter().any(|s| n.starts_with(s)))
            .collect();
        names.sort();
        names
    };
    let (old, new) = (list(committed), list(fresh));
    assert!(
        !new.is_empty(),
        "nothing regenerated in {}",
        fresh.display()
    );
    assert_eq!(old, new, "the files of {}", committed.display());
    for name in &old {
        let a = std::fs::read(committed.join(name)).unwrap();
        let b = std::fs::read(fresh.join(name)).unwrap();
        if a == b {
            continue;
        }
        // Text files say where they differ; a PNG only that it does. Charts are drawn with the
        // system's sans-serif font (DejaVu Sans where the committed ones were made).
        let (Ok(a), Ok(b)) = (String::from_utf8(a), String::from_utf8(b)) else {
            panic!(
                "{} is stale (the image differs): regenerate it with the command its report names",
                committed.join(name).display()
            );
        };
        let line = a
            .lines()
            .zip(b.lines())
            .position(|(x, y)| x != y)
            .unwrap_or(a.lines().count().min(b.lines().count()));
        panic!(
            "{} is stale (first difference at line {}): regenerate it with the command it (or its report) names\n committed: {:?}\n now:       {:?}",
            committed.join(name).display(),
            line + 1,
            a.lines().nth(line),
            b.lines().nth(line)
        );
    }
}

#[test]
fn precision_reports_of_fuel_and_neghip_are_current() {
    let Some(data) = common::data_dir() else {
        eprintln!("SKIP precision_reports_of_fuel_and_neghip_are_current: no data directory");
        return;
    };
    let cwd = scratch("precision");
    for dataset in ["fuel", "neghip"] {
        vizsim_in(&cwd, &data, &["precision", "--dataset", dataset]);
    }
    assert_same_files(
        &repo().join("reports/precision"),
        &cwd.join("reports/precision"),
        &[".md", ".csv", ".json", ".svg", ".png"],
        &["fuel", "neghip"],
    );
}

/// Sweeps `configs/experiments/NAME.toml` into `runs/NAME` in a scratch folder, tabulates it with
/// `table` (the arguments after the folder), and compares with the committed `reports/REPORT`.
fn experiment_tables_are_current(name: &str, table_args: &[&str], report: &str) {
    let Some(data) = common::data_dir() else {
        eprintln!("SKIP the {name} experiment's tables: no data directory");
        return;
    };
    let cwd = scratch(name);
    let file = format!("configs/experiments/{name}.toml");
    std::fs::create_dir_all(cwd.join("configs/experiments")).unwrap();
    std::fs::copy(repo().join(&file), cwd.join(&file)).unwrap();
    let runs = format!("runs/{name}");
    vizsim_in(&cwd, &data, &["sweep", &file, "--out", &runs, "--quiet"]);
    let out = format!("reports/{report}");
    let mut args = vec!["table", runs.as_str()];
    args.extend_from_slice(table_args);
    args.extend_from_slice(&["--out", &out]);
    vizsim_in(&cwd, &data, &args);
    assert_same_files(&repo().join(&out), &cwd.join(&out), &[".md", ".csv"], &[]);
}

#[test]
fn quick_experiment_tables_are_current() {
    experiment_tables_are_current("quick", &[], "quick/tables");
}

/// The experiment with the image against the float reference in every line.
#[test]
fn bit_widths_tables_are_current() {
    experiment_tables_are_current(
        "bit-widths",
        &[
            "--rows",
            "dataset,skip.reciprocal_bits,interpolation.weight_bits",
            "--columns",
            "compositing.accumulator_bits",
            "--metric",
            "psnr,image-error,cycles",
        ],
        "bit-widths/tables",
    );
}
