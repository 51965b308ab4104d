//! A hostile-input corpus (issue 17, "Tests that stay"): small malformed, extreme or
//! non-regular inputs of every kind (hardware configurations, transfer functions, experiment
//! files, NRRD headers, raw files, dataset descriptors, camera paths, images, sweep results,
//! command-line numbers), made here in temporary folders and run through every command that
//! reads that kind. Each case must fail cleanly:
//!
//! - a non-zero exit that is not a panic (101) nor a signal, and no "panicked" on stderr;
//! - a message naming the file or the field (each case lists what stderr must contain);
//! - no output file left, under its name or as a hidden `.NAME.tmpPID` temporary;
//! - within a time bound (the process is killed after `TIMEOUT`: a hang fails the case) and
//!   within a small memory budget (`VIZSIM_MEMORY_BUDGET`).
//!
//! `tests/hostile.rs` holds the hand-written cases of the defects; this file is the
//! systematic sweep over input kinds × commands. Cases run on a few threads at once.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Mutex;
use std::time::{Duration, Instant};

const BIN: &str = env!("CARGO_BIN_EXE_vizsim");
/// Each case is an error path: a few hundred milliseconds at most; 20 s means a hang.
const TIMEOUT: Duration = Duration::from_secs(20);
/// Every case runs under this budget: a request sized by a hostile header is refused.
const BUDGET: &str = "256M";

/// One run of vizsim that must fail cleanly.
struct Case {
    what: String,
    args: Vec<String>,
    /// Each must appear on stderr (the file or the field the error is about).
    needles: Vec<String>,
    /// Must not exist afterwards (nor their hidden temporaries).
    outputs: Vec<PathBuf>,
    /// Working folder: also checked for temporaries left behind.
    dir: PathBuf,
}

struct Corpus {
    root: PathBuf,
    cases: Vec<Case>,
    n: usize,
}

impl Corpus {
    fn new(name: &str) -> Corpus {
        let root = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
            .join(format!("vizsim-corpus-{}-{name}", std::process::id()));
        let _ = std::fs::remove_dir_all(&root);
        std::fs::create_dir_all(&root).unwrap();
        Corpus {
            root,
            cases: Vec::new(),
            n: 0,
        }
    }

    /// A fresh folder for one case.
    fn dir(&mut self) -> PathBuf {
        self.n += 1;
        let dir = self.root.join(format!("c{}", self.n));
        std::fs::create_dir_all(&dir).unwrap();
        dir
    }

    fn add(&mut self, what: String, dir: PathBuf, args: Vec<String>, needles: &[&str]) {
        // Every output option a command has points into the case's folder.
        let mut outputs = Vec::new();
        for (i, a) in args.iter().enumerate() {
            if [
                "-o", "--output", "--json", "--out", "--rays", "--diff", "--vcd",
            ]
            .contains(&a.as_str())
            {
                // An output that exists before the run (a sweep folder given as input) is
                // not one the run may not leave.
                if let Some(p) = args.get(i + 1).map(|p| dir.join(p)) {
                    if std::fs::symlink_metadata(&p).is_err() {
                        outputs.push(p);
                    }
                }
            }
        }
        self.cases.push(Case {
            what,
            args,
            needles: needles.iter().map(|s| s.to_string()).collect(),
            outputs,
            dir,
        });
    }
}

fn s(x: &Path) -> String {
    x.display().to_string()
}

fn mkfifo(path: &Path) {
    let ok = Command::new("mkfifo").arg(path).status();
    assert!(
        matches!(ok, Ok(st) if st.success()),
        "mkfifo {}",
        path.display()
    );
}

