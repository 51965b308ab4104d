//! The distance volume as a leaping structure (docs/model.md, "The distance volume"): its
//! configuration, experiment modes, the functional model (image bit-identical to no leaping,
//! never more steps) and the cycle model (image and counts equal the functional model's; every
//! step waits for its distance word from memory).

mod common;

use common::{assert_leap_matches, camera, render_fixed, views};
use vizsim::camera::{Projection, View};
use vizsim::config::{HardwareConfig, LeapStructure};
use vizsim::experiment::spec::Mode;
use vizsim::functional::renderer::Leaping;
use vizsim::occupancy::OccupancyKind;
use vizsim::render::RenderSettings;
use vizsim::transfer::{self, TransferFunction};
use vizsim::volume::phantom::{generate, PhantomKind, PhantomSpec};
use vizsim::volume::{dataset, Volume};

fn ball_tf() -> TransferFunction {
    common::tf(&[
        (0.0, [0.0; 4]),
        (60.0, [0.0; 4]),
        (90.0, [0.2, 0.5, 1.0, 0.3]),
        (200.0, [1.0, 0.8, 0.2, 0.9]),
    ])
}

fn phantom(kind: PhantomKind, size: usize) -> Volume {
    generate(&PhantomSpec {
        size,
        ..PhantomSpec::default_for(kind)
    })
}

fn distance_leapings() -> Vec<Leaping> {
    let mut out = Vec::new();
    for bits in [4, 8] {
        for kind in [OccupancyKind::Zero, OccupancyKind::Class] {
            out.push(Leaping::Distance { bits, kind });
        }
    }
    out
}

/// Every view of `views()`, ERT on and off, 4 and 8 bits, '0' and class visibility, both skip
/// policies (inside `assert_leap_matches`).
fn assert_distance_leaping_is_invisible(volume: &Volume, tf: &TransferFunction, size: u32) {
    for (view, projection) in views() {
        let cam = camera(volume, view.clone(), projection, size);
        for ert in [Some(0.95), None] {
            let settings = RenderSettings {
                ert_threshold: ert,
                ..Default::default()
            };
            let plain = render_fixed(volume, tf, &cam, &settings, Leaping::None);
            for leaping in distance_leapings() {
                let what = format!("{} {view:?} {projection:?} ert {ert:?}", volume.name);
                assert_leap_matches(volume, tf, &cam, &settings, &plain, leaping, &what);
            }
        }
    }
}

// ---------------------------------------------------------------- configuration and modes

#[test]
fn the_default_configuration_serialises_nothing_new() {
    let config = HardwareConfig::default_config();
    assert_eq!(config.occupancy.structure, LeapStructure::Map);
    assert_eq!(config.occupancy.distance_bits, 8);
    let text = toml::to_string(&config).unwrap();
    assert!(!text.contains("structure"), "{text}");
    assert!(!text.contains("distance_bits"), "{text}");
    assert_eq!(Leaping::from_config(&config), Leaping::None);
}

#[test]
fn the_structure_and_bits_are_configured_and_validated() {
    let set = |overrides: &[&str]| {
        let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
        HardwareConfig::load(None, &o)
    };
    let c = set(&[
        "occupancy.structure=\"distance\"",
        "occupancy.distance_bits=4",
    ])
    .unwrap();
    assert_eq!(
        Leaping::from_config(&c),
        Leaping::Distance {
            bits: 4,
            kind: OccupancyKind::Class
        }
    );
    let text = toml::to_string(&c).unwrap();
    assert!(text.contains("structure = \"distance\"") && text.contains("distance_bits = 4"));
    let err = set(&["occupancy.distance_bits=6"]).unwrap_err().to_string();
    assert!(
        err.contains("occupancy.distance_bits") && err.contains("[4, 8]"),
        "{err}"
    );
    let err = set(&["occupancy.structure=\"octree\""])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("structure") && err.contains("map") && err.contains("distance"),
        "{err}"
    );
    let err = set(&["occupancy.structure=distance", "occupancy.hierarchy=true"])
        .unwrap_err()
        .to_string();
    assert!(err.contains("occupancy.hierarchy"), "{err}");
}

