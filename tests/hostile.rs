//! Hostile inputs (issue 17): inputs that are FIFOs or devices, unbounded or oversized text
//! inputs, absurd numbers. Each must end quickly with a non-zero exit and a message naming
//! the path or field; none may hang, panic or exhaust memory.

mod common;

use std::path::PathBuf;
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

fn scratch(name: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-hostile-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn mkfifo(path: &std::path::Path) {
    let ok = Command::new("mkfifo")
        .arg(path)
        .status()
        .map(|s| s.success());
    assert!(matches!(ok, Ok(true)), "mkfifo {}", path.display());
}

fn assert_refused(args: &[&str], needles: &[&str]) {
    let (ok, stderr) = common::run_bounded(None, args, 30);
    assert!(!ok, "{args:?} succeeded");
    assert!(!stderr.contains("panicked"), "{args:?} panicked: {stderr}");
    for n in needles {
        assert!(stderr.contains(n), "{args:?}: stderr lacks {n:?}: {stderr}");
    }
}

#[test]
fn fifos_and_devices_are_refused_not_read() {
    let dir = scratch("fifo");
    let fifo = dir.join("hw.toml");
    mkfifo(&fifo);
    let png = dir.join("x.png");
    let base = [
        "render",
        "--dataset",
        "phantom:sphere:8",
        "-o",
        png.to_str().unwrap(),
    ];
    let mut args = base.to_vec();
    args.extend(["--model", "fixed", "--config", fifo.to_str().unwrap()]);
    assert_refused(&args, &["hw.toml", "not a regular file"]);
    let mut args = base.to_vec();
    args.extend(["--model", "fixed", "--config", "/dev/zero"]);
    assert_refused(&args, &["/dev/zero", "not a regular file"]);
    let mut args = base.to_vec();
    args.extend(["--tf", fifo.to_str().unwrap()]);
    // A transfer-function argument that is no regular file is not taken for a file at all.
    assert_refused(&args, &["hw.toml"]);

    let data = dir.join("data");
    std::fs::create_dir_all(&data).unwrap();
    mkfifo(&data.join("x_4x4x4_uint8.raw"));
    assert_refused(
        &["info", "x", "--data-dir", data.to_str().unwrap()],
        &["x_4x4x4_uint8.raw", "not a regular file"],
    );
    let experiment = dir.join("e.toml");
    mkfifo(&experiment);
    assert_refused(
        &[
            "sweep",
            experiment.to_str().unwrap(),
            "--out",
            dir.join("o").to_str().unwrap(),
        ],
        &["e.toml", "not a regular file"],
    );
    assert!(!png.exists());
}

#[test]
fn oversized_text_inputs_are_refused() {
    let dir = scratch("big");
    let big = dir.join("big.toml");
    let mut text = String::from("# padding\n");
    while text.len() <= (16 << 20) {
        text.push_str(&"#".repeat(1023));
        text.push('\n');
    }
    std::fs::write(&big, text).unwrap();
    let png = dir.join("x.png");
    assert_refused(
        &[
            "render",
            "--dataset",
            "phantom:sphere:8",
            "--model",
            "fixed",
            "--config",
            big.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
        ],
        &["big.toml", "16 MiB"],
    );
}

#[test]
fn an_absurd_ideal_latency_is_refused() {
    assert_refused(
        &[
            "sim",
            "--dataset",
            "phantom:sphere:8",
            "--memory",
            "ideal",
            "--ideal-latency",
            "18446744073709551615",
        ],
        &["ideal memory latency", "1..=1048576"],
    );
}

/// A kill -9 during an atomic write leaves a hidden temporary; the next write to the same path
/// removes it when its process is gone, and leaves a live process's temporary alone.
#[test]
fn stale_temporaries_of_a_killed_write_are_cleaned_on_the_next_write() {
    if !std::path::Path::new("/proc/self").exists() {
        eprintln!("skipped: no /proc to tell live processes");
        return;
    }
    let dir = scratch("stale-tmp");
    let mut gone = Command::new("true").spawn().unwrap();
    let dead_pid = gone.id();
    gone.wait().unwrap();
    let stale = dir.join(format!(".out.json.tmp{dead_pid}"));
    let mut running = Command::new("sleep").arg("30").spawn().unwrap();
    let live = dir.join(format!(".out.json.tmp{}", running.id()));
    let other = dir.join(format!(".other.json.tmp{dead_pid}"));
    for f in [&stale, &live, &other] {
        std::fs::write(f, b"half a file").unwrap();
    }
    let out = dir.join("out.json");
    vizsim::output::write_json(&out, &serde_json::json!({"a": 1})).unwrap();
    assert!(out.exists());
    assert!(!stale.exists(), "the dead process's temporary is removed");
    assert!(live.exists(), "a live process's temporary stays");
    assert!(other.exists(), "temporaries of other paths stay");
    running.kill().unwrap();
    running.wait().unwrap();
}

/// Charts are drawn under temporaries that carry the process id and keep the extension
/// (plotters picks the format by it); one a killed `plot` left is removed by the next chart
/// written to the same name, and nothing but the chart is left.
#[test]
fn a_chart_killed_while_drawing_leaves_nothing_the_next_run_keeps() {
    if !std::path::Path::new("/proc/self").exists() {
        eprintln!("skipped: no /proc to tell live processes");
        return;
    }
    let dir = scratch("stale-chart-tmp");
    let mut gone = Command::new("true").spawn().unwrap();
    let dead_pid = gone.id();
    gone.wait().unwrap();
    let stale = [
        dir.join(format!(".c.png.tmp{dead_pid}.png")),
        dir.join(format!(".c.svg.tmp{dead_pid}.svg")),
    ];
    for f in &stale {
        std::fs::write(f, b"half a chart").unwrap();
    }
    vizsim::plot::LineChart {
        title: "t",
        x_label: "x",
        y_label: "y",
        series: vec![vizsim::plot::Series {
            name: "s".into(),
            points: vec![(1.0, 2.0), (2.0, 3.0)],
        }],
        log_y: false,
    }
    .write(&dir.join("c"))
    .unwrap();
    let mut left: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().into_string().unwrap())
        .collect();
    left.sort();
    assert_eq!(left, ["c.png", "c.svg"]);
    let png = std::fs::read(dir.join("c.png")).unwrap();
    assert!(png.starts_with(b"\x89PNG"), "drawn as PNG");
}

