//! Volume loaders: raw files, file-name convention, dataset descriptors and NRRD; plus
//! property tests that no input makes a loader panic or allocate a header's promised size.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use flate2::write::GzEncoder;
use flate2::Compression;
use proptest::prelude::*;
use vizsim::volume::descriptor;
use vizsim::volume::raw::{self, RawFileName};
use vizsim::volume::{nrrd, Volume, MAX_DIM};
use vizsim::Error;

// ---------------------------------------------------------------------------------------------
// Helpers

/// Records the largest single allocation made by the current thread, so a test can check that
/// a header promising gigabytes does not make the loader reserve them.
struct LargestAllocation;

thread_local! {
    static LARGEST: Cell<usize> = const { Cell::new(0) };
}

fn note_allocation(size: usize) {
    // `try_with`: the allocator also runs while thread-locals are being torn down.
    let _ = LARGEST.try_with(|largest| largest.set(largest.get().max(size)));
}

unsafe impl GlobalAlloc for LargestAllocation {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note_allocation(layout.size());
        unsafe { System.alloc(layout) }
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note_allocation(layout.size());
        unsafe { System.alloc_zeroed(layout) }
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        note_allocation(new_size);
        unsafe { System.realloc(ptr, layout, new_size) }
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        unsafe { System.dealloc(ptr, layout) }
    }
}

#[global_allocator]
static ALLOCATOR: LargestAllocation = LargestAllocation;

/// Runs `f` and returns its result with the largest allocation it made on this thread.
fn with_largest_allocation<T>(f: impl FnOnce() -> T) -> (T, usize) {
    LARGEST.with(|largest| largest.set(0));
    let result = f();
    (result, LARGEST.with(Cell::get))
}

/// A fresh directory under cargo's scratch folder, removed when dropped.
struct TempDir(PathBuf);

