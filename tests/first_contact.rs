//! What a new user meets first (issue 13, section 4): the demo with a partial or missing data
//! folder, the published dataset names, help texts, dry-run estimates and error messages.

mod common;

use std::path::PathBuf;
use std::process::{Command, Output};

fn vizsim_env(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut cmd = Command::new(env!("CARGO_BIN_EXE_vizsim"));
    cmd.args(args).current_dir(env!("CARGO_MANIFEST_DIR"));
    for (k, v) in env {
        cmd.env(k, v);
    }
    cmd.output().expect("run vizsim")
}

fn vizsim(args: &[&str]) -> Output {
    vizsim_env(args, &[])
}

fn text(out: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-first-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn demo_renders_what_is_there_and_says_what_it_skipped() {
    let dir = scratch("demo");
    let empty = dir.join("empty-data");
    std::fs::create_dir_all(&empty).unwrap();
    let out_dir = dir.join("demo");
    let out = vizsim_env(
        &["demo", "--frames", "2", "--out", out_dir.to_str().unwrap()],
        &[("VIZSIM_DATA", empty.to_str().unwrap())],
    );
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stdout}\n{stderr}");
    assert!(stdout.contains("no fuel"), "{stdout}");
    assert!(stdout.contains("fuel is not there, left out"), "{stdout}");
    assert!(
        out_dir.join("orbit-phantom-metaballs-64.png").is_file(),
        "{stdout}"
    );
    let galleries = std::fs::read_dir(&out_dir)
        .unwrap()
        .filter(|e| {
            let name = e.as_ref().unwrap().file_name();
            name.to_string_lossy().starts_with("gallery-phantom")
        })
        .count();
    assert_eq!(
        galleries,
        vizsim::volume::phantom::PhantomKind::ALL.len(),
        "one gallery per phantom"
    );
    assert!(out_dir.join("flythrough-tube.png").is_file(), "{stdout}");
    assert!(out_dir.join("sequence-metaballs.png").is_file(), "{stdout}");
    assert!(
        stdout.contains("phantom:metaballs:64: 5 time steps") && stdout.contains("frames/s"),
        "{stdout}"
    );
}

#[test]
fn an_explicit_data_folder_that_does_not_exist_is_an_error() {
    let out = vizsim(&["demo", "--data-dir", "/nope/vizsim-data", "--frames", "1"]);
    let (_, stderr) = text(&out);
    assert!(!out.status.success());
    assert!(
        stderr.contains("--data-dir /nope/vizsim-data: no such folder"),
        "{stderr}"
    );
    let out = vizsim(&["info", "fuel", "--data-dir", "/nope/vizsim-data"]);
    assert!(!out.status.success());
    assert!(text(&out).1.contains("--data-dir"), "{}", text(&out).1);
}

#[test]
fn published_names_resolve_to_their_stand_ins() {
    let Some(data) = common::data_dir() else {
        eprintln!("SKIP published_names_resolve_to_their_stand_ins: no data directory");
        return;
    };
    let data = data.to_str().unwrap();
    for (name, stand_in) in [
        ("skull", "tooth_103x94x161"),
        ("foot", "foot-lossy"),
        ("vessel", "aneurism"),
    ] {
        let out = vizsim(&["info", name, "--data-dir", data, "--json"]);
        let (stdout, stderr) = text(&out);
        assert!(out.status.success(), "{name}: {stderr}");
        assert!(
            stdout.contains(&format!("\"name\": \"{stand_in}\"")),
            "{stdout}"
        );
    }
}

#[test]
fn help_describes_every_argument_and_points_nowhere_circular() {
    let (help, _) = text(&vizsim(&["precision", "--help"]));
    // Every option line of clap's help is followed by its description on the same line.
    // Option lines start in the options column; a description's wrapped line that happens to
    // start with `--set` is indented to the description column.
    let option_line = |l: &&str| {
        let indent = l.len() - l.trim_start().len();
        indent <= 6 && l.trim_start().starts_with("--")
    };
    for line in help.lines().filter(option_line) {
        let option = line.split_whitespace().next().unwrap();
        if option == "--help" || option == "--version" {
            continue;
        }
        let described = line
            .trim_start()
            .split("  ")
            .filter(|p| !p.is_empty())
            .count()
            >= 2;
        assert!(described, "precision {option} has no description: {line:?}");
    }
    let (help, _) = text(&vizsim(&["info", "--help"]));
    assert!(!help.contains("vizsim info --help"), "{help}");
    assert!(help.contains("phantom:"), "{help}");
    let (help, _) = text(&vizsim(&["sweep", "--help"]));
    assert!(help.contains("--dry-run"));
    assert!(help.contains("how many runs"), "{help}");
}