/// A dataset with no preset transfer function fails the sweep's validation, dry run or not,
/// before anything is written (issue 17, item 7: the real run used to fail after writing the
/// lock, the resolved experiment and empty result files).
#[test]
fn a_dataset_without_a_transfer_function_fails_before_the_sweep_writes() {
    let dir = scratch("no-tf");
    let data = dir.join("data");
    std::fs::create_dir_all(&data).unwrap();
    std::fs::write(data.join("blob_8x8x8_uint8.raw"), vec![7u8; 512]).unwrap();
    let experiment = dir.join("e.toml");
    std::fs::write(
        &experiment,
        "name = \"e\"\ndatasets = [\"blob\"]\ntf = [\"class\"]\nmodes = [\"none\"]\n\
         models = [\"step\"]\n[frames]\norbit = 1\n",
    )
    .unwrap();
    let out = dir.join("out");
    for dry in [true, false] {
        let mut args = vec![
            "sweep",
            experiment.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--data-dir",
            data.to_str().unwrap(),
        ];
        if dry {
            args.push("--dry-run");
        }
        assert_refused(&args, &["tf", "`class` for dataset `blob`", "blob-class"]);
        assert!(
            !out.exists(),
            "dry run {dry}: the output folder was created"
        );
    }
}

/// Outputs that are not regular files are written through, not replaced by a renamed
/// temporary: a symlink stays a symlink (its target gets the image), a full device reports
/// the full disk (issue 17, item 5).
#[test]
fn symlinks_and_devices_as_outputs_are_written_through() {
    let dir = scratch("outputs");
    let real = dir.join("real.png");
    let link = dir.join("link.png");
    std::os::unix::fs::symlink(&real, &link).unwrap();
    let render = |out: &std::path::Path| {
        common::run_bounded(
            None,
            &[
                "render",
                "--dataset",
                "phantom:sphere:16",
                "--size",
                "8x8",
                "-o",
                out.to_str().unwrap(),
            ],
            30,
        )
    };
    let (ok, stderr) = render(&link);
    assert!(ok, "{stderr}");
    let meta = std::fs::symlink_metadata(&link).unwrap();
    assert!(meta.file_type().is_symlink(), "the link was replaced");
    let png = std::fs::read(&real).unwrap();
    assert_eq!(&png[1..4], b"PNG", "the link's target holds the image");
    let full = std::path::Path::new("/dev/full");
    if full.exists() {
        let (ok, stderr) = render(full);
        assert!(!ok, "writing to /dev/full succeeded");
        assert!(!stderr.contains("panicked"), "{stderr}");
        assert!(stderr.contains("/dev/full"), "{stderr}");
        use std::os::unix::fs::FileTypeExt;
        let kind = std::fs::symlink_metadata(full).unwrap().file_type();
        assert!(kind.is_char_device(), "/dev/full was replaced");
    } else {
        eprintln!("skipped the /dev/full part: no /dev/full here");
    }
}

