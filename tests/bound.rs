//! Invariant (c) of the brief: the fixed-point image stays within the error bound its bit
//! widths predict, against the float reference (`vizsim::bound`), over phantoms, views, widths
//! and the modes the bound covers; and the bound is a prediction that follows the widths, not
//! a threshold that any image would pass.

mod common;

use vizsim::bound::{check, unsupported, ErrorBound};
use vizsim::config::HardwareConfig;
use vizsim::run::{self, check_error_bound, Model, Probes, RunDescription};
use vizsim::transfer;
use vizsim::volume::{dataset, Volume};

fn config(sets: &[&str]) -> HardwareConfig {
    let sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
    HardwareConfig::load(None, &sets).unwrap()
}

fn run_of(dataset_name: &str, view: &str, persp: bool, size: u32, sets: &[&str]) -> RunDescription {
    let mut run = RunDescription::new(dataset_name, "class", Model::Step, config(sets));
    run.view = view.into();
    run.size = (size, size);
    if persp {
        run.projection = vizsim::camera::Projection::Persp;
    }
    run
}

fn phantom(name: &str) -> Volume {
    dataset::load(name, None).unwrap()
}

#[test]
fn the_fixed_image_is_within_its_bound_over_phantoms_views_and_widths() {
    let widths: [&[&str]; 7] = [
        &[],
        &["ray.increment_frac_bits=6"],
        &["ray.position_frac_bits=8", "ray.increment_frac_bits=8"],
        &["interpolation.weight_bits=3"],
        &["classification.lut_bits=5"],
        &["compositing.accumulator_bits=8"],
        &["compositing.ert=false"],
    ];
    for name in ["phantom:sphere:32", "phantom:shells:32", "phantom:cast:32"] {
        let volume = phantom(name);
        for (view, persp) in [("orbit:7/72", false), ("orbit:50/72", true)] {
            for sets in widths {
                let run = run_of(name, view, persp, 40, sets);
                let result = check_error_bound(&run, &volume, None).unwrap();
                assert!(
                    result.holds(),
                    "{name} {view} {sets:?}: {}",
                    result.describe()
                );
                assert!(
                    result.pixels == 1600 && result.max_bound[0] > 0,
                    "{result:?}"
                );
            }
        }
    }
}

/// The modes the bound covers besides the widths: sample spacing (opacity correction),
/// interleaved sampling, ERT thresholds, leaping structures, bricks and blocking (which keep
/// the image), the iso surface (refined or not), clipping and opaque geometry (whose surface colour each model rounds its own
/// way), and the cycle model's frame (equal to the fixed-point one).
#[test]
fn the_bound_holds_across_the_modes_it_covers() {
    let name = "phantom:metaballs:32";
    let volume = phantom(name);
    let cases: [(&str, &[&str]); 14] = [
        ("spacing 0.5", &[]),
        ("spacing 2", &[]),
        ("interleave 2", &["ray.interleave=2"]),
        ("threshold 0.6", &["compositing.ert_threshold=0.6"]),
        (
            "8³ map",
            &["occupancy.subcube=8", "occupancy.hierarchy=true"],
        ),
        ("distance volume", &["occupancy.structure=\"distance\""]),
        ("bricks 8", &["bricks.size=8"]),
        ("leap values", &["occupancy.structure=\"leap-values\""]),
        ("iso surface", &["iso.enabled=true"]),
        (
            "iso, no refinement",
            &["iso.enabled=true", "iso.refinement_steps=0"],
        ),
        (
            "blocking",
            &["blocking.enabled=true", "blocking.block_size=8"],
        ),
        (
            "clip box",
            &["clip.box=[[3.0, 2.0, 4.0], [25.0, 20.0, 28.0]]"],
        ),
        (
            "clip plane",
            &["clip.planes=[{point=[16.0, 16.0, 16.0], normal=[1.0, 0.4, -0.2]}]"],
        ),
        (
            "geometry",
            &[
                "geometry.shape=\"sphere\"",
                "geometry.centre=[16.0, 16.0, 16.0]",
                "geometry.radius=7.0",
                "geometry.colour=[0.9, 0.3, 0.1]",
            ],
        ),
    ];
    for (case, sets) in cases {
        let mut run = run_of(name, "orbit:11/72", case == "interleave 2", 40, sets);
        run.sample_spacing = match case {
            "spacing 0.5" => 0.5,
            "spacing 2" => 2.0,
            _ => 1.0,
        };
        let result = check_error_bound(&run, &volume, None).unwrap();
        assert!(result.holds(), "{case}: {}", result.describe());
    }
    // The cycle model's image, through the same check.
    let run = RunDescription {
        model: Model::Cycle,
        ..run_of(name, "orbit:3/72", false, 32, &["occupancy.subcube=8"])
    };
    let report = run::execute(
        &run,
        &run::prepare(&run, &volume).unwrap(),
        Probes::default(),
    )
    .unwrap();
    let result = check_error_bound(&run, &volume, Some(&report.frame)).unwrap();
    assert!(result.holds(), "cycle model: {}", result.describe());
}

