//! Leap values in the volume as a leaping structure (docs/model.md, "Leap values in the
//! volume"): empty-region leaping is invisible (bit for bit against no leaping) and leaps;
//! homogeneous leaping is lossy but close; the cycle model's image and counts equal the
//! functional model's for both, and a ray waits for its sample's words; blowholes of the cast
//! phantom keep their footprint under every leaping structure; bad configurations are errors.

mod common;

use common::{camera, render_fixed, views};
use vizsim::arch::pipeline::simulate;
use vizsim::arch::sdram_module::SdramMemory;
use vizsim::arch::voxel_memory::IdealMemory;
use vizsim::camera::{Projection, View};
use vizsim::config::{HardwareConfig, LeapRegions};
use vizsim::functional::arith::{Accumulator, Compositor};
use vizsim::functional::renderer::{FixedRenderer, Leaping};
use vizsim::occupancy::OccupancyKind;
use vizsim::render::float::FloatRenderer;
use vizsim::render::{Frame, RenderSettings};
use vizsim::transfer::{self, TransferFunction};
use vizsim::volume::phantom::{generate, PhantomKind, PhantomSpec};
use vizsim::volume::{dataset, Volume};

fn phantom(kind: PhantomKind, size: usize) -> Volume {
    generate(&PhantomSpec {
        size,
        ..PhantomSpec::default_for(kind)
    })
}

fn class_tf(volume: &Volume) -> TransferFunction {
    transfer::resolve("class", &volume.name).unwrap()
}

const EMPTY: Leaping = Leaping::LeapValues {
    regions: LeapRegions::Empty,
    kind: OccupancyKind::Class,
};
const HOMOGENEOUS: Leaping = Leaping::LeapValues {
    regions: LeapRegions::Homogeneous,
    kind: OccupancyKind::Class,
};

/// Empty-region leaping against no leaping in every view, ERT on and off: identical pixels,
/// never more steps (`assert_leap_matches`); returns the steps saved over all views.
fn assert_empty_leaping_is_invisible(volume: &Volume, tf: &TransferFunction, size: u32) -> u64 {
    let mut saved = 0;
    for (view, projection) in views() {
        let cam = camera(volume, view.clone(), projection, size);
        for ert in [Some(0.95), None] {
            let settings = RenderSettings {
                ert_threshold: ert,
                ..Default::default()
            };
            let plain = render_fixed(volume, tf, &cam, &settings, Leaping::None);
            for kind in [OccupancyKind::Zero, OccupancyKind::Class] {
                let leaping = Leaping::LeapValues {
                    regions: LeapRegions::Empty,
                    kind,
                };
                let what = format!(
                    "{} {view:?} {projection:?} ert {ert:?} {kind:?}",
                    volume.name
                );
                let leapt = render_fixed(volume, tf, &cam, &settings, leaping);
                assert!(leapt.pixels == plain.pixels, "image differs: {what}");
                for (l, p) in leapt.rays.iter().zip(&plain.rays) {
                    // Every step samples (the words bring the leap value); leaps pass over
                    // exactly the positions the plain ray sampled in vain.
                    assert_eq!(l.leaps, 0, "{what}");
                    assert!(l.samples <= p.samples, "{what}");
                    assert_eq!(l.samples + l.skipped, p.samples, "{what}");
                    assert_eq!(l.terminated_early, p.terminated_early, "{what}");
                }
                saved += plain.stats().steps() - leapt.stats().steps();
            }
        }
    }
    saved
}

// ---------------------------------------------------------------- functional model

#[test]
fn empty_region_leaping_is_invisible_and_leaps_on_phantoms() {
    for kind in [
        PhantomKind::Cast,
        PhantomKind::Metaballs,
        PhantomKind::Sphere,
    ] {
        let volume = phantom(kind, 48);
        let saved = assert_empty_leaping_is_invisible(&volume, &class_tf(&volume), 32);
        assert!(saved > 0, "{}: no step saved", volume.name);
    }
}

