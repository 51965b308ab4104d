//! Shared test helpers.
#![allow(dead_code)]

use std::path::PathBuf;

use vizsim::transfer::{ControlPoint, TransferFunction};
use vizsim::volume::Volume;

/// The real-data folder when present (env VIZSIM_DATA, else ../shared/data). Tests that need
/// it print that they skip when it is absent; CI always has it.
pub fn data_dir() -> Option<PathBuf> {
    let dir = std::env::var_os("VIZSIM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../shared/data"));
    if dir.is_dir() {
        Some(dir)
    } else {
        eprintln!(
            "SKIP: no data directory at {} (set VIZSIM_DATA)",
            dir.display()
        );
        None
    }
}

/// A small ball of density falling off from 200 at the centre to 0 at radius `n`/3.
pub fn ball(n: usize) -> Volume {
    let c = (n - 1) as f32 / 2.0;
    let r = n as f32 / 3.0;
    let mut data = Vec::with_capacity(n * n * n);
    for z in 0..n {
        for y in 0..n {
            for x in 0..n {
                let d = ((x as f32 - c).powi(2) + (y as f32 - c).powi(2) + (z as f32 - c).powi(2))
                    .sqrt();
                data.push(if d < r {
                    (200.0 * (1.0 - d / r)).round() as u16
                } else {
                    0
                });
            }
        }
    }
    Volume::new("test-ball", [n, n, n], [1.0; 3], 8, data).unwrap()
}

/// A volume filled with one value.
pub fn uniform(dims: [usize; 3], value: u16) -> Volume {
    Volume::new(
        "test-uniform",
        dims,
        [1.0; 3],
        8,
        vec![value; dims[0] * dims[1] * dims[2]],
    )
    .unwrap()
}

pub fn tf(points: &[(f32, [f32; 4])]) -> TransferFunction {
    TransferFunction::new(
        "test".into(),
        String::new(),
        points
            .iter()
            .map(|&(value, rgba)| ControlPoint { value, rgba })
            .collect(),
        "test",
    )
    .unwrap()
}