/// Phong shading: the gradients' quantisation and interpolation, the light direction's and every
/// shading product's rounding are in the bound, over widths that shade coarsely.
#[test]
fn the_bound_holds_with_shading() {
    for name in ["phantom:sphere:32", "phantom:metaballs:32"] {
        let volume = phantom(name);
        for sets in [
            &[][..],
            &["shading.gradient_bits=4"],
            &["classification.lut_bits=5"],
            &["interpolation.weight_bits=3"],
        ] {
            for persp in [false, true] {
                let mut run = run_of(name, "orbit:29/72", persp, 40, sets);
                run.shading = true;
                let result = check_error_bound(&run, &volume, None).unwrap();
                assert!(result.holds(), "{name} {sets:?}: {}", result.describe());
            }
        }
    }
}

/// A background other than black: its rounding in both models is in the bound.
#[test]
fn the_bound_holds_over_a_coloured_background() {
    let volume = phantom("phantom:jet:32");
    let tf = transfer::resolve_for("class", &volume).unwrap();
    let hardware = config(&[]);
    let run = run_of("phantom:jet:32", "orbit:20/72", false, 40, &[]);
    let settings = vizsim::render::RenderSettings {
        background: [0.3, 0.55, 0.9, 1.0],
        ..run.settings()
    };
    let camera = run.camera(&volume).unwrap();
    let fixed = vizsim::functional::renderer::FixedRenderer::new(
        &volume,
        &tf,
        &settings,
        &hardware,
        vizsim::functional::renderer::Leaping::None,
    )
    .unwrap()
    .render(&camera);
    let float = vizsim::render::float::FloatRenderer::new(&volume, &tf, &settings)
        .unwrap()
        .render(&camera);
    let bound = ErrorBound::new(&volume, &tf, &settings, &hardware)
        .unwrap()
        .predict(&camera);
    let result = check(&fixed, &float, &bound).unwrap();
    assert!(result.holds(), "{}", result.describe());
}

/// The bound is a prediction from the widths: it shrinks as they widen, it is a few levels at
/// the default widths (not a threshold any image passes), and an image made with narrower
/// increments than the widths it is checked against breaks it.
#[test]
fn the_bound_follows_the_widths_and_catches_an_image_of_other_widths() {
    let name = "phantom:sphere:32";
    let volume = phantom(name);
    let mean_bound = |sets: &[&str]| {
        check_error_bound(&run_of(name, "orbit:7/72", false, 40, sets), &volume, None)
            .unwrap()
            .mean_bound
    };
    let increments = [6, 8, 12].map(|b| mean_bound(&[&format!("ray.increment_frac_bits={b}")]));
    assert!(
        increments[0] > increments[1] && increments[1] > increments[2],
        "{increments:?}"
    );
    let accumulators =
        [8, 10, 12].map(|b| mean_bound(&[&format!("compositing.accumulator_bits={b}")]));
    assert!(
        accumulators[0] > accumulators[1] && accumulators[1] > accumulators[2],
        "{accumulators:?}"
    );
    assert!(
        increments[2] < 10.0,
        "default widths: mean bound {}",
        increments[2]
    );

    // The fixed image of 5-bit increments against the bound of the default 12 bits.
    let run = run_of(name, "orbit:7/72", false, 40, &[]);
    let tf = transfer::resolve_for("class", &volume).unwrap();
    let camera = run.camera(&volume).unwrap();
    let narrow = RunDescription {
        hardware: config(&["ray.increment_frac_bits=5"]),
        ..run.clone()
    };
    let frame_of = |run: &RunDescription| {
        run::execute(run, &run::prepare(run, &volume).unwrap(), Probes::default())
            .unwrap()
            .frame
    };
    let float = frame_of(&RunDescription {
        model: Model::Float,
        ..run.clone()
    });
    let bound = ErrorBound::new(&volume, &tf, &run.settings(), &run.hardware)
        .unwrap()
        .predict(&camera);
    let result = check(&frame_of(&narrow), &float, &bound).unwrap();
    assert!(!result.holds(), "{}", result.describe());
    assert!(check(&frame_of(&run), &float, &bound).unwrap().holds());
}

#[test]
fn homogeneous_leap_values_are_refused_by_name() {
    let volume = phantom("phantom:sphere:32");
    let sets = [
        "occupancy.structure=\"leap-values\"",
        "leap_values.regions=\"homogeneous\"",
    ];
    let run = run_of("phantom:sphere:32", "front", false, 16, &sets);
    let reason = unsupported(&run.hardware).expect("outside the bound");
    assert!(reason.contains("homogeneous leap values"), "{reason}");
    let error = check_error_bound(&run, &volume, None)
        .unwrap_err()
        .to_string();
    assert!(error.contains("homogeneous leap values"), "{error}");
}

/// On every real dataset (whenever the data folder is there, as in CI), orthographic and
/// perspective, at the default widths.
#[test]
fn the_fixed_image_is_within_its_bound_on_real_data() {
    let Some(dir) = common::data_dir() else {
        eprintln!("SKIP the_fixed_image_is_within_its_bound_on_real_data: no data directory");
        return;
    };
    for entry in dataset::scan(&dir).unwrap() {
        let volume = dataset::load(&entry.name, Some(&dir)).unwrap();
        for (view, persp) in [("orbit:5/72", false), ("orbit:50/72", true)] {
            let run = run_of(&entry.name, view, persp, 48, &[]);
            let result = check_error_bound(&run, &volume, None).unwrap();
            assert!(
                result.holds(),
                "{} {view}: {}",
                entry.name,
                result.describe()
            );
        }
    }
}
