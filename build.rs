//! Embeds every transfer function in configs/transfer/ into the binary, so that `--tf zero` and
//! `--tf class` work from any directory and a fresh clone needs nothing else.

use std::fmt::Write;

fn main() {
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