#[test]
fn empty_region_leaping_is_invisible_on_fuel_and_neghip() {
    let Some(dir) = common::data_dir() else {
        eprintln!("skipped: no data folder (set VIZSIM_DATA or put ../shared/data beside)");
        return;
    };
    for name in ["fuel", "neghip"] {
        let volume = dataset::load(name, Some(&dir)).unwrap();
        for kind in ["zero", "class"] {
            let tf = transfer::resolve(kind, name).unwrap();
            assert_empty_leaping_is_invisible(&volume, &tf, 48);
        }
    }
}

/// Homogeneous leaping is lossy, but on the cast (homogeneous metal with noise) it stays close
/// to the plain image and takes far fewer steps; the float reference follows the same region
/// protocol and agrees with the fixed-point image as closely as without leaping.
#[test]
fn homogeneous_leaping_is_close_and_leaps_further() {
    let volume = phantom(PhantomKind::Cast, 64);
    let tf = class_tf(&volume);
    let cam = camera(&volume, View::Orbit { k: 7, n: 72 }, Projection::Ortho, 48);
    let settings = RenderSettings::default();
    // The metal is 180 ± 6: a range of 5 % (12 levels) keeps it one region.
    let mut config = HardwareConfig::default_config();
    config.leap_values.range_fraction = 0.05;
    let render = |leaping| {
        FixedRenderer::new(&volume, &tf, &settings, &config, leaping)
            .unwrap()
            .render(&cam)
    };
    let (plain, empty, lossy) = (render(Leaping::None), render(EMPTY), render(HOMOGENEOUS));
    assert!(lossy.stats().steps() < empty.stats().steps());
    assert!(empty.stats().steps() < plain.stats().steps());
    let psnr = common_psnr(&plain, &lossy);
    assert!(psnr > 25.0 && psnr.is_finite(), "PSNR {psnr}");

    config.leap_values.regions = LeapRegions::Homogeneous;
    let words = vizsim::leapvalues::LeapValueVolume::build(
        &volume,
        &config.leap_values,
        &config.volume_word,
        1.0,
        |_, _| true,
    )
    .unwrap();
    let float_lossy = FloatRenderer::new(&volume, &tf, &settings)
        .unwrap()
        .with_leap_values(words)
        .render(&cam);
    let float_plain = FloatRenderer::new(&volume, &tf, &settings)
        .unwrap()
        .render(&cam);
    let (lossy_gap, plain_gap) = (
        common_psnr(&float_lossy, &lossy),
        common_psnr(&float_plain, &plain),
    );
    assert!(lossy_gap > plain_gap - 6.0, "{lossy_gap} vs {plain_gap}");
}

fn common_psnr(a: &Frame, b: &Frame) -> f64 {
    let mut sum = 0f64;
    for (p, q) in a.pixels.iter().zip(&b.pixels) {
        for c in 0..4 {
            let d = p[c] as f64 - q[c] as f64;
            sum += d * d;
        }
    }
    let mse = sum / (4 * a.pixels.len()) as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0f64 * 255.0 / mse).log10()
    }
}

#[test]
fn composite_steps_is_composite_for_one_step_and_k_composites_within_rounding() {
    let c = Compositor::new(12, 8, None, [0.0; 4]);
    for alpha in [0u16, 1, 17, 128, 254, 255] {
        let rgba = [200, 100, 50, alpha];
        let (mut once, mut steps) = (Accumulator::default(), Accumulator::default());
        c.composite(&mut once, rgba);
        c.composite_steps(&mut steps, rgba, 1);
        assert_eq!(once, steps);
        for k in [2u32, 3, 7, 40, 1000] {
            let mut repeated = Accumulator::default();
            for _ in 0..k {
                c.composite(&mut repeated, rgba);
            }
            let mut one = Accumulator::default();
            c.composite_steps(&mut one, rgba, k);
            // Each product rounds by half a unit at most: the power by squaring over log2(k)
            // products against k compositings.
            let tolerance = (k.min(64) + 2) as i64;
            assert!(
                (one.alpha as i64 - repeated.alpha as i64).abs() <= tolerance,
                "alpha {alpha} k {k}: {one:?} vs {repeated:?}"
            );
            assert!(one.colour.iter().all(|&x| x <= one.alpha));
        }
    }
}

