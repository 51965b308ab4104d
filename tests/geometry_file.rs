//! `geometry.file` (a depth image, `geometry.shape = "depth-file"`) is read like every other
//! input: only a regular file (a FIFO or `/dev/zero` is refused, not read), its header checked
//! against the file's length and the memory budget before any value is read, and only the
//! values the header announces read. Its errors name the field.

mod common;

use std::path::{Path, PathBuf};
use std::process::Command;
use std::time::{Duration, Instant};

use vizsim::clip::DepthImage;

fn scratch(name: &str) -> PathBuf {
    let dir = Path::new(env!("CARGO_TARGET_TMPDIR")).join(format!(
        "vizsim-geometry-file-{}-{name}",
        std::process::id()
    ));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// Renders an 8×8 frame with `file` as the depth image under a 512 MiB budget; must fail with
/// every needle in its message.
fn render_refused(dir: &Path, file: &str, needles: &[&str]) {
    let png = dir.join("x.png");
    let set_file = format!("geometry.file={file}");
    let args = [
        "render",
        "--dataset",
        "phantom:sphere:32",
        "--size",
        "8x8",
        "--model",
        "fixed",
        "--memory-budget",
        "512M",
        "--set",
        "geometry.shape=depth-file",
        "--set",
        &set_file,
        "-o",
        png.to_str().unwrap(),
    ];
    let (ok, stderr) = common::run_bounded(None, &args, 20);
    assert!(!ok, "{file}: succeeded");
    assert!(!stderr.contains("panicked"), "{file}: panicked: {stderr}");
    for n in needles {
        assert!(stderr.contains(n), "{file}: stderr lacks {n:?}: {stderr}");
    }
    assert!(!png.exists(), "{file}: an image was written");
}

/// A file of `length` bytes (sparse: nothing but the header is written) starting with `header`.
fn sparse_file(path: &Path, header: &str, length: u64) {
    use std::io::Write;
    let mut f = std::fs::File::create(path).unwrap();
    f.write_all(header.as_bytes()).unwrap();
    f.set_len(length).unwrap();
}

#[test]
fn a_device_or_a_fifo_is_refused_before_it_is_read() {
    let dir = scratch("devices");
    render_refused(
        &dir,
        "/dev/zero",
        &["/dev/zero", "geometry.file", "not a regular file"],
    );
    let fifo = dir.join("depth.fifo");
    let ok = Command::new("mkfifo").arg(&fifo).status().unwrap();
    assert!(ok.success(), "mkfifo");
    render_refused(
        &dir,
        fifo.to_str().unwrap(),
        &["depth.fifo", "geometry.file", "not a regular file"],
    );
    // The library refuses them too.
    let e = DepthImage::read(Path::new("/dev/zero")).expect_err("/dev/zero");
    assert!(e.to_string().contains("not a regular file"), "{e}");
    let e = DepthImage::check_file(&fifo).expect_err("fifo");
    assert!(e.to_string().contains("not a regular file"), "{e}");
}

#[test]
fn a_missing_file_names_the_field() {
    let dir = scratch("missing");
    render_refused(
        &dir,
        "nonexist.bin",
        &["field `geometry.file`", "nonexist.bin", "No such file"],
    );
}

#[test]
fn the_header_is_checked_against_the_length_and_the_budget_before_reading() {
    let dir = scratch("length");
    // 3 GB behind a valid 8×8 header: refused from its length, without reading it (a read
    // would take seconds and 3 GB of memory).
    let sparse = dir.join("sparse.depth");
    sparse_file(&sparse, "VIZDEPTH 8 8\n", 3 << 30);
    let start = Instant::now();
    render_refused(
        &dir,
        sparse.to_str().unwrap(),
        &["sparse.depth", "geometry.file", "a 8x8 image needs 256"],
    );
    assert!(
        start.elapsed() < Duration::from_secs(5),
        "took {:?}: the file was read",
        start.elapsed()
    );
    // A header announcing 1 GiB of values, with a file of that length: over a 512 MiB budget
    // before anything is read.
    let header = "VIZDEPTH 16384 16384\n";
    let big = dir.join("big.depth");
    sparse_file(&big, header, header.len() as u64 + 16384 * 16384 * 4);
    render_refused(
        &dir,
        big.to_str().unwrap(),
        &["big.depth", "geometry.file", "over the budget"],
    );
    // The library checks the header without reading the values.
    assert_eq!(
        DepthImage::check_file(&big).ok(),
        Some((16384, 16384)),
        "a file as long as its header says passes the check"
    );
    let e = DepthImage::check_file(&sparse).expect_err("wrong length");
    assert!(e.to_string().contains("3221225459 bytes"), "{e}");
}

#[test]
fn a_valid_file_still_reads() {
    let dir = scratch("valid");
    let path = dir.join("ok.depth");
    let image = DepthImage {
        width: 3,
        height: 2,
        depth: vec![0.0, 1.5, -1.0, 2.0, f32::INFINITY, 7.25],
    };
    image.write(&path).unwrap();
    assert_eq!(DepthImage::check_file(&path).unwrap(), (3, 2));
    let read = DepthImage::read(&path).unwrap();
    assert_eq!((read.width, read.height), (3, 2));
    assert_eq!(read.depth, image.depth);
}
