//! Where `demo` and `precision` write, and what they check before working: the demo leaves
//! results it does not own alone (another experiment's, or a folder a sweep is writing into),
//! bounds its frames, and both refuse an `--out` that is a file before any work; `precision`
//! writes only inside its `--out`, whatever a descriptor's `name` says.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn vizsim(args: &[&str], cwd: &Path) -> Output {
    Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(args)
        .current_dir(cwd)
        .env_remove("VIZSIM_DATA")
        .output()
        .expect("run vizsim")
}

fn text(out: &Output) -> (String, String) {
    (
        String::from_utf8_lossy(&out.stdout).into_owned(),
        String::from_utf8_lossy(&out.stderr).into_owned(),
    )
}

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!(
        "vizsim-demo-precision-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Every file under `dir`, relative to it, sorted.
fn files_under(dir: &Path) -> Vec<PathBuf> {
    let mut found = Vec::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for entry in std::fs::read_dir(&d).unwrap() {
            let path = entry.unwrap().path();
            if path.is_dir() {
                stack.push(path);
            } else {
                found.push(path.strip_prefix(dir).unwrap().to_path_buf());
            }
        }
    }
    found.sort();
    found
}

/// A descriptor of an 8³ raw volume whose `name` is `name`.
fn descriptor(dir: &Path, file: &str, name: &str) -> PathBuf {
    let vol = dir.join("vol");
    std::fs::create_dir_all(&vol).unwrap();
    let voxels: Vec<u8> = (0..512u32).map(|i| (i * 37 % 251) as u8).collect();
    std::fs::write(vol.join("x_8x8x8_uint8.raw"), voxels).unwrap();
    let path = vol.join(file);
    std::fs::write(
        &path,
        format!("name = {name:?}\nfile = \"x_8x8x8_uint8.raw\"\n"),
    )
    .unwrap();
    path
}

#[test]
fn precision_writes_only_inside_its_out_whatever_the_dataset_is_named() {
    let dir = scratch("names");
    let absolute = dir.join("abs").join("x");
    for (file, name, stem) in [
        ("up.toml", "../../escaped".to_string(), "escaped"),
        (
            "abs.toml",
            absolute.to_str().unwrap().to_string(),
            "", // checked below: no file under abs/
        ),
        ("dots.toml", "..".to_string(), "dataset"),
    ] {
        let desc = descriptor(&dir, file, &name);
        let out_dir = dir.join("a/b/prn");
        let _ = std::fs::remove_dir_all(dir.join("a"));
        let out = vizsim(
            &[
                "precision",
                "--dataset",
                desc.to_str().unwrap(),
                "--tf",
                "zero",
                "--size",
                "8x8",
                "--out",
                "a/b/prn",
            ],
            &dir,
        );
        let (stdout, stderr) = text(&out);
        assert!(out.status.success(), "{name}: {stdout}\n{stderr}");
        let written = files_under(&dir.join("a"));
        assert!(
            written.iter().all(|p| p.starts_with("b/prn")),
            "{name}: written outside --out: {written:?}"
        );
        assert!(
            !dir.join("abs").exists(),
            "{name}: wrote at its absolute name"
        );
        let in_out = files_under(&out_dir);
        assert_eq!(in_out.len(), 9, "{name}: {in_out:?}");
        for path in &in_out {
            let file = path.to_str().unwrap();
            assert!(!file.starts_with('.'), "{name}: a hidden file {file}");
            if !stem.is_empty() {
                assert!(file.starts_with(stem), "{name}: {file}");
            }
        }
        for line in stdout.lines().filter(|l| l.starts_with("wrote ")) {
            let path = Path::new(line.trim_start_matches("wrote "));
            assert!(dir.join(path).is_file(), "{name}: {line}");
        }
    }
}

#[test]
fn precision_checks_its_out_before_the_sweep_and_leaves_no_folder() {
    let dir = scratch("out");
    std::fs::write(dir.join("a.png"), b"not a folder").unwrap();
    let out = vizsim(
        &[
            "precision",
            "--dataset",
            "phantom:shells:16",
            "--tf",
            "zero",
            "--size",
            "8x8",
            "--out",
            "a.png",
        ],
        &dir,
    );
    let (stdout, stderr) = text(&out);
    assert!(!out.status.success());
    assert!(
        stderr.contains("a.png: is a file, not a folder (--out names a folder)"),
        "{stderr}"
    );
    assert!(
        !stdout.contains(" in "),
        "refused before the sweep: {stdout}"
    );
    assert_eq!(std::fs::read(dir.join("a.png")).unwrap(), b"not a folder");

    // A folder under a file cannot be made: said before the sweep, and nothing is left.
    let out = vizsim(
        &[
            "precision",
            "--dataset",
            "phantom:shells:16",
            "--tf",
            "zero",
            "--size",
            "8x8",
            "--out",
            "a.png/prn",
        ],
        &dir,
    );
    let (stdout, stderr) = text(&out);
    assert!(!out.status.success());
    assert!(stderr.contains("--out a.png/prn"), "{stderr}");
    assert!(
        !stdout.contains(" in "),
        "refused before the sweep: {stdout}"
    );
    // A precision that fails on its dataset leaves no new folder.
    let out = vizsim(
        &["precision", "--dataset", "nope-no-such", "--out", "new/prn"],
        &dir,
    );
    assert!(!out.status.success());
    assert!(!dir.join("new").exists(), "{}", text(&out).1);
}
/// A small sweep of an experiment named `name` into `out` (a second or so).
fn small_sweep(cwd: &Path, name: &str, out: &str) {
    let file = cwd.join(format!("{name}.toml"));
    std::fs::write(
        &file,
        format!(
            "name = \"{name}\"\ndatasets = [\"phantom:metaballs:16\"]\ntf = [\"class\"]\n\
             modes = [\"none\"]\nmodels = [\"step\"]\n\n[frames]\norbit = 4\nselect = [0]\n\
             size = \"8x8\"\n"
        ),
    )
    .unwrap();
    let swept = vizsim(
        &["sweep", file.to_str().unwrap(), "--out", out, "--quiet"],
        cwd,
    );
    assert!(swept.status.success(), "{}", text(&swept).1);
}

