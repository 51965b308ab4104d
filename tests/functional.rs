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
        let cam = camera(&volume, view, projection, 64);
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
        let cam = camera(&volume, view, projection, 48);
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