/// A file input given to a command: what it is and how to make it in a folder.
#[derive(Clone, Copy)]
enum Input {
    /// Text written as the file.
    Text(&'static str),
    /// Bytes written as the file.
    Bytes(&'static [u8]),
    Fifo,
    /// A symlink to /dev/zero (endless input).
    Zero,
    /// A folder in the file's place.
    Folder,
    /// No file at all.
    Missing,
    /// A symlink to itself (ELOOP).
    LinkLoop,
}

impl Input {
    /// Makes the input at `path`.
    fn make(self, path: &Path) {
        match self {
            Input::Text(t) => std::fs::write(path, t).unwrap(),
            Input::Bytes(b) => std::fs::write(path, b).unwrap(),
            Input::Fifo => mkfifo(path),
            Input::Zero => std::os::unix::fs::symlink("/dev/zero", path).unwrap(),
            Input::Folder => std::fs::create_dir_all(path).unwrap(),
            Input::Missing => {}
            Input::LinkLoop => std::os::unix::fs::symlink(path, path).unwrap(),
        }
    }

    fn label(self) -> String {
        match self {
            Input::Text(t) => format!("text {:?}", t.chars().take(40).collect::<String>()),
            Input::Bytes(b) => format!("{} bytes", b.len()),
            Input::Fifo => "a FIFO".into(),
            Input::Zero => "/dev/zero".into(),
            Input::Folder => "a folder".into(),
            Input::Missing => "a missing file".into(),
            Input::LinkLoop => "a symlink loop".into(),
        }
    }
}

/// Inputs that are not regular files, or not there: every file input must refuse them.
const NOT_FILES: [Input; 5] = [
    Input::Fifo,
    Input::Zero,
    Input::Folder,
    Input::Missing,
    Input::LinkLoop,
];

/// Content that is no TOML, or TOML of the wrong shape: every TOML input must refuse it.
const BAD_TOML: [Input; 7] = [
    Input::Text(""),
    Input::Text("this is [not toml"),
    Input::Bytes(b"\xff\xfe\x00binary\x00\x01\x02"),
    Input::Text("x = 1\nx = 2\n"),
    Input::Text("[a]\nb = [[[[[[[[[[[[[[[[[[[[[[[[[[[[[[1]]]]]]]]]]]]]]]]]]]]]]]]]]]]]\n"),
    Input::Text("name = \"\\ud800\"\n"),
    Input::Text(
        "[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[[",
    ),
];

/// The preset configuration with one field replaced (or a section broken): values of the
/// right name but the wrong type or range.
fn config_mutations() -> Vec<(String, String, &'static str)> {
    let preset = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("configs/hardware/vizard2.toml"),
    )
    .unwrap();
    let replace = |from: &str, to: &str| {
        assert!(preset.contains(from), "the preset has no `{from}`");
        preset.replacen(from, to, 1)
    };
    let mut out = Vec::new();
    // (mutated file, what, the field the message must name)
    for (field, line) in field_lines(&preset) {
        for bad in [
            "-1",
            "nan",
            "inf",
            "1e308",
            "18446744073709551616",
            "\"x\"",
            "[]",
            "{}",
        ] {
            let key = field.rsplit('.').next().unwrap().to_string();
            out.push((
                replace(&line, &format!("{key} = {bad}")),
                format!("{field} = {bad}"),
                "",
            ));
        }
    }
    out.push((
        format!("{preset}\n[bogus]\nx = 1\n"),
        "an unknown section".into(),
        "bogus",
    ));
    out
}

/// Numeric `key = value` lines of the preset and their dotted field names (a sample: every
/// third, to keep the corpus small).
fn field_lines(preset: &str) -> Vec<(String, String)> {
    let mut section = String::new();
    let mut out = Vec::new();
    for line in preset.lines() {
        let t = line.trim();
        if t.starts_with('[') {
            section = t[1..t.find(']').unwrap_or(t.len())].to_string();
        } else if let Some((k, v)) = t.split_once('=') {
            let v = v.split('#').next().unwrap().trim();
            if v.parse::<f64>().is_ok() && !section.is_empty() {
                out.push((format!("{section}.{}", k.trim()), t.to_string()));
            }
        }
    }
    out.into_iter().step_by(3).collect()
}

/// Runs one case; returns a failure description, or None when it failed cleanly.
fn run_case(case: &Case) -> Option<String> {
    let mut child = Command::new(BIN)
        .args(&case.args)
        .current_dir(&case.dir)
        .env("VIZSIM_MEMORY_BUDGET", BUDGET)
        .env_remove("VIZSIM_DATA")
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run vizsim");
    // Read stderr on the side: a chatty process must not block on a full pipe.
    let mut pipe = child.stderr.take().unwrap();
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        let _ = pipe.read_to_string(&mut text);
        text
    });
    let start = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().unwrap() {
            break status;
        }
        if start.elapsed() > TIMEOUT {
            let _ = child.kill();
            let _ = child.wait();
            return Some(format!("hung (killed after {TIMEOUT:?})"));
        }
        std::thread::sleep(Duration::from_millis(5));
    };
    let stderr = reader.join().unwrap();
    let excerpt: String = stderr.chars().take(600).collect();
    let Some(code) = status.code() else {
        return Some(format!("killed by a signal ({status}): {excerpt}"));
    };
    if code == 0 {
        return Some("succeeded".into());
    }
    if code == 101 || stderr.contains("panicked") {
        return Some(format!("panicked: {excerpt}"));
    }
    for n in &case.needles {
        if !stderr.contains(n.as_str()) {
            return Some(format!("stderr lacks {n:?}: {excerpt}"));
        }
    }
    for out in &case.outputs {
        // An output that was a FIFO or device before the run is not "left behind".
        if std::fs::symlink_metadata(out).is_ok_and(|m| m.is_file() || m.is_dir()) {
            return Some(format!("left {}", out.display()));
        }
    }
    let mut stack = vec![case.dir.clone()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).into_iter().flatten().flatten() {
            let name = e.file_name().to_string_lossy().into_owned();
            if name.starts_with('.') && name.contains(".tmp") {
                return Some(format!("left the temporary {}", e.path().display()));
            }
            if e.file_type().is_ok_and(|t| t.is_dir()) {
                stack.push(e.path());
            }
        }
    }
    None
}

/// Runs the cases on a few threads and fails with every failure listed.
fn run_all(corpus: Corpus, min_cases: usize) {
    assert!(
        corpus.cases.len() >= min_cases,
        "only {} cases",
        corpus.cases.len()
    );
    let next = AtomicUsize::new(0);
    let failures = Mutex::new(Vec::new());
    let threads = std::thread::available_parallelism().map_or(2, |n| n.get().clamp(2, 4));
    std::thread::scope(|scope| {
        for _ in 0..threads {
            scope.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(case) = corpus.cases.get(i) else {
                    break;
                };
                if let Some(why) = run_case(case) {
                    failures.lock().unwrap().push(format!(
                        "{}\n    vizsim {}\n    {why}",
                        case.what,
                        case.args.join(" ")
                    ));
                }
            });
        }
    });
    let failures = failures.into_inner().unwrap();
    assert!(
        failures.is_empty(),
        "{} of {} cases failed:\n{}",
        failures.len(),
        corpus.cases.len(),
        failures.join("\n")
    );
    let _ = std::fs::remove_dir_all(&corpus.root);
}

/// Commands that read a hardware configuration (`--config FILE`), with their outputs in `dir`.
fn config_commands(dir: &Path, config: &Path) -> Vec<Vec<String>> {
    let c = s(config);
    let o = |n: &str| s(&dir.join(n));
    let frame = ["--dataset", "phantom:sphere:8", "--size", "8x8"];
    let mut out = Vec::new();
    let with = |mut v: Vec<String>| {
        v.extend(["--config".to_string(), c.clone()]);
        v
    };
    let base = |cmd: &str, extra: &[&str]| -> Vec<String> {
        std::iter::once(cmd)
            .chain(extra.iter().copied())
            .map(str::to_string)
            .collect()
    };
    let mut render = base("render", &frame);
    render.extend(["--model", "fixed", "-o"].map(String::from));
    render.push(o("x.png"));
    out.push(with(render));
    let mut sim = base("sim", &frame);
    sim.extend(["-o".into(), o("s.png"), "--json".into(), o("s.json")]);
    out.push(with(sim));
    let mut precision = base("precision", &frame);
    precision.extend(["--out".into(), o("prec")]);
    out.push(with(precision));
    out.push(with(base("occupancy", &["phantom:sphere:8"])));
    out.push(with(base(
        "update",
        &["phantom:sphere:8", "--subcube", "4"],
    )));
    out.push(with(base(
        "sequence",
        &[
            "--source",
            "phantom:metaballs:8",
            "--steps",
            "2",
            "--size",
            "8x8",
            "--subcube",
            "4",
        ],
    )));
    out
}

