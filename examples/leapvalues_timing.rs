//! Times each leap-value preprocessing step and the distance volume on the cast phantom (the
//! figures quoted in docs/leapvalues.md). Run:
//!
//! ```text
//! cargo run --release --example leapvalues_timing -- [SIZE [REPETITIONS]]   # default 256 3
//! ```
//!
//! Parameters: range 12 (|v − seed| <= 12, 4.7 % of the 8-bit range, the metal's ±6 noise band
//! fits whatever metal voxel seeds), minimum region 64 voxels, S_max = S = 1, the default
//! 32-bit word; distance volume with the phantom's class transfer function, 8-bit table.
//! Each step's time is the minimum over the repetitions; all of them are printed.

use std::time::Duration;

use vizsim::functional::arith::ClassificationTable;
use vizsim::leapvalues::{
    distance_volume, preprocess, LeapValueParams, SegmentationParams, VolumeWord, VoxelClass,
};
use vizsim::transfer;
use vizsim::volume::phantom::{generate, parse_spec};

fn ms(d: Duration) -> String {
    format!("{:.0}", d.as_secs_f64() * 1e3)
}

fn main() -> anyhow::Result<()> {
    let args: Vec<String> = std::env::args().collect();
    let size: usize = args.get(1).map_or(Ok(256), |s| s.parse())?;
    let repetitions: usize = args.get(2).map_or(Ok(3), |s| s.parse())?;
    let volume = generate(&parse_spec(&format!("cast:{size}"))?);
    let params = LeapValueParams {
        segmentation: SegmentationParams {
            range: 12,
            min_region_size: 64,
        },
        max_spacing: 1.0,
        spacing: 1.0,
        layout: VolumeWord::default(),
    };
    let tf = transfer::resolve("class", &volume.name)?;
    let table = ClassificationTable::build(&tf, 256, 8, 1.0);
    println!(
        "volume {} ({} voxels), {} rayon threads",
        volume.name,
        volume.voxel_count(),
        rayon::current_num_threads()
    );
    let mut runs = Vec::new();
    for _ in 0..repetitions {
        let p = preprocess(&volume, &params)?;
        let d8 = distance_volume(&volume, 8, |lo, hi| table.any_visible(lo, hi))?;
        let d4 = distance_volume(&volume, 4, |lo, hi| table.any_visible(lo, hi))?;
        let t = p.times();
        println!(
            "  run: segmentation {} ms, classification {} ms, leap values {} ms, encoding {} ms, \
             distance volume 8 bit {} ms, 4 bit {} ms",
            ms(t.segmentation),
            ms(t.classification),
            ms(t.leap_values),
            ms(t.encoding),
            ms(d8.elapsed),
            ms(d4.elapsed)
        );
        runs.push((p, d8, d4));
    }
    let min = |f: &dyn Fn(&(_, _, _)) -> Duration| runs.iter().map(f).min().unwrap_or_default();
    let (p, d8, _) = &runs[0];
    let s = &p.segmentation;
    let mut largest: Vec<_> = s.regions.iter().collect();
    largest.sort_by_key(|r| std::cmp::Reverse(r.voxels));
    println!(
        "regions {} (dissolved {} regions, {} voxels); largest: {}",
        s.regions.len(),
        s.dissolved_regions,
        s.dissolved_voxels,
        largest
            .iter()
            .take(4)
            .map(|r| format!(
                "{} voxels mean {} boundary {}",
                r.voxels,
                r.mean,
                r.boundary.len()
            ))
            .collect::<Vec<_>>()
            .join("; ")
    );
    let no_region = p
        .classification
        .classes
        .iter()
        .filter(|&&c| c == VoxelClass::NoRegion)
        .count();
    println!(
        "guard distance {}; guards {}, leap voxels {}, no region {}; leap values: mean {:.2}, max {}, saturated {}",
        p.classification.guard.voxels(),
        p.classification.guards,
        p.classification.leaps,
        no_region,
        p.leap_values.mean,
        p.leap_values.max,
        p.leap_values.saturated
    );
    println!(
        "distance volume: visible cells {}, saturated cells (8 bit) {}",
        d8.visible_cells, d8.saturated_cells
    );
    println!("| step | time (ms, best of {repetitions}) |");
    println!("|---|---:|");
    for (name, time) in [
        ("1 segmentation", min(&|r| r.0.segmentation.elapsed)),
        ("2 classification", min(&|r| r.0.classification.elapsed)),
        ("3 leap values", min(&|r| r.0.leap_values.elapsed)),
        ("4 encoding", min(&|r| r.0.encoded.elapsed)),
        ("steps 1-4", min(&|r| r.0.times().total())),
        ("5 distance volume (8 bit)", min(&|r| r.1.elapsed)),
        ("5 distance volume (4 bit)", min(&|r| r.2.elapsed)),
    ] {
        println!("| {name} | {} |", ms(time));
    }
    Ok(())
}
