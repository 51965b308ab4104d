//! The cycle-accurate pipeline against its golden model (the functional fixed-point model) and
//! against closed forms.

mod common;

use common::{camera, views};
use vizsim::arch::pipeline::{simulate, CycleResult};
use vizsim::arch::voxel_memory::IdealMemory;
use vizsim::camera::{Projection, View};
use vizsim::config::{HardwareConfig, SkipPolicy};
use vizsim::functional::renderer::{FixedRenderer, Leaping};
use vizsim::occupancy::OccupancyKind;
use vizsim::render::RenderSettings;
use vizsim::transfer::TransferFunction;
use vizsim::volume::Volume;

fn ball_tf() -> TransferFunction {
    common::tf(&[
        (0.0, [0.0; 4]),
        (60.0, [0.0; 4]),
        (90.0, [0.2, 0.5, 1.0, 0.3]),
        (200.0, [1.0, 0.8, 0.2, 0.9]),
    ])
}

fn config() -> HardwareConfig {
    let mut c = HardwareConfig::default_config();
    c.occupancy.sram_bits = 1 << 24;
    c
}

/// Runs the cycle model with the ideal memory (latency `mem_latency`).
fn run(
    renderer: &FixedRenderer,
    cam: &vizsim::camera::Camera,
    config: &HardwareConfig,
    mem_latency: u64,
    skip_dead: bool,
) -> CycleResult {
    let mut memory = IdealMemory::new(mem_latency);
    simulate(
        renderer,
        cam,
        &renderer.skipper(),
        &mut memory,
        config,
        skip_dead,
        None,
    )
    .unwrap()
}

fn check_against_functional(volume: &Volume, tf: &TransferFunction, size: u32) {
    for (view, projection) in views() {
        let cam = camera(volume, view.clone(), projection, size);
        for ert in [Some(0.95), None] {
            let settings = RenderSettings {
                ert_threshold: ert,
                ..Default::default()
            };
            for (leaping, policy) in [
                (Leaping::None, SkipPolicy::LeapOnly),
                (
                    Leaping::Occupancy {
                        subcube: 4,
                        hierarchy: false,
                        kind: OccupancyKind::Class,
                    },
                    SkipPolicy::LeapOnly,
                ),
                (
                    Leaping::Occupancy {
                        subcube: 4,
                        hierarchy: false,
                        kind: OccupancyKind::Class,
                    },
                    SkipPolicy::SampleThenLeap,
                ),
                (
                    Leaping::Occupancy {
                        subcube: 8,
                        hierarchy: true,
                        kind: OccupancyKind::Zero,
                    },
                    SkipPolicy::LeapOnly,
                ),
                (
                    Leaping::Occupancy {
                        subcube: 8,
                        hierarchy: true,
                        kind: OccupancyKind::Zero,
                    },
                    SkipPolicy::SampleThenLeap,
                ),
            ] {
                let mut config = config();
                config.skip.policy = policy;
                let renderer = FixedRenderer::new(volume, tf, &settings, &config, leaping).unwrap();
                let functional = renderer.render(&cam);
                let cycle = run(&renderer, &cam, &config, 5, true);
                let what = format!("{view:?} {projection:?} ert {ert:?} {leaping:?} {policy:?}");
                assert!(
                    cycle.frame.pixels == functional.pixels,
                    "image differs: {what}"
                );
                let f = functional.stats();
                let s = &cycle.stats;
                // The same samples are composited; the cycle model may issue more (after ERT,
                // before the feedback arrives), which it discards.
                assert_eq!(s.composited, f.samples, "{what}");
                assert_eq!(s.samples, s.composited + s.discarded_after_ert, "{what}");
                assert_eq!(s.rays_terminated_early, f.rays_terminated_early, "{what}");
                if ert.is_none() {
                    assert_eq!(s.steps, f.steps(), "{what}");
                    assert_eq!(
                        (s.samples, s.leaps, s.leap_samples),
                        (f.samples, f.leaps, f.leap_samples),
                        "{what}"
                    );
                    assert_eq!(cycle.frame.rays, functional.rays, "{what}: per-ray counts");
                    assert_eq!(s.discarded_after_ert, 0);
                }
                if policy == SkipPolicy::SampleThenLeap && leaping != Leaping::None {
                    assert!(s.leap_samples > 0 && s.leaps == 0, "{what}: {s:?}");
                }
                assert!(s.cycles >= s.steps, "{what}: one issue per clock at most");
            }
        }
    }
}

