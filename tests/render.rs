mod common;

use glam::Vec3;
use vizsim::camera::{Camera, Projection, View};
use vizsim::render::float::FloatRenderer;
use vizsim::render::{sample_range, RenderSettings};

fn camera_for(dims: [usize; 3], view: View, projection: Projection, size: u32) -> Camera {
    let extent = Vec3::new(
        (dims[0] - 1) as f32,
        (dims[1] - 1) as f32,
        (dims[2] - 1) as f32,
    );
    Camera::for_volume(extent, view, projection, size, size).unwrap()
}

#[test]
fn image_is_bit_identical_on_one_and_two_threads() {
    let volume = common::ball(40);
    let tf = common::tf(&[
        (0.0, [0.0; 4]),
        (40.0, [0.2, 0.5, 1.0, 0.1]),
        (200.0, [1.0, 0.8, 0.2, 0.7]),
    ]);
    for projection in [Projection::Ortho, Projection::Persp] {
        let camera = camera_for(volume.dims, View::Orbit { k: 7, n: 72 }, projection, 48);
        let settings = RenderSettings {
            shading: true,
            ..Default::default()
        };
        let renderer = FloatRenderer::new(&volume, &tf, &settings).unwrap();
        let run = |threads| {
            rayon::ThreadPoolBuilder::new()
                .num_threads(threads)
                .build()
                .unwrap()
                .install(|| renderer.render(&camera))
        };
        let (one, two) = (run(1), run(2));
        assert_eq!(one.pixels, two.pixels);
        assert_eq!(one.rays, two.rays);
        assert!(one.stats().samples > 0);
    }
}

#[test]
fn uniform_medium_matches_the_analytic_transmittance() {
    // A front view of a uniform 32^3 block: a central ray crosses 31 voxel distances, so it
    // takes 31 or 32 samples at spacing 1 depending on where the camera's sample grid falls.
    let dims = [32, 32, 32];
    let volume = common::uniform(dims, 100);
    let a = 0.05f32;
    let tf = common::tf(&[(0.0, [1.0, 1.0, 1.0, a])]);
    let settings = RenderSettings {
        ert_threshold: None,
        ..Default::default()
    };
    let frame = FloatRenderer::new(&volume, &tf, &settings)
        .unwrap()
        .render(&camera_for(dims, View::Front, Projection::Ortho, 32));
    let centre = 16 * 32 + 16;
    let record = frame.rays[centre];
    assert!((31..=32).contains(&record.samples), "{}", record.samples);
    let expected = 1.0 - (1.0 - a).powi(record.samples as i32); // white emission on black background
    let got = frame.pixels[centre][0] as f32 / 255.0;
    assert!(
        (got - expected).abs() <= 0.5 / 255.0 + 1e-4,
        "{got} vs {expected}"
    );
}

#[test]
fn halving_the_spacing_with_opacity_correction_keeps_the_image() {
    let volume = common::ball(32);
    let tf = common::tf(&[
        (0.0, [0.0; 4]),
        (20.0, [1.0, 0.6, 0.3, 0.2]),
        (200.0, [1.0, 1.0, 1.0, 0.6]),
    ]);
    let camera = camera_for(
        volume.dims,
        View::Orbit { k: 5, n: 72 },
        Projection::Ortho,
        32,
    );
    let render = |spacing| {
        let settings = RenderSettings {
            sample_spacing: spacing,
            ert_threshold: None,
            ..Default::default()
        };
        FloatRenderer::new(&volume, &tf, &settings)
            .unwrap()
            .render(&camera)
    };
    let (full, half) = (render(1.0), render(0.5));
    assert!(half.stats().samples > full.stats().samples * 19 / 10);
    let max_diff = full
        .pixels
        .iter()
        .zip(&half.pixels)
        .flat_map(|(a, b)| (0..4).map(move |c| (a[c] as i32 - b[c] as i32).abs()))
        .max()
        .unwrap();
    // Discretisation differs (the field is sampled twice as often), opacity does not drift.
    assert!(max_diff <= 12, "max channel difference {max_diff}");
}

#[test]
fn early_ray_termination_never_adds_samples_and_stops_at_the_threshold() {
    let volume = common::uniform([24, 24, 24], 200);
    let tf = common::tf(&[(0.0, [1.0, 1.0, 1.0, 0.3])]);
    let camera = camera_for(volume.dims, View::Front, Projection::Ortho, 24);
    let render = |ert| {
        let settings = RenderSettings {
            ert_threshold: ert,
            ..Default::default()
        };
        FloatRenderer::new(&volume, &tf, &settings)
            .unwrap()
            .render(&camera)
    };
    let (off, on) = (render(None), render(Some(0.95)));
    assert!(on.stats().samples < off.stats().samples);
    assert!(on.stats().rays_terminated_early > 0);
    // 1 - 0.7^k >= 0.95 first at k = 9.
    let centre = 12 * 24 + 12;
    assert_eq!(on.rays[centre].samples, 9);
    assert!(on.rays[centre].terminated_early);
    for (a, b) in on.rays.iter().zip(&off.rays) {
        assert!(a.samples <= b.samples);
    }
}

#[test]
fn sample_range_takes_every_grid_point_inside() {
    assert_eq!(sample_range(0.5, 3.5, 1.0), (1, 4));
    assert_eq!(sample_range(1.0, 3.0, 1.0), (1, 4));
    assert_eq!(sample_range(1.2, 1.8, 1.0), (2, 2)); // no grid point inside
    assert_eq!(sample_range(0.0, 1.0, 0.25), (0, 5));
}