impl TempDir {
    fn new(label: &str) -> Self {
        static COUNTER: AtomicUsize = AtomicUsize::new(0);
        let n = COUNTER.fetch_add(1, Ordering::Relaxed);
        let dir = Path::new(env!("CARGO_TARGET_TMPDIR"))
            .join(format!("loaders-{label}-{}-{n}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("create temp dir");
        TempDir(dir)
    }

    fn write(&self, name: &str, bytes: &[u8]) -> PathBuf {
        let path = self.0.join(name);
        std::fs::write(&path, bytes).expect("write test file");
        path
    }
}

impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn gzip(bytes: &[u8]) -> Vec<u8> {
    let mut encoder = GzEncoder::new(Vec::new(), Compression::default());
    encoder.write_all(bytes).expect("gzip into memory");
    encoder.finish().expect("gzip into memory")
}

/// Deterministic, varied voxel values.
fn pattern(voxels: usize, modulus: u32) -> Vec<u16> {
    (0..voxels as u32)
        .map(|i| (i.wrapping_mul(2_654_435_761) % modulus) as u16)
        .collect()
}

fn bytes_u8(values: &[u16]) -> Vec<u8> {
    values.iter().map(|&v| v as u8).collect()
}

fn bytes_u16_le(values: &[u16]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_le_bytes()).collect()
}

fn bytes_u16_be(values: &[u16]) -> Vec<u8> {
    values.iter().flat_map(|v| v.to_be_bytes()).collect()
}

/// An attached NRRD: header lines, blank line, payload.
fn nrrd_file(header_lines: &[&str], payload: &[u8]) -> Vec<u8> {
    let mut file = b"NRRD0004\n".to_vec();
    for line in header_lines {
        file.extend_from_slice(line.as_bytes());
        file.push(b'\n');
    }
    file.push(b'\n');
    file.extend_from_slice(payload);
    file
}

fn error_text<T: std::fmt::Debug>(result: Result<T, Error>) -> String {
    result.expect_err("expected an error").to_string()
}

fn assert_volume(volume: &Volume, name: &str, dims: [usize; 3], bits: u8, data: &[u16]) {
    assert_eq!(volume.name, name);
    assert_eq!(volume.dims, dims);
    assert_eq!(volume.bits, bits);
    assert_eq!(volume.data, data);
}

// ---------------------------------------------------------------------------------------------
// Raw files and the file-name convention

#[test]
fn raw_8bit_round_trip() {
    let dir = TempDir::new("raw8");
    let values = pattern(5 * 3 * 2, 256);
    let path = dir.write("vol.raw", &bytes_u8(&values));
    let volume = raw::load_raw(&path, "vol", [5, 3, 2], 8, [1.0, 2.0, 0.5]).unwrap();
    assert_volume(&volume, "vol", [5, 3, 2], 8, &values);
    assert_eq!(volume.spacing, [1.0, 2.0, 0.5]);
    // x fastest.
    assert_eq!(volume.get(1, 0, 0), values[1]);
    assert_eq!(volume.get(0, 1, 0), values[5]);
    assert_eq!(volume.get(0, 0, 1), values[15]);
}

#[test]
fn raw_16bit_round_trip_little_endian() {
    let dir = TempDir::new("raw16");
    let values = pattern(4 * 4 * 3, 65_536);
    let path = dir.write("vol.raw", &bytes_u16_le(&values));
    let volume = raw::load_raw(&path, "vol", [4, 4, 3], 16, [1.0; 3]).unwrap();
    assert_volume(&volume, "vol", [4, 4, 3], 16, &values);
}

#[test]
fn raw_16bit_big_endian() {
    let dir = TempDir::new("raw16be");
    let values = pattern(2 * 3 * 4, 65_536);
    let path = dir.write("vol.raw", &bytes_u16_be(&values));
    let volume =
        raw::load_raw_with_endian(&path, "vol", [2, 3, 4], 16, [1.0; 3], raw::Endian::Big).unwrap();
    assert_eq!(volume.data, values);
}

#[test]
fn raw_larger_than_one_read_chunk() {
    let dir = TempDir::new("rawbig");
    let dims = [64, 64, 40];
    let values = pattern(64 * 64 * 40, 65_536);
    let path = dir.write("big.raw", &bytes_u16_le(&values));
    let volume = raw::load_raw(&path, "big", dims, 16, [1.0; 3]).unwrap();
    assert_eq!(volume.data, values);
}

#[test]
fn raw_size_mismatch_names_file_and_both_sizes() {
    let dir = TempDir::new("rawsize");
    let path = dir.write("short_4x4x4_uint8.raw", &[7u8; 63]);
    let message = error_text(raw::load_raw_by_file_name(&path));
    assert!(message.contains("short_4x4x4_uint8.raw"), "{message}");
    assert!(message.contains("63"), "{message}");
    assert!(message.contains("64"), "{message}");

    let long = dir.write("long.raw", &[7u8; 129]);
    let message = error_text(raw::load_raw(&long, "long", [4, 4, 4], 16, [1.0; 3]));
    assert!(message.contains("long.raw"), "{message}");
    assert!(
        message.contains("129") && message.contains("128"),
        "{message}"
    );
}

#[test]
fn raw_bad_dims_rejected_before_reading() {
    // The file does not even exist: dims are checked first.
    let path = Path::new("/nonexistent/vizsim/x.raw");
    let message = error_text(raw::load_raw(path, "x", [99_999_999, 2, 2], 8, [1.0; 3]));
    assert!(message.contains("out of range"), "{message}");
    let message = error_text(raw::load_raw(path, "x", [1, 2, 2], 8, [1.0; 3]));
    assert!(message.contains("out of range"), "{message}");
    let message = error_text(raw::load_raw(path, "x", [2, 2, 2], 12, [1.0; 3]));
    assert!(message.contains("12 bits"), "{message}");
}

#[test]
fn raw_file_name_convention() {
    let parse = raw::parse_raw_file_name;
    let expect = |name: &str, dims: [usize; 3], bits: u8| {
        Some(RawFileName {
            name: name.into(),
            dims,
            bits,
        })
    };
    assert_eq!(
        parse("fuel_64x64x64_uint8.raw"),
        expect("fuel", [64, 64, 64], 8)
    );
    assert_eq!(
        parse("boston_teapot_256x256x178_uint8.raw"),
        expect("boston_teapot", [256, 256, 178], 8)
    );
    assert_eq!(
        parse("foot_256x256x256_uint8.LOSSY_zfp_p8_preview.raw"),
        expect("foot", [256, 256, 256], 8)
    );
    assert_eq!(
        parse("ct_512x512x300_uint16.raw"),
        expect("ct", [512, 512, 300], 16)
    );
    assert_eq!(
        parse("ct_512x512x300_uint16_v2.raw"),
        expect("ct", [512, 512, 300], 16)
    );
    assert_eq!(
        parse("hydrogen_atom_128x128x128_uint8.raw"),
        expect("hydrogen_atom", [128, 128, 128], 8)
    );
    // Leftmost dims/type group wins.
    assert_eq!(
        parse("a_2x3x4_uint8_5x6x7_uint16.raw"),
        expect("a", [2, 3, 4], 8)
    );

    for bad in [
        "fuel.raw",
        "fuel_64x64x64_uint8.nrrd",
        "fuel_64x64x64_uint8.RAW",
        "fuel_64x64_uint8.raw",
        "fuel_64x64x64x2_uint8.raw",
        "fuel_64x64x64_int8.raw",
        "fuel_64x64x64_uint32.raw",
        "fuel_64x64x64_uint80.raw",
        "fuel_64xx64_uint8.raw",
        "fuel_+64x64x64_uint8.raw",
        "fuel_64X64X64_uint8.raw",
        "_64x64x64_uint8.raw",
        "64x64x64_uint8.raw",
        "fuel_99999999999999999999999x2x2_uint8.raw",
        "",
        ".raw",
    ] {
        assert_eq!(parse(bad), None, "{bad}");
    }
}

#[test]
fn raw_by_file_name() {
    let dir = TempDir::new("rawname");
    let values = pattern(3 * 2 * 2, 65_536);
    let path = dir.write("thing_3x2x2_uint16.raw", &bytes_u16_le(&values));
    let volume = raw::load_raw_by_file_name(&path).unwrap();
    assert_volume(&volume, "thing", [3, 2, 2], 16, &values);
    assert_eq!(volume.spacing, [1.0; 3]);

    let unnamed = dir.write("thing.raw", &[0u8; 8]);
    let message = error_text(raw::load_raw_by_file_name(&unnamed));
    assert!(
        message.contains("thing.raw") && message.contains("NAME_XxYxZ"),
        "{message}"
    );
}

/// Finds the shared dataset folder: `$VIZSIM_DATA`, else `../shared/data` from the crate.
fn data_dir() -> Option<PathBuf> {
    let dir = match std::env::var_os("VIZSIM_DATA") {
        Some(dir) => PathBuf::from(dir),
        None => Path::new(env!("CARGO_MANIFEST_DIR")).join("../shared/data"),
    };
    dir.is_dir().then_some(dir)
}

#[test]
fn real_fuel_dataset() {
    let Some(dir) = data_dir() else {
        println!("skipped: no dataset folder (set VIZSIM_DATA)");
        return;
    };
    let volume = raw::load_raw_by_file_name(&dir.join("fuel_64x64x64_uint8.raw")).unwrap();
    assert_eq!(volume.name, "fuel");
    assert_eq!(volume.dims, [64, 64, 64]);
    assert_eq!(volume.bits, 8);
    assert_eq!(volume.data.iter().filter(|&&v| v > 0).count(), 13_731);
}

// ---------------------------------------------------------------------------------------------
// Dataset descriptors

#[test]
fn descriptor_raw_with_defaults_from_file_name() {
    let dir = TempDir::new("desc");
    let values = pattern(4 * 3 * 2, 256);
    dir.write("blob_4x3x2_uint8.raw", &bytes_u8(&values));
    let path = dir.write("blob.toml", b"file = \"blob_4x3x2_uint8.raw\"\n");
    let volume = descriptor::load_descriptor(&path).unwrap();
    assert_volume(&volume, "blob", [4, 3, 2], 8, &values);
    assert_eq!(volume.spacing, [1.0; 3]);
}

#[test]
fn descriptor_raw_explicit_fields() {
    let dir = TempDir::new("descfull");
    let values = pattern(3 * 3 * 2, 65_536);
    std::fs::create_dir(dir.0.join("data")).unwrap();
    dir.write("data/scan.bin.raw", &bytes_u16_be(&values));
    let path = dir.write(
        "d.toml",
        br#"
name = "scan"
file = "data/scan.bin.raw"
dims = [3, 3, 2]
type = "uint16"
endian = "big"
spacing = [0.5, 0.5, 2.0]
"#,
    );
    let volume = descriptor::load_descriptor(&path).unwrap();
    assert_volume(&volume, "scan", [3, 3, 2], 16, &values);
    assert_eq!(volume.spacing, [0.5, 0.5, 2.0]);
}

#[test]
fn descriptor_rejects_unknown_field() {
    let dir = TempDir::new("descunknown");
    let path = dir.write(
        "d.toml",
        b"file = \"a_2x2x2_uint8.raw\"\nspacingz = [1, 1, 1]\n",
    );
    let message = error_text(descriptor::load_descriptor(&path));
    assert!(message.contains("d.toml"), "{message}");
    assert!(message.contains("spacingz"), "{message}");
}

#[test]
fn descriptor_rejects_out_of_range_values() {
    let dir = TempDir::new("descrange");
    dir.write("a_2x2x2_uint8.raw", &[0u8; 8]);
    for (body, field) in [
        ("spacing = [1.0, 0.0, 1.0]", "spacing"),
        ("spacing = [1.0, -2.0, 1.0]", "spacing"),
        ("spacing = [nan, 1.0, 1.0]", "spacing"),
        ("spacing = [inf, 1.0, 1.0]", "spacing"),
        ("type = \"int8\"", "type"),
        ("endian = \"middle\"", "endian"),
        ("dims = [1, 2, 2]", "dims"),
        ("name = \"\"", "name"),
    ] {
        let text = format!("file = \"a_2x2x2_uint8.raw\"\n{body}\n");
        let path = dir.write("d.toml", text.as_bytes());
        let error = descriptor::load_descriptor(&path).expect_err(body);
        assert!(
            matches!(&error, Error::Config { field: f, .. } if f == field),
            "{body}: {error}"
        );
        let message = error.to_string();
        assert!(
            message.contains("d.toml") && message.contains(field),
            "{message}"
        );
    }
}

#[test]
fn descriptor_type_errors_name_the_field() {
    let dir = TempDir::new("desctype");
    let path = dir.write("d.toml", b"file = \"a.raw\"\ndims = [2, 2]\n");
    let message = error_text(descriptor::load_descriptor(&path));
    assert!(
        message.contains("d.toml") && message.contains("dims"),
        "{message}"
    );

    let path = dir.write("d.toml", b"dims = [2, 2, 2]\n");
    let message = error_text(descriptor::load_descriptor(&path));
    assert!(message.contains("file"), "{message}");
}

#[test]
fn descriptor_needs_dims_unless_file_name_gives_them() {
    let dir = TempDir::new("descdims");
    dir.write("plain.raw", &[0u8; 8]);
    let path = dir.write("d.toml", b"file = \"plain.raw\"\n");
    let error = descriptor::load_descriptor(&path).unwrap_err();
    assert!(
        matches!(&error, Error::Config { field, .. } if field == "dims"),
        "{error}"
    );

    let path = dir.write("d.toml", b"file = \"plain.raw\"\ndims = [2, 2, 2]\n");
    assert_eq!(descriptor::load_descriptor(&path).unwrap().dims, [2, 2, 2]);

    let path = dir.write("d.toml", b"file = \"plain.vol\"\ndims = [2, 2, 2]\n");
    let error = descriptor::load_descriptor(&path).unwrap_err();
    assert!(
        matches!(&error, Error::Config { field, .. } if field == "file"),
        "{error}"
    );
}

/// A descriptor whose raw file is not there says so, naming the descriptor and the path (a
/// probe found "field `dims`: required" for a missing file with a free-form name).
#[test]
fn descriptor_with_a_missing_raw_file_names_the_file() {
    let dir = TempDir::new("descmissing");
    for (file, more) in [
        ("scan.raw", ""),
        ("blob_2x2x2_uint8.raw", ""),
        ("scan.raw", "dims = [2, 2, 2]\n"),
    ] {
        let path = dir.write("d.toml", format!("file = \"{file}\"\n{more}").as_bytes());
        let error = descriptor::load_descriptor(&path).unwrap_err();
        let message = error.to_string();
        assert!(
            matches!(&error, Error::Config { field, .. } if field == "file")
                && message.contains("d.toml")
                && message.contains(&dir.0.join(file).display().to_string())
                && message.contains("No such file"),
            "{file} {more}: {message}"
        );
    }
}

#[test]
fn descriptor_delegates_to_nrrd() {
    let dir = TempDir::new("descnrrd");
    let values = pattern(2 * 2 * 3, 256);
    let header = [
        "type: uchar",
        "dimension: 3",
        "sizes: 2 2 3",
        "encoding: raw",
    ];
    dir.write("vol.nrrd", &nrrd_file(&header, &bytes_u8(&values)));
    let path = dir.write("named.toml", b"file = \"vol.nrrd\"\nspacing = [1, 1, 3]\n");
    let volume = descriptor::load_descriptor(&path).unwrap();
    assert_volume(&volume, "named", [2, 2, 3], 8, &values);
    assert_eq!(volume.spacing, [1.0, 1.0, 3.0]);

    let path = dir.write("d.toml", b"file = \"vol.nrrd\"\ndims = [2, 2, 3]\n");
    let error = descriptor::load_descriptor(&path).unwrap_err();
    assert!(
        matches!(&error, Error::Config { field, .. } if field == "dims"),
        "{error}"
    );
}

// ---------------------------------------------------------------------------------------------
// NRRD

#[test]
fn nrrd_attached_raw_8bit() {
    let dir = TempDir::new("nrrd8");
    let values = pattern(3 * 4 * 5, 256);
    let header = [
        "# a comment",
        "type: unsigned char",
        "dimension: 3",
        "space: left-posterior-superior",
        "sizes: 3 4 5",
        "spacings: 0.5 1 2",
        "kinds: domain domain domain",
        "encoding: raw",
        "byte skip: 0",
        "creator:=hand",
    ];
    let path = dir.write("sample.nrrd", &nrrd_file(&header, &bytes_u8(&values)));
    let volume = nrrd::load_nrrd(&path).unwrap();
    assert_volume(&volume, "sample", [3, 4, 5], 8, &values);
    assert_eq!(volume.spacing, [0.5, 1.0, 2.0]);
}

#[test]
fn nrrd_attached_raw_16bit_both_endians_crlf() {
    let dir = TempDir::new("nrrd16");
    let values = pattern(2 * 3 * 2, 65_536);
    for (endian, payload) in [
        ("little", bytes_u16_le(&values)),
        ("big", bytes_u16_be(&values)),
    ] {
        let header = format!(
            "NRRD0005\r\ntype: uint16\r\ndimension: 3\r\nsizes: 2 3 2\r\nendian: {endian}\r\n\
             encoding: raw\r\n\r\n"
        );
        let mut file = header.into_bytes();
        file.extend_from_slice(&payload);
        let path = dir.write("v.nrrd", &file);
        let volume = nrrd::load_nrrd(&path).unwrap();
        assert_volume(&volume, "v", [2, 3, 2], 16, &values);
    }
}

#[test]
fn nrrd_attached_gzip() {
    let dir = TempDir::new("nrrdgz");
    let values = pattern(40 * 30 * 20, 65_536);
    let header = [
        "type: ushort",
        "dimension: 3",
        "sizes: 40 30 20",
        "space directions: (0.5,0,0) (0,0.5,0) (0,0,3)",
        "endian: little",
        "encoding: gzip",
    ];
    let path = dir.write(
        "ct.nrrd",
        &nrrd_file(&header, &gzip(&bytes_u16_le(&values))),
    );
    let volume = nrrd::load_nrrd(&path).unwrap();
    assert_volume(&volume, "ct", [40, 30, 20], 16, &values);
    assert_eq!(volume.spacing, [0.5, 0.5, 3.0]);

    // Concatenated gzip members form one stream.
    let bytes = bytes_u16_le(&values);
    let (first, second) = bytes.split_at(1001);
    let mut payload = gzip(first);
    payload.extend_from_slice(&gzip(second));
    let path = dir.write("ct.nrrd", &nrrd_file(&header, &payload));
    assert_eq!(nrrd::load_nrrd(&path).unwrap().data, values);
}

#[test]
fn nrrd_detached_header() {
    let dir = TempDir::new("nhdr");
    let values = pattern(4 * 2 * 3, 256);
    std::fs::create_dir(dir.0.join("payload")).unwrap();
    dir.write("payload/brain.raw", &bytes_u8(&values));
    let header = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 2 3\nencoding: raw\n\
                  data file: payload/brain.raw\n";
    let path = dir.write("brain.nhdr", header.as_bytes());
    let volume = nrrd::load_nrrd(&path).unwrap();
    assert_volume(&volume, "brain", [4, 2, 3], 8, &values);

    // The `datafile` spelling, gzip encoded.
    dir.write("payload/brain.raw.gz", &gzip(&bytes_u8(&values)));
    let header = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 2 3\nencoding: gz\n\
                  datafile: payload/brain.raw.gz\n";
    let path = dir.write("brain2.nhdr", header.as_bytes());
    assert_eq!(nrrd::load_nrrd(&path).unwrap().data, values);

    let header = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 2 3\nencoding: raw\n\
                  data file: payload/missing.raw\n";
    let path = dir.write("brain3.nhdr", header.as_bytes());
    let message = error_text(nrrd::load_nrrd(&path));
    // Both files named: the header says which volume (issue 17, item 12).
    assert!(
        message.contains("missing.raw") && message.contains("brain3.nhdr"),
        "{message}"
    );
    dir.write("payload/short.raw", &[0u8; 5]);
    let header = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 2 3\nencoding: raw\n\
                  data file: payload/short.raw\n";
    let path = dir.write("brain5.nhdr", header.as_bytes());
    let message = error_text(nrrd::load_nrrd(&path));
    assert!(
        message.contains("short.raw") && message.contains("brain5.nhdr"),
        "{message}"
    );

    let header = "NRRD0004\ntype: uint8\ndimension: 3\nsizes: 4 2 3\nencoding: raw\n";
    let path = dir.write("brain4.nhdr", header.as_bytes());
    let message = error_text(nrrd::load_nrrd(&path));
    assert!(message.contains("data file"), "{message}");
}

/// Loads an attached NRRD made of `header` (+ a 2x2x2 8-bit payload) and returns the error.
fn nrrd_error(header: &[&str]) -> String {
    let dir = TempDir::new("nrrderr");
    let path = dir.write("bad.nrrd", &nrrd_file(header, &[1u8; 8]));
    let message = error_text(nrrd::load_nrrd(&path));
    assert!(message.contains("bad.nrrd"), "{message}");
    message
}

#[test]
fn nrrd_unsupported_type() {
    for ty in ["float", "double", "int", "short", "signed char", "int16"] {
        let type_line = format!("type: {ty}");
        let message = nrrd_error(&[&type_line, "dimension: 3", "sizes: 2 2 2", "encoding: raw"]);
        assert!(
            message.contains("unsupported type") && message.contains(ty),
            "{message}"
        );
    }
}

#[test]
fn nrrd_unsupported_encoding() {
    for encoding in ["ascii", "hex", "bzip2", "txt"] {
        let line = format!("encoding: {encoding}");
        let message = nrrd_error(&["type: uchar", "dimension: 3", "sizes: 2 2 2", &line]);
        assert!(
            message.contains("unsupported encoding") && message.contains(encoding),
            "{message}"
        );
    }
}

#[test]
fn nrrd_unsupported_dimension() {
    let message = nrrd_error(&["type: uchar", "dimension: 2", "sizes: 4 2", "encoding: raw"]);
    assert!(
        message.contains("dimension") && message.contains("3-D"),
        "{message}"
    );
}

#[test]
fn nrrd_other_header_errors() {
    let base = ["type: uchar", "dimension: 3", "encoding: raw"];
    let with = |extra: &[&str]| {
        let mut lines = base.to_vec();
        lines.extend_from_slice(extra);
        nrrd_error(&lines)
    };
    for (extra, expected) in [
        (&["sizes: 2 2"][..], "expected 3 values"),
        (&["sizes: 2 2 x"], "not a valid size"),
        (&["sizes: 99999999 2 2"], "out of range"),
        (&["sizes: 2 2 2", "byte skip: 4"], "byte skip"),
        (&["sizes: 2 2 2", "line skip: 1"], "line skip"),
        (&["sizes: 2 2 2", "spacings: 1 0 1"], "spacings"),
        // Bounded: 3e38 made the camera NaN, 1e-38 rendered nothing (issue 17, item 12).
        (&["sizes: 2 2 2", "spacings: 3e38 1 1"], "out of range"),
        (&["sizes: 2 2 2", "spacings: 1e-38 1 1"], "out of range"),
        (
            &["sizes: 2 2 2", "spacings: 1 1 5000"],
            "differ by more than",
        ),
        (
            &["sizes: 2 2 2", "space directions: (1,0,0) (0,0,0) none"],
            "non-zero",
        ),
        (
            &["sizes: 2 2 2", "space directions: (1,0,0) (0,1,0"],
            "without `)`",
        ),
        (&["sizes: 2 2 2", "endian: middle"], "endian"),
        (&["sizes: 2 2 2", "sizes: 2 2 2"], "given twice"),
        (
            &["sizes: 2 2 2", "this line has no colon"],
            "neither a field",
        ),
        (&["sizes: 2 2 2", "data file: LIST"], "several data files"),
        // The list's file names follow on the next lines; they are not called malformed.
        (
            &["data file: LIST", "a.raw", "b.raw", "sizes: 2 2 2"],
            "several data files",
        ),
        (
            &["sizes: 2 2 2", "data file: s%03d.raw 1 4 1"],
            "several data files",
        ),
    ] {
        let message = with(extra);
        assert!(message.contains(expected), "{extra:?}: {message}");
    }
    let message = nrrd_error(&["dimension: 3", "sizes: 2 2 2", "encoding: raw"]);
    assert!(message.contains("missing field `type`"), "{message}");
    let message = nrrd_error(&[
        "type: ushort",
        "dimension: 3",
        "sizes: 2 2 1",
        "encoding: raw",
    ]);
    assert!(message.contains("out of range"), "{message}");
    let message = nrrd_error(&[
        "type: ushort",
        "dimension: 3",
        "sizes: 2 2 2",
        "encoding: raw",
    ]);
    assert!(message.contains("endian"), "{message}");
}

#[test]
fn nrrd_bad_magic() {
    let dir = TempDir::new("nrrdmagic");
    for first_line in ["NRRD0006", "NRRD", "P6", "\u{0}\u{1}binary"] {
        let file = format!("{first_line}\ntype: uchar\n\n");
        let path = dir.write("m.nrrd", file.as_bytes());
        let message = error_text(nrrd::load_nrrd(&path));
        assert!(message.contains("not a NRRD file"), "{message}");
    }
}

#[test]
fn nrrd_truncated_and_overlong_payloads() {
    let dir = TempDir::new("nrrdtrunc");
    let header = [
        "type: uchar",
        "dimension: 3",
        "sizes: 2 2 2",
        "encoding: raw",
    ];
    let path = dir.write("t.nrrd", &nrrd_file(&header, &[1u8; 5]));
    let message = error_text(nrrd::load_nrrd(&path));
    assert!(
        message.contains("truncated payload: 5 bytes, need 8"),
        "{message}"
    );

    let path = dir.write("t.nrrd", &nrrd_file(&header, &[1u8; 9]));
    let message = error_text(nrrd::load_nrrd(&path));
    assert!(message.contains("9 bytes, need 8"), "{message}");

    let gz = [
        "type: uchar",
        "dimension: 3",
        "sizes: 2 2 2",
        "encoding: gzip",
    ];
    let path = dir.write("t.nrrd", &nrrd_file(&gz, &gzip(&[1u8; 5])));
    let message = error_text(nrrd::load_nrrd(&path));
    assert!(
        message.contains("truncated payload: 5 bytes, need 8"),
        "{message}"
    );

    let path = dir.write("t.nrrd", &nrrd_file(&gz, &gzip(&[1u8; 9])));
    let message = error_text(nrrd::load_nrrd(&path));
    assert!(message.contains("longer than the 8 bytes"), "{message}");

    // The whole payload, then bytes that are no gzip member: said so (it was "unexpected end
    // of file"), whether the bytes look like a member's start or not.
    for trailing in [&b"xyz"[..], b"\x1f\x8b\x08garbage"] {
        let mut payload = gzip(&[1u8; 8]);
        payload.extend_from_slice(trailing);
        let path = dir.write("t.nrrd", &nrrd_file(&gz, &payload));
        let message = error_text(nrrd::load_nrrd(&path));
        assert!(
            message.contains("the 8 bytes needed decode, what follows them does not"),
            "{message}"
        );
    }

    let path = dir.write("t.nrrd", &nrrd_file(&gz, b"definitely not gzip"));
    let message = error_text(nrrd::load_nrrd(&path));
    assert!(
        message.contains("t.nrrd") && message.contains("gzip"),
        "{message}"
    );

    // Header without the blank line that introduces an attached payload.
    let path = dir.write(
        "t.nrrd",
        b"NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: raw\n",
    );
    let message = error_text(nrrd::load_nrrd(&path));
    assert!(message.contains("no payload"), "{message}");
}

#[test]
fn nrrd_huge_header_sizes_do_not_allocate() {
    // 8192 x 8192 x 32 passes the dims guard (2^31 voxels = 4 GiB of uint16) but the payload
    // holds 1 KiB: the loader must fail on the payload without reserving the promised size.
    let dir = TempDir::new("nrrdhuge");
    for encoding in ["raw", "gzip"] {
        let header = [
            "type: uint16",
            "dimension: 3",
            "sizes: 8192 8192 32",
            "endian: little",
            &format!("encoding: {encoding}"),
        ];
        let payload = if encoding == "gzip" {
            gzip(&[3u8; 1024])
        } else {
            vec![3u8; 1024]
        };
        let path = dir.write("huge.nrrd", &nrrd_file(&header, &payload));
        let (result, largest) = with_largest_allocation(|| nrrd::load_nrrd(&path));
        let message = error_text(result);
        assert!(
            message.contains("truncated payload: 1024 bytes"),
            "{message}"
        );
        assert!(
            largest < 1 << 20,
            "{encoding}: allocated {largest} bytes at once"
        );
    }
}

// ---------------------------------------------------------------------------------------------
// Property tests: arbitrary input never panics.

proptest! {
    #![proptest_config(ProptestConfig::with_cases(256))]

    #[test]
    fn nrrd_arbitrary_file_never_panics(
        bytes in prop_oneof![
            proptest::collection::vec(any::<u8>(), 0..2048),
            proptest::collection::vec(any::<u8>(), 0..2048).prop_map(|mut tail| {
                let mut file = b"NRRD0004\n".to_vec();
                file.append(&mut tail);
                file
            }),
        ]
    ) {
        let dir = TempDir::new("prop-bytes");
        let path = dir.write("any.nrrd", &bytes);
        let _ = nrrd::load_nrrd(&path);
    }

    #[test]
    fn nrrd_arbitrary_header_never_panics_nor_overallocates(
        lines in proptest::collection::vec((header_field(), header_value()), 0..12),
        magic in prop_oneof![Just("NRRD0004"), Just("NRRD0001"), Just("NRRD0009")],
        payload in proptest::collection::vec(any::<u8>(), 0..600),
        compress in any::<bool>(),
    ) {
        let dir = TempDir::new("prop-header");
        let payload = if compress { gzip(&payload) } else { payload };
        dir.write("payload.raw", &payload);
        let mut file = format!("{magic}\n");
        for (field, value) in &lines {
            file.push_str(&format!("{field}{value}\n"));
        }
        file.push('\n');
        let mut file = file.into_bytes();
        file.extend_from_slice(&payload);
        let path = dir.write("h.nrrd", &file);

        let (result, largest) = with_largest_allocation(|| nrrd::load_nrrd(&path));
        // Header and payload are tiny, so nothing legitimate needs a large block.
        prop_assert!(largest < 1 << 20, "allocated {} bytes at once", largest);
        let huge_size = lines.iter().any(|(field, value)| {
            *field == "sizes: "
                && value
                    .split_whitespace()
                    .any(|s| s.parse::<u64>().is_ok_and(|n| n > MAX_DIM as u64))
        });
        if huge_size {
            prop_assert!(result.is_err());
        }
    }

    #[test]
    fn descriptor_arbitrary_toml_never_panics(
        text in prop_oneof![
            proptest::collection::vec(any::<u8>(), 0..512),
            proptest::collection::vec(descriptor_line(), 0..8)
                .prop_map(|lines| lines.join("\n").into_bytes()),
        ]
    ) {
        let dir = TempDir::new("prop-desc");
        dir.write("a_2x2x2_uint8.raw", &[1u8; 8]);
        dir.write("b.raw", &[1u8; 16]);
        dir.write(
            "c.nrrd",
            &nrrd_file(&["type: uchar", "dimension: 3", "sizes: 2 2 2", "encoding: raw"], &[1u8; 8]),
        );
        let path = dir.write("d.toml", &text);
        let _ = descriptor::load_descriptor(&path);
    }

    #[test]
    fn raw_file_name_arbitrary_never_panics(name in any::<String>()) {
        let _ = raw::parse_raw_file_name(&name);
    }

    #[test]
    fn raw_file_name_round_trip(
        name in "[a-z][a-z_]{0,10}",
        dims in proptest::array::uniform3(0usize..100_000),
        bits in prop_oneof![Just(8u8), Just(16u8)],
        suffix in "(\\.[A-Za-z0-9_]{0,10})?",
    ) {
        let file_name = format!("{name}_{}x{}x{}_uint{bits}{suffix}.raw", dims[0], dims[1], dims[2]);
        prop_assert_eq!(
            raw::parse_raw_file_name(&file_name),
            Some(RawFileName { name, dims, bits })
        );
    }
}

/// Real field names (with their separator), plus a key/value pair and a comment.
fn header_field() -> impl Strategy<Value = &'static str> {
    proptest::sample::select(vec![
        "type: ",
        "dimension: ",
        "sizes: ",
        "spacings: ",
        "space directions: ",
        "endian: ",
        "encoding: ",
        "byte skip: ",
        "line skip: ",
        "data file: ",
        "datafile: ",
        "content: ",
        "kinds: ",
        "key:=",
        "# ",
        "",
    ])
}