/// `sim` checks its output paths before simulating: an unwritable `--json` fails at once, with
/// no frame simulated and no image written (issue 17, item 12).
#[test]
fn sim_checks_its_outputs_before_simulating() {
    let dir = scratch("sim-outputs");
    let not_a_folder = dir.join("file");
    std::fs::write(&not_a_folder, b"x").unwrap();
    let json = not_a_folder.join("report.json");
    let image = dir.join("frame.png");
    let output = Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args([
            "sim",
            "--dataset",
            "phantom:sphere:32",
            "--size",
            "16x16",
            "-o",
            image.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(!output.status.success());
    assert!(
        stderr.contains("report.json") || stderr.contains("file"),
        "{stderr}"
    );
    assert!(
        !String::from_utf8_lossy(&output.stdout).contains("cycles"),
        "the frame was simulated first"
    );
    assert!(!image.exists());
}

/// A data folder that links to itself or holds a link to itself lists each dataset once,
/// under its own name (issue 17, item 12: it was listed three times under changed names).
#[test]
fn a_symlink_loop_in_the_data_folder_lists_each_dataset_once() {
    let dir = scratch("data-loop");
    std::fs::write(dir.join("blob_8x8x8_uint8.raw"), vec![1u8; 512]).unwrap();
    std::os::unix::fs::symlink(".", dir.join("loop")).unwrap();
    std::os::unix::fs::symlink(&dir, dir.join("absolute")).unwrap();
    let names: Vec<String> = vizsim::volume::dataset::scan(&dir)
        .unwrap()
        .into_iter()
        .map(|e| e.name)
        .collect();
    assert_eq!(names, ["blob"]);
}

/// Runs vizsim with a memory budget in the environment; returns success and stderr.
fn run_with_budget(budget: &str, args: &[&str]) -> (bool, String) {
    let output = Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(args)
        .env("VIZSIM_MEMORY_BUDGET", budget)
        .output()
        .unwrap();
    (
        output.status.success(),
        String::from_utf8_lossy(&output.stderr).into_owned(),
    )
}

/// Requests whose memory is known up front are refused with the figure and the budget
/// instead of aborting in the allocation (issue 17, item 4): a 16384² frame, a small gzip
/// NRRD that declares 2048×1024×1024 voxels, a phantom over a tiny budget, an experiment of
/// six axes of 100 values (dry run).
#[test]
fn requests_over_the_memory_budget_are_refused_up_front() {
    let dir = scratch("budget");
    let (ok, stderr) = run_with_budget(
        "1G",
        &[
            "sim",
            "--dataset",
            "phantom:sphere:16",
            "--size",
            "16384x16384",
        ],
    );
    assert!(
        !ok && stderr.contains("16384x16384 frame") && stderr.contains("budget of 1.0 GiB"),
        "{stderr}"
    );

    let bomb = dir.join("bomb.nrrd");
    let mut file =
        b"NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2048 1024 1024\nencoding: gzip\n\n".to_vec();
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::fast());
    std::io::Write::write_all(&mut gz, &vec![0u8; 1 << 20]).unwrap();
    file.extend(gz.finish().unwrap());
    std::fs::write(&bomb, file).unwrap();
    let (ok, stderr) = run_with_budget("1G", &["info", bomb.to_str().unwrap()]);
    assert!(
        !ok && stderr.contains("bomb.nrrd") && stderr.contains("4.0 GiB"),
        "{stderr}"
    );

    // The command-line option wins over the environment.
    let (ok, stderr) = run_with_budget(
        "1T",
        &["--memory-budget", "1M", "info", "phantom:sphere:128"],
    );
    assert!(
        !ok && stderr.contains("phantom") && stderr.contains("budget of 1.0 MiB"),
        "{stderr}"
    );
    let (ok, stderr) = run_with_budget("1T", &["--memory-budget", "5Q", "info", "phantom:sphere"]);
    assert!(!ok && stderr.contains("K, M, G or T"), "{stderr}");

    let mut experiment = String::from(
        "name = \"huge\"\ndatasets = [\"phantom:sphere:8\"]\ntf = [\"zero\"]\nmodes = [\"none\"]\n\
         models = [\"step\"]\n[frames]\norbit = 1\n[axes]\n",
    );
    let values: Vec<String> = (1..=100).map(|v| v.to_string()).collect();
    for field in [
        "ray_queue.rays",
        "skip.latency",
        "compositing.stage_latency",
        "compositing.ert_feedback_latency",
        "memory.address_fifo_depth",
        "memory.voxel_fifo_depth",
    ] {
        experiment += &format!("\"{field}\" = [{}]\n", values.join(", "));
    }
    let path = dir.join("huge.toml");
    std::fs::write(&path, experiment).unwrap();
    let out = dir.join("out");
    let start = Instant::now();
    let (ok, stderr) = run_with_budget(
        "64G",
        &[
            "sweep",
            path.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--dry-run",
        ],
    );
    assert!(
        !ok && stderr.contains("1000000000000 runs, over the limit"),
        "{stderr}"
    );
    assert!(
        start.elapsed() < Duration::from_secs(20),
        "took {:?}",
        start.elapsed()
    );
    assert!(!out.exists());
}

/// An output that is a FIFO is written through: without a reader the run fails at once naming
/// it (it used to wait for a reader forever), with a reader the reader gets the whole file.
#[test]
fn a_fifo_output_needs_its_reader() {
    let dir = scratch("fifo-output");
    let fifo = dir.join("out.json");
    mkfifo(&fifo);
    let png = dir.join("x.png");
    let args = [
        "render",
        "--dataset",
        "phantom:sphere:8",
        "--size",
        "8x8",
        "-o",
        png.to_str().unwrap(),
        "--json",
        fifo.to_str().unwrap(),
    ];
    assert_refused(&args, &["out.json", "FIFO that nobody reads"]);
    let reader = Command::new("cat")
        .arg(&fifo)
        .stdout(Stdio::piped())
        .spawn()
        .unwrap();
    // Let the reader reach its open() (it counts as the FIFO's reader from there on).
    std::thread::sleep(Duration::from_millis(300));
    let (ok, stderr) = common::run_bounded(None, &args, 30);
    assert!(ok, "{stderr}");
    let json = reader.wait_with_output().unwrap().stdout;
    let value: serde_json::Value = serde_json::from_slice(&json).expect("the whole JSON");
    assert!(value.get("run").is_some(), "{value}");
    use std::os::unix::fs::FileTypeExt;
    let kind = std::fs::symlink_metadata(&fifo).unwrap().file_type();
    assert!(kind.is_fifo(), "the FIFO was replaced");
}

/// A text input is refused before parsing when its parse would exceed the memory budget
/// (issue 17, item 4: a transfer function of 10^6 points took 2.6 GB): a 4 MiB transfer
/// function of 90,000 points under a 64 MiB budget.
#[test]
fn a_text_input_whose_parse_exceeds_the_budget_is_refused() {
    let dir = scratch("tf-budget");
    let tf = dir.join("many.toml");
    let mut text = String::new();
    let mut i = 0;
    while text.len() < 4 << 20 {
        text += &format!(
            "[[points]]\nvalue = {}\nrgba = [0, 0, 0, 0]\n",
            i as f64 * 0.5
        );
        i += 1;
    }
    std::fs::write(&tf, text).unwrap();
    let png = dir.join("x.png");
    let (ok, stderr) = run_with_budget(
        "64M",
        &[
            "render",
            "--dataset",
            "phantom:sphere:8",
            "--size",
            "8x8",
            "--tf",
            tf.to_str().unwrap(),
            "-o",
            png.to_str().unwrap(),
        ],
    );
    assert!(!ok, "rendered with a 4 MiB transfer function under 64 MiB");
    assert!(
        stderr.contains("many.toml") && stderr.contains("budget of 64.0 MiB"),
        "{stderr}"
    );
    assert!(!png.exists());
}

/// A command that fails after making its output folder removes the folder when it made it and
/// it is empty; a folder that was there, or holds something, stays.
#[test]
fn a_failed_write_leaves_no_new_empty_folder() {
    let dir = scratch("new-folder");
    let fail = |out: &std::path::Path, leave_file: bool| {
        vizsim::output::removing_new_folder_on_error(out, || -> Result<(), String> {
            std::fs::create_dir_all(out).unwrap();
            if leave_file {
                std::fs::write(out.join("kept"), b"x").unwrap();
            }
            Err("failed".into())
        })
    };
    let new = dir.join("new");
    assert!(fail(&new, false).is_err());
    assert!(!new.exists(), "the new empty folder is removed");
    let with_file = dir.join("with-file");
    assert!(fail(&with_file, true).is_err());
    assert!(
        with_file.join("kept").exists(),
        "a folder with content stays"
    );
    let existing = dir.join("existing");
    std::fs::create_dir_all(&existing).unwrap();
    assert!(fail(&existing, false).is_err());
    assert!(existing.is_dir(), "a folder that was there stays");
    // Success keeps the new folder.
    let made = dir.join("made");
    vizsim::output::removing_new_folder_on_error(&made, || -> Result<(), String> {
        std::fs::create_dir_all(&made).unwrap();
        Ok(())
    })
    .unwrap();
    assert!(made.is_dir());
}
