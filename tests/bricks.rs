//! Ray start and end (issue 15, parts 1 and 2): bounding bricks, clip planes, a clip box and
//! opaque geometry, in the float reference, the functional model and the cycle model, through
//! the one run path (`run::prepare` / `run::execute`).
//!
//! - Bricks only cut samples of zero opacity: the image equals the plain image bit for bit
//!   (each model against itself), with plain stepping and with occupancy-map leaping.
//! - The cycle image equals the functional image with bricks (both setups), clipping and
//!   geometry.
//! - A slow ray-setup traversal starves the ray queue (`stall_cycles.ray_queue_empty`).
//! - Clipping away the whole volume gives the background; bad input gives clear errors.

mod common;

use vizsim::bricks::RayRangeStats;
use vizsim::clip::DepthImage;
use vizsim::compare::compare;
use vizsim::config::HardwareConfig;
use vizsim::error::Error;
use vizsim::run::{execute, prepare, Model, Probes, RunDescription, RunReport};
use vizsim::volume::Volume;

const SIZE: u32 = 64;

fn config(sets: &[&str]) -> HardwareConfig {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    HardwareConfig::load(None, &sets).unwrap()
}

fn description(
    volume: &Volume,
    tf: &str,
    model: Model,
    view: &str,
    sets: &[&str],
) -> RunDescription {
    let mut run = RunDescription::new(&volume.name, tf, model, config(sets));
    run.size = (SIZE, SIZE);
    run.view = view.to_string();
    run
}

fn render(volume: &Volume, tf: &str, model: Model, view: &str, sets: &[&str]) -> RunReport {
    let run = description(volume, tf, model, view, sets);
    let prepared = prepare(&run, volume).unwrap_or_else(|e| panic!("{sets:?}: {e}"));
    execute(&run, &prepared, Probes::default()).unwrap_or_else(|e| panic!("{sets:?}: {e}"))
}

fn phantom(spec: &str) -> Volume {
    vizsim::volume::dataset::load(spec, None).unwrap()
}

fn range(report: &RunReport) -> &RayRangeStats {
    report
        .measurements
        .ray_range
        .as_ref()
        .expect("ray range figures when the feature is on")
}

/// Every model, with and without bricks (and with leaping for the fixed models): the same image,
/// never more samples, and the bricks cut something. Returns the positions cut in total.
fn check_bricks_invisible(volume: &Volume, tfs: &[&str], views: &[&str], bricks: &[usize]) -> u64 {
    let mut cut = 0;
    for &tf in tfs {
        for &view in views {
            for model in [Model::Float, Model::Step] {
                for leap in [None, Some("occupancy.subcube=8")] {
                    if leap.is_some() && model == Model::Float {
                        continue;
                    }
                    let base: Vec<&str> = leap.into_iter().collect();
                    let plain = render(volume, tf, model, view, &base);
                    for &b in bricks {
                        let size = format!("bricks.size={b}");
                        let mut sets = base.clone();
                        sets.push(&size);
                        let with = render(volume, tf, model, view, &sets);
                        let what = format!("{} {tf} {view} {model:?} {sets:?}", volume.name);
                        assert!(
                            plain.frame.pixels == with.frame.pixels,
                            "{what}: bricks changed the image"
                        );
                        assert!(
                            with.measurements.steps <= plain.measurements.steps,
                            "{what}: more steps with bricks"
                        );
                        let r = range(&with);
                        assert_eq!(r.positions_in_box, r.positions_in_range + r.positions_cut);
                        cut += r.positions_cut;
                    }
                }
            }
        }
    }
    cut
}

#[test]
fn bricks_keep_the_image_bit_exact_on_phantoms() {
    for spec in [
        "phantom:sphere:64",
        "phantom:metaballs:64",
        "phantom:shells:48",
    ] {
        let volume = phantom(spec);
        let cut = check_bricks_invisible(
            &volume,
            &["class", "zero"],
            &["front", "orbit:7/72"],
            &[4, 16],
        );
        assert!(
            cut > 0,
            "{spec}: bricks cut nothing, the test checks nothing"
        );
    }
}

