//! The functional fixed-point model against itself (leaping vs not) and against the float
//! reference.

mod common;

use common::{assert_leaping_is_invisible, camera, render_fixed, views};
use vizsim::camera::{Projection, View};
use vizsim::compare::compare;
use vizsim::config::HardwareConfig;
use vizsim::functional::renderer::{FixedRenderer, Leaping};
use vizsim::occupancy::OccupancyKind;
use vizsim::render::float::FloatRenderer;
use vizsim::render::RenderSettings;
use vizsim::transfer::TransferFunction;

fn ball_tf() -> TransferFunction {
    common::tf(&[
        (0.0, [0.0; 4]),
        (60.0, [0.0; 4]),
        (90.0, [0.2, 0.5, 1.0, 0.2]),
        (200.0, [1.0, 0.8, 0.2, 0.8]),
    ])
}

#[test]
fn leaping_image_equals_plain_image_on_a_ball() {
    assert_leaping_is_invisible(&common::ball(64), &ball_tf(), 48);
}

#[test]
fn leaping_actually_leaps_and_saves_steps() {
    let volume = common::ball(64);
    let tf = ball_tf();
    let cam = camera(&volume, View::Orbit { k: 3, n: 72 }, Projection::Ortho, 64);
    let settings = RenderSettings::default();
    let plain = render_fixed(&volume, &tf, &cam, &settings, Leaping::None).stats();
    let leap = render_fixed(
        &volume,
        &tf,
        &cam,
        &settings,
        Leaping::Occupancy {
            subcube: 8,
            hierarchy: false,
            kind: OccupancyKind::Class,
        },
    )
    .stats();
    assert!(leap.leaps > 0 && leap.skipped > 0);
    assert!(
        leap.steps() * 2 < plain.steps(),
        "{} vs {}",
        leap.steps(),
        plain.steps()
    );
    assert_eq!(leap.samples + leap.skipped, plain.samples);
}

#[test]
fn hierarchy_never_costs_more_steps_on_sparse_data() {
    let volume = common::ball(64);
    let tf = ball_tf();
    let cam = camera(&volume, View::Orbit { k: 11, n: 72 }, Projection::Ortho, 64);
    let settings = RenderSettings::default();
    let run = |hierarchy| {
        render_fixed(
            &volume,
            &tf,
            &cam,
            &settings,
            Leaping::Occupancy {
                subcube: 4,
                hierarchy,
                kind: OccupancyKind::Class,
            },
        )
        .stats()
    };
    let (one, two) = (run(false), run(true));
    assert!(two.leaps < one.leaps, "{} vs {}", two.leaps, one.leaps);
    assert_eq!(one.samples, two.samples);
}

#[test]
fn fixed_point_image_is_close_to_the_float_reference() {
    let volume = common::ball(64);
    let tf = ball_tf();
    let settings = RenderSettings::default();
    for (view, projection) in views() {
        let cam = camera(&volume, view.clone(), projection, 64);
        let fixed = render_fixed(&volume, &tf, &cam, &settings, Leaping::None);
        let float = FloatRenderer::new(&volume, &tf, &settings)
            .unwrap()
            .render(&cam);
        let cmp = compare(&fixed.pixels, &float.pixels, 64, 64).unwrap();
        assert!(cmp.psnr_db > 40.0, "{view:?} {projection:?}: {cmp:?}");
        assert!(
            cmp.max_abs_error.iter().all(|&e| e <= 8),
            "{view:?}: {cmp:?}"
        );
    }
}

#[test]
fn fixed_point_ert_stops_at_the_threshold_in_a_uniform_medium() {
    // Per-sample opacity 0.3 (77/255 in the 8-bit table): A crosses 0.95 after 9 samples.
    let volume = common::uniform([24, 24, 24], 200);
    let tf = common::tf(&[(0.0, [1.0, 1.0, 1.0, 0.3])]);
    let cam = camera(&volume, View::Front, Projection::Ortho, 24);
    let frame = render_fixed(
        &volume,
        &tf,
        &cam,
        &RenderSettings::default(),
        Leaping::None,
    );
    let centre = frame.rays[12 * 24 + 12];
    assert_eq!(centre.samples, 9);
    assert!(centre.terminated_early);
}

#[test]
fn fixed_point_is_bit_identical_on_one_and_two_threads() {
    let volume = common::ball(40);
    let tf = ball_tf();
    let cam = camera(&volume, View::Orbit { k: 9, n: 72 }, Projection::Persp, 40);
    let mut config = HardwareConfig::default_config();
    config.occupancy.subcube = 4;
    let renderer = FixedRenderer::new(
        &volume,
        &tf,
        &RenderSettings::default(),
        &config,
        Leaping::from_config(&config),
    )
    .unwrap();
    let run = |n| {
        rayon::ThreadPoolBuilder::new()
            .num_threads(n)
            .build()
            .unwrap()
            .install(|| renderer.render(&cam))
    };
    let (a, b) = (run(1), run(2));
    assert_eq!(a.pixels, b.pixels);
    assert_eq!(a.rays, b.rays);
}