#[test]
fn distance_modes_parse_and_print() {
    let m = Mode::parse("ert+distance8").unwrap();
    assert!(m.ert && m.distance_bits == 8 && m.subcube == 0);
    assert_eq!(m.name(), "ert+distance8");
    assert_eq!(Mode::parse("distance4").unwrap().name(), "distance4");
    assert!(Mode::parse("distance6").unwrap_err().contains("[4, 8]"));
    assert!(Mode::parse("distancex").is_err());
    assert!(Mode::parse("leap8+distance8").is_err());
    assert!(Mode::parse("distance8+hier").is_err());
    // Modes without a distance volume serialise as before.
    let json = serde_json::to_string(&Mode::parse("ert+leap8").unwrap()).unwrap();
    assert!(!json.contains("distance"), "{json}");
}

// ---------------------------------------------------------------- functional model

#[test]
fn distance_leaping_is_invisible_on_a_ball() {
    assert_distance_leaping_is_invisible(&common::ball(40), &ball_tf(), 32);
}

#[test]
fn distance_leaping_is_invisible_on_phantoms() {
    for kind in [
        PhantomKind::Shells,
        PhantomKind::Jet,
        PhantomKind::Metaballs,
    ] {
        let volume = phantom(kind, 48);
        let tf = transfer::resolve("class", &volume.name).unwrap_or_else(|_| ball_tf());
        assert_distance_leaping_is_invisible(&volume, &tf, 32);
    }
}

#[test]
fn distance_leaping_leaps_and_eight_bits_leap_further() {
    let volume = common::ball(48);
    let tf = ball_tf();
    let cam = camera(&volume, View::Orbit { k: 7, n: 72 }, Projection::Ortho, 32);
    let settings = RenderSettings::default();
    let steps = |leaping| {
        render_fixed(&volume, &tf, &cam, &settings, leaping)
            .stats()
            .steps()
    };
    let plain = steps(Leaping::None);
    let four = steps(Leaping::Distance {
        bits: 4,
        kind: OccupancyKind::Class,
    });
    let eight = steps(Leaping::Distance {
        bits: 8,
        kind: OccupancyKind::Class,
    });
    assert!(four < plain && eight <= four, "{plain} {four} {eight}");
}

#[test]
fn distance_leaping_is_invisible_on_fuel_and_neghip() {
    let Some(dir) = common::data_dir() else {
        return;
    };
    for name in ["fuel", "neghip"] {
        let volume = dataset::load(name, Some(&dir)).unwrap();
        for kind in ["zero", "class"] {
            let tf = transfer::resolve(kind, name).unwrap();
            assert_distance_leaping_is_invisible(&volume, &tf, 48);
        }
    }
}

// ---------------------------------------------------------------- cycle model

mod cycle {
    use super::*;
    use vizsim::arch::pipeline::{simulate, CycleResult};
    use vizsim::arch::sdram_module::SdramMemory;
    use vizsim::arch::voxel_memory::{IdealMemory, VoxelMemory};
    use vizsim::config::SkipPolicy;
    use vizsim::functional::renderer::FixedRenderer;

    fn config() -> HardwareConfig {
        let mut c = HardwareConfig::default_config();
        c.occupancy.sram_bits = 1 << 24;
        c
    }

    fn run<M: VoxelMemory>(
        renderer: &FixedRenderer,
        cam: &vizsim::camera::Camera,
        config: &HardwareConfig,
        memory: &mut M,
    ) -> CycleResult {
        simulate(
            renderer,
            cam,
            &renderer.skipper(),
            memory,
            config,
            true,
            None,
        )
        .unwrap()
    }