#[test]
fn bricks_keep_the_image_bit_exact_with_perspective_and_shading() {
    let volume = phantom("phantom:metaballs:64");
    for shading in [false, true] {
        for model in [Model::Float, Model::Step] {
            let mut plain = description(&volume, "class", model, "orbit:3/72", &[]);
            plain.projection = vizsim::camera::Projection::Persp;
            plain.shading = shading;
            let mut bricks = plain.clone();
            bricks.hardware = config(&["bricks.size=8"]);
            let a = execute(
                &plain,
                &prepare(&plain, &volume).unwrap(),
                Probes::default(),
            )
            .unwrap();
            let b = execute(
                &bricks,
                &prepare(&bricks, &volume).unwrap(),
                Probes::default(),
            )
            .unwrap();
            assert!(
                a.frame.pixels == b.frame.pixels,
                "{model:?} shading {shading}"
            );
            assert!(range(&b).positions_cut > 0);
        }
    }
}

#[test]
fn bricks_keep_the_image_bit_exact_on_fuel_neghip_and_aneurism() {
    let Some(dir) = common::data_dir() else {
        return;
    };
    for name in ["fuel", "neghip"] {
        let volume = vizsim::volume::dataset::load(name, Some(&dir)).unwrap();
        let cut = check_bricks_invisible(&volume, &["class", "zero"], &["orbit:5/72"], &[4, 8, 16]);
        assert!(cut > 0, "{name}: bricks cut nothing");
    }
    // A 256³ view: the aneurism (very sparse), class classification.
    let volume = vizsim::volume::dataset::load("aneurism", Some(&dir)).unwrap();
    let cut = check_bricks_invisible(&volume, &["class"], &["orbit:13/72"], &[16]);
    assert!(cut > 0, "aneurism: bricks cut nothing");
}

fn assert_cycle_equals_functional(
    volume: &Volume,
    tf: &str,
    view: &str,
    sets: &[&str],
) -> (RunReport, RunReport) {
    let step = render(volume, tf, Model::Step, view, sets);
    let cycle = render(volume, tf, Model::Cycle, view, sets);
    assert!(
        step.frame.pixels == cycle.frame.pixels,
        "{sets:?}: cycle image differs from the functional image"
    );
    // The same start and end per ray (steps differ: the cycle model also counts the samples
    // issued after ERT and discarded).
    let ends = |r: &RunReport| -> Vec<(i64, i64, u32)> {
        r.frame
            .rays
            .iter()
            .map(|r| (r.first_sample, r.end_sample, r.positions_cut))
            .collect()
    };
    assert!(
        ends(&step) == ends(&cycle),
        "{sets:?}: ray starts and ends differ"
    );
    (step, cycle)
}

#[test]
fn cycle_image_equals_functional_image_with_bricks_both_setups() {
    let volume = phantom("phantom:metaballs:64");
    let plain = render(&volume, "class", Model::Cycle, "orbit:11/72", &[]);
    for setup in ["traversal", "table"] {
        for leap in ["occupancy.subcube=0", "occupancy.subcube=4"] {
            let s = format!("bricks.setup={setup}");
            let sets = ["bricks.size=8", s.as_str(), leap];
            let (step, cycle) =
                assert_cycle_equals_functional(&volume, "class", "orbit:11/72", &sets);
            assert!(cycle.frame.pixels == plain.frame.pixels, "{sets:?}");
            let r = range(&cycle);
            assert_eq!(r.positions_cut, range(&step).positions_cut);
            assert!(r.positions_cut > 0);
            let cycles = cycle.measurements.cycles.unwrap();
            match setup {
                "traversal" => {
                    assert!(r.bricks_visited.unwrap() > 0 && r.setup_cycles.unwrap() > 0);
                    assert!(r.table_bytes.is_none());
                }
                _ => {
                    assert_eq!(r.table_bytes, Some(SIZE as u64 * SIZE as u64 * 4));
                    // Over the host link (32 bits at 33 MHz: 1.32 bytes per 100 MHz
                    // cycle), as a volume update: the load comes before the first ray.
                    let bytes = r.table_bytes.unwrap() as f64;
                    assert_eq!(r.table_load_cycles, Some((bytes / 1.32).ceil() as u64));
                    assert!(cycles > r.table_load_cycles.unwrap());
                    assert!(r.setup_cycles.is_none());
                }
            }
        }
    }
}