#[test]
fn a_short_dry_run_is_estimated_in_seconds() {
    let dir = scratch("dry");
    let exp = dir.join("tiny.toml");
    std::fs::write(
        &exp,
        "name = \"tiny\"\ndatasets = [\"phantom:sphere:16\"]\nmodes = [\"ert\"]\nmodels = [\"step\"]\n[frames]\norbit = 2\nsize = \"16x16\"\n",
    )
    .unwrap();
    let out = vizsim(&[
        "sweep",
        exp.to_str().unwrap(),
        "--out",
        dir.join("o").to_str().unwrap(),
        "--dry-run",
    ]);
    let (stdout, stderr) = text(&out);
    assert!(out.status.success(), "{stderr}");
    assert!(
        stdout.contains("estimate under 1 s + under 1 s"),
        "{stdout}"
    );
    assert!(!stdout.contains(" 0 min"), "{stdout}");
}

#[test]
fn an_io_error_names_the_path_once_and_the_option() {
    let dir = scratch("io");
    let png = dir.join("x.png");
    let out = vizsim(&[
        "render",
        "--dataset",
        "phantom:sphere:16",
        "--config",
        "/nope/hw.toml",
        "-o",
        png.to_str().unwrap(),
    ]);
    let (_, stderr) = text(&out);
    assert!(!out.status.success());
    assert!(stderr.contains("--config /nope/hw.toml"), "{stderr}");
    assert_eq!(
        stderr.matches("No such file or directory").count(),
        1,
        "{stderr}"
    );
    assert!(!png.exists());
}