    /// Image, composited samples and (ERT off) samples, leaps and per-ray records equal the
    /// functional model's; one distance read per step (ERT off), at least one with ERT.
    fn check(volume: &Volume, tf: &TransferFunction, size: u32, sdram: bool) {
        for (view, projection) in views() {
            let cam = camera(volume, view.clone(), projection, size);
            for ert in [Some(0.95), None] {
                let settings = RenderSettings {
                    ert_threshold: ert,
                    ..Default::default()
                };
                for leaping in distance_leapings() {
                    for policy in [SkipPolicy::LeapOnly, SkipPolicy::SampleThenLeap] {
                        let mut config = config();
                        config.skip.policy = policy;
                        let renderer =
                            FixedRenderer::new(volume, tf, &settings, &config, leaping).unwrap();
                        let functional = renderer.render(&cam);
                        let cycle = if sdram {
                            config
                                .memory
                                .check_covers_with(volume.dims, true, "test")
                                .unwrap();
                            let mut memory = SdramMemory::new(
                                &config.memory,
                                &config.sdram,
                                volume.dims,
                                config.clock.frequency_mhz,
                            );
                            let c = run(&renderer, &cam, &config, &mut memory);
                            let reads = memory.stats_json()["reads"].as_u64().unwrap();
                            // replicated4: four words per sample, one per distance read.
                            assert_eq!(reads, 4 * c.stats.samples + c.stats.distance_reads);
                            c
                        } else {
                            run(&renderer, &cam, &config, &mut IdealMemory::new(5))
                        };
                        let what =
                            format!("{view:?} {projection:?} ert {ert:?} {leaping:?} {policy:?}");
                        assert!(
                            cycle.frame.pixels == functional.pixels,
                            "image differs: {what}"
                        );
                        let f = functional.stats();
                        let s = &cycle.stats;
                        assert_eq!(s.composited, f.samples, "{what}");
                        assert_eq!(s.rays_terminated_early, f.rays_terminated_early, "{what}");
                        assert!(s.distance_reads >= s.steps, "{what}");
                        if ert.is_none() {
                            assert_eq!(
                                (s.steps, s.samples, s.leaps, s.leap_samples),
                                (f.steps(), f.samples, f.leaps, f.leap_samples),
                                "{what}"
                            );
                            assert_eq!(cycle.frame.rays, functional.rays, "{what}");
                            assert_eq!(s.distance_reads, s.steps, "{what}");
                        }
                    }
                }
            }
        }
    }

    #[test]
    fn cycle_model_equals_functional_with_a_distance_volume_ideal_memory() {
        check(&common::ball(40), &ball_tf(), 24, false);
    }

    #[test]
    fn cycle_model_equals_functional_with_a_distance_volume_sdram() {
        check(&common::ball(40), &ball_tf(), 24, true);
        let shells = phantom(PhantomKind::Shells, 48);
        let tf = transfer::resolve("class", &shells.name).unwrap_or_else(|_| ball_tf());
        check(&shells, &tf, 24, true);
    }

    /// One ray in flight: every step waits for the skip unit and for its distance word, so a
    /// step costs at least skip.latency + the memory latency; the map costs skip.latency.
    #[test]
    fn each_step_waits_for_its_distance_word() {
        let volume = common::ball(32);
        let tf = ball_tf();
        let cam = camera(&volume, View::Front, Projection::Ortho, 8);
        let settings = RenderSettings {
            ert_threshold: None,
            ..Default::default()
        };
        let mut config = config();
        config.ray_queue.rays = 1;
        let latency = 20;
        let leaping = Leaping::Distance {
            bits: 8,
            kind: OccupancyKind::Class,
        };
        let renderer = FixedRenderer::new(&volume, &tf, &settings, &config, leaping).unwrap();
        let c = run(&renderer, &cam, &config, &mut IdealMemory::new(latency));
        let per_step = config.skip.latency as u64 + latency;
        assert!(c.stats.steps > 0);
        assert!(
            c.stats.cycles >= c.stats.steps * per_step,
            "{} cycles for {} steps",
            c.stats.cycles,
            c.stats.steps
        );
        assert!(c.stats.stall_cycles.distance_word > 0);
        // The same frame with the map: no distance reads, no such stalls, fewer cycles.
        let map = Leaping::Occupancy {
            subcube: 4,
            hierarchy: false,
            kind: OccupancyKind::Class,
        };
        let renderer = FixedRenderer::new(&volume, &tf, &settings, &config, map).unwrap();
        let m = run(&renderer, &cam, &config, &mut IdealMemory::new(latency));
        assert_eq!(m.stats.distance_reads, 0);
        assert_eq!(m.stats.stall_cycles.distance_word, 0);
    }