#[test]
fn a_slow_traversal_setup_starves_the_ray_queue() {
    let volume = phantom("phantom:metaballs:64");
    let fast = render(
        &volume,
        "class",
        Model::Cycle,
        "front",
        &[
            "bricks.size=8",
            "bricks.setup_cycles_per_ray=0",
            "bricks.setup_cycles_per_brick=0",
        ],
    );
    let slow = render(
        &volume,
        "class",
        Model::Cycle,
        "front",
        &[
            "bricks.size=8",
            "bricks.setup_cycles_per_ray=40",
            "bricks.setup_cycles_per_brick=4",
        ],
    );
    assert!(fast.frame.pixels == slow.frame.pixels);
    let empty = |r: &RunReport| r.measurements.stall_cycles.unwrap().ray_queue_empty;
    let rays = (SIZE * SIZE) as u64;
    // 40+ cycles per ray through one setup unit: the frame takes at least that, and the queue
    // runs dry most of the time.
    let slow_cycles = slow.measurements.cycles.unwrap();
    assert!(slow_cycles >= 40 * rays, "{slow_cycles}");
    assert!(
        empty(&slow) > empty(&fast) + 20 * rays,
        "ray_queue_empty: slow {} fast {}",
        empty(&slow),
        empty(&fast)
    );
    assert_eq!(
        range(&slow).setup_cycles.unwrap(),
        40 * rays + 4 * range(&slow).bricks_visited.unwrap()
    );
    // Eight setup units in parallel feed the queue eight times as fast: the frame is no longer
    // bound by setup alone (but not faster than with a free setup).
    let parallel = render(
        &volume,
        "class",
        Model::Cycle,
        "front",
        &[
            "bricks.size=8",
            "bricks.setup_cycles_per_ray=40",
            "bricks.setup_cycles_per_brick=4",
            "bricks.setup_units=8",
        ],
    );
    assert!(parallel.frame.pixels == slow.frame.pixels);
    let parallel_cycles = parallel.measurements.cycles.unwrap();
    assert!(
        parallel_cycles * 2 < slow_cycles && parallel_cycles >= fast.measurements.cycles.unwrap(),
        "8 units {parallel_cycles}, 1 unit {slow_cycles}"
    );
    assert!(empty(&parallel) < empty(&slow));
}

#[test]
fn the_default_configuration_is_unchanged_without_the_feature() {
    let text = serde_json::to_string(&HardwareConfig::default_config()).unwrap();
    for section in ["bricks", "clip", "geometry"] {
        assert!(!text.contains(section), "{section} written out while off");
    }
    let volume = phantom("phantom:sphere:32");
    let r = render(&volume, "class", Model::Cycle, "front", &[]);
    assert!(r.measurements.ray_range.is_none());
    let json = serde_json::to_string(&r.measurements).unwrap();
    assert!(!json.contains("ray_range") && !json.contains("positions_cut"));
}

const CLIP_PLANE: &str = "clip.planes=[{point=[32.0,32.0,32.0],normal=[1.0,0.3,0.0]}]";
const CLIP_BOX: &[&str] = &["clip.box=[[8.0,0.0,10.0],[60.0,50.0,63.0]]"];
const SPHERE: &[&str] = &[
    "geometry.shape=sphere",
    "geometry.centre=[40.0,30.0,24.0]",
    "geometry.radius=14.0",
    "geometry.colour=[0.9,0.5,0.1]",
];

#[test]
fn clipping_and_geometry_agree_in_all_three_models() {
    let volume = phantom("phantom:metaballs:64");
    let mut cases: Vec<Vec<&str>> = vec![vec![CLIP_PLANE], CLIP_BOX.to_vec(), SPHERE.to_vec()];
    let mut all = vec![CLIP_PLANE, "bricks.size=8", "occupancy.subcube=4"];
    all.extend(CLIP_BOX);
    all.extend(SPHERE);
    cases.push(all);
    let plain = render(&volume, "class", Model::Step, "orbit:9/72", &[]);
    for sets in &cases {
        let (step, _) = assert_cycle_equals_functional(&volume, "class", "orbit:9/72", sets);
        assert!(
            step.frame.pixels != plain.frame.pixels,
            "{sets:?} changed nothing"
        );
        assert!(range(&step).positions_cut > 0, "{sets:?}");
        assert!(
            step.measurements.steps < plain.measurements.steps,
            "{sets:?}"
        );
        let float = render(&volume, "class", Model::Float, "orbit:9/72", sets);
        let cmp = compare(&step.frame.pixels, &float.frame.pixels, SIZE, SIZE).unwrap();
        assert!(cmp.psnr_db > 35.0, "{sets:?}: fixed vs float {cmp:?}");
        // The same sample indices are cut in the float and the fixed model.
        let cut = |r: &RunReport| r.frame.rays.iter().filter(|r| r.positions_cut > 0).count();
        let (a, b) = (cut(&step), cut(&float));
        assert!(
            a.abs_diff(b) <= a / 20 + 2,
            "{sets:?}: rays cut fixed {a} float {b}"
        );
    }
    // The sphere is opaque: where no volume sample is left in front of it, its colour shows.
    let sphere = render(&volume, "zero", Model::Step, "front", SPHERE);
    let centre = sphere.frame.pixels[(SIZE / 2 * SIZE + SIZE / 2 + 6) as usize];
    assert_eq!(centre[3], 255);
    assert!(
        sphere
            .frame
            .pixels
            .iter()
            .filter(|p| **p != [0, 0, 0, 255])
            .count()
            > 0
    );
}

