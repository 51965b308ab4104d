//! Iso-surface mode with hitpoint refinement (issue 15, part 5), through the one run path.
//!
//! - The cycle image equals the functional image bit for bit in iso mode, with and without
//!   refinement, with plain stepping, occupancy-map and distance leaping, on SDRAM and the
//!   ideal memory; the pipeline issues exactly the functional model's samples and refinement
//!   samples, and each refinement sample is a memory read that costs cycles.
//! - Leaping is invisible in iso mode too (image and refinement samples equal).
//! - Refinement never moves a hit outside the interval between the two samples it refines
//!   (fixed point: the axis box of the two positions; float: [(k-1)·S, k·S]), and the refined
//!   hit is still at or above the iso value.
//! - Refinement brings a coarse spacing closer to a fine-step reference (float model).
//! - Bad input (iso value outside the dataset, refinement steps out of range, leap values in
//!   the volume) gives an error naming the field; the default configuration has no `[iso]`.

mod common;

use vizsim::compare::compare;
use vizsim::config::HardwareConfig;
use vizsim::functional::arith::{interpolate_exact, iso_threshold};
use vizsim::functional::leaping::{SampleValue, SkipState};
use vizsim::render::clip_to_box;
use vizsim::render::float::FloatRenderer;
use vizsim::run::{execute, prepare, Memory, Model, Probes, RunDescription, RunReport};
use vizsim::volume::Volume;

const SIZE: u32 = 48;

fn config(sets: &[String]) -> HardwareConfig {
    HardwareConfig::load(None, sets).unwrap_or_else(|e| panic!("{sets:?}: {e}"))
}

fn iso_sets(value: f64, steps: u32, extra: &[&str]) -> Vec<String> {
    let mut sets = vec![
        "iso.enabled=true".to_string(),
        format!("iso.value={value}"),
        format!("iso.refinement_steps={steps}"),
    ];
    sets.extend(extra.iter().map(|s| s.to_string()));
    sets
}

fn description(
    volume: &Volume,
    model: Model,
    view: &str,
    spacing: f32,
    sets: &[String],
) -> RunDescription {
    let mut run = RunDescription::new(&volume.name, "class", model, config(sets));
    run.size = (SIZE, SIZE);
    run.view = view.to_string();
    run.sample_spacing = spacing;
    run
}

fn render(volume: &Volume, model: Model, view: &str, spacing: f32, sets: &[String]) -> RunReport {
    let run = description(volume, model, view, spacing, sets);
    let prepared = prepare(&run, volume).unwrap_or_else(|e| panic!("{sets:?}: {e}"));
    execute(&run, &prepared, Probes::default()).unwrap_or_else(|e| panic!("{sets:?}: {e}"))
}

fn phantom(spec: &str) -> Volume {
    vizsim::volume::dataset::load(spec, None).unwrap()
}

/// Half the largest density of a volume (the iso value 0 stands for).
fn half_max(volume: &Volume) -> f64 {
    *volume.data.iter().max().unwrap() as f64 / 2.0
}

#[test]
fn cycle_image_equals_functional_image_in_iso_mode() {
    for spec in ["phantom:sphere:32", "phantom:metaballs:32"] {
        let volume = phantom(spec);
        let value = half_max(&volume);
        for steps in [0, 6] {
            for leap in [
                &[][..],
                &["occupancy.subcube=8", "occupancy.kind=\"class\""][..],
                &[
                    "occupancy.subcube=4",
                    "occupancy.kind=\"zero\"",
                    "skip.policy=\"sample-then-leap\"",
                ][..],
                &[
                    "occupancy.structure=\"distance\"",
                    "occupancy.kind=\"class\"",
                ][..],
            ] {
                for view in ["front", "orbit:5/36"] {
                    let sets = iso_sets(value, steps, leap);
                    let what = format!("{spec} {view} {sets:?}");
                    let step = render(&volume, Model::Step, view, 1.0, &sets);
                    for memory in [Memory::Sdram, Memory::Ideal { latency: 20 }] {
                        let mut run = description(&volume, Model::Cycle, view, 1.0, &sets);
                        run.memory = memory;
                        let prepared = prepare(&run, &volume).unwrap();
                        let cycle = execute(&run, &prepared, Probes::default())
                            .unwrap_or_else(|e| panic!("{what}: {e}"));
                        assert!(
                            step.frame.pixels == cycle.frame.pixels,
                            "{what} {memory:?}: cycle image differs from the functional image"
                        );
                        assert_eq!(step.frame.rays, cycle.frame.rays, "{what}: ray records");
                        let m = &cycle.measurements;
                        assert_eq!(m.samples, step.measurements.samples, "{what}");
                        assert_eq!(
                            m.refinement_samples, step.measurements.refinement_samples,
                            "{what}"
                        );
                        assert_eq!(
                            m.discarded_after_ert,
                            Some(0),
                            "{what}: no sample past a hit"
                        );
                    }
                    let r = step.measurements.refinement_samples;
                    if steps == 0 {
                        assert_eq!(r, 0, "{what}");
                    } else {
                        // Every refined hit takes exactly `steps` refinement samples.
                        assert!(
                            r > 0 && r.is_multiple_of(steps as u64),
                            "{what}: {r} refinement samples"
                        );
                    }
                    // Something was hit and something was missed.
                    let opaque = step.frame.pixels.iter().filter(|p| p[0] > 0).count();
                    assert!(
                        opaque > 0 && opaque < step.frame.pixels.len(),
                        "{what}: {opaque} lit pixels"
                    );
                }
            }
        }
    }
}