// ---------------------------------------------------------------- cycle model

fn cycle_config() -> HardwareConfig {
    let mut c = HardwareConfig::default_config();
    c.occupancy.sram_bits = 1 << 24;
    c
}

/// The cycle model's image, composited samples and (ERT off) every count and ray record equal
/// the functional model's, with ideal memory and with SDRAM.
#[test]
fn cycle_model_equals_functional_with_leap_values() {
    let volume = phantom(PhantomKind::Cast, 48);
    let tf = class_tf(&volume);
    let config = cycle_config();
    for (view, projection) in views() {
        let cam = camera(&volume, view.clone(), projection, 24);
        for ert in [Some(0.95), None] {
            let settings = RenderSettings {
                ert_threshold: ert,
                ..Default::default()
            };
            for leaping in [EMPTY, HOMOGENEOUS] {
                let renderer =
                    FixedRenderer::new(&volume, &tf, &settings, &config, leaping).unwrap();
                let functional = renderer.render(&cam);
                for sdram in [false, true] {
                    let cycle = if sdram {
                        let mut memory = SdramMemory::new(
                            &config.memory,
                            &config.sdram,
                            volume.dims,
                            config.clock.frequency_mhz,
                        );
                        simulate(
                            &renderer,
                            &cam,
                            &renderer.skipper(),
                            &mut memory,
                            &config,
                            true,
                            None,
                        )
                    } else {
                        let mut memory = IdealMemory::new(5);
                        simulate(
                            &renderer,
                            &cam,
                            &renderer.skipper(),
                            &mut memory,
                            &config,
                            true,
                            None,
                        )
                    }
                    .unwrap();
                    let what =
                        format!("{view:?} {projection:?} ert {ert:?} {leaping:?} sdram {sdram}");
                    assert!(
                        cycle.frame.pixels == functional.pixels,
                        "image differs: {what}"
                    );
                    let (f, s) = (functional.stats(), &cycle.stats);
                    assert_eq!(s.composited, f.samples, "{what}");
                    assert_eq!(s.rays_terminated_early, f.rays_terminated_early, "{what}");
                    if ert.is_none() {
                        assert_eq!((s.steps, s.samples), (f.steps(), f.samples), "{what}");
                        assert_eq!(cycle.frame.rays, functional.rays, "{what}");
                    }
                }
            }
        }
    }
}

/// With one ray in flight, every step of empty-region leaping waits for its own sample's
/// words before the skip unit computes the next position, so it costs at least the memory
/// latency plus the skip latency; the stall shows as `leap_word`, and more rays hide it.
#[test]
fn a_ray_waits_for_its_words_and_more_rays_hide_it() {
    let volume = phantom(PhantomKind::Cast, 32);
    let tf = class_tf(&volume);
    let cam = camera(&volume, View::Front, Projection::Ortho, 8);
    let settings = RenderSettings {
        ert_threshold: None,
        ..Default::default()
    };
    let cycles = |rays: usize, leaping: Leaping| {
        let mut config = cycle_config();
        config.ray_queue.rays = rays;
        let renderer = FixedRenderer::new(&volume, &tf, &settings, &config, leaping).unwrap();
        let latency = 20;
        let r = simulate(
            &renderer,
            &cam,
            &renderer.skipper(),
            &mut IdealMemory::new(latency),
            &config,
            true,
            None,
        )
        .unwrap();
        (r.stats, latency + config.skip.latency as u64)
    };
    let (one, per_step) = cycles(1, EMPTY);
    assert!(
        one.cycles >= one.steps * per_step,
        "{} cycles for {} steps",
        one.cycles,
        one.steps
    );
    assert!(one.stall_cycles.leap_word > 0);
    let (plain_one, _) = cycles(1, Leaping::None);
    assert_eq!(plain_one.stall_cycles.leap_word, 0);
    assert!(plain_one.cycles < plain_one.steps * per_step);
    let (many, _) = cycles(32, EMPTY);
    assert!(
        many.cycles * 4 < one.cycles,
        "{} vs {}",
        many.cycles,
        one.cycles
    );
}

