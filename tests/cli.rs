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
    let out = vizsim(&[
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
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
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

#[test]
fn info_reports_the_published_occupancy() {
    let Some(dir) = common::data_dir() else {
        return;
    };
    for (name, published) in [("fuel", 5.24), ("neghip", 46.38), ("aneurism", 1.01)] {
        let out = vizsim(&["info", name, "--json", "--data-dir", dir.to_str().unwrap()]);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
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
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        serde_json::from_slice(&out.stdout).unwrap()
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
    let out = vizsim(&[
        "precision",
        "--dataset",
        "phantom:sphere:32",
        "--size",
        "32x32",
        "--out",
        dir.to_str().unwrap(),
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
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
}

#[test]
fn occupancy_reports_the_published_storage_and_sram_fit() {
    let out = vizsim(&["occupancy", "phantom:jet:64", "--json"]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
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
}

#[test]
fn sim_writes_the_statistics_architects_need() {
    let dir = scratch("sim");
    let json = dir.join("sim.json");
    let png = dir.join("sim.png");
    let out = vizsim(&[
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
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
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