#[test]
fn a_clip_plane_that_removes_the_whole_volume_gives_the_background() {
    let volume = phantom("phantom:metaballs:32");
    let away = "clip.planes=[{point=[100.0,0.0,0.0],normal=[1.0,0.0,0.0]}]";
    for model in [Model::Float, Model::Step, Model::Cycle] {
        let r = render(&volume, "zero", model, "orbit:4/72", &[away]);
        assert!(
            r.frame.pixels.iter().all(|p| *p == [0, 0, 0, 255]),
            "{model:?}: a pixel is not the background"
        );
        assert_eq!(r.measurements.samples, 0, "{model:?}");
        assert!(range(&r).positions_cut > 0);
    }
    // The opposite plane keeps everything: the plain image.
    let keep = "clip.planes=[{point=[-100.0,0.0,0.0],normal=[1.0,0.0,0.0]}]";
    for model in [Model::Float, Model::Step, Model::Cycle] {
        let plain = render(&volume, "zero", model, "orbit:4/72", &[]);
        let kept = render(&volume, "zero", model, "orbit:4/72", &[keep]);
        assert!(plain.frame.pixels == kept.frame.pixels, "{model:?}");
        assert_eq!(range(&kept).positions_cut, 0);
    }
}

fn scratch(name: &str) -> std::path::PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-bricks-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

#[test]
fn a_depth_image_ends_rays_at_its_surface() {
    let volume = phantom("phantom:metaballs:32");
    let dir = scratch("depth");
    // Left half: a surface right at the start of every ray (nothing sampled, its colour shows);
    // right half: no surface (the plain image).
    let depth: Vec<f32> = (0..SIZE * SIZE)
        .map(|i| if i % SIZE < SIZE / 2 { 0.0 } else { -1.0 })
        .collect();
    let path = dir.join("half.depth");
    DepthImage {
        width: SIZE,
        height: SIZE,
        depth,
    }
    .write(&path)
    .unwrap();
    let file = format!("geometry.file={}", path.display());
    let sets = [
        "geometry.shape=depth-file",
        file.as_str(),
        "geometry.colour=[0.0,1.0,0.0]",
    ];
    let (step, _) = assert_cycle_equals_functional(&volume, "zero", "front", &sets);
    let plain = render(&volume, "zero", Model::Step, "front", &[]);
    let float = render(&volume, "zero", Model::Float, "front", &sets);
    for (i, ((p, q), f)) in step
        .frame
        .pixels
        .iter()
        .zip(&plain.frame.pixels)
        .zip(&float.frame.pixels)
        .enumerate()
    {
        if i as u32 % SIZE < SIZE / 2 {
            assert_eq!(*p, [0, 255, 0, 255], "pixel {i}");
            assert_eq!(*f, [0, 255, 0, 255], "float pixel {i}");
        } else {
            assert_eq!(p, q, "pixel {i}");
        }
    }
    // A depth image of another size is refused with the field named.
    let run = description(&volume, "zero", Model::Step, "front", &sets);
    let mut other = run.clone();
    other.size = (SIZE, SIZE + 1);
    let err = prepare(&other, &volume)
        .err()
        .expect("size mismatch refused");
    assert!(err.to_string().contains("geometry.file"), "{err}");
    // A truncated file is refused too.
    let bytes = std::fs::read(&path).unwrap();
    std::fs::write(&path, &bytes[..bytes.len() - 3]).unwrap();
    let err = prepare(&run, &volume)
        .err()
        .expect("truncated file refused");
    assert!(matches!(err, Error::Format { .. }), "{err}");
}