#[test]
fn cycle_image_equals_functional_image_on_a_ball() {
    check_against_functional(&common::ball(40), &ball_tf(), 32);
}

#[test]
fn cycle_image_equals_functional_image_with_shading() {
    let volume = common::ball(32);
    let tf = ball_tf();
    let config = config();
    let settings = RenderSettings {
        shading: true,
        ..Default::default()
    };
    let cam = camera(&volume, View::Orbit { k: 11, n: 72 }, Projection::Persp, 32);
    let renderer = FixedRenderer::new(&volume, &tf, &settings, &config, Leaping::None).unwrap();
    assert!(run(&renderer, &cam, &config, 3, true).frame.pixels == renderer.render(&cam).pixels);
}

#[test]
fn one_ray_in_flight_pays_the_skip_latency_and_eight_hide_it() {
    let volume = common::uniform([16, 16, 16], 100);
    let tf = common::tf(&[(0.0, [1.0, 1.0, 1.0, 0.01])]);
    let settings = RenderSettings {
        ert_threshold: None,
        ..Default::default()
    };
    let cam = camera(&volume, View::Front, Projection::Ortho, 8);
    let cycles_per_step = |rays: usize| {
        let mut config = config();
        config.ray_queue.rays = rays;
        let renderer = FixedRenderer::new(&volume, &tf, &settings, &config, Leaping::None).unwrap();
        let r = run(&renderer, &cam, &config, 1, true);
        r.stats.cycles as f64 / r.stats.steps as f64
    };
    let (one, eight, sixteen) = (cycles_per_step(1), cycles_per_step(8), cycles_per_step(16));
    eprintln!("cycles per step: R=1 {one:.3}, R=8 {eight:.3}, R=16 {sixteen:.3}");
    // R = 1: a step every `latency` = 8 cycles (plus a little per-ray setup and drain).
    assert!((8.0..8.6).contains(&one), "R=1: {one} cycles per step");
    // R >= 8: about one step per cycle.
    assert!(
        eight < 1.2 && sixteen < 1.2,
        "R=8: {eight}, R=16: {sixteen}"
    );
}

/// With sample-then-leap a step in an empty sub-cube issues a memory request, yet the ray's
/// update P + n·V still comes back from the skip unit after `skip.latency` cycles: one ray in
/// flight takes a step per 8 cycles with either policy, and eight rays hide the latency.
#[test]
fn leap_samples_pay_the_skip_latency_like_any_step() {
    let volume = common::uniform([32, 32, 32], 0);
    let tf = common::tf(&[(0.0, [0.0; 4]), (255.0, [1.0; 4])]);
    let settings = RenderSettings {
        ert_threshold: None,
        ..Default::default()
    };
    let cam = camera(&volume, View::Front, Projection::Ortho, 8);
    let leaping = Leaping::Occupancy {
        subcube: 4,
        hierarchy: false,
        kind: OccupancyKind::Zero,
    };
    let stats = |rays: usize, policy: SkipPolicy| {
        let mut config = config();
        config.ray_queue.rays = rays;
        config.skip.policy = policy;
        let renderer = FixedRenderer::new(&volume, &tf, &settings, &config, leaping).unwrap();
        let r = run(&renderer, &cam, &config, 1, true);
        assert!(r.frame.pixels == renderer.render(&cam).pixels);
        r.stats
    };
    let lo = stats(1, SkipPolicy::LeapOnly);
    let stl = stats(1, SkipPolicy::SampleThenLeap);
    // Everything is empty: leap-only issues no request, sample-then-leap one per step.
    assert_eq!((lo.samples, stl.leaps), (0, 0));
    assert_eq!(stl.samples, lo.steps);
    assert_eq!(stl.steps, lo.steps);
    assert!(stl.leap_samples > 0);
    for (name, s) in [("leap-only", &lo), ("sample-then-leap", &stl)] {
        let per_step = s.cycles as f64 / s.steps as f64;
        eprintln!(
            "R=1 {name}: {} cycles, {} steps, {per_step:.3} cycles per step",
            s.cycles, s.steps
        );
        assert!((8.0..8.6).contains(&per_step), "R=1 {name}: {per_step}");
    }
    for policy in [SkipPolicy::LeapOnly, SkipPolicy::SampleThenLeap] {
        let s = stats(8, policy);
        let per_step = s.cycles as f64 / s.steps as f64;
        assert!(per_step < 1.2, "R=8 {policy:?}: {per_step}");
    }
}