#[test]
fn demo_leaves_another_experiments_results_alone_and_says_so_before_rendering() {
    let dir = scratch("other-experiment");
    std::fs::create_dir_all(dir.join("empty")).unwrap();
    small_sweep(&dir, "exp2", "demoW/quick");
    let before = std::fs::read(dir.join("demoW/quick/results.jsonl")).unwrap();
    let out = vizsim(
        &[
            "demo",
            "--frames",
            "1",
            "--out",
            "demoW",
            "--data-dir",
            "empty",
            "--threads",
            "1",
        ],
        &dir,
    );
    let (stdout, stderr) = text(&out);
    assert!(!out.status.success(), "{stdout}");
    assert!(
        stderr.contains("demo --out demoW")
            && stderr.contains("demoW/quick")
            && stderr.contains("experiment `exp2`")
            && stderr.contains("another --out"),
        "{stderr}"
    );
    assert!(!stdout.contains("they are removed"), "{stdout}");
    assert_eq!(
        std::fs::read(dir.join("demoW/quick/results.jsonl")).unwrap(),
        before,
        "exp2's results are kept"
    );
    assert!(dir.join("demoW/quick/timing.jsonl").is_file());
    // Refused before anything was rendered.
    assert!(!dir.join("demoW/orbit-phantom-metaballs-64.png").exists());
}

#[test]
fn demo_keeps_its_own_results_and_waits_for_no_sweep_writing_into_its_folder() {
    let dir = scratch("locked");
    std::fs::create_dir_all(dir.join("empty")).unwrap();
    let demo = |dir: &Path| {
        vizsim(
            &[
                "demo",
                "--frames",
                "1",
                "--out",
                "demo",
                "--data-dir",
                "empty",
                "--threads",
                "1",
            ],
            dir,
        )
    };
    let first = demo(&dir);
    assert!(first.status.success(), "{}", text(&first).1);
    let results = dir.join("demo/quick/results.jsonl");
    let own = std::fs::read(&results).unwrap();
    // A sweep (of a newer version of the quick experiment) writing into the folder: it holds
    // the lock and has appended a run the demo does not know.
    let lock = vizsim::experiment::store::lock_folder(&dir.join("demo/quick")).unwrap();
    let mut line: serde_json::Value =
        serde_json::from_str(String::from_utf8_lossy(&own).lines().next().unwrap()).unwrap();
    line["key"] = "a-run-of-a-newer-version".into();
    let mut newer = own.clone();
    newer.extend_from_slice(format!("{line}\n").as_bytes());
    std::fs::write(&results, &newer).unwrap();
    let orbit = dir.join("demo/orbit-phantom-metaballs-64.png");
    std::fs::remove_file(&orbit).unwrap();
    let locked = demo(&dir);
    let (stdout, stderr) = text(&locked);
    assert!(!locked.status.success(), "{stdout}");
    assert!(
        stderr.contains("demo/quick") && stderr.contains("another sweep is writing"),
        "{stderr}"
    );
    assert!(!stdout.contains("they are removed"), "{stdout}");
    assert_eq!(
        std::fs::read(&results).unwrap(),
        newer,
        "the sweep's results"
    );
    assert!(!orbit.exists(), "refused before rendering");
    drop(lock);
    // Its own results, still valid, are kept by a re-run.
    std::fs::write(&results, &own).unwrap();
    let again = demo(&dir);
    let (stdout, stderr) = text(&again);
    assert!(again.status.success(), "{stderr}");
    assert!(!stdout.contains("they are removed"), "{stdout}");
    assert_eq!(std::fs::read(&results).unwrap(), own);
}

#[test]
fn demo_frames_are_bounded_and_a_file_as_out_is_refused_up_front() {
    let dir = scratch("frames");
    let out = vizsim(
        &[
            "demo",
            "--frames",
            "99999999",
            "--out",
            "demo",
            "--memory-budget",
            "512M",
        ],
        &dir,
    );
    let (_, stderr) = text(&out);
    assert!(!out.status.success());
    assert!(
        stderr.contains("--frames 99999999: at most 3600"),
        "{stderr}"
    );
    assert!(!dir.join("demo").exists(), "nothing made");

    std::fs::write(dir.join("a.png"), b"not a folder").unwrap();
    let start = std::time::Instant::now();
    let out = vizsim(&["demo", "--frames", "1", "--out", "a.png"], &dir);
    let (stdout, stderr) = text(&out);
    assert!(!out.status.success(), "{stdout}");
    assert!(
        stderr.contains("a.png: is a file, not a folder (--out names a folder)"),
        "{stderr}"
    );
    assert!(
        !stdout.contains("orbit"),
        "refused before rendering: {stdout}"
    );
    assert!(start.elapsed().as_secs() < 10);
    assert_eq!(std::fs::read(dir.join("a.png")).unwrap(), b"not a folder");
}