/// Commands that read a transfer function (`--tf FILE`).
fn tf_commands(dir: &Path, tf: &Path) -> Vec<Vec<String>> {
    let t = s(tf);
    let o = |n: &str| s(&dir.join(n));
    let v = |a: &[&str]| a.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    vec![
        v(&[
            "render",
            "--dataset",
            "phantom:sphere:8",
            "--size",
            "8x8",
            "--tf",
            &t,
            "-o",
            &o("x.png"),
        ]),
        v(&[
            "sim",
            "--dataset",
            "phantom:sphere:8",
            "--size",
            "8x8",
            "--tf",
            &t,
            "--json",
            &o("s.json"),
        ]),
        v(&[
            "precision",
            "--dataset",
            "phantom:sphere:8",
            "--size",
            "8x8",
            "--tf",
            &t,
            "--out",
            &o("p"),
        ]),
        v(&["occupancy", "phantom:sphere:8", "--tf", &t]),
        v(&["update", "phantom:sphere:8", "--tf", &t, "--subcube", "4"]),
        v(&[
            "sequence",
            "--source",
            "phantom:metaballs:8",
            "--steps",
            "2",
            "--size",
            "8x8",
            "--tf",
            &t,
            "--subcube",
            "4",
        ]),
    ]
}

/// A valid transfer function in `dir`: volume cases must fail on the volume, not on a dataset
/// without a preset.
fn valid_tf(dir: &Path) -> String {
    let path = dir.join("tf.toml");
    if !path.exists() {
        std::fs::copy(
            Path::new(env!("CARGO_MANIFEST_DIR"))
                .join("configs/transfer/phantom-sphere-class.toml"),
            &path,
        )
        .unwrap();
    }
    s(&path)
}

/// Commands that read a volume file (`FILE` as the dataset).
fn volume_commands(dir: &Path, volume: &Path) -> Vec<Vec<String>> {
    let f = s(volume);
    let o = |n: &str| s(&dir.join(n));
    let tf = if dir.exists() {
        valid_tf(dir)
    } else {
        String::new()
    };
    let v = |a: &[&str]| a.iter().map(|x| x.to_string()).collect::<Vec<_>>();
    vec![
        v(&["info", &f]),
        v(&[
            "render",
            "--dataset",
            &f,
            "--size",
            "8x8",
            "-o",
            &o("x.png"),
            "--tf",
            &tf,
        ]),
        v(&[
            "sim",
            "--dataset",
            &f,
            "--size",
            "8x8",
            "--tf",
            &tf,
            "-o",
            &o("s.png"),
        ]),
        v(&["occupancy", &f, "--tf", &tf]),
        v(&["update", &f, "--tf", &tf, "--subcube", "4"]),
        v(&[
            "precision",
            "--dataset",
            &f,
            "--size",
            "8x8",
            "--tf",
            &tf,
            "--out",
            &o("p"),
        ]),
    ]
}

/// Runs every command of a kind on every hostile input of that kind.
fn cross(
    corpus: &mut Corpus,
    kind: &str,
    file_name: &str,
    inputs: &[(Input, &str)],
    commands: fn(&Path, &Path) -> Vec<Vec<String>>,
) {
    for &(input, needle) in inputs {
        let probe = corpus.root.join("probe");
        let count = commands(&probe, &probe.join(file_name)).len();
        for i in 0..count {
            let dir = corpus.dir();
            let path = dir.join(file_name);
            input.make(&path);
            let args = commands(&dir, &path).swap_remove(i);
            let needle = if needle.is_empty() { file_name } else { needle };
            corpus.add(
                format!("{kind} {}: {}", input.label(), args[0]),
                dir,
                args,
                &[needle],
            );
        }
    }
}

#[test]
fn hostile_configurations_transfer_functions_and_camera_paths() {
    let mut corpus = Corpus::new("config");
    let not_files: Vec<(Input, &str)> = NOT_FILES.iter().map(|&i| (i, "")).collect();
    let bad_toml: Vec<(Input, &str)> = BAD_TOML.iter().map(|&i| (i, "")).collect();
    cross(
        &mut corpus,
        "config",
        "hw.toml",
        &not_files,
        config_commands,
    );
    cross(&mut corpus, "config", "hw.toml", &bad_toml, config_commands);
    // Wrong types and ranges in the preset, through the commands that differ in how they use
    // it (render validates, sim runs the cycle model).
    for (text, what, needle) in config_mutations() {
        for cmd in [0, 1] {
            let dir = corpus.dir();
            let path = dir.join("hw.toml");
            std::fs::write(&path, &text).unwrap();
            let args = config_commands(&dir, &path).swap_remove(cmd);
            let field = what.split(' ').next().unwrap().to_string();
            let needles: Vec<&str> = if needle.is_empty() {
                vec!["hw.toml", field.rsplit('.').next().unwrap()]
            } else {
                vec!["hw.toml", needle]
            };
            let needles: Vec<String> = needles.iter().map(|s| s.to_string()).collect();
            let refs: Vec<&str> = needles.iter().map(String::as_str).collect();
            corpus.add(format!("config {what}"), dir, args, &refs);
        }
    }

    // Transfer functions: a file argument that is no regular file is not read as one (it
    // is then no preset either: the message names the argument).
    cross(&mut corpus, "tf", "t.toml", &not_files, tf_commands);
    let tf_bad: Vec<(Input, &str)> = BAD_TOML
        .iter()
        .map(|&i| (i, ""))
        .chain(
            [
                "[[points]]\nvalue = 0\nrgba = [0, 0, 0]\n",
                "[[points]]\nvalue = nan\nrgba = [0, 0, 0, 0]\n",
                "[[points]]\nvalue = -5\nrgba = [0, 0, 0, 0]\n",
                "[[points]]\nvalue = 1e300\nrgba = [0, 0, 0, 0]\n",
                "[[points]]\nvalue = 0\nrgba = [inf, 0, 0, 0]\n",
                "[[points]]\nvalue = 0\nrgba = [0, 0, 0, -1]\n",
                "[[points]]\nvalue = 0\nrgba = [0, 0, 0, 2]\n",
                "[[points]]\nvalue = 3\nrgba = [0, 0, 0, 0]\n[[points]]\nvalue = 1\nrgba = [0, 0, 0, 0]\n",
                "points = []\n",
                "points = 5\n",
                "[[points]]\n",
                "name = 5\n[[points]]\nvalue = 0\nrgba = [0, 0, 0, 0]\n",
                "[[points]]\nvalue = 0\nrgba = [0, 0, 0, 0]\nextra = 1\n",
            ]
            .map(|t| (Input::Text(t), "")),
        )
        .collect();
    cross(&mut corpus, "tf", "t.toml", &tf_bad, tf_commands);

    // Camera paths (`--view path:FILE:K/N`).
    let path_inputs: Vec<(Input, &str)> = NOT_FILES
        .iter()
        .chain(BAD_TOML.iter())
        .copied()
        .chain(
            [
                "[[key]]\neye = [0.5, 0.5, 0.5]\nlook_at = [0.5, 0.5, 0.5]\nup = [0, 0, 1]\n",
                "units = \"extent\"\n[[key]]\neye = [nan, 0, 0]\nlook_at = [1, 1, 1]\nup = [0, 0, 1]\n",
                "units = \"parsec\"\n[[key]]\neye = [0, 0, 0]\nlook_at = [1, 1, 1]\nup = [0, 0, 1]\n",
                "fov_y_deg = 1e9\n[[key]]\neye = [0, 0, 0]\nlook_at = [1, 1, 1]\nup = [0, 0, 1]\n",
                "[[key]]\neye = [1e38, 0, 0]\nlook_at = [1, 1, 1]\nup = [1e38, 1e38, 1e38]\n",
                "key = []\n",
            ]
            .map(Input::Text),
        )
        .map(|i| (i, "p.toml"))
        .collect();
    for (input, needle) in path_inputs {
        for cmd in ["render", "sim"] {
            let dir = corpus.dir();
            let path = dir.join("p.toml");
            input.make(&path);
            let view = format!("path:{}:0/10", s(&path));
            let out = s(&dir.join("x.png"));
            let args: Vec<String> = [
                cmd,
                "--dataset",
                "phantom:sphere:8",
                "--size",
                "8x8",
                "--view",
                &view,
                "-o",
                &out,
            ]
            .map(String::from)
            .to_vec();
            corpus.add(
                format!("path {}: {cmd}", input.label()),
                dir,
                args,
                &[needle],
            );
        }
    }
    run_all(corpus, 300);
}

