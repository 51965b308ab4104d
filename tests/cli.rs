//! The binary's behaviour on good and bad input: messages that say what and where, a non-zero
//! exit, and no output file left behind on failure.

mod common;

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn vizsim(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("run vizsim")
}

/// Runs a command that must succeed; its standard error is shown when it does not.
fn succeeds(args: &[&str]) -> Output {
    let out = vizsim(args);
    assert!(
        out.status.success(),
        "{args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    out
}

fn scratch(name: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-cli-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Runs a command that must fail: non-zero exit, the stderr mentions every `needle`, no panic,
/// and `output` was not created.
fn assert_fails(args: &[&str], needles: &[&str], output: &Path) {
    let out = vizsim(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{args:?} succeeded");
    assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    for n in needles {
        assert!(stderr.contains(n), "{args:?}: stderr lacks {n:?}: {stderr}");
    }
    assert!(!output.exists(), "{args:?} left {}", output.display());
}

#[test]
fn render_writes_a_png_and_json() {
    let dir = scratch("ok");
    let png = dir.join("out.png");
    let json = dir.join("stats.json");
    succeeds(&[
        "render",
        "--dataset",
        "phantom:sphere:32",
        "--tf",
        "class",
        "--size",
        "40x30",
        "-o",
        png.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (40, 30));
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(stats["stats"]["rays"], 1200);
    assert!(stats["stats"]["samples"].as_u64().unwrap() > 0);
    // Per-ray counts: one row per pixel, and their samples add up to the total.
    let rays = dir.join("rays.csv");
    let out = vizsim(&[
        "render",
        "--dataset",
        "phantom:sphere:32",
        "--size",
        "40x30",
        "-o",
        png.to_str().unwrap(),
        "--rays",
        rays.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let text = std::fs::read_to_string(&rays).unwrap();
    assert_eq!(text.lines().skip(1).count(), 1200);
    assert_eq!(
        column_total(&text, "samples"),
        stats["stats"]["samples"].as_u64().unwrap()
    );

    // Iso mode with bricks: the per-ray refinement samples and cut positions are columns too,
    // and add up to the frame's totals.
    let out = vizsim(&[
        "render",
        "--dataset",
        "phantom:sphere:32",
        "--size",
        "40x30",
        "--set",
        "iso.enabled=true",
        "--bricks",
        "8",
        "-o",
        png.to_str().unwrap(),
        "--rays",
        rays.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let stats: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let text = std::fs::read_to_string(&rays).unwrap();
    let refinement = stats["refinement_samples"].as_u64().unwrap();
    let cut = stats["ray_range"]["positions_cut"].as_u64().unwrap();
    assert!(refinement > 0 && cut > 0, "the frame refines and cuts");
    assert_eq!(column_total(&text, "refinement_samples"), refinement);
    assert_eq!(column_total(&text, "positions_cut"), cut);
    assert_eq!(
        column_total(&text, "samples"),
        stats["samples"].as_u64().unwrap()
    );
}

/// The sum of a per-ray CSV's column, found by its header.
fn column_total(csv: &str, name: &str) -> u64 {
    let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
    let at = header.iter().position(|h| *h == name).expect(name);
    csv.lines()
        .skip(1)
        .map(|r| r.split(',').nth(at).unwrap().parse::<u64>().unwrap())
        .sum()
}

#[test]
fn unknown_dataset_lists_what_is_available() {
    let dir = scratch("unknown");
    let png = dir.join("out.png");
    assert_fails(
        &[
            "render",
            "--dataset",
            "nonesuch",
            "-o",
            png.to_str().unwrap(),
        ],
        &["nonesuch", "phantom:"],
        &png,
    );
    // The list is every name the resolver takes: the files, the aliases whose file is there
    // (a probe found the list without the phantoms tsdf and tube and without skull and foot).
    // The listing reads names only, so empty files stand for the datasets.
    let data = dir.join("data");
    std::fs::create_dir_all(data.join("lossy_previews")).unwrap();
    for file in [
        "aneurism_8x8x8_uint8.raw",
        "tooth_103x94x161_uint8.raw",
        "tooth_140x120x161_uint8.raw",
        "lossy_previews/foot_8x8x8_uint8.raw",
    ] {
        std::fs::write(data.join(file), b"").unwrap();
    }
    assert_fails(
        &[
            "render",
            "--data-dir",
            data.to_str().unwrap(),
            "--dataset",
            "nonesuch",
            "-o",
            png.to_str().unwrap(),
        ],
        &[
            "aneurism, foot-lossy, tooth_103x94x161, tooth_140x120x161, ",
            "vessel (alias of aneurism)",
            "skull (stand-in: tooth_103x94x161)",
            "foot (stand-in: foot-lossy)",
            "phantom:sphere|shells|jet|metaballs|cast|tsdf|tube[:SIZE]",
        ],
        &png,
    );
}

/// A dataset given as a path names a file: a missing one is "no such file" (with the path
/// read), a folder is refused as one, not reported as an unknown dataset name.
#[test]
fn a_missing_volume_file_is_named_as_a_file() {
    let dir = scratch("missing-file");
    let png = dir.join("out.png");
    let missing = dir.join("gone_8x8x8_uint8.raw");
    assert_fails(
        &[
            "render",
            "--dataset",
            missing.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
        ],
        &["no such file", missing.to_str().unwrap()],
        &png,
    );
    for relative in ["gone_8x8x8_uint8.raw", "volumes/gone"] {
        let out = vizsim(&["info", relative]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success());
        assert!(stderr.contains("no such file"), "{relative}: {stderr}");
        assert!(!stderr.contains("available:"), "{relative}: {stderr}");
    }
    let out = vizsim(&["info", dir.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(stderr.contains("is a folder"), "{stderr}");
    // Whatever the data folder (here a stale one), and a path that is there but is not a
    // regular file is not reported missing (a review found a FIFO called "no such file").
    let out = Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(["info", missing.to_str().unwrap()])
        .env("VIZSIM_DATA", dir.join("no-data-here"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("no such file"),
        "{stderr}"
    );
    #[cfg(unix)]
    {
        let fifo = dir.join("pipe_8x8x8_uint8.raw");
        assert!(Command::new("mkfifo")
            .arg(&fifo)
            .status()
            .unwrap()
            .success());
        let out = vizsim(&["info", fifo.to_str().unwrap()]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{stderr}");
        assert!(stderr.contains("not a regular file"), "{stderr}");
        assert!(!stderr.contains("no such file"), "{stderr}");
    }
}

#[test]
fn bad_image_sizes_fail_cleanly() {
    let dir = scratch("size");
    let png = dir.join("out.png");
    for size in ["0x10", "100000x10", "abc"] {
        assert_fails(
            &[
                "render",
                "--dataset",
                "phantom:sphere:16",
                "--size",
                size,
                "-o",
                png.to_str().unwrap(),
            ],
            &[size],
            &png,
        );
    }
}

#[test]
fn bad_transfer_function_files_name_the_file_and_field() {
    let dir = scratch("tf");
    let png = dir.join("out.png");
    let tf = dir.join("bad.toml");
    std::fs::write(&tf, "[[points]]\nvalue = 300\nrgba = [0, 0, 0, 2]\n").unwrap();
    assert_fails(
        &[
            "render",
            "--dataset",
            "phantom:sphere:16",
            "--tf",
            tf.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
        ],
        &["bad.toml", "points[0].rgba"],
        &png,
    );
    std::fs::write(
        &tf,
        "[[points]]\nvalue = 3\nrgba = [0, 0, 0, 1]\nopacity = 1\n",
    )
    .unwrap();
    assert_fails(
        &[
            "render",
            "--dataset",
            "phantom:sphere:16",
            "--tf",
            tf.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
        ],
        &["bad.toml", "opacity"],
        &png,
    );
}

#[test]
fn raw_file_with_wrong_size_names_the_file() {
    let dir = scratch("raw");
    let png = dir.join("out.png");
    let raw = dir.join("blob_8x8x8_uint8.raw");
    std::fs::write(&raw, vec![1u8; 500]).unwrap();
    assert_fails(
        &[
            "render",
            "--dataset",
            raw.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
        ],
        &["blob_8x8x8_uint8.raw", "512"],
        &png,
    );
}

/// A share that is not exactly 0 or 100 % never prints as either (a review found the tooth,
/// 99.999 % occupied, printed as "occupied 100.00 %").
#[test]
fn info_prints_no_share_as_0_or_100_that_is_not() {
    let dir = scratch("shares");
    let raw = dir.join("blob_64x64x64_uint8.raw");
    // One empty voxel, one at the top of the range, every other one 1.
    let mut voxels = vec![1u8; 64 * 64 * 64];
    voxels[0] = 0;
    voxels[1] = 255;
    std::fs::write(&raw, voxels).unwrap();
    let out = succeeds(&["info", raw.to_str().unwrap()]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    for expected in [
        "occupied  > 99.99 % of voxels > 0",
        "      0..15    > 99.999 % ",
        "    240..255    < 0.001 % #",
        "     16..31       0.000 % \n",
    ] {
        assert!(stdout.contains(expected), "{expected:?}: {stdout}");
    }
}

/// A time too short for milliseconds is given in microseconds, and a count of one takes the
/// singular (a review found "map 335 (0.00 ms)" and "1 bits of map SRAM").
#[test]
fn short_times_and_single_counts_read_naturally() {
    let out = succeeds(&[
        "sequence",
        "--source",
        "phantom:metaballs:16",
        "--steps",
        "2",
        "--subcube",
        "8",
        "--size",
        "8x8",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains(" + map 8 (0.08 µs) + ") && !stdout.contains("0.00 ms"),
        "{stdout}"
    );
    let out = succeeds(&[
        "sim",
        "--dataset",
        "phantom:sphere:16",
        "--subcube",
        "16",
        "--size",
        "8x8",
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("structure memory: 1 bit of map SRAM\n"),
        "{stdout}"
    );
}

/// A negative value of a numeric option reaches the option's own check (a review found
/// `--spacing -1` answered with clap's "unexpected argument '-1' found" while `--spacing 0`
/// named the allowed range); an unsigned option says it is negative.
#[test]
fn negative_numbers_reach_the_options_checks() {
    let dir = scratch("negative");
    let png = dir.join("x.png");
    let render = |extra: &[&'static str]| {
        let frame = ["render", "--dataset", "phantom:sphere:16", "--size", "8x8"];
        [&frame[..], extra, &["-o", png.to_str().unwrap()]].concat()
    };
    for (args, needles) in [
        (
            render(&["--spacing", "-1"]),
            &["sample spacing -1: allowed 1/64..=16 voxels"][..],
        ),
        (
            render(&["--model", "fixed", "--subcube", "-8"]),
            &["'--subcube <SUBCUBE>': must not be negative"][..],
        ),
        (
            render(&["--bricks", "-8"]),
            &["'--bricks <BRICKS>': must not be negative"][..],
        ),
        (
            render(&["--threads", "-1"]),
            &["`-1`: expected 1..=1024 threads"][..],
        ),
        (
            vec![
                "sequence",
                "--source",
                "phantom:metaballs:16",
                "--map",
                "none",
                "--dt",
                "-1",
            ],
            &["time step dt = -1: must be a finite number above 0"][..],
        ),
        (
            vec![
                "sequence",
                "--source",
                "phantom:metaballs:16",
                "--steps",
                "-1",
            ],
            &["'--steps <STEPS>': must not be negative"][..],
        ),
        (
            vec![
                "sim",
                "--dataset",
                "phantom:sphere:16",
                "--memory",
                "ideal",
                "--ideal-latency",
                "-1",
            ],
            &["'--ideal-latency <IDEAL_LATENCY>': must not be negative"][..],
        ),
        (
            vec!["verify-skip", "--subcube", "2,-16"],
            &["'--subcube <SUBCUBE>': must not be negative"][..],
        ),
        (
            vec!["advise", "--dataset", "phantom:sphere:16", "--views", "-1"],
            &["'--views <VIEWS>': must not be negative"][..],
        ),
        (
            vec!["table", "no-such-folder", "--frame-step", "-1"],
            &["'--frame-step <FRAME_STEP>': must not be negative"][..],
        ),
        (
            vec!["advise", "--dataset", "phantom:sphere:16", "--rays", "-64"],
            &["'--rays <RAYS>': must not be negative"][..],
        ),
        // Text options with a leading minus (clap took `-16x16` for a flag).
        (
            vec![
                "render",
                "--dataset",
                "phantom:sphere:16",
                "--size",
                "-16x16",
                "-o",
                png.to_str().unwrap(),
            ],
            &["--size: image size `-16x16`: expected WxH"][..],
        ),
        (
            vec![
                "precision",
                "--dataset",
                "phantom:sphere:16",
                "--size",
                "-8x8",
            ],
            &["--size: image size `-8x8`"][..],
        ),
        (
            vec!["sweep", "no-such.toml", "--out", "x", "--shard", "-1/2"],
            &["--shard -1/2: expected I/N"][..],
        ),
        (
            render(&["--memory-budget", "-1G"]),
            &["`-1G`: expected bytes"][..],
        ),
    ] {
        assert_fails(&args, needles, &png);
        let stderr = String::from_utf8_lossy(&vizsim(&args).stderr).into_owned();
        assert!(
            !stderr.contains("unexpected argument"),
            "{args:?}: {stderr}"
        );
    }
    // A valid value gets as far as the command.
    assert_fails(
        &["advise", "--validate", "no-such-folder", "--max-views", "2"],
        &["--validate no-such-folder"],
        &png,
    );
    assert_fails(
        &["plot", "no-such-folder", "--frame-step", "2"],
        &["no-such-folder"],
        &png,
    );
}

/// `advise` without its input names both ways to give it (a review found only `--dataset`
/// named), and `--threads` is described for every command, the sweep's part in sweep's help.
#[test]
fn advise_names_both_inputs_and_threads_help_fits_every_command() {
    let out = vizsim(&["advise"]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(
        stderr.contains("--dataset <DATASET>|--validate <RESULTS_DIR>"),
        "{stderr}"
    );
    for command in ["compare", "info", "verify-skip", "render"] {
        let help = String::from_utf8_lossy(&succeeds(&[command, "--help"]).stdout).into_owned();
        assert!(
            help.contains("Worker threads (default: all cores). The results do not")
                && !help.contains("results.jsonl"),
            "{command}: {help}"
        );
    }
    let sweep = String::from_utf8_lossy(&succeeds(&["sweep", "--help"]).stdout).into_owned();
    assert!(sweep.contains("merge sorts them"), "{sweep}");
}

#[test]
fn info_reports_the_published_occupancy() {
    let Some(dir) = common::data_dir() else {
        return;
    };
    for (name, published) in [("fuel", 5.24), ("neghip", 46.38), ("aneurism", 1.01)] {
        let out = succeeds(&["info", name, "--json", "--data-dir", dir.to_str().unwrap()]);
        let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let pct = info["occupied_percent"].as_f64().unwrap();
        assert!(
            (pct - published).abs() < 0.005,
            "{name}: {pct} vs {published}"
        );
    }
}

#[test]
fn verify_skip_reports_no_violations_when_rounding_down_and_some_when_rounding_to_nearest() {
    let run = |rounding: &str| -> serde_json::Value {
        let out = vizsim(&[
            "verify-skip",
            "--increment-bits",
            "6",
            "--reciprocal-bits",
            "4",
            "--subcube",
            "8",
            "--rounding",
            rounding,
            "--json",
        ]);
        // The report is printed either way; a violation fails the check.
        let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
        let violations = report["violations"].as_u64().unwrap();
        assert_eq!(
            out.status.success(),
            violations == 0,
            "{rounding}: {violations} violations, {}",
            String::from_utf8_lossy(&out.stderr)
        );
        report
    };
    let down = run("down");
    assert_eq!(down["violations"], 0);
    assert_eq!(down["cases"], 2 * 64 * (8 * 64)); // 2 directions x increments x positions
    assert!(down["worst_wasted_steps"].as_u64().unwrap() >= 1);
    assert!(run("nearest")["violations"].as_u64().unwrap() > 0);
}

#[test]
fn precision_sweep_writes_tables_and_plots_and_skip_widths_never_change_the_image() {
    let dir = scratch("precision");
    let out = succeeds(&[
        "precision",
        "--dataset",
        "phantom:sphere:32",
        "--size",
        "32x32",
        "--out",
        dir.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    // Every file is named as written, and there is no other.
    let mut written: Vec<&str> = stdout
        .lines()
        .filter_map(|l| l.strip_prefix("wrote "))
        .collect();
    written.sort();
    let mut files: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().path().display().to_string())
        .collect();
    files.sort();
    assert_eq!(written, files);
    for suffix in [
        ".csv",
        ".md",
        ".json",
        "-psnr.png",
        "-psnr.svg",
        "-max-error.png",
        "-steps.png",
    ] {
        let path = dir.join(format!("phantom-sphere-32{suffix}"));
        assert!(path.is_file(), "missing {}", path.display());
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("phantom-sphere-32.json")).unwrap())
            .unwrap();
    // The summary on screen gives each field's PSNR at its narrowest and widest width, as
    // the report has them.
    let first = &report["image"][0];
    let db = first["comparison"]["psnr_db"].as_f64().unwrap();
    let line = format!(
        "  {}: {} bits {db:.1} dB, ",
        first["field"].as_str().unwrap(),
        first["bits"]
    );
    assert!(stdout.contains(&line), "no {line:?} in {stdout}");
    let cost = report["cost"].as_array().unwrap();
    assert!(!cost.is_empty());
    assert!(cost
        .iter()
        .all(|p| p["image_identical_to_no_leaping"] == true));
    // More increment bits never make the default-width image worse than 4 bits do.
    let psnr = |bits: u64| {
        report["image"]
            .as_array()
            .unwrap()
            .iter()
            .find(|p| p["field"] == "ray.increment_frac_bits" && p["bits"] == bits)
            .map(|p| p["comparison"]["psnr_db"].as_f64().unwrap_or(f64::INFINITY))
            .unwrap()
    };
    assert!(psnr(12) > psnr(4));
    // Every width's image is within the bound those widths predict, and the bound narrows
    // from 4 to 12 increment bits.
    let image = report["image"].as_array().unwrap();
    assert!(image.iter().all(|p| p["bound"]["violations"] == 0));
    let bound = |bits: u64| {
        image
            .iter()
            .find(|p| p["field"] == "ray.increment_frac_bits" && p["bits"] == bits)
            .map(|p| p["bound"]["mean_bound"].as_f64().unwrap())
            .unwrap()
    };
    assert!(bound(12) < bound(4), "{} {}", bound(12), bound(4));
    let md = std::fs::read_to_string(dir.join("phantom-sphere-32.md")).unwrap();
    assert!(
        md.contains("| bound max (R,G,B) | bound mean | over bound |"),
        "{md}"
    );
}

/// A precision sweep in perspective, without ERT and shaded: the options reach its runs (the
/// report names them) and the gradient width is swept as an image axis, within its bound.
#[test]
fn precision_sweeps_the_gradient_width_when_shading() {
    let dir = scratch("precision-shaded");
    succeeds(&[
        "precision",
        "--dataset",
        "phantom:sphere:32",
        "--size",
        "24x24",
        "--projection",
        "persp",
        "--no-ert",
        "--shading",
        "--out",
        dir.to_str().unwrap(),
    ]);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("phantom-sphere-32.json")).unwrap())
            .unwrap();
    assert!(report["made_by"]
        .as_str()
        .unwrap()
        .contains("--projection persp --no-ert --shading"));
    let gradient: Vec<&serde_json::Value> = report["image"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["field"] == "shading.gradient_bits")
        .collect();
    assert_eq!(gradient.len(), 11);
    assert!(gradient.iter().all(|p| p["bound"]["violations"] == 0));
}

/// `--check-bound` checks invariant (c) on the run's frame (render: either model; sim: the
/// cycle model's image) and writes it into the JSON; a configuration outside the bound is
/// refused before anything is written.
#[test]
fn check_bound_reports_invariant_c_and_refuses_what_it_does_not_cover() {
    let dir = scratch("check-bound");
    let frame = [
        "--dataset",
        "phantom:shells:32",
        "--size",
        "32x32",
        "--view",
        "orbit:9/72",
    ];
    for command in [
        &["render", "--model", "fixed"][..],
        &["render"][..],
        &["sim"][..],
    ] {
        let json = dir.join(format!("{}.json", command.len()));
        let png = dir.join(format!("{}.png", command.len()));
        let mut args: Vec<&str> = command.to_vec();
        args.extend(frame);
        args.extend(["--check-bound", "-o", png.to_str().unwrap()]);
        args.extend(["--json", json.to_str().unwrap()]);
        let out = succeeds(&args);
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            stdout.contains("invariant (c): fixed vs float")
                && stdout.contains("every pixel within its bound (1024 pixels)"),
            "{command:?}: {stdout}"
        );
        // Its means are over R, G, B, and say so (the reference line's are over R, G, B, A).
        let line = stdout
            .lines()
            .find(|l| l.starts_with("invariant (c)"))
            .unwrap();
        assert_eq!(line.matches(", mean (R, G, B) ").count(), 2, "{line}");
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        assert_eq!(report["error_bound"]["violations"], 0, "{command:?}");
        assert_eq!(report["error_bound"]["pixels"], 1024, "{command:?}");
    }
    let png = dir.join("homogeneous.png");
    let mut args = vec![
        "render",
        "--model",
        "fixed",
        "--set",
        "occupancy.structure=\"leap-values\"",
        "--set",
        "leap_values.regions=\"homogeneous\"",
    ];
    args.extend(frame);
    args.extend(["--check-bound", "-o", png.to_str().unwrap()]);
    assert_fails(&args, &["--check-bound", "homogeneous leap values"], &png);
}

#[test]
fn occupancy_reports_the_published_storage_and_sram_fit() {
    let out = succeeds(&["occupancy", "phantom:jet:64", "--json"]);
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    let sizes = report["sizes"].as_array().unwrap();
    // Published storage for 64^3: 32 Kbit at 2^3 ... 8 bit at 32^3.
    let bits: Vec<(u64, u64)> = sizes
        .iter()
        .map(|r| (r["subcube"].as_u64().unwrap(), r["bits"].as_u64().unwrap()))
        .collect();
    assert_eq!(
        bits,
        vec![(2, 32768), (4, 4096), (8, 512), (16, 64), (32, 8), (64, 1)]
    );
    assert!(sizes.iter().all(|r| r["fits_sram"] == true)); // 32 Kbit < 131072
    for r in sizes {
        let (zero, class) = (
            r["skippable_zero_percent"].as_f64().unwrap(),
            r["skippable_class_percent"].as_f64().unwrap(),
        );
        // A class map hides at least what the '0' map hides (zero is transparent in every preset).
        assert!(class >= zero, "{r}");
    }
    let small = vizsim(&[
        "occupancy",
        "phantom:jet:64",
        "--json",
        "--set",
        "occupancy.sram_bits=1000",
    ]);
    let report: serde_json::Value = serde_json::from_slice(&small.stdout).unwrap();
    assert_eq!(report["sizes"][0]["fits_sram"], false);
    assert_eq!(report["sizes"][2]["fits_sram"], true);
    // The table says what its columns count.
    let table = succeeds(&["occupancy", "phantom:jet:64"]);
    let text = String::from_utf8_lossy(&table.stdout);
    assert!(
        text.contains("| empty groups '0' |") && text.contains("empty groups: 2×2×2 groups"),
        "{text}"
    );
}

#[test]
fn sim_writes_the_statistics_architects_need() {
    let dir = scratch("sim");
    let json = dir.join("sim.json");
    let png = dir.join("sim.png");
    succeeds(&[
        "sim",
        "--dataset",
        "phantom:metaballs:32",
        "--size",
        "24x24",
        "--subcube",
        "4",
        "--hierarchy",
        "-o",
        png.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    let s: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let cycles = s["cycles"].as_u64().unwrap();
    assert!(cycles >= s["steps"].as_u64().unwrap());
    assert_eq!(
        s["steps"],
        s["samples"].as_u64().unwrap() + s["leaps"].as_u64().unwrap()
    );
    assert!((s["fps"].as_f64().unwrap() - 100e6 / cycles as f64).abs() < 1e-6);
    for field in [
        "discarded_after_ert",
        "sim_cycles_per_second",
        "frame_time_ns",
    ] {
        assert!(s[field].is_number(), "{field}");
    }
    let modules = s["memory_stats"]["modules"].as_array().unwrap();
    assert_eq!(modules.len(), 4);
    for m in modules {
        for field in ["row_hits", "row_misses", "refreshes", "reads"] {
            assert!(m[field].is_u64(), "{field}");
        }
    }
    assert!(
        s["memory_stats"]["avg_ns_per_voxel_access"]
            .as_f64()
            .unwrap()
            >= 10.0
    );
    for cause in [
        "ray_queue_empty",
        "skip_unit_busy",
        "memory",
        "compositing_buffer_full",
    ] {
        assert!(s["pipeline"]["stall_cycles"][cause].is_u64(), "{cause}");
    }
    assert_eq!(s["run"]["hardware"]["skip"]["latency"], 8);
    assert!(png.is_file());
}

#[test]
fn sim_rejects_impossible_hardware_before_running() {
    let dir = scratch("sim-bad");
    let json = dir.join("sim.json");
    for (set, field) in [
        ("memory.voxel_fifo_depth=0", "memory.voxel_fifo_depth"),
        ("ray_queue.rays=0", "ray_queue.rays"),
        ("skip.latency=0", "skip.latency"),
        ("memory.banks=3", "memory.banks"),
        ("memory.rows=8", "memory.rows"),
    ] {
        assert_fails(
            &[
                "sim",
                "--dataset",
                "phantom:sphere:64",
                "--set",
                set,
                "--json",
                json.to_str().unwrap(),
            ],
            &[field],
            &json,
        );
    }
}

/// `vizsim … | head`: when the reader of standard output goes away, the command ends quietly
/// with the SIGPIPE status (141), not with a panic (status 101 and a message on stderr).
#[test]
fn a_reader_that_goes_away_ends_the_command_quietly() {
    use std::process::Stdio;
    let mut child = Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(["sim", "--dataset", "phantom:sphere:16", "--size", "8x8"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run vizsim");
    // Close the reading end before the command has printed anything (it starts in
    // milliseconds; this takes microseconds), so that its first line meets a closed pipe.
    drop(child.stdout.take());
    let out = child.wait_with_output().expect("wait for vizsim");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "panicked: {stderr}");
    assert_eq!(out.status.code(), Some(141), "stderr: {stderr}");
}

/// `vizsim … > /dev/full`: a standard output that cannot be written (a full disk) is an error
/// with status 1 naming the cause, not a panic (status 101).
#[test]
fn a_full_standard_output_is_an_error_not_a_panic() {
    let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
        eprintln!("skipped: no /dev/full here");
        return;
    };
    let out = Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(["sim", "--dataset", "phantom:sphere:16", "--size", "8x8"])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(full)
        .output()
        .expect("run vizsim");
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!stderr.contains("panicked"), "panicked: {stderr}");
    assert_eq!(out.status.code(), Some(1), "stderr: {stderr}");
    assert!(
        stderr.contains("error: writing to standard output") && stderr.contains("space"),
        "{stderr}"
    );
}

/// `vizsim … 2>/dev/full`: a standard error that cannot be written makes an error exit with
/// status 1 (not a panic's 101) and lets a note pass (found by probing: `info nonexist` and a
/// render with a stand-in note exited 101).
#[test]
fn a_full_standard_error_is_no_panic() {
    let run = |args: &[&str]| {
        let Ok(full) = std::fs::OpenOptions::new().write(true).open("/dev/full") else {
            return None;
        };
        Some(
            Command::new(env!("CARGO_BIN_EXE_vizsim"))
                .args(args)
                .current_dir(env!("CARGO_MANIFEST_DIR"))
                .stderr(full)
                .output()
                .expect("run vizsim"),
        )
    };
    let Some(error) = run(&["info", "no-such-dataset"]) else {
        eprintln!("skipped: no /dev/full here");
        return;
    };
    assert_eq!(error.status.code(), Some(1));
    // A published name that resolves to its stand-in (skull: the tooth) says so on stderr.
    let data = Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data");
    if !data.is_dir() {
        eprintln!("skipped the note case: no ../shared/data");
        return;
    }
    let png = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-full-stderr-{}.png", std::process::id()));
    let note = run(&[
        "render",
        "--dataset",
        "skull",
        "--data-dir",
        data.to_str().unwrap(),
        "--size",
        "8x8",
        "-o",
        png.to_str().unwrap(),
    ])
    .unwrap();
    assert!(note.status.success(), "{:?}", note.status);
    assert!(png.exists());
    let _ = std::fs::remove_file(&png);
}

/// Options that take several values take them as a comma list too (`verify-skip --subcube
/// 2,16` was "invalid digit"), and `--occupancy 0` names the '0' map as its help says.
#[test]
fn list_options_take_commas_and_the_zero_map_is_0() {
    let out = succeeds(&[
        "verify-skip",
        "--increment-bits",
        "5",
        "--reciprocal-bits",
        "5",
        "--subcube",
        "2,16",
    ]);
    let text = String::from_utf8_lossy(&out.stdout);
    assert!(
        text.contains("sub-cube 2³") && text.contains("sub-cube 16³"),
        "{text}"
    );
    // The widths checked are named, with the shipped ones when they differ.
    assert!(
        text.contains(
            "widths: position 5, increment 5, reciprocal 5, distance 5 bits; the shipped \
             configuration (configs/hardware/vizard2.toml) has --position-bits 12 \
             --increment-bits 12 --reciprocal-bits 8 --distance-bits 4"
        ),
        "{text}"
    );
    let shipped = succeeds(&[
        "verify-skip",
        "--position-bits",
        "12",
        "--increment-bits",
        "12",
        "--reciprocal-bits",
        "8",
        "--distance-bits",
        "4",
        "--subcube",
        "2",
    ]);
    let shipped = String::from_utf8_lossy(&shipped.stdout);
    assert!(
        shipped.contains("(the shipped configuration's)"),
        "{shipped}"
    );
    let dir = scratch("occupancy-0");
    let png = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let json = |name: &str| dir.join(name).to_str().unwrap().to_string();
    for (occupancy, name) in [("0", "a"), ("zero", "b")] {
        succeeds(&[
            "render",
            "--dataset",
            "phantom:sphere:16",
            "--model",
            "fixed",
            "--subcube",
            "4",
            "--occupancy",
            occupancy,
            "--size",
            "8x8",
            "-o",
            &png(&format!("{name}.png")),
            "--json",
            &json(&format!("{name}.json")),
        ]);
    }
    let kind = |name: &str| -> serde_json::Value {
        let text = std::fs::read_to_string(dir.join(format!("{name}.json"))).unwrap();
        serde_json::from_str::<serde_json::Value>(&text).unwrap()["run"]["hardware"]["occupancy"]
            ["kind"]
            .clone()
    };
    assert_eq!(kind("a"), "zero");
    assert_eq!(kind("a"), kind("b"));
}

/// `info`, `occupancy` and `update` take their dataset positionally or as `--dataset`, as the
/// other commands do (`occupancy --dataset fuel` was "unexpected argument"); not both.
#[test]
fn dataset_commands_take_dataset_as_an_option_too() {
    for command in ["info", "occupancy"] {
        let positional = succeeds(&[command, "phantom:jet:32"]);
        let option = succeeds(&[command, "--dataset", "phantom:jet:32"]);
        assert_eq!(positional.stdout, option.stdout, "{command}");
        let both = vizsim(&[command, "phantom:jet:32", "--dataset", "phantom:jet:32"]);
        assert!(!both.status.success(), "{command}");
        let neither = vizsim(&[command]);
        assert!(!neither.status.success(), "{command}");
        assert!(String::from_utf8_lossy(&neither.stderr).contains("DATASET"));
    }
    let update = succeeds(&["update", "--dataset", "phantom:jet:32", "--subcube", "8"]);
    assert!(String::from_utf8_lossy(&update.stdout).starts_with("phantom:jet:32 [32, 32, 32]"));
}

/// A command that fails after checking its outputs leaves no folder it made for them (found by
/// probing: a render refused for its iso value left `newdir/` and `newdir2/sub/` behind); one
/// that succeeds makes them.
#[test]
fn a_failed_command_leaves_no_new_folders() {
    let dir = scratch("no-new-folders");
    let png = dir.join("a/b/x.png");
    let json = dir.join("c/x.json");
    let args = |iso: &'static str| {
        vec![
            "render".to_string(),
            "--dataset".into(),
            "phantom:sphere:16".into(),
            "--size".into(),
            "8x8".into(),
            "--set".into(),
            "iso.enabled=true".into(),
            "--set".into(),
            format!("iso.value={iso}"),
            "-o".into(),
            png.to_str().unwrap().into(),
            "--json".into(),
            json.to_str().unwrap().into(),
        ]
    };
    let failed = args("60000");
    let out = vizsim(&failed.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("iso.value"));
    assert!(!dir.join("a").exists() && !dir.join("c").exists());
    let ok = args("100");
    succeeds(&ok.iter().map(String::as_str).collect::<Vec<_>>());
    assert!(png.is_file() && json.is_file());
    // Only the folders it made: an empty folder that was there, reached through a new one and
    // `..`, stays (the review found it removed).
    let existing = dir.join("existing");
    std::fs::create_dir_all(&existing).unwrap();
    let through = dir.join("new/../existing/x.png");
    let out = vizsim(&[
        "render",
        "--dataset",
        "phantom:nosuch:16",
        "-o",
        through.to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(existing.is_dir() && !dir.join("new").exists());
}

/// An output that names an input, or another output of the same command, is refused before
/// anything is written: the later write would silently replace the file (found by probing:
/// `compare a.png b.png --diff a.png` overwrote a.png).
#[test]
fn outputs_that_would_overwrite_an_input_or_each_other_are_refused() {
    let dir = scratch("distinct");
    let a = dir.join("a.png");
    let render = vizsim(&[
        "render",
        "--dataset",
        "phantom:sphere:32",
        "--size",
        "8x8",
        "-o",
        a.to_str().unwrap(),
    ]);
    assert!(render.status.success());
    let b = dir.join("b.png");
    std::fs::copy(&a, &b).unwrap();
    let original = std::fs::read(&a).unwrap();
    let (a_, b_) = (a.to_str().unwrap(), b.to_str().unwrap());
    // Through a folder that does not exist yet and `..`.
    let a_again = dir.join("new").join("..").join("a.png");
    assert_fails(
        &["compare", a_, b_, "--diff", a_again.to_str().unwrap()],
        &["--diff", "is the input"],
        &dir.join("new"),
    );
    assert_eq!(std::fs::read(&a).unwrap(), original, "the input is intact");
    let same = dir.join("same.out");
    let same_ = same.to_str().unwrap();
    for (command, first) in [("sim", "--json"), ("render", "--json")] {
        assert_fails(
            &[
                command,
                "--dataset",
                "phantom:sphere:32",
                "--size",
                "8x8",
                "-o",
                same_,
                first,
                same_,
            ],
            &["--json", "is also the file of --output"],
            &same,
        );
    }
    // Devices are no files: /dev/null may take several outputs.
    succeeds(&[
        "compare",
        a_,
        b_,
        "--json",
        "/dev/null",
        "--diff",
        "/dev/null",
    ]);
}

/// The volume file a dataset descriptor or a detached NRRD header names is an input too: an
/// output on it is refused and the file stays (a review overwrote it with `--json`, `--rays`,
/// `--vcd` and `--command-trace` while the descriptor itself was protected).
#[test]
fn the_data_file_behind_a_descriptor_or_header_is_an_input() {
    let dir = scratch("data-file");
    let data = dir.join("v.raw");
    let voxels: Vec<u8> = (0..16 * 16 * 16).map(|i| (i * 7 % 251) as u8).collect();
    std::fs::write(&data, &voxels).unwrap();
    std::fs::write(
        dir.join("d.toml"),
        "file = \"v.raw\"\ndims = [16, 16, 16]\n",
    )
    .unwrap();
    std::fs::write(
        dir.join("h.nhdr"),
        "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 16 16 16\nencoding: raw\ndata file: v.raw\n\n",
    )
    .unwrap();
    // A descriptor naming the header: two links from the dataset to the data.
    std::fs::write(dir.join("dh.toml"), "file = \"h.nhdr\"\n").unwrap();
    let png = dir.join("r.png");
    let (data_, png_) = (data.to_str().unwrap(), png.to_str().unwrap());
    for (command, dataset, option) in [
        ("render", "d.toml", "--json"),
        ("render", "d.toml", "--rays"),
        ("sim", "h.nhdr", "--json"),
        ("sim", "dh.toml", "--vcd"),
        ("sim", "dh.toml", "--command-trace"),
    ] {
        let dataset = dir.join(dataset);
        assert_fails(
            &[
                command,
                "--dataset",
                dataset.to_str().unwrap(),
                "--tf",
                "zero",
                "--size",
                "8x8",
                "-o",
                png_,
                option,
                data_,
            ],
            &[option, "is the input", "v.raw"],
            &png,
        );
        assert_eq!(std::fs::read(&data).unwrap(), voxels, "{command} {option}");
    }
    // The header behind the descriptor is protected as well, and the dataset still renders.
    let header = dir.join("h.nhdr");
    let dh = dir.join("dh.toml");
    assert_fails(
        &[
            "sim",
            "--dataset",
            dh.to_str().unwrap(),
            "--tf",
            "zero",
            "--size",
            "8x8",
            "--json",
            header.to_str().unwrap(),
        ],
        &["--json", "is the input"],
        &png,
    );
    succeeds(&[
        "render",
        "--dataset",
        dh.to_str().unwrap(),
        "--tf",
        "zero",
        "--size",
        "8x8",
        "-o",
        png_,
    ]);
}

/// `-` is standard output for `--json` only; as the per-ray CSV's name it made a file called `-`.
#[test]
fn rays_to_standard_output_are_refused_not_written_to_a_file_named_dash() {
    let dir = scratch("rays-dash");
    let png = dir.join("r.png");
    assert_fails(
        &[
            "render",
            "--dataset",
            "phantom:sphere:16",
            "--size",
            "8x8",
            "-o",
            png.to_str().unwrap(),
            "--rays",
            "-",
        ],
        &["--rays -", "only `--json -`"],
        &png,
    );
    assert!(!Path::new(env!("CARGO_MANIFEST_DIR")).join("-").exists());
}

/// The fixed-point model's per-ray CSV says where each ray enters and leaves the volume, as the
/// float reference's does (it wrote 0 and 0 for every ray: found by probing).
#[test]
fn the_fixed_models_rays_enter_and_leave_where_the_float_references_do() {
    let dir = scratch("rays-t");
    let csv_of = |model: &str| -> String {
        let (png, rays) = (
            dir.join(format!("{model}.png")),
            dir.join(format!("{model}.csv")),
        );
        succeeds(&[
            "render",
            "--dataset",
            "phantom:sphere:32",
            "--size",
            "12x10",
            "--view",
            "orbit:5/72",
            "--model",
            model,
            "-o",
            png.to_str().unwrap(),
            "--rays",
            rays.to_str().unwrap(),
        ]);
        std::fs::read_to_string(rays).unwrap()
    };
    let column = |csv: &str, name: &str| -> Vec<String> {
        let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
        let at = header.iter().position(|h| *h == name).unwrap();
        csv.lines()
            .skip(1)
            .map(|l| l.split(',').nth(at).unwrap().to_string())
            .collect()
    };
    let (float, fixed) = (csv_of("float"), csv_of("fixed"));
    for name in ["t_enter", "t_exit"] {
        assert_eq!(column(&fixed, name), column(&float, name), "{name}");
    }
    assert!(
        column(&fixed, "t_exit")
            .iter()
            .any(|t| t.parse::<f32>().unwrap() > 0.0),
        "some rays cross the volume"
    );
}

/// Options that would change nothing are refused rather than ignored (found by probing): the
/// hierarchy without a map, the ideal memory's latency for the SDRAM model, a waveform window
/// without a waveform, leaping flags for `precision` (its points set the leaping themselves).
#[test]
fn options_that_would_change_nothing_are_refused() {
    let dir = scratch("ignored");
    let json = dir.join("out.json");
    let json_ = json.to_str().unwrap();
    let sim = |extra: &[&str]| -> Vec<String> {
        let mut args = [
            "sim",
            "--dataset",
            "phantom:sphere:32",
            "--size",
            "8x8",
            "--json",
            json_,
        ]
        .map(String::from)
        .to_vec();
        args.extend(extra.iter().map(|s| s.to_string()));
        args
    };
    for (extra, needle) in [
        (&["--hierarchy"][..], "--hierarchy"),
        (&["--ideal-latency", "500"][..], "--ideal-latency"),
        (&["--vcd-cycles", "0..10"][..], "--vcd"),
    ] {
        let args = sim(extra);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_fails(&args, &[needle], &json);
    }
    // Where they apply, they are taken.
    for extra in [
        &["--hierarchy", "--subcube", "8"][..],
        &["--memory", "ideal", "--ideal-latency", "500"],
    ] {
        let args = sim(extra);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        let out = vizsim(&args);
        assert!(
            out.status.success(),
            "{extra:?}: {}",
            String::from_utf8_lossy(&out.stderr)
        );
    }
    let report = dir.join("precision");
    assert_fails(
        &[
            "precision",
            "--dataset",
            "phantom:sphere:32",
            "--size",
            "8x8",
            "--out",
            report.to_str().unwrap(),
            "--subcube",
            "16",
        ],
        &["--subcube"],
        &report,
    );
}

/// A frame that reads no voxel (every sub-cube empty: the rays only leap) has no rates per
/// read: the row-hit rate and the cost per access are null, not figures made from a count of 0.
#[test]
fn a_frame_that_reads_nothing_reports_no_rates_per_read() {
    let dir = scratch("no-reads");
    let tf = dir.join("clear.toml");
    std::fs::write(
        &tf,
        "name = \"clear\"\n[[points]]\nvalue = 0\nrgba = [0, 0, 0, 0]\n[[points]]\nvalue = 255\nrgba = [1, 1, 1, 0]\n",
    )
    .unwrap();
    let json = dir.join("out.json");
    let out = succeeds(&[
        "sim",
        "--dataset",
        "phantom:sphere:32",
        "--size",
        "8x8",
        "--tf",
        tf.to_str().unwrap(),
        "--subcube",
        "8",
        "--json",
        json.to_str().unwrap(),
    ]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("no voxel read"));
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["memory_stats"]["reads"], 0);
    for field in [
        "row_hit_rate",
        "avg_ns_per_voxel_access",
        "avg_access_latency_cycles",
    ] {
        assert!(
            report["memory_stats"][field].is_null(),
            "{field}: {}",
            report["memory_stats"][field]
        );
    }
    // The run's measurements (at the top level) leave them out.
    for field in ["page_hit_rate", "avg_ns_per_voxel_access"] {
        assert!(report.get(field).is_none(), "{field}");
    }
    assert_eq!(report["row_hits"], 0);
}

/// A volume of your own has no presets: `--tf zero` is the generic '0' classification (every
/// non-zero voxel visible), and `class` (the default) says to give `zero` or a file rather
/// than listing the presets of other datasets (found by probing).
#[test]
fn a_volume_of_your_own_renders_with_the_generic_zero_classification() {
    let dir = scratch("own-volume");
    let raw = dir.join("blob_16x16x16_uint8.raw");
    let data: Vec<u8> = (0..16 * 16 * 16)
        .map(|i| if i % 7 == 0 { 0 } else { (i % 251) as u8 })
        .collect();
    std::fs::write(&raw, data).unwrap();
    let (png, json) = (dir.join("blob.png"), dir.join("blob.json"));
    let render = |tf: &str| {
        vizsim(&[
            "render",
            "--dataset",
            raw.to_str().unwrap(),
            "--tf",
            tf,
            "--size",
            "8x8",
            "-o",
            png.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ])
    };
    let out = render("zero");
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["transfer_function"], "blob-zero");
    assert!(report["stats"]["samples"].as_u64().unwrap() > 0);
    std::fs::remove_file(&png).unwrap();
    assert_fails(
        &[
            "render",
            "--dataset",
            raw.to_str().unwrap(),
            "--size",
            "8x8",
            "-o",
            png.to_str().unwrap(),
        ],
        &["`class`", "blob-class", "--tf zero"],
        &png,
    );
}

/// Messages name the option or setting at fault, as the user wrote it (found by probing: the
/// skip calculator's field names, "too many" for zero, a missing data folder without the
/// variable that named it, "File exists" for a plot folder that is a file), and a waveform
/// window after the frame is said to be empty.
#[test]
fn messages_name_the_option_at_fault() {
    let dir = scratch("messages");
    for (args, needle) in [
        (
            &["verify-skip", "--increment-bits", "40"][..],
            "--position-bits",
        ),
        (
            &["verify-skip", "--max-increment-voxels", "0"],
            "at least 1",
        ),
        // The increment's bound comes from the position bits, and says so (it read
        // `0..=0` alone).
        (
            &[
                "verify-skip",
                "--increment-bits",
                "24",
                "--position-bits",
                "0",
            ],
            "0..=0, at most --position-bits",
        ),
        // The increments are too many because of the increment bits too (it blamed only
        // --max-increment-voxels, which was left at its default).
        (
            &["verify-skip", "--increment-bits", "25"],
            "--increment-bits 25",
        ),
        // A whole number too large for a size is not called "not a whole number"; a data
        // folder that is a file is not called missing.
        (
            &["info", "phantom:sphere:18446744073709551617"],
            "size `18446744073709551617` is too large",
        ),
        (
            &["info", "--data-dir", "/dev/null", "fuel"],
            "--data-dir /dev/null: not a folder",
        ),
    ] {
        assert_fails(args, &[needle], &dir.join("none"));
    }
    let out = Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(["info", "fuel"])
        .env("VIZSIM_DATA", dir.join("missing"))
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && stderr.contains("VIZSIM_DATA"),
        "{stderr}"
    );
    let file = dir.join("plots.png");
    std::fs::write(&file, b"not a folder").unwrap();
    let sweep = dir.join("sweep");
    let exp = dir.join("e.toml");
    std::fs::write(
        &exp,
        "name = \"m\"\ndatasets = [\"phantom:sphere:16\"]\ntf = [\"class\"]\nmodes = [\"none\"]\n\
         models = [\"step\"]\n[frames]\norbit = 1\nsize = \"8x8\"\n",
    )
    .unwrap();
    succeeds(&[
        "sweep",
        exp.to_str().unwrap(),
        "--out",
        sweep.to_str().unwrap(),
    ]);
    // One frame of one mode: nothing to draw, said, and no folder claimed.
    let out = succeeds(&["plot", sweep.to_str().unwrap()]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(stderr.contains("no chart to draw"), "{stderr}");
    assert!(!sweep.join("plots").exists());
    for command in ["plot", "table"] {
        let out = vizsim(&[
            command,
            sweep.to_str().unwrap(),
            "--out",
            file.to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && stderr.contains("is a file, not a folder"),
            "{command}: {stderr}"
        );
    }
    // A metric no result carries is said, not tabulated as nothing: alone it is an error and
    // writes nothing; among others a note.
    let tables = dir.join("tables");
    assert_fails(
        &[
            "table",
            sweep.to_str().unwrap(),
            "--out",
            tables.to_str().unwrap(),
            "--metric",
            "cycles",
        ],
        &["--metric cycles"],
        &tables,
    );
    let out = succeeds(&[
        "table",
        sweep.to_str().unwrap(),
        "--out",
        tables.to_str().unwrap(),
        "--metric",
        "cycles,steps",
    ]);
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("no result carries --metric cycles"),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    // A requested dataset the results do not hold is named, even beside one they hold.
    assert_fails(
        &[
            "table",
            sweep.to_str().unwrap(),
            "--dataset",
            "phantom:sphere:16,nosuch",
        ],
        &["--dataset nosuch"],
        &sweep.join("tables"),
    );
    // An empty results file: no charts claimed, as `table` says.
    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    std::fs::write(empty.join("results.jsonl"), b"").unwrap();
    assert_fails(
        &["plot", empty.to_str().unwrap()],
        &["no results"],
        &empty.join("plots"),
    );
    let vcd = dir.join("w.vcd");
    let out = vizsim(&[
        "sim",
        "--dataset",
        "phantom:sphere:16",
        "--size",
        "8x8",
        "--vcd",
        vcd.to_str().unwrap(),
        "--vcd-cycles",
        "100000..200000",
    ]);
    assert!(out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("holds no cycle"));
}

/// A transfer function argument names what is wrong with it: a path that is no regular file
/// (`/dev/zero` would be read forever) is not called missing, and a misspelt preset lists the
/// dataset's own presets, not all seventy.
#[test]
fn transfer_function_arguments_say_what_they_are_not() {
    let dir = scratch("tf-arguments");
    let png = dir.join("f.png");
    let frame = ["render", "--dataset", "phantom:sphere:16", "--size", "8x8"];
    let with_tf = |tf: &str| {
        let mut args = frame.to_vec();
        args.extend(["--tf", tf, "--output", png.to_str().unwrap()]);
        args.iter().map(|s| s.to_string()).collect::<Vec<_>>()
    };
    // A folder named like a preset does not hide it.
    std::fs::create_dir_all(dir.join("class")).unwrap();
    let in_dir = Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(with_tf("class"))
        .current_dir(&dir)
        .output()
        .unwrap();
    assert!(
        in_dir.status.success(),
        "{}",
        String::from_utf8_lossy(&in_dir.stderr)
    );
    std::fs::remove_file(&png).unwrap();
    for tf in [dir.to_str().unwrap(), "/dev/null"] {
        let args = with_tf(tf);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_fails(&args, &["is not a regular file"], &png);
    }
    let args = with_tf("clas");
    let args: Vec<&str> = args.iter().map(String::as_str).collect();
    let out = vizsim(&args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "{stderr}");
    assert!(
        stderr.contains("phantom-sphere-class") && !stderr.contains("aneurism-class"),
        "{stderr}"
    );
}

/// `compare` checks an image's size against the memory budget before decoding it, and its
/// PSNR says it is over R, G and B (an alpha difference leaves it infinite).
#[test]
fn compare_keeps_to_the_memory_budget_and_names_its_psnr() {
    let dir = scratch("compare-budget");
    let (a, b) = (dir.join("a.png"), dir.join("b.png"));
    image::RgbaImage::new(1500, 1500).save(&a).unwrap();
    image::RgbaImage::from_pixel(1500, 1500, image::Rgba([0, 0, 0, 9]))
        .save(&b)
        .unwrap();
    let (a_, b_) = (a.to_str().unwrap(), b.to_str().unwrap());
    let json = dir.join("c.json");
    assert_fails(
        &[
            "--memory-budget",
            "10M",
            "compare",
            a_,
            b_,
            "--json",
            json.to_str().unwrap(),
        ],
        &["a.png: a 1500x1500 image needs about", "budget of 10.0 MiB"],
        &json,
    );
    let out = succeeds(&["--memory-budget", "100M", "compare", a_, b_]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("PSNR (R, G, B) inf dB") && stdout.contains("A 9"),
        "{stdout}"
    );
}

/// Out-of-range numbers are echoed as written, not expanded into hundreds of digits.
#[test]
fn out_of_range_numbers_are_echoed_compactly() {
    let dir = scratch("numbers");
    let json = dir.join("s.json");
    let frame = ["sim", "--dataset", "phantom:sphere:16", "--size", "8x8"];
    for (extra, needle) in [
        (&["--sample", "1e300"][..], "--sample 1e300:"),
        (
            &["--set", "compositing.ert_threshold=1e300"],
            "1e300 is out of range",
        ),
        (
            &["--set", "memory.host_link_mhz=1e-300"],
            "1e-300 is out of range",
        ),
    ] {
        let mut args = frame.to_vec();
        args.extend(extra);
        args.extend(["--json", json.to_str().unwrap()]);
        assert_fails(&args, &[needle], &json);
        let stderr = String::from_utf8_lossy(&vizsim(&args).stderr).into_owned();
        assert!(stderr.len() < 1000, "{extra:?}: {stderr}");
    }
}

/// A run whose last output cannot be written leaves none of its outputs: the image, the
/// command trace and the waveform written before it would look like a finished run (found by
/// probing: `--json /dev/full` left the PNG).
#[test]
fn a_run_that_fails_to_write_one_output_leaves_none() {
    let dir = scratch("all-or-none");
    let (png, trace, vcd) = (dir.join("f.png"), dir.join("t.csv"), dir.join("w.vcd"));
    let frame = ["--dataset", "phantom:sphere:32", "--size", "8x8"];
    let mut sim = vec!["sim"];
    sim.extend(frame);
    sim.extend([
        "-o",
        png.to_str().unwrap(),
        "--command-trace",
        trace.to_str().unwrap(),
        "--vcd",
        vcd.to_str().unwrap(),
    ]);
    let mut render = vec!["render"];
    render.extend(frame);
    render.extend(["-o", png.to_str().unwrap()]);
    for args in [&sim, &render] {
        let mut failing = args.clone();
        failing.extend(["--json", "/dev/full"]);
        assert_fails(&failing, &["/dev/full"], &png);
        assert!(
            !trace.exists() && !vcd.exists(),
            "{args:?} left its trace or waveform"
        );
        let leftovers: Vec<_> = std::fs::read_dir(&dir).unwrap().flatten().collect();
        assert!(leftovers.is_empty(), "temporaries left: {leftovers:?}");
        // Written together when every output can be.
        let json = dir.join("ok.json");
        let mut working = args.clone();
        working.extend(["--json", json.to_str().unwrap()]);
        succeeds(&working);
        assert!(png.exists() && json.exists());
        for file in std::fs::read_dir(&dir).unwrap().flatten() {
            std::fs::remove_file(file.path()).unwrap();
        }
    }
}

/// A published name that resolves to its stand-in says so on standard error: standard output
/// stays JSON with `--json` (real data: the tooth stands in for the skull).
#[test]
fn a_stand_in_note_leaves_json_output_parseable() {
    let Some(data) = common::data_dir() else {
        return;
    };
    let data = data.display().to_string();
    let out = succeeds(&["info", "skull", "--json", "--data-dir", &data]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    let report: serde_json::Value = serde_json::from_str(&stdout)
        .unwrap_or_else(|e| panic!("info skull --json is not JSON ({e}): {stdout}"));
    assert!(report.is_object(), "{report}");
    assert!(
        String::from_utf8_lossy(&out.stderr).contains("stand-in tooth_103x94x161"),
        "the note is still given"
    );
}

/// `compare` checks every output path before it compares, and writes its outputs together or
/// not at all (found by probing: `--diff afile/d.png`, under a regular file, printed the result
/// and wrote the --json before failing; so did `--diff` naming a folder).
#[test]
fn compare_with_one_bad_output_writes_none() {
    let dir = scratch("compare-outputs");
    let a = dir.join("a.png");
    succeeds(&[
        "render",
        "--dataset",
        "phantom:sphere:32",
        "--size",
        "8x8",
        "-o",
        a.to_str().unwrap(),
    ]);
    let a_ = a.to_str().unwrap();
    let json = dir.join("cj.json");
    let afile = dir.join("afile");
    std::fs::write(&afile, "a regular file").unwrap();
    let under_a_file = afile.join("d.png");
    let folder = dir.join("out");
    std::fs::create_dir(&folder).unwrap();
    for (diff, needle) in [
        (under_a_file.to_str().unwrap(), "afile/d.png"),
        (folder.to_str().unwrap(), "is a folder"),
    ] {
        let args = [
            "compare",
            a_,
            a_,
            "--json",
            json.to_str().unwrap(),
            "--diff",
            diff,
        ];
        assert_fails(&args, &[needle], &json);
        let out = vizsim(&args);
        assert!(
            !String::from_utf8_lossy(&out.stdout).contains("max |error|"),
            "{diff}: the result was printed before the failure"
        );
    }
    // Both written when both can be.
    let diff = dir.join("d.png");
    succeeds(&[
        "compare",
        a_,
        a_,
        "--json",
        json.to_str().unwrap(),
        "--diff",
        diff.to_str().unwrap(),
    ]);
    assert!(json.exists() && diff.exists());
}

/// `verify-skip` counts its cases before it starts: a run of days is refused with the count,
/// the estimated time, the options that set it and `--max-cases` (found by probing:
/// `--increment-bits 20` ran for what would have been about 55 hours without a word).
#[test]
fn verify_skip_refuses_a_run_of_days_up_front() {
    let start = std::time::Instant::now();
    let mut child = Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(["verify-skip", "--increment-bits", "20"])
        .stdout(std::process::Stdio::piped())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    // Before the bound the run did not end: it is stopped here rather than hang the test.
    while child.try_wait().unwrap().is_none() {
        if start.elapsed() > std::time::Duration::from_secs(20) {
            child.kill().unwrap();
            panic!("verify-skip --increment-bits 20 still running after 20 s");
        }
        std::thread::sleep(std::time::Duration::from_millis(50));
    }
    let out = child.wait_with_output().unwrap();
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(
        !out.status.success() && !stderr.contains("panicked"),
        "{stderr}"
    );
    for needle in [
        "35,184,372,088,832 cases",
        "--increment-bits 20",
        "would take about",
        "--max-cases",
    ] {
        assert!(stderr.contains(needle), "lacks {needle:?}: {stderr}");
    }
    // The bound is the user's: a small run over a small bound is refused, under it runs.
    let small = [
        "verify-skip",
        "--increment-bits",
        "6",
        "--subcube",
        "8",
        "--reciprocal-bits",
        "6",
    ];
    let mut over = small.to_vec();
    over.extend(["--max-cases", "65535"]);
    assert_fails(
        &over,
        &["65,536 cases", "--max-cases 65,535"],
        &scratch("verify-none").join("x"),
    );
    let mut at = small.to_vec();
    at.extend(["--max-cases", "65536"]);
    succeeds(&at);
}

/// A fixed-model frame of no steps (nothing in the clip box) has no frame rate: the JSON has
/// no `fps` and the line says why (found by probing: it printed `inf fps` and wrote
/// `"fps": 1e+18`, a stand-in that would dominate any mean or chart).
#[test]
fn a_frame_of_no_steps_has_no_frame_rate() {
    let dir = scratch("no-steps");
    let (png, json) = (dir.join("e.png"), dir.join("e.json"));
    let out = succeeds(&[
        "render",
        "--dataset",
        "phantom:sphere:32",
        "--size",
        "8x8",
        "--model",
        "fixed",
        "--set",
        "clip.box=[[100.0,100.0,100.0],[200.0,200.0,200.0]]",
        "-o",
        png.to_str().unwrap(),
        "--json",
        json.to_str().unwrap(),
    ]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        stdout.contains("0 steps") && stdout.contains("no frame rate"),
        "{stdout}"
    );
    assert!(!stdout.contains("inf fps"), "{stdout}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["steps"], 0, "{report}");
    assert_eq!(report["frame_time_ns"], 0.0);
    assert!(report.get("fps").is_none(), "fps {}", report["fps"]);
}

/// The step model's frame time is called published only at the published 12.5 ns per step
/// (`--set clock.step_time_ns=5` printed "at the published 5 ns per step").
#[test]
fn only_the_published_step_time_is_called_published() {
    let dir = scratch("step-time");
    let png = dir.join("f.png");
    let render = |set: &[&str]| {
        let mut args = vec![
            "render",
            "--model",
            "fixed",
            "--dataset",
            "phantom:sphere:32",
            "--size",
            "8x8",
            "-o",
            png.to_str().unwrap(),
        ];
        args.extend_from_slice(set);
        String::from_utf8_lossy(&succeeds(&args).stdout).into_owned()
    };
    let published = render(&[]);
    assert!(
        published.contains(" fps at the published 12.5 ns per step"),
        "{published}"
    );
    let five = render(&["--set", "clock.step_time_ns=5"]);
    assert!(
        five.contains(" fps at clock.step_time_ns = 5 ns per step, not the published 12.5 ns"),
        "{five}"
    );
    assert!(!five.contains("published 5"), "{five}");
}

/// `sim` and `render` say when the hierarchy groups nothing (a volume that is one sub-cube along
/// every axis): it ran silently, with the result of the map alone.
#[test]
fn a_hierarchy_that_groups_nothing_is_said_to_be_without_effect() {
    let dir = scratch("hier");
    let png = dir.join("h.png");
    let note = "note: the hierarchy (occupancy.hierarchy) is without effect here, as the 2×2×2 \
                group of 32³ sub-cubes is larger than the volume [32, 32, 32]";
    for command in [&["sim"][..], &["render", "--model", "fixed"]] {
        let run = |subcube: &str| {
            let mut args = command.to_vec();
            args.extend([
                "--dataset",
                "phantom:sphere:32",
                "--size",
                "8x8",
                "--subcube",
                subcube,
                "--hierarchy",
                "-o",
                png.to_str().unwrap(),
            ]);
            String::from_utf8_lossy(&succeeds(&args).stdout).into_owned()
        };
        let whole = run("32");
        assert!(whole.contains(note), "{command:?}: {whole}");
        let grouped = run("16");
        assert!(
            !grouped.contains("without effect"),
            "{command:?}: {grouped}"
        );
    }
}

/// `precision` writes its tables, JSON and charts together or not at all: a folder where one of
/// them goes left the others (and the chart's temporaries) behind, a failed run that looked
/// finished (found by probing).
#[test]
fn precision_writes_its_report_together_or_not_at_all() {
    let precision = |dir: &Path| {
        vizsim(&[
            "precision",
            "--threads",
            "1",
            "--dataset",
            "phantom:sphere:16",
            "--size",
            "16x16",
            "--out",
            dir.to_str().unwrap(),
        ])
    };
    for blocked in ["phantom-sphere-16-psnr.png", "phantom-sphere-16.json"] {
        let dir = scratch(&format!("precision-blocked-{blocked}"));
        std::fs::create_dir_all(dir.join(blocked)).unwrap();
        let out = precision(&dir);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && stderr.contains(blocked),
            "{stderr}"
        );
        let left: Vec<String> = std::fs::read_dir(&dir)
            .unwrap()
            .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
            .collect();
        assert_eq!(left, vec![blocked.to_string()], "{blocked}: {left:?}");
    }
    // Unblocked, the same run writes all nine files.
    let dir = scratch("precision-whole");
    let out = precision(&dir);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert_eq!(std::fs::read_dir(&dir).unwrap().count(), 9);
}

/// A leaping flag and a `--set` of the same field are refused rather than one silently winning
/// (a probe found `--bricks 8 --set bricks.size=16` running with 8 and `--no-ert --set
/// compositing.ert=true` without ERT); a flag's error names the flag as typed, not the `--set`
/// it stands for; a sub-cube size with a structure that has none, and `--occupancy` without a
/// map, are refused.
#[test]
fn flags_and_settings_that_contradict_or_do_nothing_are_refused() {
    let out = scratch("contradicting").join("x.png");
    let out_ = out.to_str().unwrap();
    let sim = |extra: &[&str]| -> Vec<String> {
        let mut args = vec![
            "sim",
            "--dataset",
            "phantom:sphere:16",
            "--size",
            "8x8",
            "--output",
            out_,
        ];
        args.extend_from_slice(extra);
        args.iter().map(|a| a.to_string()).collect()
    };
    for (extra, needles) in [
        (
            &["--bricks", "8", "--set", "bricks.size=16"][..],
            &[
                "--bricks 8",
                "--set bricks.size=16",
                "both set `bricks.size`",
            ][..],
        ),
        (
            &["--no-ert", "--set", "compositing.ert=true"],
            &["--no-ert", "both set `compositing.ert`"],
        ),
        (
            &["--subcube", "8", "--set", "occupancy.subcube = 16"],
            &["--subcube 8", "both set `occupancy.subcube`"],
        ),
        (
            &[
                "--hierarchy",
                "--subcube",
                "8",
                "--set",
                "occupancy.hierarchy=false",
            ],
            &["--hierarchy", "both set `occupancy.hierarchy`"],
        ),
        (
            &[
                "--occupancy",
                "zero",
                "--set",
                "occupancy.kind=class",
                "--subcube",
                "4",
            ],
            &["--occupancy zero", "both set `occupancy.kind`"],
        ),
        (
            &["--subcube", "7"],
            &["with --subcube 7:", "occupancy.subcube"],
        ),
        (
            &["--subcube", "8", "--set", "occupancy.structure=distance"],
            &["occupancy.subcube", "has no sub-cubes"],
        ),
        (
            &["--occupancy", "zero"],
            &["--occupancy", "no occupancy map"],
        ),
    ] {
        let args = sim(extra);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        assert_fails(&args, needles, &out);
        let stderr = String::from_utf8_lossy(&vizsim(&args).stderr).into_owned();
        if extra.contains(&"7") {
            assert!(!stderr.contains("--set"), "{stderr}");
        }
    }
    // The same settings without the contradiction run.
    for extra in [
        &["--bricks", "8"][..],
        &["--set", "bricks.size=16"],
        &["--occupancy", "zero", "--subcube", "4"],
        // Bricks follow the kind too.
        &["--occupancy", "zero", "--bricks", "8"],
        &["--set", "occupancy.structure=distance"],
    ] {
        let args = sim(extra);
        let args: Vec<&str> = args.iter().map(String::as_str).collect();
        succeeds(&args);
    }
}

/// Images are PNG: a name with another extension is refused before any work, where `render -o
/// x.jpg` wrote PNG bytes under a JPEG name; `.PNG` and a name without an extension are taken.
#[test]
fn an_image_named_for_another_format_is_refused() {
    let dir = scratch("image-names");
    let render = |name: &str| {
        vizsim(&[
            "render",
            "--dataset",
            "phantom:sphere:16",
            "--size",
            "8x8",
            "-o",
            dir.join(name).to_str().unwrap(),
        ])
    };
    for name in ["x.jpg", "x.ppm", "x.png.tmp"] {
        let out = render(name);
        let stderr = String::from_utf8_lossy(&out.stderr);
        assert!(!out.status.success(), "{name}");
        assert!(
            stderr.contains("written as PNG") && stderr.contains(name),
            "{stderr}"
        );
        assert!(!dir.join(name).exists(), "{name}");
    }
    for name in ["x.PNG", "frame"] {
        assert!(render(name).status.success(), "{name}");
        let bytes = std::fs::read(dir.join(name)).unwrap();
        assert!(bytes.starts_with(b"\x89PNG"), "{name}");
    }
    let a = dir.join("x.PNG");
    let a_ = a.to_str().unwrap();
    let jpg = dir.join("d.jpg");
    assert_fails(
        &["compare", a_, a_, "--diff", jpg.to_str().unwrap()],
        &["--diff", "written as PNG"],
        &jpg,
    );
    let mut sim = vec!["sim", "--dataset", "phantom:sphere:16", "--size", "8x8"];
    let jpg_ = jpg.to_str().unwrap();
    sim.extend_from_slice(&["--output", jpg_]);
    assert_fails(&sim, &["--output", "written as PNG"], &jpg);
}

/// Leap values are refused where their figures would be wrong: with shading the voxel word
/// cannot hold density, leap value and gradient (a probe found "16 bits of every voxel word, no
/// extra memory" reported for a word that has no room), and sampled simulation estimates them
/// about 10 % low, outside its interval.
#[test]
fn leap_values_are_refused_where_their_figures_would_be_wrong() {
    let out = scratch("leap-values-refused").join("x.json");
    let out_ = out.to_str().unwrap();
    let base = [
        "sim",
        "--dataset",
        "phantom:cast:32",
        "--size",
        "8x8",
        "--set",
        "occupancy.structure=leap-values",
        "--json",
        out_,
    ];
    let with = |extra: &[&'static str]| [&base[..], extra].concat();
    assert_fails(
        &with(&["--shading"]),
        &["volume_word.word_bits", "need 56 bits", "has 32"],
        &out,
    );
    assert_fails(
        &with(&["--sample", "0.05"]),
        &["sampling", "leap values", "run this structure exactly"],
        &out,
    );
    // Without either, and shading or sampling with another structure, they run.
    succeeds(&with(&[]));
    let without_leap_values = |extra: &[&'static str]| {
        let plain = ["sim", "--dataset", "phantom:cast:32", "--size", "8x8"];
        succeeds(&[&plain[..], extra].concat());
    };
    without_leap_values(&["--shading", "--subcube", "8"]);
    without_leap_values(&["--sample", "0.05"]);
}

/// A setting whose feature is off is named as without effect, with the switch that is off
/// (a probe found `--set iso.value=80` without iso, or a distance width with the map, run a
/// plain frame while the resolved line listed them as set); with the feature on, no note.
#[test]
fn settings_whose_feature_is_off_are_named_as_without_effect() {
    let sim = |sets: &[&str]| {
        let mut args = vec!["sim", "--dataset", "phantom:sphere:16", "--size", "8x8"];
        for s in sets {
            args.extend_from_slice(&["--set", s]);
        }
        String::from_utf8_lossy(&succeeds(&args).stdout).into_owned()
    };
    let idle = sim(&[
        "iso.value=8",
        "occupancy.distance_bits=4",
        "blocking.block_size=8",
        "bricks.setup=table",
        "geometry.radius=5.0",
        "occupancy.hierarchy=true",
        "skip.policy=sample-then-leap",
        "sdram.t_rc=3",
        "memory.overtaking=false",
        "memory.overtaking_window=2",
        "sdram.refresh=false",
        "sdram.refresh_interval=100",
        "skip.reciprocal_bits=2",
        "occupancy.kind=\"zero\"",
        "clock.step_time_ns=5",
    ]);
    for expected in [
        "note: without effect here:",
        "occupancy.hierarchy = true (occupancy.subcube is 0: no map)",
        "skip.policy = \"sample-then-leap\" (no leaping structure)",
        "sdram.t_rc = 3 (shorter than t_ras + t_rp = 7",
        "iso.value = 8.0 (iso.enabled is false)",
        "occupancy.distance_bits = 4 (occupancy.structure is not \"distance\")",
        "blocking.block_size = 8 (blocking.enabled is false)",
        // Sections not written out while off: named by the --set that was given.
        "--set bricks.setup=table (bricks.size is 0)",
        "--set geometry.radius=5.0 (geometry.shape is \"none\")",
        // A review found these switched off, or unread, without a word.
        "memory.overtaking_window = 2 (memory.overtaking is false)",
        "sdram.refresh_interval = 100 (sdram.refresh is false)",
        "skip.reciprocal_bits = 2 (no leaping structure)",
        "occupancy.kind = \"zero\" (no leaping structure, bricks or blocking)",
        "clock.step_time_ns = 5.0 (the step model's cost per step; the cycle model counts cycles)",
    ] {
        assert!(idle.contains(expected), "{expected}: {idle}");
    }
    // The untimed step model reads no timing field, and reads the cost per step.
    let png = scratch("timing-fields").join("x.png");
    let fixed = String::from_utf8_lossy(
        &succeeds(&[
            "render",
            "--model",
            "fixed",
            "--dataset",
            "phantom:sphere:16",
            "--size",
            "8x8",
            "-o",
            png.to_str().unwrap(),
            "--set",
            "skip.latency=20",
            "--set",
            "sdram.cl=3",
            "--set",
            "clock.step_time_ns=5",
        ])
        .stdout,
    )
    .into_owned();
    for expected in [
        "skip.latency = 20 (the step model counts steps, not cycles)",
        "sdram.cl = 3 (the step model counts steps, not cycles)",
    ] {
        assert!(fixed.contains(expected), "{expected}: {fixed}");
    }
    assert!(!fixed.contains("clock.step_time_ns = 5.0 ("), "{fixed}");
    let used = sim(&[
        "iso.enabled=true",
        "iso.value=8",
        "occupancy.structure=distance",
        "occupancy.distance_bits=4",
        "skip.reciprocal_bits=6",
        "occupancy.kind=\"zero\"",
        "memory.overtaking_window=2",
        "sdram.refresh_interval=100",
    ]);
    assert!(!used.contains("without effect"), "{used}");
    // The ideal memory reads no SDRAM or memory field (a probe's changes ran unnoticed).
    let ideal = String::from_utf8_lossy(
        &succeeds(&[
            "sim",
            "--dataset",
            "phantom:sphere:16",
            "--size",
            "8x8",
            "--memory",
            "ideal",
            "--set",
            "sdram.t_rcd=4",
        ])
        .stdout,
    )
    .into_owned();
    assert!(
        ideal.contains("note: without effect with --memory ideal: sdram.t_rcd = 4"),
        "{ideal}"
    );
}

/// A run that does not leap names the leaping structure's fields as without effect (a review
/// found `render --set occupancy.subcube=8` on the float model, and a distance volume, listed
/// as set and silently ignored); the kind stays in effect when it chooses the bricks' test.
#[test]
fn leaping_fields_are_without_effect_in_a_run_that_does_not_leap() {
    let dir = scratch("not-leaping");
    let png = dir.join("x.png");
    let render = |model: &str, sets: &[&str]| {
        let mut args = vec![
            "render",
            "--dataset",
            "phantom:sphere:16",
            "--size",
            "8x8",
            "--model",
            model,
            "-o",
            png.to_str().unwrap(),
        ];
        for s in sets {
            args.extend_from_slice(&["--set", s]);
        }
        String::from_utf8_lossy(&succeeds(&args).stdout).into_owned()
    };
    let float = render(
        "float",
        &["occupancy.subcube=8", "occupancy.hierarchy=true"],
    );
    for expected in [
        "note: without effect here:",
        "occupancy.subcube = 8 (the float model does not leap)",
        "occupancy.hierarchy = true (the float model does not leap)",
    ] {
        assert!(float.contains(expected), "{expected}: {float}");
    }
    let distance = render("float", &["occupancy.structure=distance"]);
    assert!(
        distance.contains("occupancy.structure = \"distance\" (the float model does not leap)"),
        "{distance}"
    );
    let kind = render("float", &["occupancy.kind=\"zero\""]);
    assert!(
        kind.contains("occupancy.kind = \"zero\" (the float model does not leap)"),
        "{kind}"
    );
    // The kind chooses the bricks' test on every model; the fixed-point model leaps.
    let bricks = render("float", &["occupancy.kind=\"zero\"", "bricks.size=8"]);
    assert!(!bricks.contains("without effect"), "{bricks}");
    let fixed = render(
        "fixed",
        &["occupancy.subcube=8", "occupancy.hierarchy=true"],
    );
    assert!(!fixed.contains("without effect"), "{fixed}");
    // A sequence with `--map none` renders without the map.
    let sequence = |map: &str| {
        let out = succeeds(&[
            "sequence",
            "--source",
            "phantom:metaballs:16",
            "--steps",
            "1",
            "--size",
            "8x8",
            "--map",
            map,
            "--subcube",
            "8",
        ]);
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let none = sequence("none");
    assert!(
        none.contains("without effect here: occupancy.subcube = 8 (--map none: no leaping)"),
        "{none}"
    );
    let scan = sequence("scan");
    assert!(!scan.contains("without effect"), "{scan}");
}

/// `update` says when the map with its min/max and prefix tables exceeds the configured SRAM
/// (a probe found the table-based figures given for a chip that cannot hold the table).
#[test]
fn update_says_when_its_tables_exceed_the_sram() {
    let update = |sram: &str| {
        let out = succeeds(&[
            "update",
            "phantom:metaballs:32",
            "--subcube",
            "8",
            "--set",
            &format!("occupancy.sram_bits={sram}"),
        ]);
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    // 64 sub-cubes: 64 map bits, 64 × 16 table bits, 256 × 9 prefix bits = 3,392.
    let small = update("2048");
    assert!(
        small.contains("need 3392 bits on chip, more than occupancy.sram_bits (2048)"),
        "{small}"
    );
    assert!(!update("4096").contains("note:"));
    assert!(
        small.contains("the scan pass needs only the map"),
        "{small}"
    );
    // A map over the SRAM on its own: no way of building it helps (a review found the scan
    // pass offered for a 2³ map that `sim` refuses).
    let tiny = update("32");
    assert!(
        tiny.contains("the map alone (64 bits) exceeds it too")
            && !tiny.contains("scan pass needs"),
        "{tiny}"
    );
}

/// `sequence` says the same when its map mode keeps the tables on chip (during-update,
/// rescan), with the figure its JSON gives; `--map scan` keeps only the map and says nothing.
#[test]
fn sequence_says_when_its_tables_exceed_the_sram() {
    let sequence = |map: &str, sram: &str, json: bool| {
        let mut args = vec![
            "sequence",
            "--source",
            "phantom:metaballs:32",
            "--steps",
            "1",
            "--size",
            "16x16",
            "--subcube",
            "8",
            "--map",
            map,
        ];
        let set = format!("occupancy.sram_bits={sram}");
        args.extend(["--set", &set]);
        if json {
            args.push("--json");
        }
        let out = succeeds(&args);
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    for map in ["during-update", "rescan"] {
        let small = sequence(map, "2048", false);
        assert!(
            small.contains("need 3392 bits on chip, more than occupancy.sram_bits (2048)")
                && small.contains(&format!("--map {map} builds")),
            "{small}"
        );
        assert!(!sequence(map, "4096", false).contains("note:"));
        let json: serde_json::Value = serde_json::from_str(&sequence(map, "2048", true)).unwrap();
        assert_eq!(json["table_on_chip_bits"], 3392);
    }
    assert!(!sequence("scan", "2048", false).contains("note:"));
    let json: serde_json::Value = serde_json::from_str(&sequence("scan", "2048", true)).unwrap();
    assert!(json["table_on_chip_bits"].is_null());
}

/// `update`'s JSON `download_ms` is the download with its map (writes + map bits), and the
/// text gives that sum too, as "in all", beside the writes' time (a review found the two
/// figures under one name).
#[test]
fn update_gives_the_download_with_its_map_in_text_and_json() {
    let args = ["update", "phantom:metaballs:32", "--subcube", "8"];
    let text = String::from_utf8_lossy(&succeeds(&args).stdout).into_owned();
    let json: serde_json::Value =
        serde_json::from_slice(&succeeds(&[&args[..], &["--json"]].concat()).stdout).unwrap();
    let clock = json["clock_mhz"].as_f64().unwrap();
    for (report, ms) in [
        ("download", "download_ms"),
        ("download_tiled", "download_tiled_ms"),
    ] {
        let total = json[report]["total_cycles"].as_u64().unwrap();
        let writes = json[report]["write_cycles"].as_u64().unwrap();
        assert!(total > writes, "{report}: the map adds cycles");
        let ms = json[ms].as_f64().unwrap();
        assert!((ms - total as f64 / clock / 1e3).abs() < 1e-9, "{report}");
        let all = format!("{} in all", vizsim::text::milliseconds(ms));
        assert!(text.contains(&all), "{all}: {text}");
    }
}

/// `update --next` says when rescanning the changed regions (with their stencil borders) costs
/// more than one scan pass over the whole volume, so the exact map is cheaper by a full scan;
/// when it does not, nothing is said.
#[test]
fn update_says_when_a_full_scan_beats_the_rescan() {
    let update = |next: &str| {
        let out = succeeds(&[
            "update",
            "phantom:metaballs:32",
            "--subcube",
            "8",
            "--next",
            next,
        ]);
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let number_after = |text: &str, label: &str| -> u64 {
        let rest = &text[text
            .find(label)
            .unwrap_or_else(|| panic!("{label}: {text}"))
            + label.len()..];
        rest.split(|c: char| !c.is_ascii_digit())
            .find(|s| !s.is_empty())
            .unwrap()
            .parse()
            .unwrap()
    };
    let changed = update("phantom:metaballs:32:t=0.05");
    // The rescan line's "+ rescan N" (the widen line's comes first).
    let rescan_line = &changed[changed.find("rescan: ").unwrap()..];
    let rescan = number_after(rescan_line, "+ rescan ");
    let scan = number_after(&changed, "scan pass: 4096 requests, ");
    assert!(
        changed.contains("costs more than a full scan pass"),
        "{changed}"
    );
    assert!(
        changed.contains(&format!("the rescan ({rescan} cycles)")) && rescan > scan,
        "{changed}"
    );
    let same = update("phantom:metaballs:32");
    assert!(!same.contains("costs more"), "{same}");
}

/// The precision sweep keeps to what its base configuration allows: with 8-bit positions the
/// increment widths stop at 8 (a probe's run failed on the sweep's own 9).
#[test]
fn precision_sweeps_only_widths_the_base_allows() {
    let dir = scratch("precision-narrow");
    succeeds(&[
        "precision",
        "--dataset",
        "phantom:sphere:16",
        "--size",
        "16x16",
        "--out",
        dir.to_str().unwrap(),
        "--set",
        "ray.position_frac_bits=8",
        "--set",
        "ray.increment_frac_bits=8",
        "--set",
        "skip.distance_frac_bits=4",
    ]);
    let report: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("phantom-sphere-16.json")).unwrap())
            .unwrap();
    let increments: Vec<u64> = report["image"]
        .as_array()
        .unwrap()
        .iter()
        .filter(|p| p["field"] == "ray.increment_frac_bits")
        .map(|p| p["bits"].as_u64().unwrap())
        .collect();
    assert_eq!(increments, [4, 5, 6, 7, 8]);
}

/// `render --model fixed` and `sim` compare their frame with the float reference on every run
/// (the mission's "is the fixed-point image still right?"), in one line and in `--json`'s
/// `float_reference`: the same figures `vizsim compare` gives for their PNG against the float
/// render's, homogeneous leap values' too (the reference is the intended image). The float
/// render itself has no reference to compare with.
#[test]
fn fixed_and_cycle_runs_are_compared_with_the_float_reference() {
    let dir = scratch("float-reference");
    let path = |name: &str| dir.join(name).to_str().unwrap().to_string();
    let frame = [
        "--dataset",
        "phantom:metaballs:32",
        "--size",
        "16x16",
        "--view",
        "orbit:3/72",
    ];
    let float = succeeds(
        &[
            &["render"][..],
            &frame[..],
            &["-o", &path("float.png"), "--json", &path("float.json")],
        ]
        .concat(),
    );
    assert!(!String::from_utf8_lossy(&float.stdout).contains("float reference"));
    let float_json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(path("float.json")).unwrap()).unwrap();
    assert!(float_json.get("float_reference").is_none());
    for (name, command) in [
        (
            "fixed",
            &["render", "--model", "fixed", "--subcube", "4"][..],
        ),
        ("cycle", &["sim", "--subcube", "4"][..]),
        // Lossy: the reference is the intended image, not the float model following the
        // region means (else the loss would not show).
        (
            "lossy",
            &[
                "render",
                "--model",
                "fixed",
                "--set",
                "occupancy.structure=leap-values",
                "--set",
                "leap_values.regions=homogeneous",
            ][..],
        ),
    ] {
        let (png, json) = (path(&format!("{name}.png")), path(&format!("{name}.json")));
        let out = succeeds(&[command, &frame[..], &["-o", &png, "--json", &json]].concat());
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            stdout.contains("fixed vs float reference: max error (R, G, B, A)")
                && stdout.contains(" levels, mean (R, G, B, A) "),
            "{name}: {stdout}"
        );
        // The hint at --check-bound only where it takes the run: it refuses lossy leap values.
        assert_eq!(
            stdout.contains("(--check-bound: each pixel"),
            name != "lossy",
            "{name}: {stdout}"
        );
        let compared = path(&format!("{name}-compare.json"));
        let out = succeeds(&["compare", &png, &path("float.png"), "--json", &compared]);
        let said = String::from_utf8_lossy(&out.stdout);
        assert!(said.contains(", mean (R, G, B, A) "), "{name}: {said}");
        let report: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
        let expected: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(&compared).unwrap()).unwrap();
        assert_eq!(report["float_reference"], expected, "{name}");
        assert_eq!(
            expected["identical"], false,
            "{name}: the test needs a difference"
        );
    }
}

/// A clip region that leaves nothing of the volume says so: its frame's figures are those of
/// no sample (an architect's review found 1.5 M fps reported without a word).
#[test]
fn a_clip_region_outside_the_volume_says_nothing_is_sampled() {
    let run = |clip: &str| {
        let out = succeeds(&[
            "sim",
            "--dataset",
            "phantom:sphere:16",
            "--size",
            "8x8",
            "--set",
            &format!("clip.box={clip}"),
        ]);
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    let outside = run("[[100,100,100],[200,200,200]]");
    assert!(
        outside.contains("(100.0 %); every position is cut"),
        "{outside}"
    );
    let half = run("[[0,0,0],[15,15,7]]");
    assert!(half.contains("ray start/end:"), "{half}");
    assert!(!half.contains("every position is cut"), "{half}");
}

/// `--json -` writes the JSON to standard output, as for most command-line tools, and the
/// command's text to standard error, so that the JSON can be piped (it wrote a file named `-`).
#[test]
fn json_to_standard_output_with_the_text_on_standard_error() {
    let dir = scratch("json-stdout");
    let png = dir.join("frame.png");
    let png_ = png.to_str().unwrap();
    let frame = ["--dataset", "phantom:sphere:32", "--size", "16x16"];
    let runs: [(Vec<&str>, &str, &str); 3] = [
        (
            [&["sim"][..], &frame, &["--json", "-"]].concat(),
            "\"cycles\"",
            "cycles =",
        ),
        (
            [&["render"][..], &frame, &["-o", png_, "--json", "-"]].concat(),
            "\"samples\"",
            "rays,",
        ),
        (
            vec!["compare", png_, png_, "--json", "-"],
            "\"max_abs_error\"",
            "max |error|",
        ),
    ];
    for (args, json_field, text) in runs {
        let out = succeeds(&args);
        let stdout = String::from_utf8(out.stdout).unwrap();
        let stderr = String::from_utf8_lossy(&out.stderr);
        let parsed: serde_json::Value = serde_json::from_str(&stdout)
            .unwrap_or_else(|e| panic!("{args:?}: standard output is not JSON ({e}): {stdout}"));
        assert!(parsed.is_object(), "{args:?}: {stdout}");
        assert!(stdout.contains(json_field), "{args:?}: {stdout}");
        assert!(
            stderr.contains(text),
            "{args:?}: the text is not on standard error: {stderr}"
        );
        assert!(
            stderr.contains("hardware:") || args[0] == "compare",
            "{stderr}"
        );
    }
    let dash = Path::new(env!("CARGO_MANIFEST_DIR")).join("-");
    assert!(!dash.exists(), "a file named - was written");
    // Images are not written to standard output.
    assert_fails(
        &[&["render"][..], &frame, &["-o", "-"]].concat(),
        &["--output -", "not written to standard output"],
        &dash,
    );
    for option in ["--vcd", "--command-trace"] {
        assert_fails(
            &[&["sim"][..], &frame, &[option, "-"]].concat(),
            &[option, "only `--json -` writes to standard output"],
            &dash,
        );
    }
}

/// Options a dynamic command takes but would not use are named, not silently dropped:
/// `update --brick` without `--next`, `sequence --dt` on a source with no time step.
#[test]
fn dynamic_options_without_effect_are_noted() {
    let update = succeeds(&[
        "update",
        "phantom:sphere:32",
        "--subcube",
        "8",
        "--brick",
        "3",
    ]);
    let stderr = String::from_utf8_lossy(&update.stderr);
    assert!(
        stderr.contains("--brick is without effect without --next"),
        "{stderr}"
    );
    let plain = succeeds(&["update", "phantom:sphere:32", "--subcube", "8"]);
    assert!(!String::from_utf8_lossy(&plain.stderr).contains("--brick"));
    let sequence = |extra: &[&str]| {
        let mut args = vec![
            "sequence",
            "--source",
            "phantom:tsdf:32",
            "--subcube",
            "4",
            "--size",
            "8x8",
            "--steps",
            "2",
        ];
        args.extend_from_slice(extra);
        succeeds(&args)
    };
    let noted = sequence(&["--dt", "5"]);
    let stderr = String::from_utf8_lossy(&noted.stderr);
    assert!(
        stderr.contains("--dt is without effect on phantom:tsdf:32"),
        "{stderr}"
    );
    // The figures are the same with and without it: it is truly unread.
    assert_eq!(noted.stdout, sequence(&[]).stdout);
}