// ---------------------------------------------------------------- blowholes

/// The cast with its blowholes filled with metal: air (< 90) not connected to the volume's
/// faces becomes 180.
fn filled_cast(volume: &Volume) -> Volume {
    let d = volume.dims;
    let index = |x: usize, y: usize, z: usize| x + d[0] * (y + d[1] * z);
    let mut outside = vec![false; volume.data.len()];
    let mut stack = Vec::new();
    for z in 0..d[2] {
        for y in 0..d[1] {
            for x in 0..d[0] {
                let face =
                    x == 0 || y == 0 || z == 0 || x + 1 == d[0] || y + 1 == d[1] || z + 1 == d[2];
                if face && volume.data[index(x, y, z)] < 90 {
                    outside[index(x, y, z)] = true;
                    stack.push([x, y, z]);
                }
            }
        }
    }
    while let Some(p) = stack.pop() {
        for (a, delta) in [(0, -1i64), (0, 1), (1, -1), (1, 1), (2, -1), (2, 1)] {
            let mut q = p;
            let v = q[a] as i64 + delta;
            if v < 0 || v >= d[a] as i64 {
                continue;
            }
            q[a] = v as usize;
            let i = index(q[0], q[1], q[2]);
            if !outside[i] && volume.data[i] < 90 {
                outside[i] = true;
                stack.push(q);
            }
        }
    }
    let mut filled = volume.clone();
    let mut holes = 0;
    for (i, v) in filled.data.iter_mut().enumerate() {
        if *v < 90 && !outside[i] {
            *v = 180;
            holes += 1;
        }
    }
    assert!(holes > 0, "the cast phantom has no blowhole");
    filled
}

/// Pixels where the blowholes show: where the cast's image differs from the filled cast's.
fn footprint(volume: &Volume, filled: &Volume, render: impl Fn(&Volume) -> Frame) -> Vec<bool> {
    let (a, b) = (render(volume), render(filled));
    a.pixels
        .iter()
        .zip(&b.pixels)
        .map(|(p, q)| p != q)
        .collect()
}

/// Connected groups (8-neighbours) of the footprint's pixels: one per visible blowhole, or
/// several holes overlapping in the view.
fn footprint_groups(footprint: &[bool], width: usize) -> Vec<Vec<usize>> {
    let mut seen = vec![false; footprint.len()];
    let mut groups = Vec::new();
    for start in 0..footprint.len() {
        if !footprint[start] || seen[start] {
            continue;
        }
        seen[start] = true;
        let (mut group, mut stack) = (Vec::new(), vec![start]);
        while let Some(i) = stack.pop() {
            group.push(i);
            let (x, y) = ((i % width) as i64, (i / width) as i64);
            for (dx, dy) in [
                (-1, -1),
                (0, -1),
                (1, -1),
                (-1, 0),
                (1, 0),
                (-1, 1),
                (0, 1),
                (1, 1),
            ] {
                let (u, v) = (x + dx, y + dy);
                if u < 0 || v < 0 || u >= width as i64 || v >= (footprint.len() / width) as i64 {
                    continue;
                }
                let j = (v as usize) * width + u as usize;
                if footprint[j] && !seen[j] {
                    seen[j] = true;
                    stack.push(j);
                }
            }
        }
        groups.push(group);
    }
    groups
}

