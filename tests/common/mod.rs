//! Shared test helpers.
#![allow(dead_code)]

use std::path::PathBuf;

use glam::Vec3;
use vizsim::camera::{Camera, Projection, View};
use vizsim::config::{HardwareConfig, SkipPolicy};
use vizsim::functional::renderer::{FixedRenderer, Leaping};
use vizsim::occupancy::OccupancyKind;
use vizsim::render::{Frame, RenderSettings};
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

pub fn camera(volume: &Volume, view: View, projection: Projection, size: u32) -> Camera {
    Camera::for_volume(Vec3::from(volume.extent()), view, projection, size, size).unwrap()
}

/// The fixed-point model with the default hardware, the SRAM raised so every map fits.
pub fn render_fixed(
    volume: &Volume,
    tf: &TransferFunction,
    camera: &Camera,
    settings: &RenderSettings,
    leaping: Leaping,
) -> Frame {
    render_fixed_with(volume, tf, camera, settings, leaping, SkipPolicy::LeapOnly)
}

/// `render_fixed` with a given `skip.policy`.
pub fn render_fixed_with(
    volume: &Volume,
    tf: &TransferFunction,
    camera: &Camera,
    settings: &RenderSettings,
    leaping: Leaping,
    policy: SkipPolicy,
) -> Frame {
    let mut config = HardwareConfig::default_config();
    config.occupancy.sram_bits = 1 << 24;
    config.skip.policy = policy;
    FixedRenderer::new(volume, tf, settings, &config, leaping)
        .unwrap()
        .render(camera)
}

/// Orthographic front, orthographic oblique, perspective oblique.
pub fn views() -> Vec<(View, Projection)> {
    vec![
        (View::Front, Projection::Ortho),
        (View::Orbit { k: 7, n: 72 }, Projection::Ortho),
        (View::Orbit { k: 50, n: 72 }, Projection::Persp),
    ]
}

/// One leaping configuration's image and steps against the plain fixed-point render, with both
/// skip policies: the pixels must be identical, and no ray may take more steps than without
/// leaping. Between the policies, per ray: sample-then-leap visits the same positions (the leap
/// at a position does not depend on the policy, and a sample in an empty sub-cube has zero
/// opacity, so it neither changes the pixel nor ERT), so it takes exactly as many steps; its
/// samples are leap-only's samples plus one per leap, and it never leaps without a sample.
pub fn assert_leap_matches(
    volume: &Volume,
    tf: &TransferFunction,
    cam: &Camera,
    settings: &RenderSettings,
    plain: &Frame,
    leaping: Leaping,
    what: &str,
) {
    let leap_only = render_fixed(volume, tf, cam, settings, leaping);
    let then_leap = render_fixed_with(
        volume,
        tf,
        cam,
        settings,
        leaping,
        SkipPolicy::SampleThenLeap,
    );
    for (leap, policy) in [
        (&leap_only, SkipPolicy::LeapOnly),
        (&then_leap, SkipPolicy::SampleThenLeap),
    ] {
        assert!(
            leap.pixels == plain.pixels,
            "image differs: {what} {leaping:?} {policy:?}"
        );
        for (l, p) in leap.rays.iter().zip(&plain.rays) {
            assert!(
                l.samples + l.leaps <= p.samples,
                "leaping cost more steps: {what} {leaping:?} {policy:?}"
            );
            assert_eq!(
                l.terminated_early, p.terminated_early,
                "{what} {leaping:?} {policy:?}"
            );
            // Leaps cover exactly the positions the plain ray sampled in vain.
            assert_eq!(
                l.samples + l.skipped,
                p.samples,
                "{what} {leaping:?} {policy:?}"
            );
        }
    }
    for (o, t) in leap_only.rays.iter().zip(&then_leap.rays) {
        let why = format!("{what} {leaping:?}: leap-only {o:?}, sample-then-leap {t:?}");
        assert_eq!(o.leap_samples, 0, "{why}");
        assert_eq!(t.leaps, 0, "{why}");
        assert_eq!(t.samples, o.samples + o.leaps, "{why}");
        assert_eq!(t.skipped, o.skipped - o.leaps, "{why}");
        assert!(t.leap_samples <= o.leaps, "{why}");
    }
}

/// Every sub-cube size, hierarchy on and off, '0' and class maps, ERT on and off, in every
/// view of `views()`.
pub fn assert_leaping_is_invisible(volume: &Volume, tf: &TransferFunction, size: u32) {
    for (view, projection) in views() {
        let cam = camera(volume, view.clone(), projection, size);
        for ert in [Some(0.95), None] {
            let settings = RenderSettings {
                ert_threshold: ert,
                ..Default::default()
            };
            let plain = render_fixed(volume, tf, &cam, &settings, Leaping::None);
            for subcube in [2, 4, 8, 16, 32, 64] {
                if subcube > *volume.dims.iter().max().unwrap() {
                    continue;
                }
                for hierarchy in [false, true] {
                    for kind in [OccupancyKind::Zero, OccupancyKind::Class] {
                        let what = format!("{} {view:?} {projection:?} ert {ert:?}", volume.name);
                        assert_leap_matches(
                            volume,
                            tf,
                            &cam,
                            &settings,
                            &plain,
                            Leaping::Occupancy {
                                subcube,
                                hierarchy,
                                kind,
                            },
                            &what,
                        );
                    }
                }
            }
        }
    }
}

/// Runs the vizsim binary in `dir` (the crate's folder when None), killing it after `seconds`
/// (a hang is a failure, not a stuck test run); returns whether it succeeded and its stderr.
pub fn run_bounded(dir: Option<&std::path::Path>, args: &[&str], seconds: u64) -> (bool, String) {
    use std::io::Read;
    use std::process::{Command, Stdio};
    let mut child = Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(args)
        .current_dir(dir.unwrap_or(std::path::Path::new(env!("CARGO_MANIFEST_DIR"))))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("run vizsim");
    let start = std::time::Instant::now();
    loop {
        if let Some(status) = child.try_wait().unwrap() {
            let mut stderr = String::new();
            child
                .stderr
                .take()
                .unwrap()
                .read_to_string(&mut stderr)
                .unwrap();
            return (status.success(), stderr);
        }
        if start.elapsed() > std::time::Duration::from_secs(seconds) {
            child.kill().unwrap();
            let _ = child.wait();
            panic!("{args:?} hung for {seconds} s");
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}