#[test]
fn hostile_volumes_headers_and_descriptors() {
    let mut corpus = Corpus::new("volume");
    let not_files: Vec<(Input, &str)> = NOT_FILES.iter().map(|&i| (i, "")).collect();
    cross(&mut corpus, "nrrd", "v.nrrd", &not_files, volume_commands);
    let nrrd: Vec<(Input, &str)> = [
        (Input::Text(""), ""),
        (Input::Text("NRRD0004\n"), ""),
        (Input::Text("P6\n4 4\n255\n"), ""),
        (Input::Bytes(b"NRRD0004\n\xff\xfe: \x00\n\n"), ""),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4\nencoding: raw\n\n"), "sizes"),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 0 4 4\nencoding: raw\n\n"), "sizes"),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: -4 4 4\nencoding: raw\n\n"), "sizes"),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4294967296 4294967296 4294967296\nencoding: raw\n\n"), ""),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 100000 100000 100000\nencoding: raw\n\n"), ""),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 2048 2048 2048\nencoding: gzip\n\n"), ""),
        (Input::Text("NRRD0004\ntype: float\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n\n"), "type"),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 7\nsizes: 4 4 4 4 4 4 4\nencoding: raw\n\n"), "dimension"),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: bzip2\n\n"), "encoding"),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n\nshort"), ""),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: gzip\n\nnot gzip at all"), ""),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nspacings: -1 1 1\nencoding: raw\n\n0123456789012345678901234567890123456789012345678901234567890123"), "spacings"),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nspacings: 3e38 1 1\nencoding: raw\n\n0123456789012345678901234567890123456789012345678901234567890123"), "spacings"),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nspacings: 1e-38 1 1\nencoding: raw\n\n0123456789012345678901234567890123456789012345678901234567890123"), "spacings"),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nspace directions: (nan,0,0) (0,1,0) (0,0,1)\nencoding: raw\n\n0123456789012345678901234567890123456789012345678901234567890123"), ""),
        (Input::Text("NRRD0004\ntype: uint16\ndimension: 3\nsizes: 4 4 4\nendian: middle\nencoding: raw\n\n"), "endian"),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: missing.raw\n\n"), "missing.raw"),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: /dev/zero\n\n"), "/dev/zero"),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: .\n\n"), ""),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: LIST\n\n"), "data file"),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: d_%03d.raw 0 9 1\n\n"), "data file"),
        (Input::Text("NRRD0004\ntype: uint8\ntype: uint16\ndimension: 3\nsizes: 4 4 4\nencoding: raw\n\n"), "type"),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\nline skip: 99999999999\n\n"), ""),
        (Input::Text("NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\nbyte skip: -1\n\n"), ""),
    ]
    .into_iter()
    .collect();
    cross(&mut corpus, "nrrd", "v.nrrd", &nrrd, volume_commands);
    // A header line without an end: the header reader must not take the whole file as a line.
    {
        let dir = corpus.dir();
        let path = dir.join("v.nrrd");
        let mut text = b"NRRD0004\ntype: uint8\n# ".to_vec();
        text.extend(std::iter::repeat_n(b'x', 4 << 20));
        std::fs::write(&path, text).unwrap();
        corpus.add(
            "nrrd: a 4 MB header line".into(),
            dir,
            vec!["info".into(), s(&path)],
            &["v.nrrd"],
        );
    }
    // Detached headers whose data file is a FIFO, a folder or /dev/zero.
    for input in [Input::Fifo, Input::Folder, Input::Zero, Input::LinkLoop] {
        for cmd in 0..2 {
            let dir = corpus.dir();
            input.make(&dir.join("d.raw"));
            let path = dir.join("v.nhdr");
            std::fs::write(
                &path,
                "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 4 4\nencoding: raw\ndata file: d.raw\n\n",
            )
            .unwrap();
            let args = volume_commands(&dir, &path).swap_remove(cmd);
            corpus.add(
                format!("nhdr data file {}", input.label()),
                dir,
                args,
                &["d.raw", "v.nhdr"],
            );
        }
    }

    // Raw files named by the convention, of the wrong size or absurd dimensions.
    for (name, bytes) in [
        ("x_4x4x4_uint8.raw", 63usize),
        ("x_4x4x4_uint8.raw", 65),
        ("x_4x4x4_uint16.raw", 64),
        ("x_0x4x4_uint8.raw", 0),
        ("x_99999x99999x99999_uint8.raw", 16),
        ("x_18446744073709551615x2x2_uint8.raw", 16),
        ("x_4x4x4_float.raw", 64),
    ] {
        for cmd in 0..6 {
            let dir = corpus.dir();
            let path = dir.join(name);
            std::fs::write(&path, vec![1u8; bytes]).unwrap();
            let args = volume_commands(&dir, &path).swap_remove(cmd);
            corpus.add(format!("raw {name} of {bytes} bytes"), dir, args, &[name]);
        }
    }
    // The same through a data folder: `info NAME --data-dir DIR`.
    for input in [
        Input::Fifo,
        Input::Zero,
        Input::LinkLoop,
        Input::Text("abc"),
    ] {
        let dir = corpus.dir();
        let data = dir.join("data");
        std::fs::create_dir_all(&data).unwrap();
        input.make(&data.join("x_4x4x4_uint8.raw"));
        corpus.add(
            format!("data folder raw {}", input.label()),
            dir,
            vec!["info".into(), "x".into(), "--data-dir".into(), s(&data)],
            &["x_4x4x4_uint8.raw"],
        );
    }

    // Dataset descriptors.
    let descriptors: Vec<(Input, &str)> = NOT_FILES
        .iter()
        .chain(BAD_TOML.iter())
        .map(|&i| (i, ""))
        .chain(
            [
                ("file = \"\"\n", "file"),
                ("file = \"d.raw\"\ndims = [4, 4]\n", ""),
                (
                    "file = \"d.raw\"\ndims = [4, 4, 4]\ntype = \"float\"\n",
                    "type",
                ),
                ("file = \"d.raw\"\ndims = [0, 4, 4]\n", "dims"),
                (
                    "file = \"d.raw\"\ndims = [4, 4, 4]\nspacing = [nan, 1, 1]\n",
                    "spacing",
                ),
                (
                    "file = \"d.raw\"\ndims = [4, 4, 4]\nspacing = [1, 1, 1e9]\n",
                    "spacing",
                ),
                (
                    "file = \"d.raw\"\ndims = [4, 4, 4]\nendian = \"middle\"\n",
                    "endian",
                ),
                ("file = \"d.raw\"\ndims = [-1, 4, 4]\n", "dims"),
                ("file = \"d.raw\"\ndims = [4, 4, 4]\nname = \"\"\n", "name"),
                ("file = \"d.raw\"\ndims = [4, 4, 4]\nextra = 1\n", "extra"),
                ("file = \"v.toml\"\n", ""),
                ("file = \"/dev/zero\"\ndims = [4, 4, 4]\n", "/dev/zero"),
                ("file = \"fifo.raw\"\ndims = [4, 4, 4]\n", "fifo.raw"),
                ("file = \"d.raw\"\ndims = [100000, 100000, 100000]\n", ""),
            ]
            .map(|(t, n)| (Input::Text(t), n)),
        )
        .collect();
    for (input, needle) in descriptors {
        for cmd in 0..3 {
            let dir = corpus.dir();
            std::fs::write(dir.join("d.raw"), vec![3u8; 63]).unwrap();
            mkfifo(&dir.join("fifo.raw"));
            let path = dir.join("v.toml");
            input.make(&path);
            let needle = if needle.is_empty() { "v.toml" } else { needle };
            let args = volume_commands(&dir, &path).swap_remove(cmd);
            corpus.add(
                format!("descriptor {}", input.label()),
                dir,
                args,
                &[needle, "v.toml"],
            );
        }
    }
    // A sequence folder with a hostile time step.
    for (input, needle) in [
        (Input::Fifo, "seq"),
        (Input::Zero, "seq"),
        (Input::Text("NRRD0004\n"), "b.nrrd"),
    ] {
        let dir = corpus.dir();
        let tf = valid_tf(&dir);
        let seq = dir.join("seq");
        std::fs::create_dir_all(&seq).unwrap();
        std::fs::write(seq.join("a_4x4x4_uint8.raw"), vec![1u8; 64]).unwrap();
        input.make(&seq.join("b.nrrd"));
        corpus.add(
            format!("sequence folder with {}", input.label()),
            dir,
            [
                "sequence",
                "--source",
                &s(&seq),
                "--steps",
                "2",
                "--size",
                "8x8",
                "--map",
                "none",
                "--tf",
                &tf,
            ]
            .map(String::from)
            .to_vec(),
            &[needle],
        );
    }
    run_all(corpus, 250);
}