/// No blowhole is missed. In orbit views, the blowholes' pixel footprint (where the cast's
/// image differs from the filled cast's) is identical with and without leaping for every
/// lossless structure (occupancy map with hierarchy, distance volume, empty-region leap
/// values). Homogeneous leap values are lossy: partial-volume voxels at a hole's rim that lie
/// within the segmentation range of the metal join the metal's region and read its mean, so
/// faint rim pixels (measured: at most 33 of 255 levels of contrast) can vanish; every hole
/// must still show (each footprint group keeps pixels) and 85 % of the footprint must stay.
#[test]
fn every_blowhole_keeps_its_footprint_under_every_leaping_structure() {
    let volume = phantom(PhantomKind::Cast, 64);
    let filled = filled_cast(&volume);
    let tf = class_tf(&volume);
    let settings = RenderSettings::default();
    let lossless = [
        Leaping::Occupancy {
            subcube: 8,
            hierarchy: true,
            kind: OccupancyKind::Class,
        },
        Leaping::Distance {
            bits: 8,
            kind: OccupancyKind::Class,
        },
        EMPTY,
    ];
    let size = 64;
    for k in [0, 9, 30, 50] {
        let cam = camera(&volume, View::Orbit { k, n: 72 }, Projection::Ortho, size);
        let plain = footprint(&volume, &filled, |v| {
            render_fixed(v, &tf, &cam, &settings, Leaping::None)
        });
        let groups = footprint_groups(&plain, size as usize);
        assert!(!groups.is_empty(), "view {k}: no blowhole visible");
        for leaping in lossless {
            let leapt = footprint(&volume, &filled, |v| {
                render_fixed(v, &tf, &cam, &settings, leaping)
            });
            let differ = plain.iter().zip(&leapt).filter(|(a, b)| a != b).count();
            assert_eq!(
                differ, 0,
                "view {k} {leaping:?}: {differ} pixels of the footprint differ"
            );
        }
        let lossy = footprint(&volume, &filled, |v| {
            render_fixed(v, &tf, &cam, &settings, HOMOGENEOUS)
        });
        for group in &groups {
            assert!(
                group.iter().any(|&i| lossy[i]),
                "view {k}: a blowhole ({} pixels) vanished with homogeneous leap values",
                group.len()
            );
        }
        let kept = plain.iter().zip(&lossy).filter(|(a, b)| **a && **b).count();
        let total = plain.iter().filter(|&&a| a).count();
        assert!(
            kept * 100 >= total * 85,
            "view {k}: {kept} of {total} footprint pixels kept"
        );
    }
}

// ---------------------------------------------------------------- configuration

#[test]
fn leap_value_configuration_is_validated() {
    let set = |overrides: &[&str]| {
        let o: Vec<String> = overrides.iter().map(|s| s.to_string()).collect();
        HardwareConfig::load(None, &o)
    };
    let c = set(&[
        "occupancy.structure=leap-values",
        "leap_values.regions=homogeneous",
    ])
    .unwrap();
    assert_eq!(Leaping::from_config(&c), HOMOGENEOUS);
    for (overrides, field) in [
        (
            vec!["leap_values.range_fraction=1.5"],
            "leap_values.range_fraction",
        ),
        (
            vec!["leap_values.min_region_size=0"],
            "leap_values.min_region_size",
        ),
        (
            vec!["leap_values.max_spacing=100"],
            "leap_values.max_spacing",
        ),
        (vec!["volume_word.leap_bits=0"], "volume_word.leap_bits"),
        (vec!["volume_word.leap_bits=16"], "volume_word.leap_bits"),
        (vec!["volume_word.word_bits=40"], "volume_word.word_bits"),
        (
            vec![
                "occupancy.structure=leap-values",
                "occupancy.hierarchy=true",
            ],
            "occupancy.hierarchy",
        ),
    ] {
        let err = set(&overrides).unwrap_err().to_string();
        assert!(err.contains(field), "{overrides:?}: {err}");
    }
    // The defaults serialise nothing new (run keys unchanged).
    let text = toml::to_string(&HardwareConfig::default_config()).unwrap();
    assert!(
        !text.contains("leap_values") && !text.contains("volume_word"),
        "{text}"
    );
}