    #[test]
    fn the_distance_array_needs_rows_after_the_volume() {
        let mut memory = HardwareConfig::default_config().memory;
        let dims = [64, 64, 64];
        let rows = memory.rows_needed(dims) as u32;
        memory.rows = rows;
        memory.check_covers(dims, "test").unwrap();
        let err = memory
            .check_covers_with(dims, true, "test")
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("memory.rows") && err.contains("distance"),
            "{err}"
        );
        memory.rows = 2 * rows;
        memory.check_covers_with(dims, true, "test").unwrap();
    }

    /// The distance word of a voxel: the module of the voxel's own word, the rows after the
    /// volume's, the same bank or (other-bank) every bank bit flipped; the default placement is
    /// not serialised.
    #[test]
    fn distance_words_are_placed_as_configured() {
        use vizsim::arch::address_map::{AddressMap, DistancePlacement};
        let mut config = HardwareConfig::default_config().memory;
        assert!(!toml::to_string(&config)
            .unwrap()
            .contains("distance_placement"));
        let dims = [40, 36, 30];
        let rows = config.rows_needed(dims) as u32;
        let same = AddressMap::new(&config, dims);
        config.distance_placement = DistancePlacement::OtherBank;
        assert!(toml::to_string(&config)
            .unwrap()
            .contains("distance_placement = \"other-bank\""));
        let other = AddressMap::new(&config, dims);
        for voxel in [[0, 0, 0], [1, 0, 0], [17, 9, 28], [38, 34, 28]] {
            let (words, _) = same.sample_words(voxel);
            let own = words
                .iter()
                .find(|w| w.module == same.distance_word(voxel).module)
                .copied()
                .unwrap();
            let (a, b) = (same.distance_word(voxel), other.distance_word(voxel));
            assert_eq!(
                (a.bank, a.row, a.column),
                (own.bank, own.row + rows, own.column)
            );
            assert_eq!(
                (b.module, b.bank, b.row, b.column),
                (a.module, a.bank ^ (config.banks - 1), a.row, a.column)
            );
        }
    }

    #[test]
    fn other_bank_placement_keeps_the_image_and_counts() {
        let volume = common::ball(40);
        let tf = ball_tf();
        let cam = camera(&volume, View::Orbit { k: 7, n: 72 }, Projection::Ortho, 24);
        let settings = RenderSettings {
            ert_threshold: None,
            ..Default::default()
        };
        let mut config = config();
        config.memory.distance_placement = vizsim::arch::address_map::DistancePlacement::OtherBank;
        let leaping = Leaping::Distance {
            bits: 8,
            kind: OccupancyKind::Class,
        };
        let renderer = FixedRenderer::new(&volume, &tf, &settings, &config, leaping).unwrap();
        let functional = renderer.render(&cam);
        let mut memory = SdramMemory::new(
            &config.memory,
            &config.sdram,
            volume.dims,
            config.clock.frequency_mhz,
        );
        let c = run(&renderer, &cam, &config, &mut memory);
        assert!(c.frame.pixels == functional.pixels);
        assert_eq!(c.frame.rays, functional.rays);
        assert_eq!(c.stats.distance_reads, c.stats.steps);
    }
}

// ---------------------------------------------------------------- experiments and the run path