#[test]
fn jumping_over_dead_cycles_equals_ticking() {
    let volume = common::ball(32);
    let tf = ball_tf();
    let cam = camera(&volume, View::Orbit { k: 4, n: 72 }, Projection::Ortho, 24);
    for policy in [SkipPolicy::LeapOnly, SkipPolicy::SampleThenLeap] {
        let mut config = config();
        config.ray_queue.rays = 3; // plenty of dead cycles
        config.skip.policy = policy;
        let renderer = FixedRenderer::new(
            &volume,
            &tf,
            &RenderSettings::default(),
            &config,
            Leaping::Occupancy {
                subcube: 4,
                hierarchy: true,
                kind: OccupancyKind::Class,
            },
        )
        .unwrap();
        let jumped = run(&renderer, &cam, &config, 20, true);
        let ticked = run(&renderer, &cam, &config, 20, false);
        assert!(jumped.stats.skipped_cycles > 0);
        assert_eq!(ticked.stats.skipped_cycles, 0);
        let mut a = jumped.stats.clone();
        a.skipped_cycles = 0;
        assert_eq!(a, ticked.stats, "{policy:?}");
        assert_eq!(jumped.frame.pixels, ticked.frame.pixels);
    }
}

#[test]
fn ert_feedback_latency_wastes_issued_samples_that_are_discarded() {
    let volume = common::uniform([32, 32, 32], 200);
    let tf = common::tf(&[(0.0, [1.0, 1.0, 1.0, 0.5])]);
    let cam = camera(&volume, View::Front, Projection::Ortho, 16);
    let discarded = |latency: u32| {
        let mut config = config();
        config.compositing.ert_feedback_latency = latency;
        config.ray_queue.rays = 2;
        let renderer = FixedRenderer::new(
            &volume,
            &tf,
            &RenderSettings::default(),
            &config,
            Leaping::None,
        )
        .unwrap();
        let r = run(&renderer, &cam, &config, 2, true);
        assert!(r.frame.pixels == renderer.render(&cam).pixels);
        r.stats.discarded_after_ert
    };
    let (short, long) = (discarded(1), discarded(40));
    eprintln!("discarded after ERT: feedback 1 cycle {short}, 40 cycles {long}");
    assert!(long > short, "{long} vs {short}");
}

#[test]
fn same_input_same_cycles() {
    let volume = common::ball(32);
    let tf = ball_tf();
    let config = config();
    let cam = camera(&volume, View::Orbit { k: 9, n: 72 }, Projection::Persp, 24);
    let renderer = FixedRenderer::new(
        &volume,
        &tf,
        &RenderSettings::default(),
        &config,
        Leaping::None,
    )
    .unwrap();
    let a = run(&renderer, &cam, &config, 7, true);
    let b = rayon::ThreadPoolBuilder::new()
        .num_threads(1)
        .build()
        .unwrap()
        .install(|| run(&renderer, &cam, &config, 7, true));
    assert_eq!(a.stats, b.stats);
    assert_eq!(a.frame.pixels, b.frame.pixels);
}

/// A memory that accepts requests and keeps "working" (an event every 10 cycles, as refresh
/// would) but never returns a word: a livelock only the watchdog can stop.
struct StuckMemory;

impl vizsim::arch::voxel_memory::VoxelMemory for StuckMemory {
    fn try_push(&mut self, _: vizsim::arch::voxel_memory::SampleRequest, _: u64) -> bool {
        true
    }
    fn try_push_word(&mut self, _: u64, _: [usize; 3], _: u64) -> bool {
        true
    }
    fn step(&mut self, _: u64, _: &mut Vec<u64>) {}
    fn is_idle(&self) -> bool {
        false
    }
    fn next_event(&self, now: u64) -> Option<u64> {
        Some(now + 10)
    }
    fn stats_json(&self) -> serde_json::Value {
        serde_json::json!({ "model": "stuck" })
    }
    fn longest_legal_wait(&self) -> u64 {
        50
    }
}