#[test]
fn bad_input_gives_clear_errors() {
    let load = |sets: &[&str]| {
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        HardwareConfig::load(None, &sets)
            .expect_err("refused")
            .to_string()
    };
    let e = load(&["clip.planes=[{point=[1.0,2.0,3.0],normal=[0.0,0.0,0.0]}]"]);
    assert!(
        e.contains("clip.planes[0].normal") && e.contains("zero"),
        "{e}"
    );
    let e = load(&["bricks.size=6"]);
    assert!(
        e.contains("bricks.size") && e.contains("power of two"),
        "{e}"
    );
    let e = load(&["bricks.size=64"]);
    assert!(e.contains("bricks.size"), "{e}");
    let e = load(&["bricks.setup=dda"]);
    assert!(e.contains("bricks") || e.contains("setup"), "{e}");
    let e = load(&["clip.box=[[0.0,0.0,0.0]]"]);
    assert!(e.contains("clip.box"), "{e}");
    let e = load(&["clip.box=[[5.0,0.0,0.0],[4.0,9.0,9.0]]"]);
    assert!(e.contains("clip.box"), "{e}");
    let e = load(&["geometry.shape=depth-file"]);
    assert!(e.contains("geometry.file"), "{e}");
    let e = load(&["clip.planes=[{point=[nan,0.0,0.0],normal=[1.0,0.0,0.0]}]"]);
    assert!(e.contains("clip.planes[0].point"), "{e}");
    let e = load(&["geometry.radius=0.0"]);
    assert!(e.contains("geometry.radius"), "{e}");
    // The table's rate is the host link's (one field each, not a second copy in bricks).
    let e = load(&["bricks.table_bytes_per_cycle=1.0"]);
    assert!(e.contains("unknown field"), "{e}");
    let e = load(&["bricks.setup_units=0"]);
    assert!(e.contains("bricks.setup_units"), "{e}");
    // Depth files that are not depth files: errors naming the file, no panic.
    let dir = scratch("hostile-depth");
    for (name, bytes) in [
        ("empty", Vec::new()),
        ("no-header", vec![0u8; 100]),
        ("bad-size", b"VIZDEPTH -3 4\n".to_vec()),
        ("huge", b"VIZDEPTH 99999999 99999999\n".to_vec()),
        ("wrong-magic", b"DEPTH 2 2\n0000000000000000".to_vec()),
    ] {
        let path = dir.join(name);
        std::fs::write(&path, bytes).unwrap();
        let e = DepthImage::read(&path).expect_err(name);
        assert!(e.to_string().contains(name), "{name}: {e}");
    }
    // A brick larger than the volume: refused when the run is prepared.
    let volume = phantom("phantom:sphere:16");
    let run = description(&volume, "class", Model::Step, "front", &["bricks.size=32"]);
    let e = prepare(&run, &volume).err().expect("refused").to_string();
    assert!(
        e.contains("bricks.size") && e.contains("larger than the volume"),
        "{e}"
    );
    let run = description(&volume, "class", Model::Float, "front", &["bricks.size=32"]);
    assert!(prepare(&run, &volume).is_err());
}

