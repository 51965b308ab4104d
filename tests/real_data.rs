//! The three models on the real datasets. These run whenever ../shared/data (or VIZSIM_DATA)
//! is there, as in CI, and print SKIP otherwise.

mod common;

use common::{assert_leap_matches, assert_leaping_is_invisible, camera, render_fixed};
use vizsim::camera::{Projection, View};
use vizsim::compare::compare;
use vizsim::functional::renderer::Leaping;
use vizsim::occupancy::OccupancyKind;
use vizsim::render::float::FloatRenderer;
use vizsim::render::RenderSettings;
use vizsim::transfer;
use vizsim::volume::{dataset, Volume};

fn load(name: &str) -> Option<Volume> {
    let dir = common::data_dir()?;
    Some(dataset::load(name, Some(&dir)).unwrap())
}

#[test]
fn leaping_is_invisible_on_fuel_and_neghip() {
    for name in ["fuel", "neghip"] {
        let Some(volume) = load(name) else { return };
        for kind in ["zero", "class"] {
            let tf = transfer::resolve(kind, name).unwrap();
            assert_leaping_is_invisible(&volume, &tf, 48);
        }
    }
}

/// A CI-sized sample on the 256³ volumes: one view per dataset (ortho oblique or perspective),
/// three sub-cube sizes with the hierarchy and map kind varied between them.
#[test]
fn leaping_is_invisible_on_a_sample_of_256_cubed_views() {
    let sample = [
        ("aneurism", View::Orbit { k: 13, n: 72 }, Projection::Ortho),
        (
            "foot-lossy",
            View::Orbit { k: 40, n: 72 },
            Projection::Persp,
        ),
        ("bonsai", View::Orbit { k: 61, n: 72 }, Projection::Ortho),
    ];
    let leapings = [
        (4, true, OccupancyKind::Class),
        (16, false, OccupancyKind::Zero),
        (64, true, OccupancyKind::Class),
    ];
    for (name, view, projection) in sample {
        let Some(volume) = load(name) else { return };
        let tf = transfer::resolve("class", name).unwrap();
        let cam = camera(&volume, view.clone(), projection, 64);
        let settings = RenderSettings::default();
        let plain = render_fixed(&volume, &tf, &cam, &settings, Leaping::None);
        for (subcube, hierarchy, kind) in leapings {
            assert_leap_matches(
                &volume,
                &tf,
                &cam,
                &settings,
                &plain,
                Leaping::Occupancy {
                    subcube,
                    hierarchy,
                    kind,
                },
                name,
            );
        }
    }
}

/// With the default widths the fixed-point image stays close to the float reference on every
/// real dataset (the bound docs/precision.md reports).
#[test]
fn fixed_point_stays_close_to_float_on_real_data() {
    let Some(dir) = common::data_dir() else {
        return;
    };
    for entry in dataset::scan(&dir).unwrap() {
        let volume = dataset::load(&entry.name, Some(&dir)).unwrap();
        let tf = transfer::resolve("class", &volume.name).unwrap();
        let cam = camera(&volume, View::Orbit { k: 5, n: 72 }, Projection::Ortho, 64);
        let settings = RenderSettings::default();
        let fixed = render_fixed(&volume, &tf, &cam, &settings, Leaping::None);
        let float = FloatRenderer::new(&volume, &tf, &settings)
            .unwrap()
            .render(&cam);
        let cmp = compare(&fixed.pixels, &float.pixels, 64, 64).unwrap();
        assert!(cmp.psnr_db > 35.0, "{}: {cmp:?}", volume.name);
    }
}

/// The cycle model (SDRAM) against the functional model on real data: fuel and neghip over
/// sub-cube sizes, hierarchy, ERT and projections; one 256³ view; both skip policies.
#[test]
fn cycle_model_equals_functional_on_real_data() {
    use vizsim::arch::pipeline::simulate;
    use vizsim::arch::sdram_module::SdramMemory;
    use vizsim::config::{HardwareConfig, SkipPolicy};
    use vizsim::functional::renderer::FixedRenderer;
    let mut config = HardwareConfig::default_config();
    config.occupancy.sram_bits = 1 << 24;
    let cases = [
        (
            "fuel",
            View::Orbit { k: 7, n: 72 },
            Projection::Ortho,
            Some(0.95),
            Leaping::None,
        ),
        (
            "fuel",
            View::Orbit { k: 50, n: 72 },
            Projection::Persp,
            None,
            Leaping::Occupancy {
                subcube: 2,
                hierarchy: true,
                kind: OccupancyKind::Class,
            },
        ),
        (
            "neghip",
            View::Front,
            Projection::Ortho,
            Some(0.95),
            Leaping::Occupancy {
                subcube: 8,
                hierarchy: false,
                kind: OccupancyKind::Zero,
            },
        ),
        (
            "neghip",
            View::Orbit { k: 20, n: 72 },
            Projection::Persp,
            Some(0.95),
            Leaping::Occupancy {
                subcube: 32,
                hierarchy: true,
                kind: OccupancyKind::Class,
            },
        ),
        (
            "aneurism",
            View::Orbit { k: 13, n: 72 },
            Projection::Ortho,
            Some(0.95),
            Leaping::Occupancy {
                subcube: 16,
                hierarchy: true,
                kind: OccupancyKind::Class,
            },
        ),
    ];
    for (name, view, projection, ert, leaping) in cases {
        let Some(volume) = load(name) else { return };
        let tf = transfer::resolve("class", name).unwrap();
        let cam = camera(&volume, view.clone(), projection, 32);
        let settings = RenderSettings {
            ert_threshold: ert,
            ..Default::default()
        };
        for policy in [SkipPolicy::LeapOnly, SkipPolicy::SampleThenLeap] {
            if leaping == Leaping::None && policy == SkipPolicy::SampleThenLeap {
                continue;
            }
            let mut config = config.clone();
            config.skip.policy = policy;
            let renderer = FixedRenderer::new(&volume, &tf, &settings, &config, leaping).unwrap();
            let mut memory = SdramMemory::new(&config.memory, &config.sdram, volume.dims, 100.0);
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
            let functional = renderer.render(&cam);
            let what = format!("{name} {view:?} {leaping:?} {policy:?}");
            assert!(cycle.frame.pixels == functional.pixels, "{what}");
            let (s, f) = (&cycle.stats, functional.stats());
            assert_eq!(s.composited, f.samples, "{what}");
            if ert.is_none() {
                assert_eq!(
                    (s.steps, s.samples, s.leaps, s.leap_samples),
                    (f.steps(), f.samples, f.leaps, f.leap_samples),
                    "{what}"
                );
            }
            assert!(s.cycles >= s.steps);
        }
    }
}