/// A minimal valid experiment; cases replace or append to it.
const EXPERIMENT: &str = "name = \"e\"\ndatasets = [\"phantom:sphere:8\"]\ntf = [\"zero\"]\n\
modes = [\"none\"]\nmodels = [\"step\"]\n[frames]\norbit = 2\nsize = \"4x4\"\n";

#[test]
fn hostile_experiments_results_images_and_numbers() {
    let mut corpus = Corpus::new("experiment");
    let experiments: Vec<(String, &str)> = vec![
        (EXPERIMENT.replace("name = \"e\"", "name = 5"), "name"),
        (EXPERIMENT.replace("orbit = 2", "orbit = 0"), "frames.orbit"),
        (EXPERIMENT.replace("orbit = 2", "orbit = -1"), "orbit"),
        (EXPERIMENT.replace("orbit = 2", "orbit = 1e99"), "orbit"),
        (
            EXPERIMENT.replace("orbit = 2", "orbit = 4294967296"),
            "orbit",
        ),
        (EXPERIMENT.replace("orbit = 2", "orbit = nan"), "orbit"),
        (
            EXPERIMENT.replace("size = \"4x4\"", "size = \"0x0\""),
            "frames.size",
        ),
        (
            EXPERIMENT.replace("size = \"4x4\"", "size = \"99999999x99999999\""),
            "frames.size",
        ),
        (
            EXPERIMENT.replace("size = \"4x4\"", "size = \"16384x16384\""),
            "16384",
        ),
        (EXPERIMENT.replace("size = \"4x4\"", "size = 4"), "size"),
        (EXPERIMENT.replace("[\"none\"]", "[]"), "modes"),
        (EXPERIMENT.replace("[\"none\"]", "[\"leap0\"]"), "modes"),
        (
            EXPERIMENT.replace("[\"none\"]", "[\"leap99999999999999999999\"]"),
            "modes",
        ),
        (
            EXPERIMENT.replace("[\"none\"]", "[\"iso4294967296\"]"),
            "modes",
        ),
        (
            EXPERIMENT.replace("[\"none\"]", "[\"ert+ert+hier\"]"),
            "modes",
        ),
        (EXPERIMENT.replace("[\"none\"]", "[\"+\"]"), "modes"),
        (EXPERIMENT.replace("[\"none\"]", "[\"distance\"]"), "modes"),
        (EXPERIMENT.replace("[\"step\"]", "[\"float\"]"), "models"),
        (EXPERIMENT.replace("[\"zero\"]", "[\"rainbow\"]"), "tf"),
        (
            EXPERIMENT.replace("phantom:sphere:8", "phantom:sphere:99999"),
            "datasets",
        ),
        (
            EXPERIMENT.replace("phantom:sphere:8", "phantom:sphere:0"),
            "datasets",
        ),
        (
            EXPERIMENT.replace("phantom:sphere:8", "/dev/zero"),
            "datasets",
        ),
        (
            EXPERIMENT.replace("phantom:sphere:8", "nowhere"),
            "datasets",
        ),
        (EXPERIMENT.replace("phantom:sphere:8", ""), "datasets"),
        (
            EXPERIMENT.replace("datasets = [\"phantom:sphere:8\"]\n", ""),
            "datasets",
        ),
        (format!("config = \"/dev/zero\"\n{EXPERIMENT}"), "/dev/zero"),
        (format!("config = \"fifo.toml\"\n{EXPERIMENT}"), "fifo.toml"),
        (format!("config = \".\"\n{EXPERIMENT}"), ""),
        (
            format!("config = \"nowhere.toml\"\n{EXPERIMENT}"),
            "nowhere.toml",
        ),
        (format!("bogus = 1\n{EXPERIMENT}"), "bogus"),
        (format!("zip = [[]]\n{EXPERIMENT}"), "zip"),
        (format!("zip = [[\"nope\"]]\n{EXPERIMENT}"), "zip"),
        (format!("{EXPERIMENT}select = [2]\n"), "frames.select"),
        (format!("{EXPERIMENT}select = []\n"), "frames.select"),
        (format!("{EXPERIMENT}select = [-1]\n"), "select"),
        (format!("{EXPERIMENT}every = 0\n"), "frames.every"),
        (format!("{EXPERIMENT}every = 1\nselect = [0]\n"), "frames"),
        (
            format!("{EXPERIMENT}projection = \"fisheye\"\n"),
            "frames.projection",
        ),
        (
            format!("{EXPERIMENT}path = \"nowhere.toml\"\n"),
            "nowhere.toml",
        ),
        (format!("{EXPERIMENT}path = \"fifo.toml\"\n"), "fifo.toml"),
        (
            format!("{EXPERIMENT}[axes]\n\"ray_queue.rays\" = []\n"),
            "ray_queue.rays",
        ),
        (
            format!("{EXPERIMENT}[axes]\n\"ray_queue.rays\" = 8\n"),
            "ray_queue.rays",
        ),
        (
            format!("{EXPERIMENT}[axes]\n\"ray_queue.rays\" = [0]\n"),
            "ray_queue.rays",
        ),
        (
            format!("{EXPERIMENT}[axes]\n\"ray_queue.rays\" = [nan]\n"),
            "ray_queue.rays",
        ),
        (
            format!("{EXPERIMENT}[axes]\n\"ray_queue.rays\" = [1e300]\n"),
            "ray_queue.rays",
        ),
        (
            format!("{EXPERIMENT}[axes]\n\"ray_queue.rays\" = [\"8\"]\n"),
            "ray_queue.rays",
        ),
        (
            format!("{EXPERIMENT}[axes]\n\"ray_queue.rays\" = [[8]]\n"),
            "ray_queue.rays",
        ),
        (
            format!("{EXPERIMENT}[axes]\n\"ray_queue.rays\" = [{{a = 1}}]\n"),
            "ray_queue.rays",
        ),
        (
            format!("{EXPERIMENT}[axes]\n\"no.such\" = [1]\n"),
            "no.such",
        ),
        (format!("{EXPERIMENT}[axes]\n\"\" = [1]\n"), "axes"),
        (
            format!("{EXPERIMENT}[axes]\n\"ray_queue\" = [1]\n"),
            "ray_queue",
        ),
        (
            format!("{EXPERIMENT}[axes]\n\"ray_queue.rays.x\" = [1]\n"),
            "ray_queue.rays.x",
        ),
        (
            format!("{EXPERIMENT}[axes]\n\"clock.step_time_ns\" = [5e-324]\n"),
            "clock.step_time_ns",
        ),
        (
            format!("{EXPERIMENT}[axes]\n\"compositing.ert\" = [true]\n"),
            "compositing.ert",
        ),
        (format!("{EXPERIMENT}[[exclude]]\n"), "exclude"),
        (format!("{EXPERIMENT}[[exclude]]\nnope = 1\n"), "exclude"),
        (
            format!("{EXPERIMENT}[[exclude]]\nmodel = \"step\"\n"),
            "exclude",
        ),
        (
            format!("{EXPERIMENT}[sequence]\nsteps = 0\n"),
            "sequence.steps",
        ),
        (format!("{EXPERIMENT}[sequence]\nsteps = 1e9\n"), "steps"),
        (
            EXPERIMENT
                .replace("[\"step\"]", "[\"cycle\"]")
                .replace("phantom:sphere:8", "phantom:metaballs:8")
                + "[sequence]\nsteps = 3\ndt = 3e38\nmap = [\"none\"]\n",
            "sequence.dt",
        ),
        (
            format!("{EXPERIMENT}[sequence]\nsteps = 2\ndt = nan\n"),
            "sequence",
        ),
        (
            format!("{EXPERIMENT}[sequence]\nsteps = 2\nbrick = 0\n"),
            "sequence",
        ),
        (
            format!("{EXPERIMENT}[sequence]\nsteps = 2\nmap = []\n"),
            "sequence.map",
        ),
        (
            format!("{EXPERIMENT}[sequence]\nsteps = 2\nmap = [\"x\"]\n"),
            "sequence.map",
        ),
        (
            format!("{EXPERIMENT}[sequence]\nsteps = 99999\n"),
            "sequence.steps",
        ),
    ];
    for (text, needle) in &experiments {
        for dry in [true, false] {
            let dir = corpus.dir();
            mkfifo(&dir.join("fifo.toml"));
            let path = dir.join("e.toml");
            std::fs::write(&path, text).unwrap();
            let mut args = vec![
                "sweep".to_string(),
                s(&path),
                "--out".into(),
                s(&dir.join("out")),
            ];
            if dry {
                args.push("--dry-run".into());
            }
            let what = format!(
                "experiment {:?} (dry run {dry})",
                text.lines().last().unwrap_or("")
            );
            corpus.add(what, dir, args, &["e.toml", needle]);
        }
    }
    for input in NOT_FILES.iter().chain(BAD_TOML.iter()) {
        for dry in [true, false] {
            let dir = corpus.dir();
            let path = dir.join("e.toml");
            input.make(&path);
            let mut args = vec![
                "sweep".to_string(),
                s(&path),
                "--out".into(),
                s(&dir.join("out")),
            ];
            if dry {
                args.push("--dry-run".into());
            }
            corpus.add(
                format!("experiment {} (dry run {dry})", input.label()),
                dir,
                args,
                &["e.toml"],
            );
        }
    }

    // Sweep folders whose files are hostile: merge, table, plot and a sweep into them.
    let results: [(&str, Input); 8] = [
        ("results.jsonl", Input::Fifo),
        ("results.jsonl", Input::Zero),
        ("results.jsonl", Input::Folder),
        ("results.jsonl", Input::LinkLoop),
        (
            "results.jsonl",
            Input::Text("{\"key\":\"a\"}\nnot json\n{\"key\":\"b\"}\n"),
        ),
        (
            "results.jsonl",
            Input::Text("{\"key\":5}\n{\"key\":\"b\"}\n"),
        ),
        ("timing.jsonl", Input::Fifo),
        ("experiment.resolved.json", Input::Fifo),
    ];
    for (file, input) in results {
        let readers: &[&str] = match (file, input) {
            // Every reader wants a string key (tables read results as a resumed sweep does).
            (_, Input::Text(t)) if t.starts_with("{\"key\":5}") => {
                &["merge", "table", "plot", "sweep", "sweep --dry-run"]
            }
            ("results.jsonl", _) => &["merge", "table", "plot", "sweep", "sweep --dry-run"],
            ("timing.jsonl", _) => &["merge", "sweep"],
            _ => &["merge", "sweep", "sweep --dry-run"],
        };
        for &cmd in readers {
            let dir = corpus.dir();
            let run = dir.join("run");
            std::fs::create_dir_all(&run).unwrap();
            input.make(&run.join(file));
            if file != "results.jsonl" {
                std::fs::write(run.join("results.jsonl"), "").unwrap();
            }
            let args: Vec<String> = match cmd {
                "merge" => vec!["merge".into(), s(&run), "--out".into(), s(&dir.join("m"))],
                "table" | "plot" => vec![cmd.into(), s(&run), "--out".into(), s(&dir.join("t"))],
                _ => {
                    let exp = dir.join("e.toml");
                    std::fs::write(&exp, EXPERIMENT).unwrap();
                    let mut a = vec!["sweep".into(), s(&exp), "--out".into(), s(&run)];
                    if cmd.ends_with("dry-run") {
                        a.push("--dry-run".into());
                    }
                    a
                }
            };
            // A sweep into the folder may legitimately read a FIFO timing file only after
            // its results: what matters is that it ends and names the file.
            corpus.add(
                format!("{cmd} with {file} {}", input.label()),
                dir,
                args,
                &[file],
            );
        }
    }

    // Images for compare.
    let images: Vec<(Input, &str)> = NOT_FILES
        .iter()
        .map(|&i| (i, "a.png"))
        .chain([
            (Input::Bytes(b""), "a.png"),
            (Input::Bytes(b"\x89PNG\r\n\x1a\n"), "a.png"),
            (Input::Bytes(b"\x89PNG\r\n\x1a\n\x00\x00\x00\x0dIHDR\x7f\xff\xff\xff\x7f\xff\xff\xff\x08\x06\x00\x00\x00\x00\x00\x00\x00"), "a.png"),
            (Input::Text("GIF89a"), "a.png"),
        ])
        .collect();
    for (input, needle) in images {
        let dir = corpus.dir();
        let a = dir.join("a.png");
        input.make(&a);
        let b = dir.join("b.png");
        std::fs::write(&b, b"not a png").unwrap();
        let args = [
            "compare",
            &s(&a),
            &s(&a),
            "--json",
            &s(&dir.join("c.json")),
            "--diff",
            &s(&dir.join("d.png")),
        ]
        .map(String::from)
        .to_vec();
        corpus.add(format!("compare {}", input.label()), dir, args, &[needle]);
    }

    // Command-line numbers.
    // The options as `--name=value`, so that a negative value is not taken for an option; an
    // option given replaces the default dataset or size.
    let frame = |extra: &[&str]| -> Vec<String> {
        let mut args: Vec<String> = Vec::new();
        for (name, default) in [("--dataset", "phantom:sphere:8"), ("--size", "8x8")] {
            if !extra.contains(&name) {
                args.push(format!("{name}={default}"));
            }
        }
        args.extend(extra.chunks(2).map(|p| format!("{}={}", p[0], p[1])));
        args
    };
    let numbers: Vec<(Vec<String>, &str)> = vec![
        (frame(&["--size", "0x8"]), "size"),
        (frame(&["--size", "99999999999x8"]), "size"),
        (frame(&["--size", "16384x16384"]), "16384"),
        (frame(&["--size", "-8x8"]), "size"),
        (frame(&["--size", "8"]), "size"),
        (frame(&["--spacing", "0"]), "spacing"),
        (frame(&["--spacing", "NaN"]), "spacing"),
        (frame(&["--spacing", "-1"]), "spacing"),
        (frame(&["--spacing", "1e-30"]), "spacing"),
        (frame(&["--spacing", "inf"]), "spacing"),
        (frame(&["--view", "orbit:5/0"]), "orbit"),
        (frame(&["--view", "orbit:9/4"]), "orbit"),
        (frame(&["--view", "orbit:-1/4"]), "orbit"),
        (frame(&["--view", "sideways"]), "sideways"),
        (frame(&["--subcube", "3"]), "subcube"),
        (frame(&["--subcube", "4294967296"]), "subcube"),
        (frame(&["--bricks", "1000"]), "bricks"),
        (frame(&["--set", "ray_queue.rays=0"]), "ray_queue.rays"),
        (frame(&["--set", "ray_queue.rays=nan"]), "ray_queue.rays"),
        (
            frame(&["--set", "ray_queue.rays=99999999999999999999999"]),
            "ray_queue.rays",
        ),
        (
            frame(&["--set", "clock.step_time_ns=5e-324"]),
            "clock.step_time_ns",
        ),
        (frame(&["--set", "nonsense"]), "nonsense"),
        (frame(&["--set", "a.b.c.d=1"]), "a.b.c.d"),
        (frame(&["--dataset", "phantom:sphere:100000"]), "phantom"),
        (frame(&["--dataset", "phantom:nothing:8"]), "nothing"),
        (frame(&["--dataset", "phantom:sphere:-1"]), "phantom"),
    ];
    for (extra, needle) in numbers {
        for cmd in ["render", "sim"] {
            let dir = corpus.dir();
            let mut args = vec![cmd.to_string()];
            args.extend(extra.iter().cloned());
            args.extend(["-o".into(), s(&dir.join("x.png"))]);
            corpus.add(format!("{cmd} {}", extra.join(" ")), dir, args, &[needle]);
        }
    }
    let more: Vec<(Vec<&str>, &str)> = vec![
        (
            vec![
                "sim",
                "--dataset",
                "phantom:sphere:8",
                "--memory",
                "ideal",
                "--ideal-latency",
                "0",
            ],
            "latency",
        ),
        (
            vec![
                "sim",
                "--dataset",
                "phantom:sphere:8",
                "--trace-cycles",
                "10..5",
                "--command-trace",
                "t.csv",
            ],
            "trace-cycles",
        ),
        (
            vec![
                "sim",
                "--dataset",
                "phantom:sphere:8",
                "--trace-cycles",
                "0..99999999999999999999",
                "--vcd",
                "w.vcd",
            ],
            "trace-cycles",
        ),
        (
            vec![
                "sequence",
                "--source",
                "phantom:metaballs:8",
                "--steps",
                "0",
                "--map",
                "none",
            ],
            "steps",
        ),
        (
            vec![
                "sequence",
                "--source",
                "phantom:metaballs:8",
                "--steps",
                "999999999",
                "--map",
                "none",
            ],
            "steps",
        ),
        // dt finite, but the time of a later step overflows (the trial's only panic).
        (
            vec![
                "sequence",
                "--source",
                "phantom:metaballs:8",
                "--size",
                "8x8",
                "--dt=3e38",
                "--map",
                "none",
            ],
            "overflows",
        ),
        (
            vec![
                "sequence",
                "--source",
                "phantom:metaballs:8",
                "--dt",
                "nan",
                "--map",
                "none",
            ],
            "dt",
        ),
        (
            vec![
                "sequence",
                "--source",
                "phantom:metaballs:8",
                "--brick",
                "0",
                "--map",
                "none",
            ],
            "brick",
        ),
        (
            vec![
                "sequence",
                "--source",
                "phantom:sphere:8",
                "--steps",
                "2",
                "--map",
                "none",
            ],
            "sphere",
        ),
        (
            vec![
                "update",
                "phantom:sphere:8",
                "--brick",
                "0",
                "--subcube",
                "4",
            ],
            "brick",
        ),
        (
            vec![
                "update",
                "phantom:sphere:8",
                "--next",
                "phantom:sphere:16",
                "--subcube",
                "4",
            ],
            "next",
        ),
        (vec!["info", "phantom:sphere:0"], "phantom"),
        (
            vec!["occupancy", "phantom:sphere:8", "--subcube", "1"],
            "subcube",
        ),
        (
            vec!["--memory-budget", "0", "info", "phantom:sphere:8"],
            "memory-budget",
        ),
        (
            vec!["--memory-budget", "1", "info", "phantom:sphere:8"],
            "budget",
        ),
        (
            vec!["sweep", "e.toml", "--out", "o", "--shard", "1/0"],
            "--shard 1/0: expected I/N",
        ),
        (
            vec!["sweep", "e.toml", "--out", "o", "--shard", "x"],
            "shard",
        ),
        (
            vec!["sweep", "e.toml", "--out", "o", "--model", "float"],
            "model",
        ),
        (vec!["table", "nowhere"], "nowhere"),
        (vec!["merge", "nowhere", "--out", "m"], "nowhere"),
    ];
    for (args, needle) in more {
        let dir = corpus.dir();
        std::fs::write(dir.join("e.toml"), EXPERIMENT).unwrap();
        corpus.add(
            args.join(" "),
            dir,
            args.iter().map(|x| x.to_string()).collect(),
            &[needle],
        );
    }
    run_all(corpus, 250);
}

/// `--threads` beyond what a machine can start is refused before the pool is built (the
/// adversarial trial's `--threads=4294967295` hung trying to start them).
#[test]
fn absurd_thread_counts_are_refused() {
    let mut corpus = Corpus::new("threads");
    for n in ["0", "4294967295", "18446744073709551615", "-1", "x"] {
        let dir = corpus.dir();
        let out = s(&dir.join("x.png"));
        let args = [
            &format!("--threads={n}"),
            "render",
            "--dataset",
            "phantom:sphere:8",
            "--size",
            "8x8",
            "-o",
            &out,
        ]
        .map(|a| a.to_string())
        .to_vec();
        corpus.add(
            format!("--threads={n}"),
            dir,
            args,
            &["--threads", "1..=1024"],
        );
    }
    run_all(corpus, 5);
}
