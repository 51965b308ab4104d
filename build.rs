//! Embeds every transfer function in configs/transfer/ into the binary, so that `--tf zero` and
//! `--tf class` work from any directory and a fresh clone needs nothing else; and a hash of the
//! model's sources (`VIZSIM_MODEL_HASH`), which a sweep writes beside each result so that a
//! resumed sweep reuses only timings the same model measured.

use std::fmt::Write;

/// FNV-1a over every file under `paths` (sorted, each path then its bytes).
fn model_hash(paths: &[&str]) -> u64 {
    fn walk(path: &std::path::Path, files: &mut Vec<std::path::PathBuf>) {
        if path.is_dir() {
            for entry in std::fs::read_dir(path).into_iter().flatten().flatten() {
                walk(&entry.path(), files);
            }
        } else if path.is_file() {
            files.push(path.to_path_buf());
        }
    }
    let mut files = Vec::new();
    for path in paths {
        println!("cargo:rerun-if-changed={path}");
        walk(std::path::Path::new(path), &mut files);
    }
    files.sort();
    let mut hash: u64 = 0xcbf2_9ce4_8422_2325;
    for file in files {
        let bytes = std::fs::read(&file).unwrap_or_default();
        for b in file.to_string_lossy().bytes().chain([0]).chain(bytes) {
            hash = (hash ^ b as u64).wrapping_mul(0x0100_0000_01b3);
        }
    }
    hash
}

fn main() {
    let hash = model_hash(&[
        "src",
        "configs/hardware",
        "configs/transfer",
        "Cargo.toml",
        "Cargo.lock",
    ]);
    println!("cargo:rustc-env=VIZSIM_MODEL_HASH={hash:016x}");
    let dir = std::path::Path::new("configs/transfer");
    println!("cargo:rerun-if-changed={}", dir.display());
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .map(|entries| {
            entries
                .flatten()
                .map(|e| e.file_name().to_string_lossy().into_owned())
                .filter(|n| n.ends_with(".toml"))
                .collect()
        })
        .unwrap_or_default();
    names.sort();
    let mut code = String::from("pub static EMBEDDED: &[(&str, &str)] = &[\n");
    for name in &names {
        let stem = name.trim_end_matches(".toml");
        let _ = writeln!(
            code,
            "    ({stem:?}, include_str!(concat!(env!(\"CARGO_MANIFEST_DIR\"), \"/configs/transfer/{name}\"))),"
        );
        println!("cargo:rerun-if-changed=configs/transfer/{name}");
    }
    code.push_str("];\n");
    let out = std::path::Path::new(&std::env::var("OUT_DIR").unwrap()).join("transfer_presets.rs");
    std::fs::write(out, code).unwrap();
}