#[test]
fn experiment_modes_for_bricks() {
    use vizsim::experiment::spec::{expand, Mode};
    let mode = Mode::parse("ert+bricks16+leap8").unwrap();
    assert_eq!(
        (mode.bricks, mode.subcube, mode.brick_table),
        (16, 8, false)
    );
    assert_eq!(mode.name(), "ert+leap8+bricks16");
    assert_eq!(Mode::parse(&mode.name()).unwrap(), mode);
    assert!(Mode::parse("bricks8+table").unwrap().brick_table);
    assert!(Mode::parse("table").is_err());
    assert!(Mode::parse("bricks6").is_err());
    // Tables and charts keep the modes apart.
    use vizsim::tables::mode_label;
    let labels: std::collections::BTreeSet<String> = [
        "ert",
        "ert+bricks8",
        "ert+bricks8+table",
        "ert+leap8",
        "ert+leap8+bricks16",
    ]
    .iter()
    .map(|m| mode_label(m))
    .collect();
    assert_eq!(labels.len(), 5, "{labels:?}");
    assert_eq!(mode_label("ert+leap8"), "8³");
    // Without bricks a mode serialises as before (existing result lines unchanged).
    let plain = serde_json::to_string(&Mode::parse("ert+leap8").unwrap()).unwrap();
    assert!(!plain.contains("brick"), "{plain}");

    let text = r#"
name = "bricks-modes"
datasets = ["phantom:sphere:16"]
tf = ["class"]
modes = ["ert", "ert+bricks8", "ert+bricks8+table", "ert+bricks32"]
models = ["step"]
[frames]
orbit = 72
select = [0]
size = "16x16"
"#;
    let expansion = expand(text, "test", None).unwrap();
    let configs: Vec<(usize, String)> = expansion
        .runs
        .iter()
        .map(|r| {
            (
                r.run.hardware.bricks.size,
                format!("{:?}", r.run.hardware.bricks.setup),
            )
        })
        .collect();
    assert_eq!(
        configs,
        vec![
            (0, "Traversal".into()),
            (8, "Traversal".into()),
            (8, "Table".into())
        ]
    );
    // bricks32 is larger than the 16³ volume: left out, with the reason.
    assert_eq!(expansion.skipped.len(), 1);
    assert!(expansion.skipped[0].reason.contains("brick"));
    // Run keys: the run without bricks keeps the key it had before bricks existed (the
    // configuration's serialisation has no bricks section).
    let without = serde_json::to_string(&expansion.runs[0].run.hardware).unwrap();
    assert!(!without.contains("bricks"));
    assert_ne!(expansion.runs[1].key, expansion.runs[2].key);
}

#[test]
fn render_and_sim_take_bricks_and_print_the_ray_range() {
    let dir = scratch("cli");
    for command in ["render", "sim"] {
        let png = dir.join(format!("{command}.png"));
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_vizsim"))
            .args([
                command,
                "--dataset",
                "phantom:metaballs:32",
                "--size",
                "24x24",
            ])
            .args(["--bricks", "8", "--set", "bricks.setup=table"])
            .args(["-o", png.to_str().unwrap()])
            .output()
            .unwrap();
        let stdout = String::from_utf8_lossy(&out.stdout);
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        assert!(stdout.contains("ray start/end:"), "{stdout}");
        assert_eq!(
            stdout.contains("start/end table 2304 bytes"),
            command == "sim",
            "{stdout}"
        );
    }
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args([
            "render",
            "--dataset",
            "phantom:metaballs:32",
            "--size",
            "24x24",
            "--bricks",
            "12",
        ])
        .args(["-o", dir.join("bad.png").to_str().unwrap()])
        .output()
        .unwrap();
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("bricks.size"));
}

#[test]
fn jumping_over_dead_cycles_equals_ticking_with_a_slow_setup() {
    use vizsim::arch::pipeline::simulate;
    use vizsim::arch::voxel_memory::IdealMemory;
    use vizsim::functional::renderer::{FixedRenderer, Leaping};
    let volume = phantom("phantom:metaballs:32");
    let tf = vizsim::transfer::resolve("class", &volume.name).unwrap();
    let cam = common::camera(
        &volume,
        vizsim::camera::View::Orbit { k: 4, n: 72 },
        vizsim::camera::Projection::Ortho,
        24,
    );
    for setup in ["traversal", "table"] {
        let s = format!("bricks.setup={setup}");
        let config = config(&[
            "bricks.size=8",
            &s,
            "bricks.setup_cycles_per_ray=9",
            "bricks.setup_cycles_per_brick=3",
        ]);
        let renderer = FixedRenderer::new(
            &volume,
            &tf,
            &vizsim::render::RenderSettings::default(),
            &config,
            Leaping::None,
        )
        .unwrap();
        let sim = |skip_dead: bool| {
            let mut memory = IdealMemory::new(20);
            simulate(
                &renderer,
                &cam,
                &renderer.skipper(),
                &mut memory,
                &config,
                skip_dead,
                None,
            )
            .unwrap()
        };
        let (jumped, ticked) = (sim(true), sim(false));
        assert!(jumped.stats.skipped_cycles > 0, "{setup}");
        let mut a = jumped.stats.clone();
        a.skipped_cycles = 0;
        assert_eq!(a, ticked.stats, "{setup}");
        assert!(jumped.frame.pixels == ticked.frame.pixels);
        assert!(ticked.stats.ray_range.is_some());
    }
}