#[test]
fn map_larger_than_the_sram_is_an_error() {
    let volume = common::ball(64);
    let mut config = HardwareConfig::default_config();
    config.occupancy.sram_bits = 1000; // 2^3 sub-cubes of 64^3: 32768 bits
    let err = FixedRenderer::new(
        &volume,
        &ball_tf(),
        &RenderSettings::default(),
        &config,
        Leaping::Occupancy {
            subcube: 2,
            hierarchy: false,
            kind: OccupancyKind::Zero,
        },
    )
    .err()
    .unwrap()
    .to_string();
    assert!(
        err.contains("occupancy.sram_bits") && err.contains("32768"),
        "{err}"
    );
}

#[test]
fn bad_subcube_sizes_are_errors() {
    let volume = common::ball(16);
    for subcube in [3, 32, 128] {
        let err = FixedRenderer::new(
            &volume,
            &ball_tf(),
            &RenderSettings::default(),
            &HardwareConfig::default_config(),
            Leaping::Occupancy {
                subcube,
                hierarchy: false,
                kind: OccupancyKind::Zero,
            },
        )
        .err()
        .unwrap()
        .to_string();
        assert!(err.contains(&subcube.to_string()), "{err}");
    }
}

#[test]
fn position_widths_too_narrow_for_the_volume_are_an_error() {
    let volume = common::ball(64);
    let mut config = HardwareConfig::default_config();
    config.ray.position_int_bits = 5; // positions up to 31 < 63
    let err = FixedRenderer::new(
        &volume,
        &ball_tf(),
        &RenderSettings::default(),
        &config,
        Leaping::None,
    )
    .err()
    .unwrap()
    .to_string();
    assert!(err.contains("position_int_bits"), "{err}");
}

#[test]
fn shading_keeps_leaping_invisible_and_stays_close_to_float() {
    let volume = common::ball(48);
    let tf = ball_tf();
    let settings = RenderSettings {
        shading: true,
        ..Default::default()
    };
    for (view, projection) in views() {
        let cam = camera(&volume, view.clone(), projection, 48);
        let plain = render_fixed(&volume, &tf, &cam, &settings, Leaping::None);
        for (subcube, hierarchy, kind) in [
            (2, false, OccupancyKind::Class),
            (8, true, OccupancyKind::Zero),
            (16, true, OccupancyKind::Class),
        ] {
            common::assert_leap_matches(
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
                "shaded ball",
            );
        }
        let float = FloatRenderer::new(&volume, &tf, &settings)
            .unwrap()
            .render(&cam);
        let cmp = compare(&plain.pixels, &float.pixels, 48, 48).unwrap();
        assert!(cmp.psnr_db > 40.0, "{view:?} {projection:?}: {cmp:?}");
        // Shading must actually change the picture, or this test checks nothing.
        let unshaded = render_fixed(
            &volume,
            &tf,
            &cam,
            &RenderSettings::default(),
            Leaping::None,
        );
        assert!(unshaded.pixels != plain.pixels);
    }
}

/// A 64×8×8 volume empty except for the slab x = 40..=43, and one axis-aligned ray through it
/// at y = z = 2.5 (positions on the integer x, so every count is known by hand). With s = 4 the
/// dilated occupancy bits make sub-cubes 9 and 10 (x = 36..=43) occupied and the rest empty.
fn slab_ray_counts(
    origin_x: f32,
    dir_x: f32,
    hierarchy: bool,
    policy: vizsim::config::SkipPolicy,
    ert: Option<f32>,
) -> vizsim::render::RayRecord {
    use vizsim::camera::Ray;
    use vizsim::functional::setup::setup_ray;
    let dims = [64, 8, 8];
    let data = (0..64 * 8 * 8)
        .map(|i| {
            if (40..=43).contains(&(i % 64)) {
                100
            } else {
                0
            }
        })
        .collect();
    let volume = vizsim::volume::Volume::new("slab", dims, [1.0; 3], 8, data).unwrap();
    let tf = common::tf(&[(0.0, [0.0; 4]), (100.0, [1.0, 0.5, 0.2, 1.0])]);
    let mut config = HardwareConfig::default_config();
    config.skip.policy = policy;
    let settings = RenderSettings {
        ert_threshold: ert,
        ..Default::default()
    };
    let leaping = Leaping::Occupancy {
        subcube: 4,
        hierarchy,
        kind: OccupancyKind::Class,
    };
    let renderer = FixedRenderer::new(&volume, &tf, &settings, &config, leaping).unwrap();
    let ray = Ray {
        origin: glam::Vec3A::new(origin_x, 2.5, 2.5),
        dir: glam::Vec3A::new(dir_x, 0.0, 0.0),
        t_min: 0.0,
    };
    let fixed = setup_ray(&ray, dims, 1.0, &renderer.widths);
    renderer.cast(&fixed, &renderer.skipper()).1
}