#[test]
fn distance_modes_expand_and_run_through_the_run_path() {
    use vizsim::experiment::spec::expand;
    use vizsim::run::{execute, prepare, Model, Probes};
    let text = |modes: &str| {
        format!(
            r#"
name = "distance"
datasets = ["phantom:shells:24"]
tf = ["class"]
modes = [{modes}]
models = ["step", "cycle"]
[frames]
orbit = 72
select = [5]
size = "16x16"
"#
        )
    };
    let before = expand(&text("\"none\", \"ert+leap8\""), "before", None).unwrap();
    let e = expand(
        &text("\"none\", \"ert+leap8\", \"ert+distance8\", \"distance4\""),
        "after",
        None,
    )
    .unwrap();
    assert_eq!(e.runs.len(), 8);
    // Runs without a distance volume keep their keys.
    for r in &before.runs {
        assert!(e.runs.iter().any(|s| s.key == r.key), "{}", r.mode.name());
    }
    let keys: std::collections::HashSet<_> = e.runs.iter().map(|r| &r.key).collect();
    assert_eq!(keys.len(), 8);
    let mut steps = std::collections::BTreeMap::new();
    for r in &e.runs {
        let s = &r.run.hardware.occupancy;
        assert_eq!(
            s.structure == LeapStructure::Distance,
            r.mode.distance_bits > 0,
            "{}",
            r.mode.name()
        );
        if r.mode.distance_bits > 0 {
            assert_eq!(s.distance_bits, r.mode.distance_bits);
            assert_eq!(s.subcube, 0);
        }
        let volume = &e.volumes[&r.run.dataset];
        let prepared = prepare(&r.run, volume).unwrap();
        let report = execute(&r.run, &prepared, Probes::default()).unwrap();
        steps.insert(
            (r.mode.name(), r.run.model == Model::Cycle),
            report.measurements.steps,
        );
    }
    for cycle in [false, true] {
        let none = steps[&("none".to_string(), cycle)];
        assert!(steps[&("distance4".to_string(), cycle)] < none, "{steps:?}");
        assert!(
            steps[&("ert+distance8".to_string(), cycle)] < none,
            "{steps:?}"
        );
    }
    // ERT off: the cycle model takes the functional model's steps.
    assert_eq!(
        steps[&("distance4".to_string(), false)],
        steps[&("distance4".to_string(), true)]
    );
}

/// The cycle model with SDRAM against the functional model on fuel and neghip (a distance
/// volume each, ERT on and off).
#[test]
fn cycle_model_equals_functional_with_a_distance_volume_on_real_data() {
    use vizsim::arch::pipeline::simulate;
    use vizsim::arch::sdram_module::SdramMemory;
    use vizsim::functional::renderer::FixedRenderer;
    let Some(dir) = common::data_dir() else {
        return;
    };
    let config = HardwareConfig::default_config();
    for (name, view, projection, ert, bits) in [
        (
            "fuel",
            View::Orbit { k: 7, n: 72 },
            Projection::Ortho,
            None,
            8,
        ),
        (
            "fuel",
            View::Orbit { k: 50, n: 72 },
            Projection::Persp,
            Some(0.95),
            4,
        ),
        ("neghip", View::Front, Projection::Ortho, Some(0.95), 8),
    ] {
        let volume = dataset::load(name, Some(&dir)).unwrap();
        let tf = transfer::resolve("class", name).unwrap();
        let cam = camera(&volume, view.clone(), projection, 32);
        let settings = RenderSettings {
            ert_threshold: ert,
            ..Default::default()
        };
        let leaping = Leaping::Distance {
            bits,
            kind: OccupancyKind::Class,
        };
        let renderer = FixedRenderer::new(&volume, &tf, &settings, &config, leaping).unwrap();
        let functional = renderer.render(&cam);
        let mut memory = SdramMemory::new(
            &config.memory,
            &config.sdram,
            volume.dims,
            config.clock.frequency_mhz,
        );
        let cycle = simulate(
            &renderer,
            &cam,
            &renderer.skipper(),
            &mut memory,
            &config,
            true,
            None,
        )
        .unwrap();
        assert!(cycle.frame.pixels == functional.pixels, "{name} {view:?}");
        let (f, s) = (functional.stats(), &cycle.stats);
        assert_eq!(s.composited, f.samples, "{name} {view:?}");
        if ert.is_none() {
            assert_eq!(
                (s.samples, s.leaps),
                (f.samples, f.leaps),
                "{name} {view:?}"
            );
            assert_eq!(s.distance_reads, s.steps, "{name} {view:?}");
        }
    }
}