/// A sample spacing larger than the configured guard distance covers is an error naming the
/// field, not a silently wrong image; a volume that is one single region renders (the faces
/// bound it) and stays invisible.
#[test]
fn spacing_beyond_the_guards_is_an_error_and_a_single_region_is_fine() {
    let volume = phantom(PhantomKind::Cast, 32);
    let tf = class_tf(&volume);
    let mut config = cycle_config();
    config.leap_values.max_spacing = 1.0;
    let settings = RenderSettings {
        sample_spacing: 2.0,
        ..Default::default()
    };
    let err = FixedRenderer::new(&volume, &tf, &settings, &config, EMPTY)
        .err()
        .expect("spacing 2 with guards for 1 must fail")
        .to_string();
    assert!(err.contains("leap_values.max_spacing"), "{err}");

    let uniform = common::uniform([24, 24, 24], 0);
    let tf = common::tf(&[(0.0, [0.0; 4]), (10.0, [1.0, 1.0, 1.0, 0.5])]);
    let cam = camera(&uniform, View::Orbit { k: 5, n: 72 }, Projection::Persp, 16);
    let settings = RenderSettings::default();
    let plain = render_fixed(&uniform, &tf, &cam, &settings, Leaping::None);
    let leapt = render_fixed(&uniform, &tf, &cam, &settings, EMPTY);
    assert!(plain.pixels == leapt.pixels);
    assert!(leapt.stats().steps() < plain.stats().steps());
}

#[test]
fn leap_value_modes_parse_print_and_configure() {
    use vizsim::experiment::spec::Mode;
    let m = Mode::parse("ert+leapvalues").unwrap();
    assert!(m.ert && m.leap_values == Some(LeapRegions::Empty) && m.subcube == 0);
    assert_eq!(m.name(), "ert+leapvalues");
    let h = Mode::parse("leapvalues-homogeneous").unwrap();
    assert_eq!(h.leap_values, Some(LeapRegions::Homogeneous));
    assert_eq!(h.name(), "leapvalues-homogeneous");
    assert!(Mode::parse("leap8+leapvalues").is_err());
    assert!(Mode::parse("distance8+leapvalues").is_err());
    assert!(Mode::parse("leapvalues+hier").is_err());
    assert!(Mode::parse("leapvaluesx").is_err());
    // Modes without leap values serialise as before.
    let json = serde_json::to_string(&Mode::parse("ert+leap8").unwrap()).unwrap();
    assert!(!json.contains("leap_values"), "{json}");

    let text = r#"
name = "lv"
datasets = ["phantom:cast:32"]
tf = ["class"]
modes = ["ert+leapvalues", "ert+leapvalues-homogeneous", "ert"]
models = ["step"]
[frames]
orbit = 4
size = "16x16"
"#;
    let expansion = vizsim::experiment::spec::expand(text, "lv.toml", None).unwrap();
    let structures: Vec<_> = expansion
        .runs
        .iter()
        .map(|r| {
            (
                r.run.hardware.occupancy.structure,
                r.run.hardware.leap_values.regions,
            )
        })
        .collect();
    use vizsim::config::LeapStructure;
    assert!(structures.contains(&(LeapStructure::LeapValues, LeapRegions::Homogeneous)));
    assert!(structures.contains(&(LeapStructure::LeapValues, LeapRegions::Empty)));
    assert!(structures.contains(&(LeapStructure::Map, LeapRegions::Empty)));
}
