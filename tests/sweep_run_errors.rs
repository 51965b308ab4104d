//! Runs that fail on their dataset: what preparing a run refuses on the volume (an iso value
//! outside its densities, a block size that does not divide it, a depth file that is missing,
//! not a file or of the wrong size, a volume that does not fit the SDRAM's rows, with blocking
//! or without) is refused when the experiment is validated, dry run or not, before the sweep
//! writes anything, naming the experiment file, the axis and the value. A run that still fails
//! during the sweep: tests/sweep_stops.rs.

mod common;

use std::path::{Path, PathBuf};

use vizsim::clip::DepthImage;

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!(
        "vizsim-sweep-run-errors-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// An experiment on a 16³ phantom, 8×8 frames, with `modes` and the `[axes]` lines `axes`.
fn experiment(name: &str, modes: &str, axes: &str) -> String {
    format!(
        r#"name = "{name}"
datasets = ["phantom:sphere:16"]
tf = ["class"]
modes = [{modes}]
models = ["step"]
[frames]
orbit = 8
size = "8x8"
[axes]
{axes}
"#
    )
}

/// The experiment `text`, written to `dir/FILE`, must be refused by `sweep --dry-run` and by
/// `sweep` alike, with every needle in the message and no sweep folder made.
fn refused_before_writing(dir: &Path, file: &str, text: &str, needles: &[&str]) {
    std::fs::write(dir.join(file), text).unwrap();
    let out = format!("{file}.out");
    for dry in [true, false] {
        let mut args = vec!["sweep", file, "--out", &out, "--quiet"];
        if dry {
            args.push("--dry-run");
        }
        let (ok, stderr) = common::run_bounded(Some(dir), &args, 30);
        assert!(!ok, "{args:?} succeeded");
        assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
        for n in needles {
            assert!(stderr.contains(n), "{args:?}: stderr lacks {n:?}: {stderr}");
        }
        assert!(
            !dir.join(&out).exists(),
            "{args:?}: the sweep folder was made"
        );
    }
}

#[test]
fn an_iso_value_outside_the_dataset_is_refused_before_the_sweep() {
    let dir = scratch("iso");
    // The mixed sweep of the review: 8 frames of iso.value 100, 8 of 60000 (the phantom's
    // densities are 0..=245). It wrote the first half, then stopped.
    refused_before_writing(
        &dir,
        "iso.toml",
        &experiment("iso", r#""iso2""#, r#""iso.value" = [100, 60000]"#),
        &[
            "iso.toml",
            r#"field `axes."iso.value"`"#,
            "iso.value=60000",
            "outside the densities of dataset `phantom:sphere:16`",
            "[[exclude]]",
        ],
    );
    // Excluding the value makes it a valid experiment.
    let text = experiment("iso", r#""iso2""#, r#""iso.value" = [100, 60000]"#)
        + "[[exclude]]\n\"iso.value\" = 60000\n";
    std::fs::write(dir.join("ok.toml"), text).unwrap();
    let (ok, stderr) = common::run_bounded(
        Some(&dir),
        &["sweep", "ok.toml", "--out", "ok", "--quiet"],
        30,
    );
    assert!(ok, "{stderr}");
    let lines = std::fs::read_to_string(dir.join("ok/results.jsonl")).unwrap();
    assert_eq!(lines.lines().count(), 8);
}

#[test]
fn a_block_size_that_does_not_divide_the_volume_is_refused_before_the_sweep() {
    let dir = scratch("blocking");
    refused_before_writing(
        &dir,
        "blocking.toml",
        &experiment(
            "blocking",
            r#""none""#,
            "\"blocking.enabled\" = [true]\n\"blocking.block_size\" = [8, 32]",
        ),
        &[
            "blocking.toml",
            r#"field `axes."blocking.block_size"`"#,
            "blocking.block_size=32",
            "does not divide",
        ],
    );
    // A run left out for its mode (a sub-cube larger than the volume) is left out, not an
    // error, whatever its block size (the review found the check made before the skip).
    let text = experiment(
        "blocking-skip",
        r#""ert+leap32""#,
        "\"blocking.enabled\" = [true]\n\"blocking.block_size\" = [32]",
    )
    .replace(
        r#"datasets = ["phantom:sphere:16"]"#,
        r#"datasets = ["phantom:sphere:16", "phantom:sphere:64"]"#,
    );
    std::fs::write(dir.join("skip.toml"), text).unwrap();
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(["sweep", "skip.toml", "--out", "skip", "--dry-run"])
        .current_dir(&dir)
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("left out") && stdout.contains("sub-cube larger than the volume"),
        "{stdout}"
    );
}

#[test]
fn a_volume_that_does_not_fit_the_memory_is_refused_before_the_sweep() {
    let dir = scratch("memory");
    // The cycle model on a 64³ phantom: 4,096 rows per bank hold it, 2 do not. The sweep
    // wrote the 8 frames with 4,096 rows, then stopped at the first with 2.
    let cycle = |name: &str, axes: &str| {
        experiment(name, r#""none""#, axes)
            .replace("phantom:sphere:16", "phantom:sphere:64")
            .replace(r#"models = ["step"]"#, r#"models = ["cycle"]"#)
    };
    refused_before_writing(
        &dir,
        "rows.toml",
        &cycle("rows", r#""memory.rows" = [4096, 2]"#),
        &[
            "rows.toml",
            r#"field `axes."memory.rows"`"#,
            "memory.rows=2",
            "needs 32 rows per bank",
            "the modules have 2",
        ],
    );
    // With blocking the transfer function decides how many blocks must be held: the check
    // builds the block table on the dataset.
    refused_before_writing(
        &dir,
        "blocked.toml",
        &cycle(
            "blocked",
            "\"blocking.enabled\" = [true]\n\"memory.rows\" = [4096, 4]",
        ),
        &[
            "blocked.toml",
            r#"field `axes."memory.rows"`"#,
            "blocking.enabled=true, memory.rows=4",
            "does not fit with blocking",
            "8 active blocks",
        ],
    );
    // Not the field in the error (`memory.rows`, from the base file) but an axis of its
    // section makes it fail: that axis is named, not `config`.
    std::fs::write(
        dir.join("base.toml"),
        vizsim::config::DEFAULT_TOML.replace("\nrows = 4096", "\nrows = 64"),
    )
    .unwrap();
    refused_before_writing(
        &dir,
        "banks.toml",
        &format!(
            "config = \"base.toml\"\n{}",
            cycle(
                "banks",
                "\"memory.banks\" = [4, 1]\n\"ray_queue.rays\" = [8]"
            )
        ),
        &[
            r#"field `axes."memory.banks"`"#,
            "memory.banks=1",
            "field `memory.rows`",
            "needs 128 rows per bank",
        ],
    );
    // The same runs on the step model (no SDRAM) are valid.
    let text = experiment("rows-step", r#""none""#, r#""memory.rows" = [4096, 2]"#)
        .replace("phantom:sphere:16", "phantom:sphere:64");
    std::fs::write(dir.join("step.toml"), text).unwrap();
    let (ok, stderr) = common::run_bounded(
        Some(&dir),
        &["sweep", "step.toml", "--out", "step", "--dry-run"],
        30,
    );
    assert!(ok, "{stderr}");
}

#[test]
fn a_bad_depth_file_is_refused_before_the_sweep() {
    let dir = scratch("depth");
    // Of another size than the frames (8×8).
    DepthImage {
        width: 4,
        height: 4,
        depth: vec![1.0; 16],
    }
    .write(&dir.join("small.depth"))
    .unwrap();
    // A valid header in front of 3 GB (sparse): refused from its length, not read.
    let mut f = std::fs::File::create(dir.join("sparse.depth")).unwrap();
    use std::io::Write;
    f.write_all(b"VIZDEPTH 8 8\n").unwrap();
    f.set_len(3 << 30).unwrap();
    for (file, needles) in [
        ("nonexist.bin", &["nonexist.bin", "No such file"][..]),
        ("/dev/zero", &["/dev/zero", "not a regular file"][..]),
        ("small.depth", &["4x4", "the rendered image 8x8"][..]),
        (
            "sparse.depth",
            &["sparse.depth", "a 8x8 image needs 256"][..],
        ),
    ] {
        let axes =
            format!("\"geometry.shape\" = [\"depth-file\"]\n\"geometry.file\" = [\"{file}\"]");
        let mut all = vec![
            "depth.toml",
            r#"field `axes."geometry.file"`"#,
            "geometry.file",
        ];
        all.extend_from_slice(needles);
        refused_before_writing(
            &dir,
            "depth.toml",
            &experiment("depth", r#""none""#, &axes),
            &all,
        );
    }
}