#[test]
fn tables_name_swept_columns_print_every_metric_and_format_columns_one_way() {
    let dir = scratch("tables");
    let exp = dir.join("t.toml");
    std::fs::write(
        &exp,
        "name = \"t\"\ndatasets = [\"phantom:metaballs:32\", \"phantom:shells:24\"]\nmodes = [\"none\", \"ert+leap4\"]\nmodels = [\"step\"]\n[frames]\norbit = 8\nselect = [0, 1]\nsize = \"24x24\"\n[axes]\n\"skip.latency\" = [4, 8]\n",
    )
    .unwrap();
    let out = dir.join("o");
    let run = vizsim(&[
        "sweep",
        exp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    assert!(run.status.success(), "{}", text(&run).1);
    let table = vizsim(&[
        "table",
        out.to_str().unwrap(),
        "--rows",
        "dataset,tf,mode",
        "--columns",
        "skip.latency",
        "--metric",
        "steps,skippable",
    ]);
    let (stdout, stderr) = text(&table);
    assert!(table.status.success(), "{stderr}");
    assert!(
        stdout.contains("| skip.latency = 4 | skip.latency = 8 |"),
        "{stdout}"
    );
    assert!(stdout.contains("### steps per frame"), "{stdout}");
    assert!(
        stdout.contains("### skippable sub-cubes (%) (occupancy map)"),
        "{stdout}"
    );
    assert!(
        !stdout.contains("skippable sub-cubes (%) (cycle"),
        "{stdout}"
    );
    // One number format per column: within a column every cell has the same number of
    // decimals; a count (steps) has none, in any column.
    for block in stdout.split("### ").skip(1) {
        let rows: Vec<Vec<String>> = block
            .lines()
            .filter(|l| l.starts_with('|') && !l.contains("---") && !l.contains("dataset"))
            .map(|l| l.split('|').map(|c| c.trim().to_string()).collect())
            .collect();
        let width = rows.first().map_or(0, Vec::len);
        for c in 4..width.saturating_sub(1) {
            let decimals: std::collections::BTreeSet<usize> = rows
                .iter()
                .filter(|r| r[c] != "–")
                .map(|r| {
                    let cell = r[c].trim_end_matches('*');
                    cell.split('.').nth(1).map_or(0, str::len)
                })
                .collect();
            assert!(
                decimals.len() <= 1,
                "column {c} mixes formats {decimals:?}:\n{block}"
            );
            if block.starts_with("steps per frame") {
                assert_eq!(decimals.first(), Some(&0), "steps with decimals:\n{block}");
            }
        }
    }
}

/// The leaping flags shared by the run commands are listed only where they apply, with the
/// meaning they have there. Before, `occupancy`, `precision` and `update` listed `--subcube`,
/// `--hierarchy`, `--occupancy` and `--bricks` with the render text and then refused them, and
/// `update --help` said of `--subcube` "without it, no leaping" where it is required.
#[test]
fn help_lists_the_leaping_flags_only_where_they_apply() {
    let help = |command: &str| text(&vizsim(&[command, "--help"])).0;
    let lists = |help: &str, flag: &str| {
        help.lines()
            .any(|l| l.trim_start().starts_with(&format!("{flag} ")) || l.trim() == flag)
    };
    let flags = ["--subcube", "--hierarchy", "--occupancy", "--bricks"];
    for command in ["occupancy", "precision"] {
        let help = help(command);
        for flag in flags {
            assert!(!lists(&help, flag), "{command} --help lists {flag}: {help}");
        }
    }
    let update = help("update");
    for flag in ["--hierarchy", "--occupancy", "--bricks"] {
        assert!(
            !lists(&update, flag),
            "update --help lists {flag}: {update}"
        );
    }
    // The `--subcube` entry up to the next option's line, whitespace collapsed: clap wraps
    // long descriptions at the terminal's width (and the text itself may name `--set`).
    let subcube_line = |help: &str| {
        let lines: Vec<&str> = help.lines().collect();
        let Some(start) = lines
            .iter()
            .position(|l| l.trim_start().starts_with("--subcube <SUBCUBE>"))
        else {
            return String::new();
        };
        // A wrapped continuation is indented past the option column; the next option is not.
        let indent = |l: &str| l.len() - l.trim_start().len();
        let continued = lines[start + 1..]
            .iter()
            .take_while(|l| !l.trim().is_empty() && indent(l) > indent(lines[start]) + 4);
        std::iter::once(&lines[start])
            .chain(continued)
            .flat_map(|l| l.split_whitespace())
            .skip(2)
            .collect::<Vec<_>>()
            .join(" ")
    };
    let line = subcube_line(&update);
    assert!(
        line.contains("required") && line.contains("--config") && !line.contains("no leaping"),
        "{line}"
    );
    // A sequence rebuilds the brick flags from the map's table: `--bricks` applies there, with
    // the rule it has there.
    let sequence = help("sequence");
    assert!(lists(&sequence, "--bricks"), "{sequence}");
    let words = sequence.split_whitespace().collect::<Vec<_>>().join(" ");
    assert!(
        words.contains("rebuilt each step from the map"),
        "{sequence}"
    );
    let line = subcube_line(&sequence);
    assert!(
        line.contains("required") && line.contains("--config") && !line.contains("no leaping"),
        "{line}"
    );
    // Where they apply, all four keep the one shared text.
    for command in ["render", "sim"] {
        let help = help(command);
        for flag in flags {
            assert!(lists(&help, flag), "{command} --help lacks {flag}: {help}");
        }
        assert!(
            subcube_line(&help).contains("without it, no leaping"),
            "{help}"
        );
    }
    // A hidden flag given anyway is still refused with the reason, not taken silently (a
    // review found precision making its report with --bricks).
    let scratch = std::env::temp_dir().join(format!("vizsim-precision-{}", std::process::id()));
    for command in [
        &["occupancy", "phantom:sphere:16", "--bricks", "8"][..],
        &[
            "precision",
            "--dataset",
            "phantom:sphere:16",
            "--bricks",
            "8",
            "--out",
            scratch.to_str().unwrap(),
        ],
    ] {
        let out = vizsim(command);
        let (_, stderr) = text(&out);
        assert!(
            !out.status.success() && stderr.contains("do not apply"),
            "{command:?}: {stderr}"
        );
    }
    assert!(
        !scratch.exists(),
        "a refused precision run wrote {}",
        scratch.display()
    );
    let out = vizsim(&["update", "phantom:sphere:16"]);
    let (_, stderr) = text(&out);
    assert!(
        !out.status.success() && stderr.contains("--subcube"),
        "{stderr}"
    );
}