/// `structure_memory`, the memory column of a comparison of the structures, is what the
/// models build and check: the map's bits are the built map's, the distance array's extra rows
/// are exactly what the cycle model needs beyond the volume's, leap values take flag and leap
/// bits of the words the volume has, and bricks one flag each.
#[test]
fn structure_memory_is_what_the_models_build_and_check() {
    use vizsim::run::{self, Model, RunDescription, StructureMemory};
    let dataset_name = "phantom:cast:64";
    let volume = dataset::load(dataset_name, None).unwrap();
    let run_with = |model: Model, sets: &[&str]| {
        let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
        let hardware = HardwareConfig::load(None, &sets).unwrap();
        RunDescription {
            size: (16, 16),
            ..RunDescription::new(dataset_name, "class", model, hardware)
        }
    };
    for (subcube, hierarchy) in [(4, false), (4, true), (8, false), (16, true)] {
        let sets = [
            format!("occupancy.subcube={subcube}"),
            format!("occupancy.hierarchy={hierarchy}"),
        ];
        let sets: Vec<&str> = sets.iter().map(String::as_str).collect();
        let run = run_with(Model::Step, &sets);
        let prepared = run::prepare(&run, &volume).unwrap();
        let built = prepared.fixed().unwrap().map.as_ref().unwrap();
        let memory = StructureMemory::of(&run, volume.dims).unwrap();
        assert_eq!(memory.map_sram_bits, built.storage_bits(hierarchy));
        assert_eq!(
            (memory.extra_sdram_rows_per_bank, memory.voxel_word_bits),
            (0, 0)
        );
        // The float model has no map: nothing to store.
        assert_eq!(
            StructureMemory::of(&run_with(Model::Float, &sets), volume.dims),
            None
        );
    }
    let distance = run_with(Model::Cycle, &["occupancy.structure=distance"]);
    let extra = StructureMemory::of(&distance, volume.dims)
        .unwrap()
        .extra_sdram_rows_per_bank;
    let volume_rows = distance.hardware.memory.rows_needed(volume.dims);
    for (rows, fits) in [
        (volume_rows + extra, true),
        (volume_rows + extra - 1, false),
    ] {
        let mut run = distance.clone();
        run.hardware.memory.rows = rows as u32;
        assert_eq!(run::prepare(&run, &volume).is_ok(), fits, "{rows} rows");
    }
    let leap_values = run_with(Model::Step, &["occupancy.structure=leap-values"]);
    let word = &leap_values.hardware.volume_word;
    let bits = StructureMemory::of(&leap_values, volume.dims)
        .unwrap()
        .voxel_word_bits;
    // The bits a leap word sets beyond its density: the flag and the largest leap value, as
    // the encoder lays them out.
    let layout =
        vizsim::leapvalues::VolumeWord::new(word.word_bits, word.density_bits, word.leap_bits)
            .unwrap();
    let leap_word = layout.encode(0, Some(layout.max_leap())).unwrap();
    assert_eq!(bits, leap_word.count_ones());
    assert!(word.density_bits + bits <= word.word_bits);
    let bricks = StructureMemory::of(&run_with(Model::Float, &["bricks.size=16"]), volume.dims);
    let bricks = bricks.unwrap();
    assert_eq!(
        (bricks.brick_flag_bits, bricks.map_sram_bits),
        (4 * 4 * 4, 0)
    );
    assert_eq!(
        StructureMemory::of(&run_with(Model::Cycle, &[]), volume.dims),
        None
    );
}