#[test]
fn bricks_keep_the_image_bit_exact_with_leap_values_in_the_volume() {
    let volume = phantom("phantom:metaballs:64");
    for regions in ["empty", "homogeneous"] {
        let r = format!("leap_values.regions={regions}");
        let base = ["occupancy.structure=leap-values", r.as_str()];
        for model in [Model::Float, Model::Step] {
            let plain = render(&volume, "class", model, "orbit:2/72", &base);
            let mut sets = base.to_vec();
            sets.push("bricks.size=8");
            let with = render(&volume, "class", model, "orbit:2/72", &sets);
            assert!(
                plain.frame.pixels == with.frame.pixels,
                "{regions} {model:?}"
            );
            assert!(range(&with).positions_cut > 0);
        }
        let mut sets = base.to_vec();
        sets.push("bricks.size=8");
        assert_cycle_equals_functional(&volume, "class", "orbit:2/72", &sets);
    }
}

#[test]
fn a_cylinder_pointer_ends_rays_and_shows_in_all_three_models() {
    let volume = phantom("phantom:metaballs:64");
    // Along x through the middle of the volume: a horizontal bar across the front view.
    let sets = [
        "geometry.shape=cylinder",
        "geometry.centre=[-10.0,31.5,31.5]",
        "geometry.end=[74.0,31.5,31.5]",
        "geometry.radius=2.5",
        "geometry.colour=[0.0,0.0,1.0]",
    ];
    let (step, _) = assert_cycle_equals_functional(&volume, "zero", "front", &sets);
    let float = render(&volume, "zero", Model::Float, "front", &sets);
    let cmp = compare(&step.frame.pixels, &float.frame.pixels, SIZE, SIZE).unwrap();
    assert!(cmp.psnr_db > 35.0, "{cmp:?}");
    let plain = render(&volume, "zero", Model::Step, "front", &[]);
    let row = |r: &RunReport, y: u32| -> Vec<[u8; 4]> {
        r.frame.pixels[(y * SIZE) as usize..((y + 1) * SIZE) as usize].to_vec()
    };
    // The bar's rows: every pixel shows some blue (the pointer behind or in front of the
    // volume); far from it the image is the plain one.
    for y in [SIZE / 2 - 1, SIZE / 2] {
        assert!(
            row(&step, y).iter().all(|p| p[2] > 0 && p[3] == 255),
            "row {y}"
        );
        assert!(row(&step, y) != row(&plain, y));
    }
    for y in [2, SIZE - 3] {
        assert!(row(&step, y) == row(&plain, y), "row {y}");
    }
    assert!(range(&step).positions_cut > 0);
    // An axis of zero length is refused.
    let e = HardwareConfig::load(
        None,
        &[
            "geometry.shape=cylinder".into(),
            "geometry.centre=[1.0,1.0,1.0]".into(),
            "geometry.end=[1.0,1.0,1.0]".into(),
        ],
    )
    .expect_err("refused")
    .to_string();
    assert!(e.contains("geometry.end"), "{e}");
}

/// The '0' kind skips all-zero bricks. A transfer function that gives density 0 an opacity
/// too small for the fixed-point table (0.001 rounds to 0 at 8 bits) still shows in the float
/// reference, whose bricks would then change its image: every model refuses it alike.
#[test]
fn zero_kind_bricks_are_refused_when_density_zero_has_any_opacity() {
    let volume = common::ball(16);
    let tf = common::tf(&[
        (0.0, [0.5, 0.5, 0.5, 0.001]),
        (40.0, [0.5, 0.5, 0.5, 0.001]),
        (200.0, [1.0, 0.8, 0.2, 0.6]),
    ]);
    let config = HardwareConfig::load(
        None,
        &[
            "bricks.size=4".to_string(),
            "occupancy.kind=\"zero\"".to_string(),
        ],
    )
    .unwrap();
    let settings = vizsim::render::RenderSettings::default();
    let fixed = vizsim::functional::renderer::FixedRenderer::new(
        &volume,
        &tf,
        &settings,
        &config,
        vizsim::functional::renderer::Leaping::None,
    );
    let float = vizsim::render::float::FloatRenderer::new(&volume, &tf, &settings)
        .unwrap()
        .with_ray_range(&config);
    for (model, error) in [
        ("fixed", fixed.err().map(|e| e.to_string())),
        ("float", float.err().map(|e| e.to_string())),
    ] {
        let error = error.unwrap_or_else(|| panic!("{model}: accepted"));
        assert!(error.contains("occupancy.kind"), "{model}: {error}");
    }
}
