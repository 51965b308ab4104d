//! A run that fails during a sweep (after the experiment was validated) is named (file, key,
//! dataset, tf, mode, model, frame, axis values), the results written before it are kept, and
//! the folder resumes. Its own test binary: the sweep runs in this process and is resumed
//! right after it stopped, and a child process another test spawned at that moment would
//! still hold the folder's lock (a forked child keeps the lock's file until it execs).

use std::path::Path;

use vizsim::clip::DepthImage;
use vizsim::experiment::{self, spec};
use vizsim::run::Model;

#[test]
fn a_run_that_fails_during_the_sweep_is_named_and_earlier_results_are_kept() {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-sweep-stops-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let depth = dir.join("surface.depth");
    DepthImage {
        width: 8,
        height: 8,
        depth: vec![4.0; 64],
    }
    .write(&depth)
    .unwrap();
    // Two groups: without geometry and with the depth file; the file goes away after the
    // experiment was validated, so the second group fails when it is prepared.
    let text = format!(
        r#"name = "during"
datasets = ["phantom:sphere:16"]
tf = ["class"]
modes = ["none"]
models = ["step"]
[frames]
orbit = 8
size = "8x8"
[axes]
"geometry.shape" = ["none", "depth-file"]
"geometry.file" = ["{}"]
"#,
        depth.display()
    );
    let expansion = spec::expand(&text, "during.toml", None).expect("valid experiment");
    assert_eq!(expansion.runs.len(), 16);
    std::fs::remove_file(&depth).unwrap();
    // A folder name with a space: the hint quotes it, so that it can be pasted.
    let out = dir.join("out folder");
    // Swept with `--model step` (every run is one): the hint repeats it.
    let e = experiment::sweep(&expansion, &out, None, Some(Model::Step), false)
        .expect_err("the depth file is gone")
        .to_string();
    let failed = expansion
        .runs
        .iter()
        .find(|r| e.contains(&format!("run {} (", r.key)))
        .unwrap_or_else(|| panic!("no run named: {e}"));
    for needle in [
        "during.toml: run ",
        "phantom:sphere:16, tf class, mode none, step model, frame ",
        "8×8",
        r#"geometry.shape = "depth-file""#,
        "field `geometry.file`",
        "No such file",
        "the sweep stopped there",
        &format!(
            "sweep again into the same folder to run the rest: vizsim sweep during.toml --out '{}' --model step",
            out.display()
        ),
    ] {
        assert!(e.contains(needle), "lacks {needle:?}: {e}");
    }
    assert_eq!(failed.axes["geometry.shape"], "depth-file");
    // What the message says is kept is what the folder holds, and the folder resumes.
    let written = std::fs::read_to_string(out.join("results.jsonl"))
        .unwrap()
        .lines()
        .count();
    assert!(
        e.contains(&format!("keeps the {written} result")),
        "{written} lines written: {e}"
    );
    DepthImage {
        width: 8,
        height: 8,
        depth: vec![4.0; 64],
    }
    .write(&depth)
    .unwrap();
    let summary = experiment::sweep(&expansion, &out, None, None, false).unwrap();
    assert_eq!(summary.already_done, written);
    assert_eq!(summary.ran, 16 - written);
}