#[test]
fn watchdog_stops_a_run_that_makes_no_progress_with_a_readable_dump() {
    let volume = common::ball(24);
    let tf = ball_tf();
    let mut config = config();
    config.compositing.watchdog_cycles = 100;
    let cam = camera(&volume, View::Front, Projection::Ortho, 8);
    let renderer = FixedRenderer::new(
        &volume,
        &tf,
        &RenderSettings::default(),
        &config,
        Leaping::None,
    )
    .unwrap();
    let err = simulate(
        &renderer,
        &cam,
        &renderer.skipper(),
        &mut StuckMemory,
        &config,
        true,
        None,
    )
    .err()
    .expect("watchdog must fire")
    .to_string();
    assert!(
        err.contains("watchdog") && err.contains("ray queue") && err.contains("compositing buffer"),
        "{err}"
    );
    // Readable: a few short lines (it was one 45 KB line), the ray queue cut after 8 rays.
    assert!(err.lines().count() <= 16, "{err}");
    assert!(err.lines().all(|l| l.len() <= 200), "{err}");
    assert!(err.contains("... and"), "{err}");
    // A memory that answers only after 1000 cycles waits legally: the watchdog allows the
    // memory's longest legal wait on top of its setting (issue 17, item 10).
    let mut memory = IdealMemory::new(1000);
    assert!(simulate(
        &renderer,
        &cam,
        &renderer.skipper(),
        &mut memory,
        &config,
        true,
        None
    )
    .is_ok());
}

/// The adversarial trial's case (issue 17, item 10): the slowest legal SDRAM timings with the
/// smallest watchdog stopped `sim --dataset phantom:sphere:32 --size 32x32` at cycle 1691 as a
/// "pipeline deadlock"; now the run finishes with the cycles of a patient watchdog.
#[test]
fn slowest_legal_sdram_timings_never_trip_the_smallest_watchdog() {
    use vizsim::run::{run, Model, Probes, RunDescription};
    let mut config = HardwareConfig::default_config();
    let t = &mut config.sdram;
    (t.cl, t.t_rtw) = (62, 64);
    for v in [
        &mut t.t_rcd,
        &mut t.t_rp,
        &mut t.t_ras,
        &mut t.t_rc,
        &mut t.t_rrd,
        &mut t.t_ccd,
        &mut t.t_rfc,
        &mut t.t_wr,
    ] {
        *v = 64;
    }
    let cycles = |watchdog: u64| {
        let mut hardware = config.clone();
        hardware.compositing.watchdog_cycles = watchdog;
        let mut desc = RunDescription::new("phantom:sphere:32", "class", Model::Cycle, hardware);
        desc.size = (32, 32);
        let report = run(&desc, None, Probes::default());
        report.map(|r| r.measurements.cycles)
    };
    let patient = cycles(1 << 30).unwrap();
    for watchdog in [100, 200] {
        let tight = cycles(watchdog).expect("a legal wait tripped the watchdog");
        assert_eq!(tight, patient, "watchdog {watchdog}");
    }
}

/// With shading, a voxel word holds the density and three gradient components (VIZARD II: 8 +
/// 3 × 8 of 32 bits). The SDRAM model reads one word per voxel, so a wider voxel is refused,
/// naming the field and the width that fits; the ideal memory (no words) and a fitting width run.
#[test]
fn a_shaded_voxel_wider_than_its_word_is_refused_by_the_sdram_model() {
    use vizsim::run::{prepare, Memory, Model, RunDescription};
    let volume = vizsim::volume::dataset::load("phantom:sphere:16", None).unwrap();
    let run_with = |gradient_bits: u32, memory: Memory| {
        let config = vizsim::config::HardwareConfig::load(
            None,
            &[format!("shading.gradient_bits={gradient_bits}")],
        )
        .unwrap();
        let mut run = RunDescription::new("phantom:sphere:16", "class", Model::Cycle, config);
        run.shading = true;
        run.memory = memory;
        run.size = (8, 8);
        run
    };
    let error = prepare(&run_with(9, Memory::Sdram), &volume)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        error.contains("shading.gradient_bits")
            && error.contains("35 bits")
            && error.contains("=8"),
        "{error}"
    );
    assert!(prepare(&run_with(8, Memory::Sdram), &volume).is_ok());
    assert!(prepare(&run_with(9, Memory::Ideal { latency: 6 }), &volume).is_ok());
    // A 16-bit volume at the default 8 gradient bits: refused once its width is known.
    let wide = Volume {
        bits: 16,
        data: volume.data.iter().map(|&v| v * 200).collect(),
        ..volume.clone()
    };
    let error = prepare(&run_with(8, Memory::Sdram), &wide)
        .err()
        .expect("refused")
        .to_string();
    assert!(
        error.contains("16-bit volume needs 40 bits") && error.contains("=5"),
        "{error}"
    );
}