#[test]
fn refinement_samples_are_memory_reads_that_cost_cycles() {
    let volume = phantom("phantom:metaballs:32");
    let value = half_max(&volume);
    let plain = render(
        &volume,
        Model::Cycle,
        "front",
        1.0,
        &iso_sets(value, 0, &[]),
    );
    let refined = render(
        &volume,
        Model::Cycle,
        "front",
        1.0,
        &iso_sets(value, 6, &[]),
    );
    let (p, r) = (&plain.measurements, &refined.measurements);
    assert!(r.refinement_samples > 0);
    assert_eq!(
        r.samples,
        p.samples + r.refinement_samples,
        "refinement adds only its samples"
    );
    assert!(
        r.cycles.unwrap() > p.cycles.unwrap(),
        "refinement costs cycles: {:?} vs {:?}",
        r.cycles,
        p.cycles
    );
    // Each refinement sample waits for the previous one's words: rays stall on their reads.
    assert!(r.stall_cycles.unwrap().leap_word > 0);
    let reads = |m: &Option<serde_json::Value>| m.as_ref().unwrap()["reads"].as_u64();
    if let (Some(a), Some(b)) = (reads(&plain.memory_stats), reads(&refined.memory_stats)) {
        assert!(b > a, "refinement samples read memory: {a} vs {b}");
    }
}

#[test]
fn leaping_is_invisible_in_iso_mode() {
    let volume = phantom("phantom:metaballs:48");
    let value = half_max(&volume) * 0.8;
    for steps in [0, 6] {
        for view in ["front", "orbit:11/36"] {
            let plain = render(
                &volume,
                Model::Step,
                view,
                1.0,
                &iso_sets(value, steps, &[]),
            );
            for leap in [
                &["occupancy.subcube=8", "occupancy.kind=\"class\""][..],
                &[
                    "occupancy.subcube=4",
                    "occupancy.hierarchy=true",
                    "occupancy.kind=\"class\"",
                ][..],
                &["occupancy.subcube=8", "occupancy.kind=\"zero\""][..],
                &[
                    "occupancy.structure=\"distance\"",
                    "occupancy.kind=\"class\"",
                ][..],
                &["bricks.size=8"][..],
                &[
                    "occupancy.subcube=4",
                    "occupancy.kind=\"class\"",
                    "bricks.size=16",
                ][..],
            ] {
                let sets = iso_sets(value, steps, leap);
                let with = render(&volume, Model::Step, view, 1.0, &sets);
                assert!(
                    plain.frame.pixels == with.frame.pixels,
                    "{view} {sets:?}: image changed"
                );
                let (p, w) = (&plain.measurements, &with.measurements);
                assert_eq!(
                    p.refinement_samples, w.refinement_samples,
                    "{view} {sets:?}"
                );
                assert!(w.steps <= p.steps, "{view} {sets:?}: leaping costs steps");
                if leap == ["occupancy.subcube=8", "occupancy.kind=\"class\""] {
                    assert!(w.steps < p.steps, "{view} {sets:?}: the map leaps nothing");
                }
                if leap.iter().any(|s| s.starts_with("bricks")) {
                    let cycle = render(&volume, Model::Cycle, view, 1.0, &sets);
                    assert!(
                        cycle.frame.pixels == with.frame.pixels,
                        "{view} {sets:?}: cycle"
                    );
                }
            }
            // The float reference with bricks: the same image (its own brick range).
            let float = render(
                &volume,
                Model::Float,
                view,
                1.0,
                &iso_sets(value, steps, &[]),
            );
            let bricks = render(
                &volume,
                Model::Float,
                view,
                1.0,
                &iso_sets(value, steps, &["bricks.size=8"]),
            );
            assert!(
                float.frame.pixels == bricks.frame.pixels,
                "{view}: float bricks"
            );
            assert_eq!(
                float.measurements.refinement_samples,
                bricks.measurements.refinement_samples
            );
        }
    }
}

