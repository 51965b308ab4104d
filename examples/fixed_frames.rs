//! Profiling harness for the functional fixed-point model: renders the benchmark frame
//! (`fixed_256` / `fixed_256_in_memory` in benches/render.rs: aneurism 256³, orbit view 5/72,
//! 256×256, no ERT, one thread) `FRAMES` times after preparing once, and prints the steps and
//! the time per frame. Under an instruction-counting profiler the difference between two frame
//! counts is the cost of the frames alone, without loading and preprocessing:
//!
//!   cargo build --release --example fixed_frames
//!   valgrind --tool=cachegrind --cache-sim=yes target/release/examples/fixed_frames leapvalues 1
//!   valgrind --tool=cachegrind --cache-sim=yes target/release/examples/fixed_frames leapvalues 3
//!
//! STRUCTURE: none | subcube8 | leapvalues | leapvalues-homogeneous | distance8.
//! Needs ../shared/data (or VIZSIM_DATA).

use std::time::Instant;

use vizsim::camera::{Camera, Projection, View};
use vizsim::config::{HardwareConfig, LeapRegions, LeapStructure};
use vizsim::functional::renderer::{FixedRenderer, Leaping};
use vizsim::render::RenderSettings;
use vizsim::transfer;

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let (structure, frames) = match &args[1..] {
        [s, n] => (s.as_str(), n.parse::<usize>().expect("FRAMES is a count")),
        _ => {
            eprintln!("usage: fixed_frames STRUCTURE FRAMES");
            std::process::exit(2);
        }
    };
    let mut config = HardwareConfig::default_config();
    match structure {
        "none" => {}
        "subcube8" => config.occupancy.subcube = 8,
        "distance8" => config.occupancy.structure = LeapStructure::Distance,
        "leapvalues" => config.occupancy.structure = LeapStructure::LeapValues,
        "leapvalues-homogeneous" => {
            config.occupancy.structure = LeapStructure::LeapValues;
            config.leap_values.regions = LeapRegions::Homogeneous;
        }
        other => {
            eprintln!("unknown structure {other:?}");
            std::process::exit(2);
        }
    }
    let data_dir = vizsim::volume::dataset::data_dir(None)
        .or_else(|| Some(concat!(env!("CARGO_MANIFEST_DIR"), "/../shared/data").into()));
    let volume = vizsim::volume::dataset::load("aneurism", data_dir.as_deref())
        .expect("the aneurism dataset (../shared/data or VIZSIM_DATA)");
    let tf = transfer::resolve("class", &volume.name).unwrap();
    let settings = RenderSettings {
        ert_threshold: None,
        ..Default::default()
    };
    let renderer = FixedRenderer::new(
        &volume,
        &tf,
        &settings,
        &config,
        Leaping::from_config(&config),
    )
    .unwrap();
    let camera = Camera::for_volume(
        glam::Vec3::from(volume.extent()),
        View::Orbit { k: 5, n: 72 },
        Projection::Ortho,
        256,
        256,
    )
    .unwrap();
    let pool = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap();
    let started = Instant::now();
    let mut steps = 0;
    for _ in 0..frames {
        steps = pool.install(|| renderer.render(&camera)).stats().steps();
    }
    let per_frame = started.elapsed().as_secs_f64() / frames.max(1) as f64;
    println!(
        "{structure}: {steps} steps per frame, {:.1} ms per frame, {:.1} M steps/s",
        per_frame * 1e3,
        steps as f64 / per_frame / 1e6
    );
}