/// The '0' kind skips voxels of density 0: with a transfer function that makes density 0
/// visible (fog around an object) that would change the image, so every structure and bricks
/// with the '0' kind refuse it (a probe found 14 dB images from the map, bricks and distance
/// volume), while the class kind, whose test follows the table, leaps and stays exact.
#[test]
fn the_zero_kind_is_refused_when_density_zero_is_visible() {
    use vizsim::functional::renderer::FixedRenderer;
    let volume = phantom(PhantomKind::Metaballs, 32);
    let fog = common::tf(&[
        (0.0, [0.5, 0.5, 0.5, 0.02]),
        (10.0, [0.0; 4]),
        (120.0, [0.0; 4]),
        (200.0, [1.0, 0.3, 0.1, 0.6]),
    ]);
    let settings = RenderSettings::default();
    let config = HardwareConfig::load(None, &[]).unwrap();
    let mut bricks = config.clone();
    bricks.bricks.size = 8;
    bricks.occupancy.kind = OccupancyKind::Zero;
    let zero = OccupancyKind::Zero;
    for (leaping, config) in [
        (
            Leaping::Occupancy {
                subcube: 8,
                hierarchy: false,
                kind: zero,
            },
            &config,
        ),
        (
            Leaping::Distance {
                bits: 8,
                kind: zero,
            },
            &config,
        ),
        (Leaping::None, &bricks),
    ] {
        let error = match FixedRenderer::new(&volume, &fog, &settings, config, leaping) {
            Ok(_) => panic!("{leaping:?} with the '0' kind accepted a visible density 0"),
            Err(e) => e.to_string(),
        };
        assert!(
            error.contains("occupancy.kind") && error.contains("class"),
            "{error}"
        );
        // The same with density 0 invisible is accepted.
        assert!(FixedRenderer::new(&volume, &ball_tf(), &settings, config, leaping).is_ok());
    }
    // The class kind leaps over the fog-free middle range and keeps the image.
    for (view, projection) in views() {
        let cam = camera(&volume, view.clone(), projection, 24);
        let plain = render_fixed(&volume, &fog, &cam, &settings, Leaping::None);
        let class = Leaping::Occupancy {
            subcube: 4,
            hierarchy: false,
            kind: OccupancyKind::Class,
        };
        let leaped = render_fixed(&volume, &fog, &cam, &settings, class);
        assert_eq!(plain.pixels, leaped.pixels, "{view:?}");
    }
}

/// A base configuration that names another structure still sweeps map modes: the mode sets
/// the map back before the configuration is validated (a sub-cube size is refused with the
/// distance volume), so `ert+leap4` runs the map, with the key it has from the default base.
#[test]
fn a_base_configuration_with_another_structure_sweeps_map_modes() {
    use vizsim::experiment::spec::expand;
    let dir = std::env::temp_dir().join(format!("vizsim-dist-base-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let default = std::fs::read_to_string(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/configs/hardware/vizard2.toml"
    ))
    .unwrap();
    let distance = default.replacen("structure = \"map\"", "structure = \"distance\"", 1);
    assert_ne!(default, distance, "the preset names its structure");
    let base = dir.join("distance-base.toml");
    std::fs::write(&base, distance).unwrap();
    let text = |config: &str| {
        format!(
            "name = \"b\"\n{config}datasets = [\"phantom:shells:24\"]\ntf = [\"class\"]\n\
             modes = [\"ert\", \"ert+leap4\", \"ert+leap4+hier\", \"ert+distance8\"]\n\
             models = [\"cycle\"]\n[frames]\norbit = 1\nsize = \"16x16\"\n"
        )
    };
    let from_distance = expand(
        &text(&format!("config = {:?}\n", base.to_str().unwrap())),
        "b",
        None,
    )
    .unwrap();
    let from_default = expand(&text(""), "b", None).unwrap();
    for (a, b) in from_distance.runs.iter().zip(&from_default.runs) {
        let structure = a.run.hardware.occupancy.structure;
        assert_eq!(
            structure == LeapStructure::Distance,
            a.mode.distance_bits > 0,
            "{}",
            a.mode.name()
        );
        assert_eq!(a.run.hardware.occupancy.subcube, a.mode.subcube);
        assert_eq!(a.key, b.key, "{}", a.mode.name());
    }
    std::fs::remove_dir_all(&dir).unwrap();
}