/// Fixed point: march each ray with the renderer's own steps; at the hit, the refined surface
/// position lies in the axis box of the sample before the hit and the hit, at or above the iso
/// value. Float: the refined t lies in [(k-1)·S, k·S].
#[test]
fn refinement_never_leaves_the_interval_between_the_two_samples() {
    for spec in ["phantom:sphere:32", "phantom:metaballs:32"] {
        let volume = phantom(spec);
        let value = half_max(&volume) * 0.9;
        for spacing in [1.0f32, 2.5] {
            for steps in [1u32, 6, 16] {
                let sets = iso_sets(value, steps, &[]);
                let run = description(&volume, Model::Step, "orbit:7/36", spacing, &sets);
                let prepared = prepare(&run, &volume).unwrap();
                let renderer = prepared.fixed().unwrap();
                let camera = run.camera(&volume).unwrap();
                let skipper = renderer.skipper();
                let (pf, wb) = (
                    renderer.widths.position_frac_bits,
                    renderer.widths.weight_bits,
                );
                let threshold = iso_threshold(renderer.iso.unwrap().value, wb);
                let mut refined = 0;
                for py in 0..SIZE {
                    for px in 0..SIZE {
                        let ray = renderer.setup(&camera, px, py);
                        let mut state = SkipState::default();
                        let (mut pos, mut k) = (ray.start, 0u64);
                        let mut interval = None;
                        while k < ray.samples as u64 {
                            let step = renderer.step(
                                &skipper,
                                pos,
                                &ray,
                                &mut state,
                                ray.samples as u64 - k,
                            );
                            if interval.is_none() && step.bisects {
                                let lo = [0, 1, 2].map(|a| pos[a] - ray.step[a]);
                                interval = Some((lo, pos));
                            }
                            if step.ends_ray {
                                let SampleValue::Surface = step.value else {
                                    panic!("the last step composites the surface");
                                };
                                let at = state.sample_position(step.value, pos);
                                assert!(interpolate_exact(&volume, at, pf, wb) >= threshold);
                                if let Some((lo, hi)) = interval {
                                    refined += 1;
                                    for a in 0..3 {
                                        let (l, h) = (lo[a].min(hi[a]), lo[a].max(hi[a]));
                                        assert!(
                                            (l..=h).contains(&at[a]),
                                            "{spec} pixel ({px}, {py}) axis {a}: {} outside [{l}, {h}]",
                                            at[a]
                                        );
                                    }
                                } else {
                                    assert_eq!(at, pos, "no refinement: the hit itself");
                                }
                                break;
                            }
                            if step.bisects {
                                pos = state.midpoint();
                            } else {
                                k += step.advance;
                                pos = [0, 1, 2].map(|a| pos[a] + step.advance as i64 * ray.step[a]);
                            }
                        }
                    }
                }
                assert!(refined > 0, "{spec} S={spacing}: no ray refined its hit");

                // The float reference.
                let mut float = FloatRenderer::new(
                    &volume,
                    &vizsim::transfer::resolve("class", &volume.name).unwrap(),
                    &run.settings(),
                )
                .unwrap()
                .with_iso(&run.hardware)
                .unwrap();
                float = float.with_ray_range(&run.hardware).unwrap();
                let mut checked = 0;
                for py in (0..SIZE).step_by(3) {
                    for px in (0..SIZE).step_by(3) {
                        let r = camera.voxel_ray(px, py, volume.spacing);
                        let Some((t0, t1)) = clip_to_box(&r, volume.dims) else {
                            continue;
                        };
                        let (first, end) = vizsim::render::sample_range(t0, t1, spacing);
                        if let Some((k, t)) =
                            (first..end).find_map(|k| float.iso_hit_t(&r, k, first).map(|t| (k, t)))
                        {
                            let (lo, hi) = if k > first {
                                ((k - 1) as f32 * spacing, k as f32 * spacing)
                            } else {
                                (k as f32 * spacing, k as f32 * spacing)
                            };
                            assert!(
                                t >= lo && t <= hi,
                                "{spec} float pixel ({px}, {py}): t {t} outside [{lo}, {hi}]"
                            );
                            assert!(float.interpolate(r.origin + r.dir * t) >= value as f32);
                            checked += 1;
                        }
                    }
                }
                assert!(checked > 0);
            }
        }
    }
}