#[test]
fn skip_policies_take_the_hand_counted_steps_on_a_known_empty_run() {
    use vizsim::config::SkipPolicy::{LeapOnly, SampleThenLeap};
    // (samples, leaps, leap samples, skipped positions); steps = samples + leaps.
    let counts = |r: vizsim::render::RayRecord| (r.samples, r.leaps, r.leap_samples, r.skipped);
    for (origin, dir) in [(0.0, 1.0), (63.0, -1.0)] {
        // 64 positions: sub-cubes 0..=8 and 11..=15 are empty (14 leaps of 4), 36..=43 sampled.
        let lo = slab_ray_counts(origin, dir, false, LeapOnly, None);
        assert_eq!(counts(lo), (8, 14, 0, 56), "dir {dir}: {lo:?}");
        // The same 22 steps, each a sample: 14 of them a sample followed by a leap of 4.
        let stl = slab_ray_counts(origin, dir, false, SampleThenLeap, None);
        assert_eq!(counts(stl), (22, 0, 14, 42), "dir {dir}: {stl:?}");
        // Hierarchy: 2×2×2 groups (8 voxels in x) leap whole; groups 4 and 5 hold the slab,
        // so their empty sub-cubes 8 and 11 leap 4. 4 + 1 + 1 + 2 = 8 leaps, 8 samples.
        let lo = slab_ray_counts(origin, dir, true, LeapOnly, None);
        assert_eq!(counts(lo), (8, 8, 0, 56), "dir {dir} hierarchy: {lo:?}");
        let stl = slab_ray_counts(origin, dir, true, SampleThenLeap, None);
        assert_eq!(counts(stl), (16, 0, 8, 48), "dir {dir} hierarchy: {stl:?}");
    }
    // Starting at x = 3, the last position of empty sub-cube 0: the leap there is n = 1, so
    // sample-then-leap takes an ordinary sample (not a leap sample). 61 positions.
    let lo = slab_ray_counts(3.0, 1.0, false, LeapOnly, None);
    assert_eq!(counts(lo), (8, 14, 0, 53), "{lo:?}");
    let stl = slab_ray_counts(3.0, 1.0, false, SampleThenLeap, None);
    assert_eq!(counts(stl), (22, 0, 13, 39), "{stl:?}");
    // ERT at the first opaque sample (x = 40): 9 leaps, then 36..=40 sampled; the zero-opacity
    // leap samples before it change neither the pixel nor where the ray stops.
    let ert = Some(0.95);
    let lo = slab_ray_counts(0.0, 1.0, false, LeapOnly, ert);
    let stl = slab_ray_counts(0.0, 1.0, false, SampleThenLeap, ert);
    assert_eq!(counts(lo), (5, 9, 0, 36), "{lo:?}");
    assert_eq!(counts(stl), (14, 0, 9, 27), "{stl:?}");
    assert!(lo.terminated_early && stl.terminated_early);
}

#[test]
fn sample_then_leap_samples_each_empty_subcube_once_and_keeps_the_step_count() {
    use vizsim::config::SkipPolicy;
    let volume = common::ball(64);
    let tf = ball_tf();
    let cam = camera(&volume, View::Orbit { k: 3, n: 72 }, Projection::Persp, 64);
    let settings = RenderSettings::default();
    let plain = render_fixed(&volume, &tf, &cam, &settings, Leaping::None).stats();
    for (subcube, hierarchy) in [(4, false), (8, true), (16, false)] {
        let leaping = Leaping::Occupancy {
            subcube,
            hierarchy,
            kind: OccupancyKind::Class,
        };
        let run = |policy| {
            common::render_fixed_with(&volume, &tf, &cam, &settings, leaping, policy).stats()
        };
        let (lo, stl) = (run(SkipPolicy::LeapOnly), run(SkipPolicy::SampleThenLeap));
        let what = format!("{leaping:?}: leap-only {lo:?}, sample-then-leap {stl:?}");
        assert!(lo.leaps > 0 && stl.leap_samples > 0, "{what}");
        assert_eq!(stl.steps(), lo.steps(), "{what}");
        assert_eq!(stl.samples, lo.samples + lo.leaps, "{what}");
        assert_eq!(stl.leaps, 0, "{what}");
        assert!(stl.leap_samples <= lo.leaps, "{what}");
        assert!(stl.steps() < plain.steps(), "{what}");
        assert_eq!(
            stl.rays_terminated_early, lo.rays_terminated_early,
            "{what}"
        );
    }
}