/// Plausible and hostile values: valid ones, huge sizes, malformed vectors, free text.
fn header_value() -> impl Strategy<Value = String> {
    prop_oneof![
        proptest::sample::select(vec![
            "uchar",
            "ushort",
            "uint16",
            "float",
            "signed char",
            "3",
            "2",
            "4",
            "raw",
            "gzip",
            "gz",
            "ascii",
            "little",
            "big",
            "0",
            "-1",
            "1",
            "nan",
            "2 2 2",
            "3 4 5",
            "4 4 4 4",
            "99999999",
            "99999999 2 2",
            "99999999 99999999 99999999",
            "8192 8192 32",
            "1 1 1",
            "0.5 nan 2",
            "inf 1 1",
            "(1,0,0) (0,1,0) (0,0,1)",
            "none (1,0,0) (0,0,2)",
            "(1,0,0) (0,1",
            "((",
            "(,,)",
            "payload.raw",
            "LIST",
            "missing.raw",
            "",
        ])
        .prop_map(String::from),
        "[a-z0-9 .(),:=%-]{0,20}",
        (any::<u32>(), any::<u32>(), any::<u32>()).prop_map(|(x, y, z)| format!("{x} {y} {z}")),
    ]
}

/// Descriptor lines from real keys with valid and invalid values.
fn descriptor_line() -> impl Strategy<Value = String> {
    let key = proptest::sample::select(vec![
        "name", "file", "dims", "type", "spacing", "endian", "bogus",
    ]);
    let value = proptest::sample::select(vec![
        "\"a_2x2x2_uint8.raw\"",
        "\"b.raw\"",
        "\"c.nrrd\"",
        "\"missing.nhdr\"",
        "\"x.vol\"",
        "\"\"",
        "\"uint16\"",
        "\"uint8\"",
        "\"big\"",
        "[2, 2, 2]",
        "[2, 2, 4]",
        "[99999999, 99999999, 99999999]",
        "[1, 2]",
        "[-1, 2, 2]",
        "[1.0, 0.0, 1.0]",
        "[nan, 1, 1]",
        "[1e40, 1, 1]",
        "18446744073709551616",
        "true",
        "{ a = 1 }",
    ]);
    (key, value).prop_map(|(k, v)| format!("{k} = {v}"))
}

/// Two files of one dataset name in the data folder (`fuel_4x4x4` and `fuel_8x8x8`): the short
/// name is ambiguous and says so with both full names (it read "unknown dataset"); each full
/// name loads its own file.
#[test]
fn a_name_two_files_share_is_ambiguous_not_unknown() {
    let dir = std::env::temp_dir().join(format!("vizsim-ambiguous-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("fuel_4x4x4_uint8.raw"), [1u8; 64]).unwrap();
    std::fs::write(dir.join("fuel_8x8x8_uint8.raw"), [2u8; 512]).unwrap();
    let e = vizsim::volume::dataset::load("fuel", Some(&dir))
        .expect_err("ambiguous")
        .to_string();
    assert!(
        e.contains("`fuel` is ambiguous") && e.contains("fuel_4x4x4") && e.contains("fuel_8x8x8"),
        "{e}"
    );
    let small = vizsim::volume::dataset::load("fuel_4x4x4", Some(&dir)).unwrap();
    assert_eq!(small.dims, [4, 4, 4]);
    let _ = std::fs::remove_dir_all(&dir);
}