/// Refinement at a coarse spacing is closer to a fine-step reference than no refinement.
#[test]
fn refinement_brings_a_coarse_spacing_closer_to_the_fine_reference() {
    let volume = phantom("phantom:metaballs:48");
    let value = half_max(&volume);
    let reference = render(
        &volume,
        Model::Float,
        "orbit:3/36",
        0.125,
        &iso_sets(value, 6, &[]),
    );
    for spacing in [3.0f32, 5.0] {
        let psnr = |steps| {
            let r = render(
                &volume,
                Model::Float,
                "orbit:3/36",
                spacing,
                &iso_sets(value, steps, &[]),
            );
            compare(&reference.frame.pixels, &r.frame.pixels, SIZE, SIZE)
                .unwrap()
                .psnr_db
        };
        let (without, with) = (psnr(0), psnr(6));
        assert!(
            with > without + 2.0,
            "S={spacing}: PSNR {with} with refinement, {without} without"
        );
    }
}

#[test]
fn the_fixed_point_iso_image_is_close_to_the_float_image() {
    let volume = phantom("phantom:sphere:32");
    let value = half_max(&volume);
    for steps in [0, 6] {
        let sets = iso_sets(value, steps, &[]);
        let float = render(&volume, Model::Float, "orbit:4/36", 1.0, &sets);
        let fixed = render(&volume, Model::Step, "orbit:4/36", 1.0, &sets);
        let c = compare(&float.frame.pixels, &fixed.frame.pixels, SIZE, SIZE).unwrap();
        assert!(
            c.psnr_db > 30.0,
            "refinement {steps}: PSNR {} fixed vs float",
            c.psnr_db
        );
    }
}

#[test]
fn bad_iso_input_names_the_field() {
    let volume = phantom("phantom:sphere:32");
    let max = *volume.data.iter().max().unwrap() as f64;
    let err = |sets: Vec<String>| -> String {
        match HardwareConfig::load(None, &sets) {
            Err(e) => e.to_string(),
            Ok(c) => {
                let mut run = RunDescription::new(&volume.name, "class", Model::Step, c);
                run.size = (8, 8);
                match prepare(&run, &volume) {
                    Err(e) => e.to_string(),
                    Ok(_) => panic!("{sets:?} accepted"),
                }
            }
        }
    };
    let e = err(iso_sets(max + 1.0, 6, &[]));
    assert!(e.contains("iso.value"), "{e}");
    let e = err(iso_sets(-3.0, 6, &[]));
    assert!(e.contains("iso.value"), "{e}");
    let e = err(iso_sets(max / 2.0, 17, &[]));
    assert!(
        e.contains("iso.refinement_steps") && e.contains("0..=16"),
        "{e}"
    );
    let e = err(iso_sets(max / 2.0, 6, &["iso.colour=[1.0, 2.0, 0.0]"]));
    assert!(e.contains("iso.colour"), "{e}");
    let e = err(iso_sets(
        max / 2.0,
        6,
        &["occupancy.structure=\"leap-values\""],
    ));
    assert!(e.contains("iso.enabled"), "{e}");
    // The float reference checks the value against the dataset too.
    let mut run = RunDescription::new(
        &volume.name,
        "class",
        Model::Float,
        config(&iso_sets(max + 1.0, 6, &[])),
    );
    run.size = (8, 8);
    let e = prepare(&run, &volume)
        .err()
        .expect("float accepted a value above the data")
        .to_string();
    assert!(e.contains("iso.value"), "{e}");
}

