//! Sweeps: expansion, validation before any run, resume after SIGKILL, torn lines, shards and
//! merge, tables. Small phantoms and images keep the file fast.

use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

use vizsim::experiment::spec::{expand, Model};

const BIN: &str = env!("CARGO_BIN_EXE_vizsim");

const TINY: &str = r#"
name = "ci-tiny"
datasets = ["phantom:metaballs:32", "phantom:shells:24"]
tf = ["zero", "class"]
modes = ["none", "ert+leap4", "ert+leap8+hier"]
models = ["step", "cycle"]
[frames]
orbit = 72
select = [0, 5, 11]
size = "24x24"
[axes]
"ray_queue.rays" = [8, 16]
"#;

fn temp_dir(name: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-sweep-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// `TINY` with the step model only (fast: for the merge and folder tests).
fn step_only() -> String {
    TINY.replace("models = [\"step\", \"cycle\"]", "models = [\"step\"]")
}

fn write_experiment(dir: &Path, text: &str) -> PathBuf {
    let path = dir.join("exp.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// Writes `text` as the experiment in `dir` and sweeps it into `dir/out`, which must succeed;
/// returns the experiment file and the results folder.
fn swept(dir: &Path, text: &str) -> (PathBuf, PathBuf) {
    let exp = write_experiment(dir, text);
    let out = dir.join("out");
    vizsim_ok(&[
        "sweep",
        exp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--quiet",
    ]);
    (exp, out)
}

fn vizsim(args: &[&str]) -> std::process::Output {
    Command::new(BIN).args(args).output().unwrap()
}

/// Runs vizsim and asserts it failed with `expected` in its standard error.
fn vizsim_fails(args: &[&str], expected: &str) {
    let out = vizsim(args);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "vizsim {args:?} succeeded");
    assert!(stderr.contains(expected), "vizsim {args:?}: {stderr}");
}

/// Runs vizsim and asserts it succeeded (its standard error in the message if not).
/// Runs vizsim, which must succeed; returns what it printed.
fn vizsim_ok(args: &[&str]) -> String {
    let out = vizsim(args);
    assert!(
        out.status.success(),
        "vizsim {args:?}: {}",
        String::from_utf8_lossy(&out.stderr)
    );
    String::from_utf8_lossy(&out.stdout).into_owned()
}

fn sorted_lines(path: &Path) -> Vec<String> {
    let mut lines: Vec<String> = std::fs::read_to_string(path)
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect();
    lines.sort();
    lines
}

#[test]
fn expansion_is_the_product_with_zip_and_exclusions() {
    let e = expand(TINY, "tiny", None).unwrap();
    // 2 datasets x 2 tf x 3 modes x 2 models x 2 rays x 3 frames
    assert_eq!(e.runs.len(), 2 * 2 * 3 * 2 * 2 * 3);
    let keys: std::collections::HashSet<_> = e.runs.iter().map(|r| r.key.clone()).collect();
    assert_eq!(keys.len(), e.runs.len(), "keys are distinct");
    assert_eq!(
        expand(TINY, "again", None).unwrap().runs[7].key,
        e.runs[7].key
    );
    assert!(e
        .runs
        .iter()
        .all(|r| r.run.hardware.ray_queue.rays == 8 || r.run.hardware.ray_queue.rays == 16));

    let zipped = TINY.replace(
        "\"ray_queue.rays\" = [8, 16]",
        "\"ray_queue.rays\" = [8, 16]\n\"skip.latency\" = [4, 8]",
    ) + "";
    let product = expand(&zipped, "z", None).unwrap().runs.len();
    assert_eq!(product, 2 * 2 * 3 * 2 * 4 * 3);
    let zipped = zipped.replace(
        "[frames]",
        "zip = [[\"ray_queue.rays\", \"skip.latency\"]]\n[frames]",
    );
    let e = expand(&zipped, "z", None).unwrap();
    assert_eq!(e.runs.len(), 2 * 2 * 3 * 2 * 2 * 3);
    assert!(e.runs.iter().all(
        |r| (r.run.hardware.ray_queue.rays, r.run.hardware.skip.latency) == (8, 4)
            || (r.run.hardware.ray_queue.rays, r.run.hardware.skip.latency) == (16, 8)
    ));

    let excluded = format!(
        "{TINY}\n[[exclude]]\nmodel = \"cycle\"\n\"ray_queue.rays\" = 8\n[[exclude]]\ndataset = \"phantom:shells:24\"\nmode = \"none\"\n"
    );
    let e = expand(&excluded, "x", None).unwrap();
    // 36 cycle runs with 8 rays, 24 shells none runs, 6 of them both.
    assert_eq!(e.runs.len(), 144 - 36 - 24 + 6);
    assert!(!e
        .runs
        .iter()
        .any(|r| r.run.model == Model::Cycle && r.run.hardware.ray_queue.rays == 8));
}

/// Exclude values that runs have are accepted however they are written: a mode's tokens in
/// another order, and the mode a sequence's `none` map renders (the mode without its map).
#[test]
fn excludes_that_match_runs_are_accepted() {
    let reordered = format!("{TINY}\n[[exclude]]\nmode = \"leap4+ert\"\n");
    let e = expand(&reordered, "r", None).unwrap();
    assert!(e.runs.iter().all(|r| r.run.hardware.occupancy.subcube != 4));
    let sequence = "name = \"dyn\"\ndatasets = [\"phantom:metaballs:32\"]\ntf = [\"class\"]\n\
        modes = [\"ert+leap8\"]\nmodels = [\"cycle\"]\n[frames]\norbit = 1\nsize = \"16x16\"\n\
        [sequence]\nsteps = 2\nmap = [\"update\", \"none\"]\n[[exclude]]\nmode = \"ert\"\n";
    let e = expand(sequence, "dyn", None).unwrap();
    assert_eq!(e.runs.len(), 2, "the runs without a map are excluded");
    assert!(e.runs.iter().all(|r| r.run.hardware.occupancy.subcube == 8));
    // Numbers match by value however they are written (a probe found `8.0` refused as
    // matching no run of an axis written 8).
    let float_exclude = format!("{TINY}\n[[exclude]]\n\"ray_queue.rays\" = 8.0\n");
    let e = expand(&float_exclude, "f", None).unwrap();
    assert!(!e.runs.is_empty());
    assert!(e.runs.iter().all(|r| r.run.hardware.ray_queue.rays == 16));
    let float_axis = TINY.replace(
        "\"ray_queue.rays\" = [8, 16]",
        "\"clock.step_time_ns\" = [12.5, 10.0]",
    ) + "\n[[exclude]]\n\"clock.step_time_ns\" = 10\n";
    let e = expand(&float_axis, "g", None).unwrap();
    assert!(!e.runs.is_empty());
    assert!(e
        .runs
        .iter()
        .all(|r| r.run.hardware.clock.step_time_ns == 12.5));
}

#[test]
fn bad_experiments_fail_before_any_run_naming_axis_and_value() {
    let dir = temp_dir("bad");
    for (edit, expect) in [
        (
            ("\"ray_queue.rays\" = [8, 16]", "\"ray_queue.raze\" = [8]"),
            "raze",
        ),
        (
            ("\"ray_queue.rays\" = [8, 16]", "\"ray_queue.rays\" = []"),
            "ray_queue.rays",
        ),
        (
            (
                "\"ray_queue.rays\" = [8, 16]",
                "\"ray_queue.rays\" = [8, 0]",
            ),
            "exp.toml: field `axes.\"ray_queue.rays\"`: value 0: 0 is out of range; allowed 1..=4096",
        ),
        (
            (
                "\"ray_queue.rays\" = [8, 16]",
                "\"skip.policy\" = [\"leap-only\", \"sooner\"]",
            ),
            "field `axes.\"skip.policy\"`: value \"sooner\": invalid configuration: unknown variant",
        ),
        (("phantom:shells:24", "no-such-dataset"), "no-such-dataset"),
        (("ert+leap4", "ert+leap5"), "leap5"),
        (("select = [0, 5, 11]", "select = [0, 72]"), "frame 72"),
        (
            (
                "\"ray_queue.rays\" = [8, 16]",
                "\"occupancy.subcube\" = [8]",
            ),
            "occupancy.subcube",
        ),
        // Issue 17: an empty zip group panicked; an empty [[exclude]] excluded everything.
        (
            ("name = \"ci-tiny\"", "name = \"ci-tiny\"\nzip = [[]]"),
            "a zip group is empty",
        ),
        (
            (
                "\"ray_queue.rays\" = [8, 16]",
                "\"ray_queue.rays\" = [8, 16]\n[[exclude]]",
            ),
            "empty [[exclude]]",
        ),
        // A probe (2026-12-02): values that match nothing or repeat were accepted silently,
        // and modes left out by the volume's size were blamed on `exclude`.
        (
            (
                "\"ray_queue.rays\" = [8, 16]",
                "\"ray_queue.rays\" = [8, 16]\n[[exclude]]\nmodel = \"fast\"",
            ),
            "`model = \"fast\"` matches no run",
        ),
        (
            (
                "\"ray_queue.rays\" = [8, 16]",
                "\"ray_queue.rays\" = [8, 16]\n[[exclude]]\n\"ray_queue.rays\" = 32",
            ),
            "matches no run",
        ),
        (
            ("\"none\", \"ert+leap4\"", "\"ert+ert\", \"ert+leap4\""),
            "`ert`: only one `ert` token per mode",
        ),
        (
            ("\"none\", \"ert+leap4\"", "\"ert+leap4+leap8\""),
            "`leap8`: only one `leap` token per mode",
        ),
        (
            (
                "[frames]",
                "zip = [[\"ray_queue.rays\", \"ray_queue.rays\"]]\n[frames]",
            ),
            "given twice in one zip group",
        ),
        (
            (
                "models = [\"step\", \"cycle\"]",
                "models = [\"step\"]\nsample = 0.1",
            ),
            "field `sample`",
        ),
        (
            (
                "modes = [\"none\", \"ert+leap4\", \"ert+leap8+hier\"]",
                "modes = [\"ert+leap64\"]",
            ),
            "field `modes`: no run is left",
        ),
    ] {
        let exp = write_experiment(&dir, &TINY.replace(edit.0, edit.1));
        let out = dir.join("out");
        let result = vizsim(&[
            "sweep",
            exp.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert!(!result.status.success(), "{edit:?} should fail");
        assert!(stderr.contains(expect), "{edit:?}: {stderr}");
        // The values came from the experiment file, not from `--set` on the preset (a probe
        // found axis errors blaming "configs/hardware/vizard2.toml with --set").
        assert!(!stderr.contains("--set"), "{edit:?}: {stderr}");
        assert!(!out.join("results.jsonl").exists(), "{edit:?}: nothing ran");
    }
    // A mistake in the base configuration is named with the experiment that points to it
    // (it named the hardware file alone).
    let typo = dir.join("hw-typo.toml");
    std::fs::write(
        &typo,
        vizsim::config::DEFAULT_TOML.replace("[skip]", "[skip]\nlatncy = 8"),
    )
    .unwrap();
    let exp = write_experiment(
        &dir,
        &TINY.replace(
            "name = \"ci-tiny\"",
            &format!("name = \"ci-tiny\"\nconfig = {:?}", typo.to_str().unwrap()),
        ),
    );
    vizsim_fails(
        &[
            "sweep",
            exp.to_str().unwrap(),
            "--out",
            dir.join("out").to_str().unwrap(),
        ],
        &format!(
            "exp.toml: field `config`: {}: invalid configuration: unknown field `latncy`",
            typo.display()
        ),
    );
    // A base configuration the experiment names is named with the value it was checked on.
    let based = TINY
        .replace(
            "name = \"ci-tiny\"",
            "name = \"ci-tiny\"\nconfig = \"configs/hardware/vizard2.toml\"",
        )
        .replace("\"ray_queue.rays\" = [8, 16]", "\"ray_queue.rays\" = [0]");
    let exp = write_experiment(&dir, &based);
    vizsim_fails(
        &[
            "sweep",
            exp.to_str().unwrap(),
            "--out",
            dir.join("out").to_str().unwrap(),
        ],
        "value 0: 0 is out of range; allowed 1..=4096 (with the base configuration \
         configs/hardware/vizard2.toml)",
    );
}

#[test]
fn a_killed_sweep_resumes_to_the_same_results() {
    let dir = temp_dir("kill");
    let exp = write_experiment(&dir, TINY);
    let (killed, whole) = (dir.join("killed"), dir.join("whole"));
    let args = |out: &Path| {
        vec![
            "--threads".to_string(),
            "2".into(),
            "sweep".into(),
            exp.display().to_string(),
            "--out".into(),
            out.display().to_string(),
            "--quiet".into(),
        ]
    };
    let mut child = Command::new(BIN)
        .args(args(&killed))
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let results = killed.join("results.jsonl");
    let start = Instant::now();
    loop {
        let n = std::fs::read_to_string(&results)
            .map(|t| t.lines().count())
            .unwrap_or(0);
        if n >= 3 || start.elapsed() > Duration::from_secs(60) {
            break;
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    child.kill().unwrap(); // SIGKILL
    child.wait().unwrap();
    let partial = std::fs::read_to_string(&results).unwrap().lines().count();
    assert!(
        (3..144).contains(&partial),
        "killed in the middle: {partial} of 144 results written"
    );
    // After a real kill the time of a result is written after the result: every timing line
    // is whole and belongs to a result, and at most the runs in flight (two threads) lack one.
    let result_keys: std::collections::HashSet<String> = std::fs::read_to_string(&results)
        .unwrap()
        .lines()
        .filter_map(|l| serde_json::from_str::<serde_json::Value>(l).ok())
        .map(|v| v["key"].as_str().unwrap().to_string())
        .collect();
    let timing_text = std::fs::read_to_string(killed.join("timing.jsonl")).unwrap();
    let timed: Vec<String> = timing_text
        .lines()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).expect("a whole timing line");
            v["key"].as_str().unwrap().to_string()
        })
        .collect();
    assert!(
        timed.iter().all(|k| result_keys.contains(k)),
        "a time without its result"
    );
    assert!(
        timed.len() + 2 >= result_keys.len(),
        "{} results, {} times",
        result_keys.len(),
        timed.len()
    );
    // Simulate a kill in the middle of a write too: half a line at the end.
    let mut text = std::fs::read_to_string(&results).unwrap();
    text.push_str("{\"key\":\"deadbeef\",\"dataset\":\"phan");
    std::fs::write(&results, text).unwrap();
    // A table of the folder now leaves the torn line out and says so (it was silent).
    let tables = dir.join("killed-tables");
    let table = vizsim(&[
        "table",
        killed.to_str().unwrap(),
        "--out",
        tables.to_str().unwrap(),
    ]);
    let said = String::from_utf8_lossy(&table.stderr);
    assert!(
        table.status.success() && said.contains("last line is incomplete"),
        "{said}"
    );
    // And a full disk that tore a timing line, after which appends went on, and a kill
    // between a result and its time (one result without a time).
    let timing = killed.join("timing.jsonl");
    let mut lines: Vec<String> = std::fs::read_to_string(&timing)
        .unwrap()
        .lines()
        .map(str::to_string)
        .collect();
    let lost = lines.remove(0);
    lines.insert(1, "{\"key\":\"0123\",\"wall_sec".into());
    std::fs::write(&timing, lines.join("\n") + "\n").unwrap();
    let killed_merge = dir.join("killed-merge");
    let merged = vizsim(&[
        "merge",
        killed.to_str().unwrap(),
        "--out",
        killed_merge.to_str().unwrap(),
    ]);
    assert!(merged.status.success(), "merge reads a torn timing file");
    // The torn result line is left out of the merge, and said (it was silent).
    let said = String::from_utf8_lossy(&merged.stderr);
    assert!(said.contains("last line is incomplete"), "{said}");

    let resumed = Command::new(BIN).args(args(&killed)).output().unwrap();
    assert!(resumed.status.success());
    assert!(String::from_utf8_lossy(&resumed.stderr).contains("torn"));
    let stdout = String::from_utf8_lossy(&resumed.stdout);
    assert!(stdout.contains("already done"), "{stdout}");
    let uninterrupted = Command::new(BIN).args(args(&whole)).output().unwrap();
    assert!(uninterrupted.status.success());
    let (a, b) = (
        sorted_lines(&results),
        sorted_lines(&whole.join("results.jsonl")),
    );
    assert_eq!(a.len(), 144);
    assert!(a == b, "resumed results equal the uninterrupted run");
    // One wall time per result; the lost one is null, the torn line is gone.
    let times = sorted_lines(&timing);
    assert_eq!(times.len(), 144);
    let lost_key = serde_json::from_str::<serde_json::Value>(&lost).unwrap()["key"].clone();
    let lost_now: Vec<&String> = times
        .iter()
        .filter(|t| serde_json::from_str::<serde_json::Value>(t).unwrap()["key"] == lost_key)
        .collect();
    assert_eq!(lost_now.len(), 1);
    assert!(
        lost_now[0].contains("\"wall_seconds\":null"),
        "{lost_now:?}"
    );

    // Running a finished sweep again runs nothing.
    let again = Command::new(BIN).args(args(&whole)).output().unwrap();
    assert!(String::from_utf8_lossy(&again.stdout).contains("ran 0 runs"));
    assert_eq!(sorted_lines(&whole.join("results.jsonl")).len(), 144);
}

/// A merge never destroys results already written: results already in the output folder are
/// merged in, and a folder a sweep is writing into is refused (the folder's lock, held here by
/// the test as a running sweep holds it).
#[test]
fn merge_keeps_the_results_it_would_replace() {
    let dir = temp_dir("merge-keeps");
    let exp = write_experiment(&dir, &step_only());
    let exp = exp.to_str().unwrap();
    let shard = |i: usize| {
        let d = dir.join(format!("shard{i}"));
        let r = vizsim(&[
            "sweep",
            exp,
            "--out",
            d.to_str().unwrap(),
            "--shard",
            &format!("{i}/2"),
        ]);
        assert!(r.status.success());
        d
    };
    let (a, b) = (shard(0), shard(1));
    let (a_, b_) = (a.to_str().unwrap(), b.to_str().unwrap());
    let mut both = sorted_lines(&a.join("results.jsonl"));
    both.extend(sorted_lines(&b.join("results.jsonl")));
    both.sort();
    let before = std::fs::read(a.join("results.jsonl")).unwrap();

    let lock = std::fs::File::create(a.join(".sweep.lock")).unwrap();
    lock.lock().unwrap();
    let locked = vizsim(&["merge", b_, "--out", a_]);
    assert!(
        !locked.status.success(),
        "merging into a folder a sweep is writing"
    );
    assert!(String::from_utf8_lossy(&locked.stderr).contains("another sweep is writing"));
    assert_eq!(std::fs::read(a.join("results.jsonl")).unwrap(), before);
    drop(lock);

    // Only b listed: a's own results are merged in, not replaced.
    let merged = vizsim(&["merge", b_, "--out", a_]);
    assert!(
        merged.status.success(),
        "{}",
        String::from_utf8_lossy(&merged.stderr)
    );
    assert_eq!(sorted_lines(&a.join("results.jsonl")), both);

    // A result in the output folder that differs from an input's is an error, and nothing is
    // written.
    // (b's first run, as the output folder holds it, with another step count)
    let of_b = sorted_lines(&b.join("results.jsonl")).remove(0);
    let changed = std::fs::read_to_string(a.join("results.jsonl"))
        .unwrap()
        .replacen(&of_b, &of_b.replacen("\"steps\":", "\"steps\":1", 1), 1);
    assert!(!changed.contains(&of_b));
    std::fs::write(a.join("results.jsonl"), &changed).unwrap();
    let differs = vizsim(&["merge", b_, "--out", a_]);
    assert!(!differs.status.success(), "a merged-in result differs");
    let stderr = String::from_utf8_lossy(&differs.stderr);
    assert!(stderr.contains("--out folder's earlier result"), "{stderr}");
    // It names the input the run was first read from, not "another input".
    assert!(
        stderr.contains(&format!("differs from the same run in {b_}")),
        "{stderr}"
    );
    // A file given as an input is said to be one.
    let file = a.join("results.jsonl");
    vizsim_fails(
        &["merge", file.to_str().unwrap(), "--out", b_],
        "is a file, not a sweep folder",
    );
    assert_eq!(
        std::fs::read_to_string(a.join("results.jsonl")).unwrap(),
        changed
    );
}

/// Inputs that would mislead are named, not merged or tabulated: a folder without results, the
/// results of another experiment, a misspelt table field, an experiment without a name. The
/// merged folder's description is no shard's.
#[test]
fn merge_and_table_refuse_what_would_mislead() {
    let dir = temp_dir("mislead");
    let one = step_only();
    let exp = write_experiment(&dir, &one);
    let shard = dir.join("shard0");
    let (exp_, shard_) = (exp.to_str().unwrap(), shard.to_str().unwrap());
    vizsim_ok(&["sweep", exp_, "--out", shard_, "--shard", "0/2"]);
    let merged = dir.join("merged");
    let merged_ = merged.to_str().unwrap();
    vizsim_ok(&["merge", shard_, "--out", merged_]);
    let resolved = |d: &Path| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(d.join("experiment.resolved.json")).unwrap())
            .unwrap()
    };
    assert!(resolved(&shard)["shard"].is_object());
    assert!(
        resolved(&merged)["shard"].is_null(),
        "the merged folder is no shard"
    );

    let empty = dir.join("empty");
    std::fs::create_dir_all(&empty).unwrap();
    vizsim_fails(
        &[
            "merge",
            empty.to_str().unwrap(),
            "--out",
            dir.join("m1").to_str().unwrap(),
        ],
        "not a sweep folder",
    );

    let other_exp = dir.join("other.toml");
    std::fs::write(
        &other_exp,
        one.replace("name = \"ci-tiny\"", "name = \"other\""),
    )
    .unwrap();
    let other = dir.join("other");
    vizsim_ok(&[
        "sweep",
        other_exp.to_str().unwrap(),
        "--out",
        other.to_str().unwrap(),
    ]);
    let m2 = dir.join("m2");
    vizsim_fails(
        &[
            "merge",
            shard_,
            other.to_str().unwrap(),
            "--out",
            m2.to_str().unwrap(),
        ],
        "experiment `other`",
    );
    assert!(!m2.exists(), "nothing written");

    vizsim_fails(
        &[
            "table",
            shard_,
            "--rows",
            "dataset,tff",
            "--out",
            dir.join("t").to_str().unwrap(),
        ],
        "`tff` is not a field",
    );
    // A dataset the results do not hold (a typo) is named, with those they hold.
    vizsim_fails(
        &[
            "table",
            shard_,
            "--dataset",
            "phantom:sphere:61",
            "--out",
            dir.join("t").to_str().unwrap(),
        ],
        "no results of --dataset phantom:sphere:61; the results hold phantom:",
    );

    // An --out that names a file is said to be one, for sweep and merge alike.
    let file = dir.join("afile");
    std::fs::write(&file, "").unwrap();
    let file_ = file.to_str().unwrap();
    vizsim_fails(&["sweep", exp_, "--out", file_], "is a file, not a folder");
    vizsim_fails(
        &["merge", shard_, "--out", file_],
        "is a file, not a folder",
    );

    let nameless = dir.join("nameless.toml");
    std::fs::write(&nameless, one.replace("name = \"ci-tiny\"", "name = \" \"")).unwrap();
    vizsim_fails(
        &[
            "sweep",
            nameless.to_str().unwrap(),
            "--out",
            dir.join("n").to_str().unwrap(),
        ],
        "is empty",
    );

    // The output folder's own results and description count as an input's: another
    // experiment's folder is refused as output too.
    let r = vizsim(&["merge", other.to_str().unwrap(), "--out", shard_]);
    assert!(
        !r.status.success(),
        "merged into another experiment's folder"
    );
    assert!(String::from_utf8_lossy(&r.stderr).contains("--out folder's earlier results"));
    // Listed first, the output folder's description is rewritten without its shard.
    vizsim_ok(&["merge", shard_, "--out", shard_]);
    assert!(
        resolved(&shard)["shard"].is_null(),
        "merged in place, still a shard"
    );
}

/// A table's title says what a cell holds: a mean over the frames, or one frame when the frame
/// is a row or the column (a probe found "mean over 3 frames" over a table of single frames);
/// `model` as a row or the column is refused, naming the option (it was dropped without a word:
/// each model has its own tables), and nothing is written.
#[test]
fn table_titles_say_what_a_cell_holds_and_model_is_no_row() {
    let dir = temp_dir("titles");
    let exp = write_experiment(&dir, &step_only());
    let runs = dir.join("runs");
    let runs_ = runs.to_str().unwrap();
    vizsim_ok(&["sweep", exp.to_str().unwrap(), "--out", runs_]);
    let title = |rows: &str, columns: &str| {
        let out = dir.join(format!("t-{columns}"));
        vizsim_ok(&[
            "table",
            runs_,
            "--metric",
            "steps",
            "--rows",
            rows,
            "--columns",
            columns,
            "--out",
            out.to_str().unwrap(),
        ]);
        let markdown = std::fs::read_to_string(out.join("step-steps.md")).unwrap();
        markdown.lines().next().unwrap().to_string()
    };
    let by_mode = title("dataset,tf,ray_queue.rays", "mode");
    assert!(by_mode.ends_with(", mean over 3 frames"), "{by_mode}");
    let by_frame = title("dataset,tf,mode,ray_queue.rays", "frame");
    assert!(by_frame.ends_with(", one frame per cell"), "{by_frame}");
    let frame_rows = title("dataset,tf,mode,frame", "ray_queue.rays");
    assert!(frame_rows.ends_with(", one frame per cell"), "{frame_rows}");

    for (rows, columns, option) in [
        ("dataset,model,tf,ray_queue.rays", "mode", "--rows"),
        ("dataset,tf,ray_queue.rays,mode", "model", "--columns"),
    ] {
        let out = dir.join("t-model");
        let result = vizsim(&[
            "table",
            runs_,
            "--rows",
            rows,
            "--columns",
            columns,
            "--out",
            out.to_str().unwrap(),
        ]);
        let stderr = String::from_utf8_lossy(&result.stderr);
        assert!(!result.status.success(), "{rows} / {columns} accepted");
        assert!(
            stderr.contains(&format!("{option}: `model` cannot be a row or the column")),
            "{rows} / {columns}: {stderr}"
        );
        assert!(!out.exists(), "{rows} / {columns} wrote {}", out.display());
    }
}

/// A table of step-model runs with `clock.step_time_ns` swept names each step time, not "the
/// published cost 12.5 ns" over cells computed at 5 ns; one at the preset's says published.
#[test]
fn step_model_tables_name_the_step_times_their_runs_used() {
    let dir = temp_dir("step-time");
    let experiment = r#"
name = "step-time"
datasets = ["phantom:sphere:16"]
tf = ["class"]
modes = ["ert"]
models = ["step"]
[frames]
orbit = 72
select = [0]
size = "8x8"
[axes]
"clock.step_time_ns" = [5.0, 12.5]
"#;
    let (_, runs) = swept(&dir, experiment);
    let title = |rows: &str| {
        let out = dir.join("tables");
        let _ = std::fs::remove_dir_all(&out);
        vizsim_ok(&[
            "table",
            runs.to_str().unwrap(),
            "--rows",
            rows,
            "--metric",
            "fps",
            "--out",
            out.to_str().unwrap(),
        ]);
        let markdown = std::fs::read_to_string(out.join("step-fps.md")).unwrap();
        markdown.lines().next().unwrap().to_string()
    };
    let both = title("dataset,clock.step_time_ns");
    assert!(
        both.contains("(step model, clock.step_time_ns per run: 5, 12.5 ns per step)"),
        "{both}"
    );
    assert!(!both.contains("published"), "{both}");
    let five = dir.join("five");
    std::fs::create_dir_all(&five).unwrap();
    let (_, runs) = swept(&five, &experiment.replace("[5.0, 12.5]", "[5.0]"));
    let out = five.join("tables");
    vizsim_ok(&[
        "table",
        runs.to_str().unwrap(),
        "--metric",
        "fps",
        "--out",
        out.to_str().unwrap(),
    ]);
    let markdown = std::fs::read_to_string(out.join("step-fps.md")).unwrap();
    assert!(
        markdown.starts_with(
            "### frame rate (fps) (step model, clock.step_time_ns = 5 ns per step, not the \
             published 12.5 ns)"
        ),
        "{markdown}"
    );
}

/// `--dataset` takes a dataset's alias as `sim` does: `vessel` picks the results of `aneurism`
/// (the tables label its rows "vessel (aneurism)"; it was refused as not in the results).
#[test]
fn results_filtered_by_a_dataset_alias_are_its_datasets() {
    let dir = temp_dir("alias");
    let experiment = r#"
name = "alias"
datasets = ["phantom:sphere:16", "phantom:shells:16"]
tf = ["class"]
modes = ["ert"]
models = ["step"]
[frames]
orbit = 72
select = [0]
size = "8x8"
"#;
    let (_, runs) = swept(&dir, experiment);
    // The sphere's results as an aneurism's (no 256³ volume needed to name one).
    let results = runs.join("results.jsonl");
    let text = std::fs::read_to_string(&results)
        .unwrap()
        .replace(
            "\"dataset_label\":\"phantom:sphere:16\"",
            "\"dataset_label\":\"vessel (aneurism)\"",
        )
        .replace("\"phantom:sphere:16\"", "\"aneurism\"");
    std::fs::write(&results, text).unwrap();
    let runs_ = runs.to_str().unwrap();
    let rows = |dataset: &str| {
        let out = dir.join(format!("t-{dataset}"));
        vizsim_ok(&[
            "table",
            runs_,
            "--dataset",
            dataset,
            "--metric",
            "steps",
            "--out",
            out.to_str().unwrap(),
        ]);
        let csv = std::fs::read_to_string(out.join("step-steps.csv")).unwrap();
        csv.lines().skip(1).map(str::to_string).collect::<Vec<_>>()
    };
    let by_alias = rows("vessel");
    assert_eq!(by_alias.len(), 1, "{by_alias:?}");
    assert!(
        by_alias[0].starts_with("vessel (aneurism),"),
        "{by_alias:?}"
    );
    assert_eq!(by_alias, rows("aneurism"));
    // Another alias is still a dataset the results do not hold.
    vizsim_fails(
        &["table", runs_, "--dataset", "skull"],
        "no results of --dataset skull; the results hold aneurism, phantom:shells:16",
    );
}

#[test]
fn shards_merge_to_the_unsharded_sweep() {
    let dir = temp_dir("shards");
    let exp = write_experiment(&dir, &step_only());
    let exp = exp.to_str().unwrap();
    let whole = dir.join("whole");
    assert!(vizsim(&["sweep", exp, "--out", whole.to_str().unwrap()])
        .status
        .success());
    let mut shard_dirs = Vec::new();
    for i in 0..3 {
        let d = dir.join(format!("shard{i}"));
        let shard = format!("{i}/3");
        let r = vizsim(&[
            "sweep",
            exp,
            "--out",
            d.to_str().unwrap(),
            "--shard",
            &shard,
        ]);
        assert!(r.status.success());
        let n = sorted_lines(&d.join("results.jsonl")).len();
        assert_eq!(n, 24, "shard {i} has a third of 72 runs");
        shard_dirs.push(d.display().to_string());
    }
    let merged = dir.join("merged");
    let mut args = vec!["merge".to_string()];
    args.extend(shard_dirs);
    args.extend(["--out".into(), merged.display().to_string()]);
    assert!(Command::new(BIN)
        .args(&args)
        .output()
        .unwrap()
        .status
        .success());
    let canonical = dir.join("canonical");
    assert!(vizsim(&[
        "merge",
        whole.to_str().unwrap(),
        "--out",
        canonical.to_str().unwrap()
    ])
    .status
    .success());
    assert_eq!(
        std::fs::read(merged.join("results.jsonl")).unwrap(),
        std::fs::read(canonical.join("results.jsonl")).unwrap()
    );
    // The shards' wall times come along: one per merged run, keyed like the results.
    let keys = |path: &Path| -> Vec<String> {
        let mut keys: Vec<String> = sorted_lines(path)
            .iter()
            .map(|l| serde_json::from_str::<serde_json::Value>(l).unwrap()["key"].to_string())
            .collect();
        keys.sort();
        keys
    };
    assert_eq!(
        keys(&merged.join("timing.jsonl")),
        keys(&merged.join("results.jsonl"))
    );
    assert!(!vizsim(&["sweep", exp, "--out", "x", "--shard", "3/3"])
        .status
        .success());

    // The table of the merged results: rows dataset x tf, columns the modes.
    let t = vizsim(&[
        "table",
        merged.to_str().unwrap(),
        "--rows",
        "dataset,tf,ray_queue.rays",
    ]);
    assert!(t.status.success(), "{}", String::from_utf8_lossy(&t.stderr));
    let md = std::fs::read_to_string(merged.join("tables/step-fps.md")).unwrap();
    assert!(md.contains("| none | 4³ | 8³+h |"), "{md}");
    assert_eq!(
        md.lines().filter(|l| l.starts_with("| phantom")).count(),
        2 * 2 * 2
    );
    // A swept field that is neither a row nor a column would be averaged away: an error.
    let t = vizsim(&["table", merged.to_str().unwrap()]);
    assert!(!t.status.success());
    assert!(String::from_utf8_lossy(&t.stderr).contains("ray_queue.rays"));
}

#[test]
fn a_second_sweep_into_a_busy_folder_is_refused() {
    let dir = temp_dir("lock");
    let exp = write_experiment(&dir, TINY);
    let out = dir.join("out");
    let held = vizsim::experiment::store::ResultStore::open(&out).unwrap();
    let r = vizsim(&[
        "sweep",
        exp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(!r.status.success());
    assert!(String::from_utf8_lossy(&r.stderr).contains("another sweep"));
    // Refused before the plan is printed: nothing on screen reads as a sweep that started.
    assert_eq!(String::from_utf8_lossy(&r.stdout), "");
    drop(held);
    let r = vizsim(&[
        "sweep",
        exp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--dry-run",
    ]);
    assert!(r.status.success());
}

#[test]
fn repeated_runs_are_listed_once_and_said_so() {
    let dir = temp_dir("dupes");
    let text = TINY
        .replace("select = [0, 5, 11]", "select = [0, 5, 5, 11]")
        .replace(
            "\"ray_queue.rays\" = [8, 16]",
            "\"ray_queue.rays\" = [8, 16, 16]",
        );
    let exp = write_experiment(&dir, &text);
    let once =
        vizsim::experiment::spec::load(&write_experiment(&temp_dir("dupes-once"), TINY), None)
            .unwrap();
    let twice = vizsim::experiment::spec::load(&exp, None).unwrap();
    assert!(twice.duplicates > 0);
    let keys = |e: &vizsim::experiment::spec::Expansion| {
        e.runs.iter().map(|r| r.key.clone()).collect::<Vec<_>>()
    };
    assert_eq!(keys(&once), keys(&twice), "the same runs, each once");
    let out = vizsim(&[
        "sweep",
        exp.to_str().unwrap(),
        "--out",
        dir.join("o").to_str().unwrap(),
        "--dry-run",
    ]);
    assert!(String::from_utf8_lossy(&out.stdout).contains("listed more than once"));
}

/// A folder holding one experiment's results refuses another experiment (its keys would mix
/// into the first one's tables), dry run or not, and keeps its results; the same experiment
/// resumes there (issue 17, item 12).
#[test]
fn another_experiment_into_a_used_folder_is_refused() {
    let dir = temp_dir("other-experiment");
    let small = |name: &str| {
        format!(
            "name = \"{name}\"\ndatasets = [\"phantom:sphere:16\"]\ntf = [\"zero\"]\n\
             modes = [\"none\"]\nmodels = [\"step\"]\n[frames]\norbit = 1\nsize = \"8x8\"\n"
        )
    };
    let first = dir.join("first.toml");
    let second = dir.join("second.toml");
    std::fs::write(&first, small("first")).unwrap();
    std::fs::write(&second, small("second")).unwrap();
    let out = dir.join("out");
    let out_arg = out.to_str().unwrap();
    let ok = vizsim(&[
        "sweep",
        first.to_str().unwrap(),
        "--out",
        out_arg,
        "--quiet",
    ]);
    assert!(
        ok.status.success(),
        "{}",
        String::from_utf8_lossy(&ok.stderr)
    );
    let results = sorted_lines(&out.join("results.jsonl"));
    assert_eq!(results.len(), 1);
    for extra in [&["--dry-run"][..], &["--quiet"][..]] {
        let mut args = vec!["sweep", second.to_str().unwrap(), "--out", out_arg];
        args.extend_from_slice(extra);
        let refused = vizsim(&args);
        let stderr = String::from_utf8_lossy(&refused.stderr);
        assert!(!refused.status.success(), "{extra:?}: accepted");
        assert!(
            stderr.contains("experiment `first`, not `second`"),
            "{extra:?}: {stderr}"
        );
    }
    assert_eq!(sorted_lines(&out.join("results.jsonl")), results);
    let again = vizsim(&[
        "sweep",
        first.to_str().unwrap(),
        "--out",
        out_arg,
        "--quiet",
    ]);
    assert!(again.status.success());
    assert_eq!(sorted_lines(&out.join("results.jsonl")), results);
    // Without a readable description the result lines still name their experiment (a
    // missing or garbled experiment.resolved.json let `second` resume `first`'s folder).
    let resolved = out.join("experiment.resolved.json");
    for garbled in [None, Some("{}"), Some("not json")] {
        match garbled {
            None => std::fs::remove_file(&resolved).unwrap(),
            Some(text) => std::fs::write(&resolved, text).unwrap(),
        }
        let refused = vizsim(&["sweep", second.to_str().unwrap(), "--out", out_arg]);
        let stderr = String::from_utf8_lossy(&refused.stderr);
        assert!(
            !refused.status.success() && stderr.contains("experiment `first`, not `second`"),
            "{garbled:?}: {stderr}"
        );
        assert_eq!(sorted_lines(&out.join("results.jsonl")), results);
    }
    // A description that names this experiment does not vouch for lines of another (a probe
    // put `second`'s resolved file beside `first`'s lines and `second` appended to them).
    std::fs::write(&resolved, r#"{"experiment": {"name": "second"}}"#).unwrap();
    let refused = vizsim(&["sweep", second.to_str().unwrap(), "--out", out_arg]);
    let stderr = String::from_utf8_lossy(&refused.stderr);
    assert!(
        !refused.status.success() && stderr.contains("experiment `first`, not `second`"),
        "{stderr}"
    );
    assert_eq!(sorted_lines(&out.join("results.jsonl")), results);
}

/// An experiment file edited between a sweep and its resume: runs it gained are added, but
/// results of runs it no longer has (a value or size changed) are refused, dry run or not,
/// naming one of them; before, they stayed beside the new runs and the tables mixed both.
#[test]
fn a_resume_after_the_experiment_lost_runs_is_refused() {
    let dir = temp_dir("edited-experiment");
    let text = |rays: &str, datasets: &str| {
        format!(
            "name = \"edited\"\ndatasets = [{datasets}]\ntf = [\"zero\"]\n\
             modes = [\"none\"]\nmodels = [\"step\"]\n[frames]\norbit = 1\nsize = \"8x8\"\n\
             [axes]\n\"ray_queue.rays\" = [{rays}]\n"
        )
    };
    let file = dir.join("e.toml");
    let out = dir.join("out");
    let sweep = |text: &str, extra: &[&str]| {
        std::fs::write(&file, text).unwrap();
        let mut args = vec![
            "sweep",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        vizsim(&args)
    };
    let sphere = "\"phantom:sphere:16\"";
    assert!(sweep(&text("8, 16", sphere), &["--quiet"]).status.success());
    let results = sorted_lines(&out.join("results.jsonl"));
    assert_eq!(results.len(), 2);
    for extra in [&["--dry-run"][..], &["--quiet"][..]] {
        let refused = sweep(&text("8, 32", sphere), extra);
        let stderr = String::from_utf8_lossy(&refused.stderr);
        assert!(
            !refused.status.success()
                && stderr.contains("1 of its 2 results are not runs of the experiment")
                && stderr.contains("ray_queue.rays = 16"),
            "{extra:?}: {stderr}"
        );
        assert_eq!(sorted_lines(&out.join("results.jsonl")), results);
    }
    // A dataset added keeps every result a run: the sweep adds the new ones.
    let grown = sweep(
        &text("8, 16", &format!("{sphere}, \"phantom:shells:16\"")),
        &["--quiet"],
    );
    assert!(
        grown.status.success(),
        "{}",
        String::from_utf8_lossy(&grown.stderr)
    );
    assert_eq!(sorted_lines(&out.join("results.jsonl")).len(), 4);
}

/// A run key twice in one results file with other figures (edited, or two files joined) is
/// refused by every reader, naming the file and both lines: before, a resumed sweep went on
/// silently and plot and advise used whichever line came last. The same line twice is read
/// once.
#[test]
fn a_run_twice_in_a_results_file_is_refused_by_every_reader() {
    let dir = temp_dir("run-twice");
    let (exp, out) = swept(&dir, &step_only());
    let (exp_, out_) = (exp.to_str().unwrap(), out.to_str().unwrap());
    let results = out.join("results.jsonl");
    let text = std::fs::read_to_string(&results).unwrap();
    let second = text
        .lines()
        .nth(1)
        .unwrap()
        .replace("\"steps\":", "\"steps\":1");
    std::fs::write(&results, format!("{text}{second}\n")).unwrap();
    let count = text.lines().count() + 1;
    let expected = format!("line {count} repeats run");
    vizsim_fails(&["sweep", exp_, "--out", out_, "--quiet"], &expected);
    vizsim_fails(&["sweep", exp_, "--out", out_, "--dry-run"], &expected);
    vizsim_fails(&["table", out_], &expected);
    vizsim_fails(&["plot", out_], &expected);
    vizsim_fails(
        &["merge", out_, "--out", dir.join("m").to_str().unwrap()],
        &expected,
    );
    vizsim_fails(&["advise", "--validate", out_], &expected);
    assert!(!dir.join("m").exists() && !out.join("tables").exists());
    // The same line twice: one run, one table cell's frame.
    let same = text.lines().nth(1).unwrap();
    std::fs::write(&results, format!("{text}{same}\n")).unwrap();
    vizsim_ok(&[
        "table",
        out_,
        "--rows",
        "dataset,tf,mode",
        "--columns",
        "ray_queue.rays",
    ]);
    vizsim_ok(&["merge", out_, "--out", dir.join("m").to_str().unwrap()]);
    assert_eq!(
        sorted_lines(&dir.join("m").join("results.jsonl")).len(),
        text.lines().count()
    );
}

#[test]
fn a_complete_last_line_that_is_no_result_is_refused_not_cut() {
    let dir = temp_dir("edited-last-line");
    let (exp, out) = swept(&dir, &step_only());
    let (exp_, out_) = (exp.to_str().unwrap(), out.to_str().unwrap());
    let results = out.join("results.jsonl");
    let text = std::fs::read_to_string(&results).unwrap();
    // A whole line a kill cannot write (it ends in a newline): a result without its key,
    // edited in by hand. Cutting it as torn lost what it held.
    let edited = text
        .lines()
        .next()
        .unwrap()
        .replacen("\"key\":", "\"kee\":", 1);
    let with_edit = format!("{text}{edited}\n");
    std::fs::write(&results, &with_edit).unwrap();
    let expected = format!("line {} is not a result line", text.lines().count() + 1);
    vizsim_fails(&["sweep", exp_, "--out", out_, "--quiet"], &expected);
    vizsim_fails(&["sweep", exp_, "--out", out_, "--dry-run"], &expected);
    vizsim_fails(&["table", out_], &expected);
    assert_eq!(std::fs::read_to_string(&results).unwrap(), with_edit);
    // A blank last line is still cut like a torn one, and the sweep goes on.
    std::fs::write(&results, format!("{text}\n")).unwrap();
    let said = vizsim(&["sweep", exp_, "--out", out_, "--quiet"]);
    assert!(
        said.status.success(),
        "{}",
        String::from_utf8_lossy(&said.stderr)
    );
    assert_eq!(std::fs::read_to_string(&results).unwrap(), text);
}

/// The highest resident memory of a running process so far (VmHWM), in KiB; None once it
/// has exited.
fn peak_kib(pid: u32) -> Option<u64> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let line = status.lines().find(|l| l.starts_with("VmHWM:"))?;
    line.split_whitespace().nth(1)?.parse().ok()
}

/// The dry run streams the runs instead of expanding them (issue 17, item 4): 100,000 runs
/// are counted within a 64 MiB budget that a real expansion of them (4 KiB each) is refused,
/// and the process stays small while it counts (the materialised expansion took about 160 MB).
#[test]
fn a_dry_run_streams_its_runs_in_bounded_memory() {
    let dir = temp_dir("stream");
    let values: Vec<String> = (1..=100).map(|v| v.to_string()).collect();
    let exp = write_experiment(
        &dir,
        &format!(
            "name = \"big\"\ndatasets = [\"phantom:sphere:8\"]\ntf = [\"zero\"]\n\
             modes = [\"none\"]\nmodels = [\"step\"]\n[frames]\norbit = 1000\nsize = \"4x4\"\n\
             [axes]\n\"ray_queue.rays\" = [{}]\n",
            values.join(", ")
        ),
    );
    let out = dir.join("out");
    let sweep = |dry: bool| {
        let mut cmd = Command::new(BIN);
        cmd.args([
            "sweep",
            exp.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ])
        .env("VIZSIM_MEMORY_BUDGET", "64M")
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
        if dry {
            cmd.arg("--dry-run");
        }
        cmd
    };
    let mut child = sweep(true).spawn().unwrap();
    let (pid, start) = (child.id(), Instant::now());
    let mut peak = 0;
    while child.try_wait().unwrap().is_none() {
        peak = peak.max(peak_kib(pid).unwrap_or(0));
        assert!(
            start.elapsed() < Duration::from_secs(60),
            "the dry run hung"
        );
        std::thread::sleep(Duration::from_millis(5));
    }
    let output = child.wait_with_output().unwrap();
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert!(
        stdout.contains("big: 100000 runs (100000 step model"),
        "{stdout}"
    );
    assert!(peak < 64 << 10, "the dry run peaked at {peak} KiB");
    let real = sweep(false).output().unwrap();
    let stderr = String::from_utf8_lossy(&real.stderr);
    assert!(!real.status.success());
    assert!(
        stderr.contains("expanding 100000 runs") && stderr.contains("budget of 64.0 MiB"),
        "{stderr}"
    );
    assert!(!out.exists(), "the refused sweep wrote its folder");
}

/// Files of a folder whose names are hidden temporaries of atomic writes.
fn temporaries(dir: &Path) -> Vec<String> {
    std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.starts_with('.') && n.contains(".tmp"))
                .collect()
        })
        .unwrap_or_default()
}

/// SIGKILL during `vizsim merge` (issue 17, "Tests that stay"): whenever the merge is killed,
/// the merged folder holds either no results or the complete merged results (never a torn
/// file), results never without their timings, and merging again gives exactly the bytes of
/// an uninterrupted merge, with the killed merges' temporaries cleaned away.
#[test]
fn a_killed_merge_leaves_nothing_torn_and_reruns_to_the_same_bytes() {
    const RUNS: usize = 30_000;
    let dir = temp_dir("merge-kill");
    // Three large synthetic shards (the merge must take long enough to be killed in it),
    // with a run present in two shards, as after a requeued task.
    let mut shards = Vec::new();
    for s in 0..3 {
        let shard = dir.join(format!("shard{s}"));
        std::fs::create_dir_all(&shard).unwrap();
        let (mut results, mut timing) = (String::new(), String::new());
        for i in (s..RUNS).step_by(3).chain([0]) {
            let key = format!("{:016x}", (i as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15));
            results.push_str(&format!(
                "{{\"key\":\"{key}\",\"experiment\":\"big\",\"model\":\"step\",\"mode\":\"none\",\"tf\":\"zero\",\"dataset\":\"d\",\"frame\":{i},\"steps\":1,\"fps\":{}.5,\"pad\":\"{}\"}}\n",
                i % 997,
                "x".repeat(120)
            ));
            timing.push_str(&format!("{{\"key\":\"{key}\",\"wall_seconds\":0.{i}}}\n"));
        }
        std::fs::write(shard.join("results.jsonl"), results).unwrap();
        std::fs::write(shard.join("timing.jsonl"), timing).unwrap();
        std::fs::write(
            shard.join("experiment.resolved.json"),
            "{\"experiment\":{\"name\":\"big\"}}\n",
        )
        .unwrap();
        shards.push(shard.display().to_string());
    }
    let merge = |out: &Path| {
        let mut cmd = Command::new(BIN);
        cmd.arg("merge")
            .args(&shards)
            .args(["--out", out.to_str().unwrap()])
            .stdout(Stdio::null())
            .stderr(Stdio::null());
        cmd
    };
    let reference = dir.join("reference");
    let start = Instant::now();
    assert!(merge(&reference).status().unwrap().success());
    let whole = start.elapsed();
    eprintln!("an uninterrupted merge of {RUNS} runs took {whole:?}");
    let read = |d: &Path, f: &str| std::fs::read(d.join(f)).ok();
    let expected: Vec<Option<Vec<u8>>> =
        ["results.jsonl", "timing.jsonl", "experiment.resolved.json"]
            .iter()
            .map(|f| read(&reference, f))
            .collect();
    assert_eq!(
        String::from_utf8_lossy(expected[0].as_ref().unwrap())
            .lines()
            .count(),
        RUNS
    );

    let out = dir.join("killed");
    let (mut before_results, mut complete) = (0, 0);
    for k in 0..8 {
        // Kills spread over the merge's whole duration.
        let delay = whole.mul_f64(k as f64 / 8.0);
        let mut child = merge(&out).spawn().unwrap();
        std::thread::sleep(delay);
        child.kill().unwrap();
        child.wait().unwrap();
        match read(&out, "results.jsonl") {
            None => before_results += 1,
            Some(bytes) => {
                assert!(
                    bytes == *expected[0].as_ref().unwrap(),
                    "kill {k}: torn results"
                );
                assert!(
                    read(&out, "timing.jsonl") == expected[1],
                    "kill {k}: results without their timings"
                );
                complete += 1;
            }
        }
        if let Some(bytes) = read(&out, "timing.jsonl") {
            assert!(
                bytes == *expected[1].as_ref().unwrap(),
                "kill {k}: torn timings"
            );
        }
    }
    assert!(
        before_results > 0,
        "no kill hit the merge before it wrote ({complete} complete)"
    );
    assert!(merge(&out).status().unwrap().success());
    for (f, want) in ["results.jsonl", "timing.jsonl", "experiment.resolved.json"]
        .iter()
        .zip(&expected)
    {
        assert!(read(&out, f) == *want, "{f} differs after the re-run");
    }
    assert_eq!(temporaries(&out), Vec::<String>::new(), "temporaries left");
}

/// Issue 17, items 8 and 12, each checked by its message: `12.5` and `12.50` are one axis
/// value (one run); an empty `[[exclude]]` is refused as such (it used to exclude every run);
/// when every run is left out for its sub-cube, the error says so instead of blaming
/// `exclude`.
#[test]
fn repeated_values_empty_exclusions_and_left_out_runs_are_named() {
    let base = "name = \"e\"\ndatasets = [\"phantom:sphere:8\"]\ntf = [\"zero\"]\n\
                modes = [\"none\"]\nmodels = [\"step\"]\n[frames]\norbit = 1\nsize = \"4x4\"\n";
    let e = expand(
        &format!("{base}[axes]\n\"clock.step_time_ns\" = [12.5, 12.50, 10.0]\n"),
        "floats.toml",
        None,
    )
    .unwrap();
    assert_eq!((e.runs.len(), e.duplicates), (2, 1));
    let message = |text: &str| match expand(text, "e.toml", None) {
        Ok(_) => panic!("accepted: {text}"),
        Err(err) => err.to_string(),
    };
    let empty = message(&format!("{base}[[exclude]]\n"));
    assert!(empty.contains("an empty [[exclude]] table"), "{empty}");
    let left_out = message(&base.replace("[\"none\"]", "[\"ert+leap16\"]"));
    assert!(
        left_out.contains("field `modes`")
            && left_out.contains("sub-cube larger than the volume")
            && !left_out.contains("excluded by"),
        "{left_out}"
    );
}

/// A hierarchy that groups nothing (the volume is one sub-cube along every axis) is left out
/// with its reason, as a sub-cube larger than the volume is; it ran silently, giving the
/// result of the map alone.
#[test]
fn a_hierarchy_that_groups_nothing_is_left_out_with_its_reason() {
    let text = "name = \"h\"\ndatasets = [\"phantom:sphere:32\", \"phantom:sphere:64\"]\n\
                tf = [\"zero\"]\nmodes = [\"ert+leap32\", \"ert+leap32+hier\", \"ert+leap64\"]\n\
                models = [\"step\"]\n[frames]\norbit = 1\nsize = \"4x4\"\n";
    let e = expand(text, "h.toml", None).unwrap();
    let ran: Vec<(String, String)> = e
        .runs
        .iter()
        .map(|r| (r.run.dataset.clone(), r.mode.name()))
        .collect();
    assert_eq!(
        ran,
        [
            ("phantom:sphere:32", "ert+leap32"),
            ("phantom:sphere:64", "ert+leap32"),
            ("phantom:sphere:64", "ert+leap32+hier"),
            ("phantom:sphere:64", "ert+leap64"),
        ]
        .map(|(d, m)| (d.to_string(), m.to_string()))
    );
    let hier = e
        .skipped
        .iter()
        .find(|s| s.mode == "ert+leap32+hier")
        .expect("listed as left out");
    assert_eq!(hier.dataset, "phantom:sphere:32");
    assert!(
        hier.reason
            .starts_with("the 2×2×2 group of 32³ sub-cubes is larger than the volume [32, 32, 32]"),
        "{}",
        hier.reason
    );
}

/// A cycle run without ERT, leaping, bricks, blocking or iso takes the timing of the same run
/// with another transfer function instead of simulating: its line must be the one simulating
/// writes. The same runs swept one transfer function at a time (nothing to reuse) must give
/// the same lines byte for byte.
#[test]
fn cycle_runs_that_differ_only_in_the_transfer_function_reuse_the_timing_exactly() {
    let dir = temp_dir("reuse");
    let text = |tf: &str| {
        format!(
            r#"
name = "ci-reuse"
datasets = ["phantom:metaballs:32"]
tf = {tf}
modes = ["none", "ert"]
models = ["cycle"]
[frames]
orbit = 72
select = [0, 7]
size = "24x24"
"#
        )
    };
    let (said, together) = sweep_in(&dir.join("both"), &text(r#"["zero", "class"]"#), "1");
    // One thread: the two 'none' frames of the transfer function swept second reuse; the 'ert'
    // runs never do.
    assert!(
        said.contains("2 cycle runs took the timing"),
        "the sweep says what it reused: {said}"
    );
    let mut separate = Vec::new();
    for tf in ["zero", "class"] {
        let (said, lines) = sweep_in(&dir.join(tf), &text(&format!(r#"["{tf}"]"#)), "2");
        assert!(!said.contains("took the timing"), "{said}");
        separate.extend(lines);
    }
    separate.sort();
    assert_eq!(separate.len(), 8);
    assert_eq!(together, separate);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Without ERT or leaping nothing reads a voxel value, so an exact cycle run on one dataset
/// times as the same run on another dataset of the same geometry: the sweep reuses it, and the
/// lines must be those of sweeping each dataset alone. A sampled run draws its sample by a
/// description that names the dataset, so it must not take another dataset's estimate.
#[test]
fn cycle_runs_on_datasets_of_one_geometry_reuse_the_timing_exactly_when_exact() {
    let dir = temp_dir("reuse-geometry");
    let text = |datasets: &str, sample: &str| {
        format!(
            r#"
name = "ci-reuse-geometry"
datasets = {datasets}
tf = ["class"]
modes = ["none", "ert"]
models = ["cycle"]
{sample}
[frames]
orbit = 72
select = [0, 7]
size = "24x24"
"#
        )
    };
    let both = r#"["phantom:metaballs:32", "phantom:sphere:32"]"#;
    for (sample, reused) in [("", 2), ("sample = 0.5", 0)] {
        let (said, together) =
            sweep_in(&dir.join(format!("both{reused}")), &text(both, sample), "1");
        // One thread: the 'none' frames of the dataset swept second reuse; 'ert' reads values.
        // The count as the line gives it ("  2 cycle runs"), or no such line at all.
        let expected = format!("  {reused} cycle runs took the timing");
        if reused > 0 {
            assert!(said.contains(&expected), "{sample}: {said}");
        } else {
            assert!(!said.contains("took the timing"), "{sample}: {said}");
        }
        let mut separate = Vec::new();
        for dataset in ["metaballs", "sphere"] {
            let one = format!(r#"["phantom:{dataset}:32"]"#);
            let (said, lines) = sweep_in(
                &dir.join(format!("{dataset}{reused}")),
                &text(&one, sample),
                "2",
            );
            assert!(!said.contains("took the timing"), "{said}");
            separate.extend(lines);
        }
        separate.sort();
        assert_eq!(separate.len(), 8);
        assert_eq!(together, separate, "{sample}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A resumed sweep reuses the timings of the cycle runs the folder already holds: here half of
/// the experiment is swept as shard 0 (no twin pair is inside it), then the whole experiment is
/// swept into the same folder, and each pending run's twin is a finished one. The lines must
/// be those of one uninterrupted sweep.
#[test]
fn a_resumed_sweep_reuses_the_timings_of_the_runs_it_holds() {
    let dir = temp_dir("reuse-resumed");
    let text = r#"
name = "ci-reuse-resumed"
datasets = ["phantom:metaballs:32"]
tf = ["zero", "class"]
modes = ["none"]
models = ["cycle"]
[frames]
orbit = 72
select = [0, 7, 14]
size = "24x24"
"#;
    let (said, whole) = sweep_in(&dir.join("whole"), text, "1");
    assert!(said.contains("3 cycle runs took the timing"), "{said}");
    let resumed = dir.join("resumed");
    std::fs::create_dir_all(&resumed).unwrap();
    let exp = resumed.join("exp.toml");
    std::fs::write(&exp, text).unwrap();
    let (exp_, out_) = (exp.to_str().unwrap(), resumed.join("out"));
    let out_ = out_.to_str().unwrap();
    let first = vizsim_ok(&[
        "--threads",
        "1",
        "sweep",
        exp_,
        "--out",
        out_,
        "--shard",
        "0/2",
    ]);
    assert!(
        !first.contains("took the timing"),
        "shard 0 holds no twin pair: {first}"
    );
    // The same half-done folder copied, its times marked as another model's (a folder swept by
    // an older vizsim): its lines keep their runs but lend their timings to no twin.
    let other = dir.join("other-model");
    std::fs::create_dir_all(&other).unwrap();
    for file in ["results.jsonl", "timing.jsonl", "experiment.resolved.json"] {
        std::fs::copy(resumed.join("out").join(file), other.join(file)).unwrap();
    }
    let timing = std::fs::read_to_string(other.join("timing.jsonl")).unwrap();
    assert_eq!(timing.matches("\"model\"").count(), 3, "{timing}");
    let marked: String = timing
        .lines()
        .map(|l| {
            let mut v: serde_json::Value = serde_json::from_str(l).unwrap();
            v["model"] = "an older model".into();
            format!("{v}\n")
        })
        .collect();
    std::fs::write(other.join("timing.jsonl"), marked).unwrap();
    let second = vizsim_ok(&["--threads", "1", "sweep", exp_, "--out", out_]);
    assert!(
        second.contains("3 were already done") && second.contains("  3 cycle runs took the timing"),
        "{second}"
    );
    assert_eq!(
        sorted_lines(&resumed.join("out").join("results.jsonl")),
        whole
    );
    let other_ = other.to_str().unwrap();
    let third = vizsim_ok(&["--threads", "1", "sweep", exp_, "--out", other_]);
    assert!(
        third.contains("3 were already done") && !third.contains("took the timing"),
        "{third}"
    );
    assert_eq!(sorted_lines(&other.join("results.jsonl")), whole);
    let _ = std::fs::remove_dir_all(&dir);
}

/// Sweeps the experiment `text` into `dir` (created) on `threads` threads: what it printed and
/// its result lines, sorted.
fn sweep_in(dir: &Path, text: &str, threads: &str) -> (String, Vec<String>) {
    std::fs::create_dir_all(dir).unwrap();
    let exp = dir.join("exp.toml");
    std::fs::write(&exp, text).unwrap();
    let out = dir.join("out");
    let r = vizsim(&[
        "sweep",
        exp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--threads",
        threads,
    ]);
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    (
        String::from_utf8_lossy(&r.stdout).into_owned(),
        sorted_lines(&out.join("results.jsonl")),
    )
}

/// A leaping structure that never leaps (an occupancy map with no empty sub-cube, or a
/// hierarchy with no empty group) times as the run without it: a sweep reuses the twin's
/// measurements, and the lines must be those of sweeping each mode alone (nothing to reuse),
/// byte for byte. On the 32³ metaballs phantom the 16³ map has no empty sub-cube, so the 8³
/// map has no empty group.
#[test]
fn cycle_runs_with_a_structure_that_never_leaps_reuse_the_timing_exactly() {
    let dir = temp_dir("reuse-inert");
    let modes = ["ert", "ert+leap8", "ert+leap8+hier", "ert+leap16"];
    let text = |modes: &[&str]| {
        format!(
            r#"
name = "ci-reuse-inert"
datasets = ["phantom:metaballs:32"]
tf = ["zero"]
modes = {modes:?}
models = ["cycle"]
[frames]
orbit = 72
select = [0, 7]
size = "24x24"
"#
        )
    };
    // One thread, the 'ert' group first (the longest estimate), then the leaping groups in
    // order: both frames of 16³ take the 'ert' timing, both of 8³ + hierarchy the 8³ one.
    let (said, together) = sweep_in(&dir.join("together"), &text(&modes), "1");
    assert!(
        said.contains("4 cycle runs took the timing"),
        "the sweep says what it reused: {said}"
    );
    let mut separate = Vec::new();
    for mode in modes {
        let (said, lines) = sweep_in(&dir.join(mode.replace('+', "-")), &text(&[mode]), "2");
        assert!(!said.contains("took the timing"), "{said}");
        separate.extend(lines);
    }
    separate.sort();
    assert_eq!(separate.len(), 8);
    assert_eq!(together, separate);
    // The reused lines keep the map's own figure: 0 % empty for 16³, none without a map.
    let skippable: Vec<Option<f64>> = together
        .iter()
        .map(|l| {
            let v: serde_json::Value = serde_json::from_str(l).unwrap();
            v["skippable_subcubes_percent"].as_f64()
        })
        .collect();
    assert_eq!(skippable.iter().filter(|s| s.is_none()).count(), 2);
    assert!(skippable.contains(&Some(0.0)));
    // And their own structure's memory: a 16³ map of 32³ is 8 bits, 8³ with the hierarchy
    // 64 (one byte per 2×2×2 group), none without a map.
    for l in &together {
        let v: serde_json::Value = serde_json::from_str(l).unwrap();
        let bits = v["structure_memory"]["map_sram_bits"].as_u64();
        let want = match v["mode"].as_str().unwrap() {
            "ert" => None,
            "ert+leap16" => Some(8),
            _ => Some(64),
        };
        assert_eq!(bits, want, "{l}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// Commands that write several files write all or none: a folder standing where one goes
/// fails the command and leaves none of the others (table, plot, advise --validate and merge
/// left the files written before it). An --out that cannot be made fails before the work.
#[test]
fn results_commands_write_all_their_files_or_none() {
    let dir = temp_dir("all-or-none");
    let (_, out) = swept(&dir, &step_only().replace("orbit = 72", "orbit = 12"));
    let out_ = out.to_str().unwrap();
    let files = |d: &Path| -> Vec<String> {
        let mut names: Vec<String> = std::fs::read_dir(d)
            .map(|e| {
                e.flatten()
                    .map(|e| e.file_name().to_string_lossy().into_owned())
                    .collect()
            })
            .unwrap_or_default();
        names.sort();
        names
    };
    let rows = ["--rows", "dataset,tf,mode", "--columns", "ray_queue.rays"];
    let tables = dir.join("tables");
    std::fs::create_dir_all(tables.join("step-steps.md")).unwrap();
    let mut args = vec!["table", out_, "--out", tables.to_str().unwrap()];
    args.extend(rows);
    vizsim_fails(&args, "step-steps.md");
    assert_eq!(files(&tables), ["step-steps.md"]);
    std::fs::remove_dir(tables.join("step-steps.md")).unwrap();
    vizsim_ok(&args);
    assert!(files(&tables).contains(&"step-steps.csv".to_string()));

    let plots = dir.join("plots");
    vizsim_ok(&["plot", out_, "--out", plots.to_str().unwrap()]);
    let charts = files(&plots);
    // The orbit's own step, not a 72-frame orbit's 5°.
    let per_frame = charts
        .iter()
        .find(|c| c.contains("per-frame") && c.ends_with(".svg"));
    let svg = std::fs::read_to_string(plots.join(per_frame.expect("a per-frame chart"))).unwrap();
    assert!(
        svg.contains("30° per frame for a 12-frame orbit"),
        "{svg:.300}"
    );
    let blocked = dir.join("plots2");
    std::fs::create_dir_all(blocked.join(charts.last().unwrap())).unwrap();
    let out2 = vizsim(&["plot", out_, "--out", blocked.to_str().unwrap()]);
    assert!(!out2.status.success());
    assert_eq!(files(&blocked), [charts.last().unwrap().clone()]);

    let merged = dir.join("merged");
    std::fs::create_dir_all(merged.join("experiment.resolved.json")).unwrap();
    vizsim_fails(
        &["merge", out_, "--out", merged.to_str().unwrap()],
        "is a folder",
    );
    assert!(!merged.join("timing.jsonl").exists() && !merged.join("results.jsonl").exists());

    let advice = dir.join("advice");
    std::fs::create_dir_all(advice.join("validation.json")).unwrap();
    let failed = vizsim(&[
        "advise",
        "--validate",
        out_,
        "--out",
        advice.to_str().unwrap(),
    ]);
    assert!(!failed.status.success());
    assert!(!advice.join("validation.md").exists() && !advice.join("validation.csv").exists());
    // An --out that cannot be made fails before any advice is computed.
    let failed = vizsim(&["advise", "--validate", out_, "--out", "/proc/vizsim-no"]);
    let stderr = String::from_utf8_lossy(&failed.stderr);
    assert!(
        !failed.status.success() && stderr.contains("--out /proc/vizsim-no"),
        "{stderr}"
    );
    assert!(!stderr.contains("advised"), "{stderr}");
}

/// Datasets whose names make one file name (`a/v`, `a-v`) get a chart each: the second is
/// numbered instead of overwriting the first.
#[test]
fn charts_of_datasets_with_one_file_name_are_all_kept() {
    let dir = temp_dir("chart-names");
    let lines: Vec<serde_json::Value> = ["d/a/v", "d/a-v"]
        .iter()
        .flat_map(|dataset| {
            (0..2).map(move |frame| {
                serde_json::json!({
                    "key": format!("{dataset}{frame}"), "model": "step", "dataset": dataset,
                    "tf": "zero", "mode": "none", "frame": frame, "view": format!("orbit:{frame}/8"),
                    "steps": 100 + frame, "fps": 1.0,
                })
            })
        })
        .collect();
    let written =
        vizsim::figures::write_all(&lines, &dir, &vizsim::figures::ChartKind::ALL).unwrap();
    let mut charts: Vec<String> = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".svg"))
        .collect();
    charts.sort();
    assert_eq!(written, 2);
    assert_eq!(charts.len(), 2, "{charts:?}");
    let svg = std::fs::read_to_string(dir.join(&charts[0])).unwrap();
    assert!(
        svg.contains("45° per frame for an 8-frame orbit"),
        "{svg:.300}"
    );
}

/// Figures edited into something that is no number, or so large that their mean overflows,
/// are refused by name rather than tabulated as missing or "inf".
#[test]
fn tables_refuse_figures_that_are_no_finite_number() {
    let dir = temp_dir("edited-figures");
    let (_, out) = swept(&dir, &step_only());
    let out_ = out.to_str().unwrap();
    let results = out.join("results.jsonl");
    let text = std::fs::read_to_string(&results).unwrap();
    let fps = text.replace("\"fps\":", "\"fps\":1.7e308,\"was\":");
    let table = [
        "table",
        out_,
        "--rows",
        "dataset,tf,mode",
        "--columns",
        "ray_queue.rays",
        "--metric",
        "fps",
    ];
    std::fs::write(&results, &fps).unwrap();
    vizsim_fails(&table, "is not finite");
    let first = text
        .lines()
        .next()
        .unwrap()
        .replacen("\"fps\":", "\"fps\":\"fast\",\"was\":", 1);
    let rest: String = text.lines().skip(1).map(|l| format!("{l}\n")).collect();
    std::fs::write(&results, format!("{first}\n{rest}")).unwrap();
    vizsim_fails(&table, "`fps` is \"fast\", not a number");
    vizsim_fails(&["plot", out_], "`fps` is \"fast\", not a number");
    std::fs::write(&results, &text).unwrap();
    vizsim_ok(&table);
}

/// Fields that must change together (a probe found them refused): a zipped pair is validated
/// as a pair, an invalid combination that an exclusion leaves out is not validated, one that
/// is left in is refused naming the combination, and a run the run path would refuse
/// (sampling with leap values) is refused before any run, not when it comes up.
#[test]
fn combinations_are_validated_as_they_run() {
    let one = |axes: &str| {
        format!(
            "name = \"coupled\"\ndatasets = [\"phantom:metaballs:32\"]\ntf = [\"class\"]\n\
             modes = [\"ert\"]\nmodels = [\"cycle\"]\n[frames]\norbit = 72\nselect = [0]\n\
             size = \"16x16\"\n{axes}"
        )
    };
    let zipped = one("[axes]\n\"sdram.cl\" = [2, 6]\n\"sdram.t_rtw\" = [4, 8]\n").replace(
        "[frames]",
        "zip = [[\"sdram.cl\", \"sdram.t_rtw\"]]\n[frames]",
    );
    let e = expand(&zipped, "zipped", None).unwrap();
    let pairs: Vec<(u32, u32)> = e
        .runs
        .iter()
        .map(|r| (r.run.hardware.sdram.cl, r.run.hardware.sdram.t_rtw))
        .collect();
    assert_eq!(pairs, [(2, 4), (6, 8)]);
    let crossed = one(
        "[axes]\n\"memory.address_fifo_depth\" = [4, 16]\n\"memory.overtaking_window\" = [4, 8]\n",
    );
    let refused = |text: &str| match expand(text, "t", None) {
        Ok(_) => panic!("accepted: {text}"),
        Err(e) => e.to_string(),
    };
    let err = refused(&crossed);
    assert!(
        err.contains("memory.address_fifo_depth=4, memory.overtaking_window=8")
            && err.contains("[[exclude]]"),
        "{err}"
    );
    let excluded = crossed
        + "[[exclude]]\n\"memory.address_fifo_depth\" = 4\n\"memory.overtaking_window\" = 8\n";
    assert_eq!(expand(&excluded, "excluded", None).unwrap().runs.len(), 3);
    // A value out of its own field's range is still refused by itself.
    let err = refused(&one("[axes]\n\"sdram.cl\" = [0]\n"));
    assert!(
        err.contains("axes.\"sdram.cl\"") && err.contains("value 0"),
        "{err}"
    );
    let sampled_leap_values = one("")
        .replace("modes = [\"ert\"]", "modes = [\"ert\", \"leapvalues\"]")
        .replace(
            "models = [\"cycle\"]",
            "models = [\"cycle\"]\nsample = 0.05",
        );
    let err = refused(&sampled_leap_values);
    assert!(
        err.contains("mode leapvalues") && err.contains("leap values"),
        "{err}"
    );
}

/// Shards swept from two versions of one experiment file are refused by merge (a probe merged
/// them, and the merged description named only the first version's values).
#[test]
fn merge_refuses_shards_of_two_versions_of_an_experiment() {
    let dir = temp_dir("merge-versions");
    let text = |rays: &str| {
        format!(
            "name = \"versions\"\ndatasets = [\"phantom:sphere:16\"]\ntf = [\"zero\"]\n\
             modes = [\"none\"]\nmodels = [\"step\"]\n[frames]\norbit = 2\nsize = \"8x8\"\n\
             [axes]\n\"ray_queue.rays\" = [{rays}]\n"
        )
    };
    let shard = |rays: &str, shard: &str, name: &str| {
        let file = dir.join(format!("{name}.toml"));
        // Shard "d" has another description: the same runs, so it merges.
        let described = if name == "d" {
            text(rays).replace("[frames]", "description = \"edited\"\n[frames]")
        } else {
            text(rays)
        };
        std::fs::write(&file, described).unwrap();
        let out = dir.join(name);
        vizsim_ok(&[
            "sweep",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--shard",
            shard,
            "--quiet",
        ]);
        out
    };
    let a = shard("8, 16", "0/2", "a");
    let b = shard("8, 16", "1/2", "b");
    let c = shard("8, 32", "1/2", "c");
    let arg = |p: &PathBuf| p.to_str().unwrap().to_string();
    vizsim_ok(&["merge", &arg(&a), &arg(&b), "--out", &arg(&dir.join("ab"))]);
    let d = shard("8, 16", "1/2", "d");
    vizsim_ok(&["merge", &arg(&a), &arg(&d), "--out", &arg(&dir.join("ad"))]);
    let merged = dir.join("ac");
    vizsim_fails(
        &["merge", &arg(&a), &arg(&c), "--out", &arg(&merged)],
        "different versions of experiment `versions`",
    );
    assert!(!merged.exists());
}

/// Folders swept with `--model step` and `--model cycle` from one experiment file are one
/// version of it: they merge into the full sweep's results (the review found them refused as
/// "different versions", each folder's description listing only its model's runs); a folder of
/// the other model from an edited file is still refused.
#[test]
fn merge_joins_folders_swept_with_different_models() {
    let dir = temp_dir("merge-models");
    let text = |rays: &str| {
        format!(
            "name = \"models\"\ndatasets = [\"phantom:sphere:16\"]\ntf = [\"zero\"]\n\
             modes = [\"none\"]\nmodels = [\"step\", \"cycle\"]\n[frames]\norbit = 2\n\
             size = \"8x8\"\n[axes]\n\"ray_queue.rays\" = [{rays}]\n"
        )
    };
    let arg = |p: &PathBuf| p.to_str().unwrap().to_string();
    let sweep = |rays: &str, name: &str, extra: &[&str]| {
        let file = dir.join(format!("{name}.toml"));
        std::fs::write(&file, text(rays)).unwrap();
        let out = dir.join(name);
        let mut args = vec![
            "sweep",
            file.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        args.push("--quiet");
        vizsim_ok(&args);
        out
    };
    let step = sweep("8, 16", "step", &["--model", "step"]);
    let cycle = sweep("8, 16", "cycle", &["--model", "cycle"]);
    let full = sweep("8, 16", "full", &[]);
    let merged = dir.join("merged");
    vizsim_ok(&["merge", &arg(&step), &arg(&cycle), "--out", &arg(&merged)]);
    let sorted = |d: &PathBuf| {
        let text = std::fs::read_to_string(d.join("results.jsonl")).unwrap();
        let mut lines: Vec<String> = text.lines().map(str::to_string).collect();
        lines.sort();
        lines
    };
    assert_eq!(sorted(&merged), sorted(&full));
    assert_eq!(sorted(&merged).len(), 8);
    let resolved = |d: &PathBuf| -> serde_json::Value {
        serde_json::from_str(&std::fs::read_to_string(d.join("experiment.resolved.json")).unwrap())
            .unwrap()
    };
    assert_eq!(resolved(&step)["model"], "step");
    assert!(resolved(&merged)["model"].is_null());
    assert_eq!(resolved(&merged)["runs"], resolved(&full)["runs"]);
    let edited = sweep("8, 32", "edited", &["--model", "cycle"]);
    vizsim_fails(
        &[
            "merge",
            &arg(&step),
            &arg(&edited),
            "--out",
            &arg(&dir.join("mixed")),
        ],
        "different versions of experiment `models`",
    );
}

/// `float_reference = true`: every line carries its own image against the float reference, as
/// `sim --json` gives it for the run, twins that reuse another run's timing included (their
/// image is their own: the lines equal those of sweeping each transfer function alone, where
/// nothing is reused); the keys differ from the runs without it; a sequence refuses it.
#[test]
fn lines_with_the_float_reference_carry_each_run_s_own_image_error() {
    let dir = temp_dir("float-reference");
    let text = |tf: &str, with: bool| {
        format!(
            r#"
name = "ci-float-reference"
datasets = ["phantom:metaballs:32"]
tf = {tf}
modes = ["none", "ert+leap4"]
models = ["step", "cycle"]
{}
[frames]
orbit = 72
select = [0, 7]
size = "24x24"
"#,
            if with { "float_reference = true" } else { "" }
        )
    };
    let (said, together) = sweep_in(&dir.join("both"), &text(r#"["zero", "class"]"#, true), "1");
    assert!(said.contains("took the timing"), "twins reuse: {said}");
    let mut separate = Vec::new();
    for tf in ["zero", "class"] {
        let (said, lines) = sweep_in(&dir.join(tf), &text(&format!(r#"["{tf}"]"#), true), "2");
        assert!(!said.contains("took the timing"), "{said}");
        separate.extend(lines);
    }
    separate.sort();
    assert_eq!(together, separate);
    let lines: Vec<serde_json::Value> = together
        .iter()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 16);
    // The line's figures are those `sim --json` reports for the run.
    let line = lines
        .iter()
        .find(|l| {
            l["model"] == "cycle" && l["tf"] == "zero" && l["mode"] == "none" && l["frame"] == 7
        })
        .unwrap();
    let json = dir.join("sim.json");
    vizsim_ok(&[
        "sim",
        "--dataset",
        "phantom:metaballs:32",
        "--tf",
        "zero",
        "--no-ert",
        "--view",
        "orbit:7/72",
        "--size",
        "24x24",
        "--json",
        json.to_str().unwrap(),
    ]);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    assert_eq!(report["cycles"], line["cycles"], "the same run");
    assert_eq!(line["float_reference"], report["float_reference"]);
    // The two transfer functions' images differ from their references differently.
    let of_tf = |tf: &str| {
        lines
            .iter()
            .find(|l| {
                l["model"] == "cycle" && l["tf"] == tf && l["mode"] == "none" && l["frame"] == 7
            })
            .unwrap()["float_reference"]
            .clone()
    };
    assert_ne!(of_tf("zero"), of_tf("class"));
    assert!(lines.iter().all(|l| l["float_reference"]["width"] == 24));
    // Without the option: the same runs under other keys, and no float_reference.
    let (_, without) = sweep_in(
        &dir.join("without"),
        &text(r#"["zero", "class"]"#, false),
        "2",
    );
    let keys = |lines: &[String]| -> std::collections::BTreeSet<String> {
        lines
            .iter()
            .map(|l| {
                serde_json::from_str::<serde_json::Value>(l).unwrap()["key"]
                    .as_str()
                    .unwrap()
                    .to_string()
            })
            .collect()
    };
    assert!(keys(&together).is_disjoint(&keys(&without)));
    assert!(without.iter().all(|l| !l.contains("float_reference")));
    // Tabulating the error of a folder without it says where it comes from.
    vizsim_fails(
        &[
            "table",
            dir.join("without/out").to_str().unwrap(),
            "--metric",
            "psnr",
        ],
        "come from experiments with float_reference = true",
    );
    let tables = dir.join("tables");
    vizsim_ok(&[
        "table",
        dir.join("both/out").to_str().unwrap(),
        "--metric",
        "psnr,image-error,pixels-off",
        "--out",
        tables.to_str().unwrap(),
    ]);
    let psnr = std::fs::read_to_string(tables.join("cycle-psnr.md")).unwrap();
    assert!(
        psnr.contains("PSNR against the float reference (dB) (cycle-accurate model's image)"),
        "{psnr}"
    );
    // The dry run's estimate counts the reference's frames.
    let estimate = |with: bool| {
        let e =
            vizsim::experiment::spec::expand(&text(r#"["zero"]"#, with), "e.toml", None).unwrap();
        vizsim::experiment::estimate_seconds(&e, &e.runs.iter().collect::<Vec<_>>(), 1)
    };
    assert!(
        estimate(true) > estimate(false) * 1.01,
        "{} {}",
        estimate(true),
        estimate(false)
    );
    // A sequence's steps have no reference.
    let sequence = text(r#"["class"]"#, true)
        .replace("phantom:metaballs:32", "phantom:metaballs:16")
        .replace(
            r#"modes = ["none", "ert+leap4"]"#,
            r#"modes = ["ert+leap4"]"#,
        )
        .replace(r#"models = ["step", "cycle"]"#, r#"models = ["cycle"]"#)
        + "[sequence]\nsteps = 2\n";
    let exp = write_experiment(&dir, &sequence);
    vizsim_fails(
        &[
            "sweep",
            exp.to_str().unwrap(),
            "--out",
            dir.join("seq").to_str().unwrap(),
            "--dry-run",
        ],
        "float_reference",
    );
    let _ = std::fs::remove_dir_all(&dir);
}

/// An experiment's `tf` list takes what `--tf` takes: a transfer-function file and a preset of
/// another dataset besides `zero` and `class`. A file with the dataset's own class function
/// gives the `class` runs' figures (a class map built from it), another preset other figures,
/// and a line equals `sim --json --tf FILE` of the same run.
#[test]
fn experiments_sweep_transfer_function_files_and_presets() {
    let dir = temp_dir("tf-files");
    let file = dir.join("own.toml");
    std::fs::copy(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/transfer/phantom-metaballs-class.toml"),
        &file,
    )
    .unwrap();
    let text = format!(
        r#"
name = "ci-tf-files"
datasets = ["phantom:metaballs:32"]
tf = ["class", "{}", "fuel-class"]
modes = ["ert+leap4"]
models = ["step", "cycle"]
[frames]
orbit = 72
select = [7]
size = "24x24"
"#,
        file.display()
    );
    let (_, lines) = sweep_in(&dir.join("sweep"), &text, "2");
    let lines: Vec<serde_json::Value> = lines
        .iter()
        .map(|l| serde_json::from_str(l).unwrap())
        .collect();
    assert_eq!(lines.len(), 6);
    let of = |tf: &str, model: &str| {
        lines
            .iter()
            .find(|l| l["tf"] == tf && l["model"] == model)
            .unwrap_or_else(|| panic!("no {model} line of tf {tf}"))
    };
    let own = file.to_str().unwrap();
    for (model, figures) in [
        ("step", &["steps", "samples", "leaps"][..]),
        ("cycle", &["steps", "samples", "leaps", "cycles"][..]),
    ] {
        for figure in figures {
            assert!(!of(own, model)[figure].is_null(), "{model} {figure}");
            assert_eq!(
                of(own, model)[figure],
                of("class", model)[figure],
                "{figure}"
            );
        }
        assert_ne!(
            of("fuel-class", model)["steps"],
            of("class", model)["steps"]
        );
    }
    let json = dir.join("sim.json");
    vizsim_ok(&[
        "sim",
        "--dataset",
        "phantom:metaballs:32",
        "--tf",
        own,
        "--subcube",
        "4",
        "--view",
        "orbit:7/72",
        "--size",
        "24x24",
        "--json",
        json.to_str().unwrap(),
    ]);
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    for figure in ["cycles", "steps", "row_hits"] {
        assert_eq!(report[figure], of(own, "cycle")[figure], "{figure}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A folder whose name is not UTF-8 (a file name in another encoding) is tabulated; the
/// provenance line under the table records it lossily (reading the command line as UTF-8
/// panicked).
#[test]
fn a_folder_name_that_is_not_utf8_is_tabulated() {
    use std::os::unix::ffi::OsStrExt;
    let dir = temp_dir("not-utf8");
    let (_, out) = swept(&dir, &step_only());
    let odd = dir.join(std::ffi::OsStr::from_bytes(b"w\xffo"));
    std::fs::rename(&out, &odd).unwrap();
    let r = Command::new(BIN)
        .arg("table")
        .arg(&odd)
        .args(["--rows", "dataset,tf,ray_queue.rays"])
        .arg("--out")
        .arg(dir.join("tables"))
        .output()
        .unwrap();
    assert!(r.status.success(), "{}", String::from_utf8_lossy(&r.stderr));
    let md = std::fs::read_to_string(dir.join("tables/step-steps.md")).unwrap();
    assert!(md.contains("Made by `vizsim table '"), "{md}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A sweep names the axes some of its runs do not read, and why (a review read flat lines
/// along `memory.overtaking_window` with overtaking off, and a cycle-only axis repeated on the
/// step model, as a design insensitive to them): the dry run and the sweep print it alike.
#[test]
fn a_sweep_names_the_axes_its_runs_do_not_read() {
    let dir = temp_dir("idle-axes");
    let text = TINY
        .replace(
            "modes = [\"none\", \"ert+leap4\", \"ert+leap8+hier\"]",
            "modes = [\"ert\"]",
        )
        .replace("tf = [\"zero\", \"class\"]", "tf = [\"class\"]")
        .replace("select = [0, 5, 11]", "select = [0]")
        + "\"memory.overtaking\" = [false]\n\"memory.overtaking_window\" = [2, 8]\n";
    let exp = write_experiment(&dir, &text);
    let out = dir.join("out");
    let plan = vizsim_ok(&[
        "sweep",
        exp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--dry-run",
    ]);
    // 2 datasets × 2 models × 2 rays × 2 windows = 16 runs; the step model's 8 read no queue.
    for expected in [
        "note: memory.overtaking_window is without effect in every one of its 16 runs \
         (memory.overtaking is false)",
        "note: ray_queue.rays is without effect in 8 of its 16 runs (the step model counts \
         steps, not cycles)",
    ] {
        assert!(plan.contains(expected), "{expected}: {plan}");
    }
    // An axis every run reads gets no note.
    let read = write_experiment(
        &dir,
        &TINY.replace("models = [\"step\", \"cycle\"]", "models = [\"cycle\"]"),
    );
    let plan = vizsim_ok(&[
        "sweep",
        read.to_str().unwrap(),
        "--out",
        dir.join("out2").to_str().unwrap(),
        "--dry-run",
    ]);
    assert!(!plan.contains("note:"), "{plan}");
}

/// A result line without a field every result has (an edited file) is an error naming the line
/// and the field, for `table`, `plot` and the sweep's resume alike: the resume counted it as
/// done, so the run was never redone, and the tables left it out without a word.
#[test]
fn a_result_line_without_its_figures_is_an_error_not_a_run_done() {
    let dir = temp_dir("missing-field");
    let (exp, out) = swept(&dir, &step_only());
    let results = out.join("results.jsonl");
    let good = std::fs::read_to_string(&results).unwrap();
    let (exp_, out_) = (exp.to_str().unwrap(), out.to_str().unwrap());
    let table = |to: &str| {
        [
            "table",
            out_,
            "--rows",
            "dataset,tf,mode",
            "--columns",
            "ray_queue.rays",
            "--out",
            dir.join(to).to_str().unwrap(),
        ]
        .map(str::to_string)
    };
    let table_t = table("t");
    let table_t: Vec<&str> = table_t.iter().map(String::as_str).collect();
    for (field, replacement, says) in [
        ("steps", None, "`steps` is missing"),
        ("fps", None, "`fps` is missing"),
        ("mode", None, "`mode` is missing"),
        (
            "steps",
            Some(serde_json::json!("many")),
            "`steps` is \"many\", not a number",
        ),
    ] {
        let mut lines: Vec<String> = good.lines().map(str::to_string).collect();
        let mut first: serde_json::Value = serde_json::from_str(&lines[1]).unwrap();
        let key = first["key"].as_str().unwrap().to_string();
        match &replacement {
            None => {
                first.as_object_mut().unwrap().remove(field);
            }
            Some(v) => first[field] = v.clone(),
        }
        lines[1] = first.to_string();
        std::fs::write(&results, lines.join("\n") + "\n").unwrap();
        let expected = format!("line 2, run {key}: {says}");
        vizsim_fails(&["sweep", exp_, "--out", out_, "--quiet"], &expected);
        vizsim_fails(&table_t, &expected);
        vizsim_fails(
            &["plot", out_, "--out", dir.join("p").to_str().unwrap()],
            &expected,
        );
        assert!(!dir.join("t").exists() && !dir.join("p").exists());
    }
    // The intact file reads.
    std::fs::write(&results, &good).unwrap();
    vizsim_ok(&table_t);
}

/// `--model` naming a model the experiment does not run is an error, and makes no folder (it
/// swept nothing and left an empty results file).
#[test]
fn a_model_the_experiment_does_not_run_is_refused() {
    let dir = temp_dir("absent-model");
    let exp = write_experiment(&dir, &step_only());
    let out = dir.join("out");
    vizsim_fails(
        &[
            "sweep",
            exp.to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
            "--model",
            "cycle",
        ],
        "--model cycle: ",
    );
    assert!(!out.exists());
    vizsim_ok(&[
        "sweep",
        exp.to_str().unwrap(),
        "--out",
        out.to_str().unwrap(),
        "--model",
        "step",
        "--quiet",
    ]);
}
