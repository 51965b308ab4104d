//! The aneurism fly-through (`configs/paths/aneurism.toml`): the path loads and is valid at
//! every one of its 120 frames; with the real data present, the eye stays outside every vessel
//! at every frame (the eight voxels around it are dark) and frames along the path render (something is seen) with the cycle image
//! equal to the functional image and leaping invisible, in the ordinary and the iso mode.
//! Without the data folder the data checks print SKIP and pass.

mod common;

use vizsim::camera::Projection;
use vizsim::config::HardwareConfig;
use vizsim::path::CameraPath;
use vizsim::run::{execute, prepare, Model, Probes, RunDescription, RunReport};
use vizsim::volume::Volume;

const FILE: &str = "configs/paths/aneurism.toml";
const FRAMES: u32 = 120;

#[test]
fn the_aneurism_path_loads_and_is_valid_at_every_frame() {
    let path = CameraPath::load(std::path::Path::new(FILE)).unwrap();
    assert_eq!(path.keys.len(), 10);
    path.check_frames(FRAMES).unwrap();
    // It climbs from the bottom of the volume to the aneurism sac (z = 160).
    let first = path.pose(0, FRAMES).unwrap();
    let last = path.pose(FRAMES - 1, FRAMES).unwrap();
    assert!(first.eye.z < 20.0 && last.look_at.z > 150.0);
}

fn render(volume: &Volume, model: Model, frame: u32, sets: &[&str]) -> RunReport {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    let config = HardwareConfig::load(None, &sets).unwrap();
    let mut run = RunDescription::new(&volume.name, "class", model, config);
    run.size = (40, 40);
    run.view = format!("path:{FILE}:{frame}/{FRAMES}");
    run.projection = Projection::Persp;
    let prepared = prepare(&run, volume).unwrap_or_else(|e| panic!("{sets:?}: {e}"));
    execute(&run, &prepared, Probes::default()).unwrap_or_else(|e| panic!("{sets:?}: {e}"))
}

#[test]
fn the_aneurism_path_stays_outside_the_vessels_and_renders() {
    let Some(dir) = common::data_dir() else {
        return;
    };
    let volume = vizsim::volume::dataset::load("aneurism", Some(&dir)).unwrap();
    let path = CameraPath::load(std::path::Path::new(FILE)).unwrap();
    // The eye is never inside a vessel: the eight voxels of its cell are dark.
    for k in 0..FRAMES {
        let eye = path.pose(k, FRAMES).unwrap().eye;
        let base = [eye.x, eye.y, eye.z].map(|c| (c.floor() as i64).clamp(0, 254) as usize);
        for corner in 0..8 {
            let p = [0, 1, 2].map(|a| base[a] + (corner >> a & 1));
            let v = volume.get(p[0], p[1], p[2]);
            assert!(
                v <= 30,
                "frame {k}: eye {eye:?} in the cell of vessel voxel {p:?} ({v})"
            );
        }
    }
    for frame in [0, 60, FRAMES - 1] {
        for iso in [&[][..], &["iso.enabled=true", "iso.value=80"][..]] {
            let plain = render(&volume, Model::Step, frame, iso);
            let lit = plain.frame.pixels.iter().filter(|p| p[0] > 20).count();
            assert!(
                lit > 40,
                "frame {frame} {iso:?}: only {lit} pixels show a vessel"
            );
            let mut leap = iso.to_vec();
            leap.push("occupancy.subcube=8");
            let leaping = render(&volume, Model::Step, frame, &leap);
            assert!(
                plain.frame.pixels == leaping.frame.pixels,
                "frame {frame} {iso:?}: leaping changed the image"
            );
            assert!(leaping.measurements.steps < plain.measurements.steps);
            let cycle = render(&volume, Model::Cycle, frame, &leap);
            assert!(
                cycle.frame.pixels == leaping.frame.pixels,
                "frame {frame} {iso:?}: cycle image differs from the functional image"
            );
        }
    }
}