#[test]
fn the_default_configuration_has_no_iso_section() {
    let c = HardwareConfig::default_config();
    assert!(c.iso.is_default() && !c.iso.enabled);
    assert_eq!(c.iso.refinement_steps, 6);
    let text = toml::to_string(&c).unwrap();
    assert!(
        !text.contains("[iso]"),
        "the default writes no [iso] section"
    );
    assert!(c.differences_from_default().is_empty());
    let on = config(&iso_sets(100.0, 6, &[]));
    assert!(toml::to_string(&on).unwrap().contains("[iso]"));
    assert!(on
        .differences_from_default()
        .iter()
        .any(|d| d.starts_with("iso.enabled")));
}

/// The surface is opaque, in its colour (red: green and blue stay equal), lit by the headlight.
#[test]
fn iso_mode_shades_the_surface_in_its_colour() {
    let volume = phantom("phantom:sphere:32");
    let value = half_max(&volume);
    let sets = iso_sets(value, 6, &["iso.colour=[1.0, 0.0, 0.0]"]);
    let report = render(&volume, Model::Step, "front", 1.0, &sets);
    let lit: Vec<_> = report.frame.pixels.iter().filter(|p| p[0] > 0).collect();
    assert!(!lit.is_empty());
    assert!(
        lit.iter().all(|p| p[1] == p[2] && p[3] == 255),
        "red surface, opaque"
    );
}

/// `isoN` modes in an experiment file beside the existing ones: the runs carry `[iso]`, the
/// iso value comes from an axis, each run renders through the one run path, and the existing
/// modes' runs keep their keys (no `[iso]` in their configuration).
#[test]
fn iso_modes_work_in_experiment_files() {
    use vizsim::experiment::spec::{expand, Mode};
    const TEXT: &str = r#"
name = "iso-tiny"
datasets = ["phantom:metaballs:32"]
tf = ["class"]
modes = ["ert+leap8", "ert+iso0", "ert+leap8+iso6"]
models = ["step", "cycle"]
[frames]
orbit = 72
select = [3]
size = "24x24"
[axes]
"iso.value" = [100.0]
"#;
    let e = expand(TEXT, "iso-tiny", None).unwrap();
    assert_eq!(e.runs.len(), 3 * 2);
    let volume = phantom("phantom:metaballs:32");
    let mut images = std::collections::BTreeMap::new();
    for spec in &e.runs {
        let iso = &spec.run.hardware.iso;
        match spec.mode.iso {
            Some(n) => {
                assert!(iso.enabled && iso.refinement_steps == n && iso.value == 100.0);
                assert!(spec.mode.name().ends_with(&format!("iso{n}")));
            }
            None => assert!(!iso.enabled),
        }
        let prepared = prepare(&spec.run, &volume).unwrap();
        let report = execute(&spec.run, &prepared, Probes::default()).unwrap();
        images
            .entry(spec.mode.name())
            .or_insert_with(Vec::new)
            .push(report.frame.pixels);
    }
    for (mode, frames) in &images {
        assert!(frames[0] == frames[1], "{mode}: cycle image == step image");
    }
    assert!(images["ert+iso0"] != images["ert+leap8+iso6"]);
    assert_eq!(
        Mode::parse("ert+leap8+iso6").unwrap().name(),
        "ert+leap8+iso6"
    );
    for bad in ["iso17", "isox", "iso6+leapvalues"] {
        assert!(Mode::parse(bad).is_err(), "{bad} accepted");
    }
    // The same experiment without iso modes: keys equal those of a file written before `[iso]`.
    let plain = expand(&TEXT.replace(r#""iso.value" = [100.0]"#, ""), "plain", None).unwrap();
    let with_iso_axis: Vec<_> = e
        .runs
        .iter()
        .filter(|r| r.mode.iso.is_none())
        .map(|r| serde_json::to_string(&r.run.hardware).unwrap())
        .collect();
    for r in plain.runs.iter().filter(|r| r.mode.iso.is_none()) {
        let json = serde_json::to_string(&r.run.hardware).unwrap();
        assert!(!json.contains("\"iso\""), "no [iso] without iso modes");
    }
    assert!(with_iso_axis.iter().all(|j| j.contains("\"iso\"")));
}
