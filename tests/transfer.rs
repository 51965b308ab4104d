mod common;

use vizsim::transfer::{self, correct_opacity, TransferFunction};

fn load_text(text: &str) -> vizsim::Result<TransferFunction> {
    TransferFunction::from_toml(text, "inline.toml", "inline")
}

#[test]
fn eval_is_piecewise_linear_with_constant_ends() {
    let tf = common::tf(&[(10.0, [0.0, 0.0, 0.0, 0.0]), (20.0, [1.0, 0.5, 0.0, 0.8])]);
    assert_eq!(tf.eval(0.0), [0.0; 4]);
    assert_eq!(tf.eval(15.0), [0.5, 0.25, 0.0, 0.4]);
    assert_eq!(tf.eval(200.0), [1.0, 0.5, 0.0, 0.8]);
}

#[test]
fn opacity_interval_test_sees_a_peak_between_transparent_ends() {
    // Zero opacity at 0 and at 100 does not make 50 invisible (brief, section 2).
    let tf = common::tf(&[
        (0.0, [0.0; 4]),
        (50.0, [1.0, 1.0, 1.0, 0.5]),
        (100.0, [0.0; 4]),
    ]);
    assert!(tf.any_opacity_in(0.0, 100.0));
    assert!(tf.any_opacity_in(49.0, 51.0));
    assert!(!tf.any_opacity_in(100.0, 255.0));
}

#[test]
fn unsorted_points_are_an_error_naming_the_point() {
    let err = load_text(
        "[[points]]\nvalue = 20\nrgba = [0,0,0,0]\n[[points]]\nvalue = 10\nrgba = [0,0,0,0]\n",
    )
    .unwrap_err()
    .to_string();
    assert!(
        err.contains("inline.toml") && err.contains("points[1].value"),
        "{err}"
    );
}

#[test]
fn out_of_range_colour_is_an_error() {
    let err = load_text("[[points]]\nvalue = 20\nrgba = [0,0,1.5,0]\n")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("points[0].rgba") && err.contains("0..=1"),
        "{err}"
    );
}

#[test]
fn unknown_field_is_an_error_naming_it() {
    let err = load_text("colour = 3\n[[points]]\nvalue = 20\nrgba = [0,0,0,0]\n")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("colour") && err.contains("inline.toml"),
        "{err}"
    );
}

#[test]
fn opacity_correction_composes() {
    // Two half-voxel slabs absorb like one voxel.
    let a = 0.6f32;
    let half = correct_opacity(a, 0.5);
    let two_halves = 1.0 - (1.0 - half) * (1.0 - half);
    assert!((two_halves - a).abs() < 1e-6);
    assert_eq!(correct_opacity(a, 1.0), a);
}

#[test]
fn every_embedded_preset_parses_and_zero_presets_show_every_nonzero_value() {
    let names = transfer::preset_names();
    assert!(!names.is_empty());
    for name in names {
        let tf = transfer::resolve(name, "any").unwrap();
        assert_eq!(tf.eval(0.0)[3], 0.0, "{name}: zero must be transparent");
        if name.ends_with("-zero") {
            for v in 1..=255 {
                assert!(tf.eval(v as f32)[3] > 0.0, "{name}: value {v} invisible");
            }
        }
    }
}

#[test]
fn every_dataset_and_phantom_has_zero_and_class_presets() {
    let mut keys: Vec<String> = vizsim::volume::phantom::PhantomKind::ALL
        .iter()
        .map(|k| transfer::preset_key(&format!("phantom:{}:64", k.name())))
        .collect();
    if let Some(dir) = common::data_dir() {
        keys.extend(
            vizsim::volume::dataset::scan(&dir)
                .unwrap()
                .into_iter()
                .map(|e| e.name),
        );
    }
    let names = transfer::preset_names();
    for key in keys {
        for kind in ["zero", "class"] {
            let want = format!("{key}-{kind}");
            assert!(names.contains(&want.as_str()), "missing preset {want}");
        }
    }
}

#[test]
fn unknown_preset_lists_the_presets() {
    let err = transfer::resolve("nonesuch", "fuel")
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("nonesuch") && err.contains("fuel-class"),
        "{err}"
    );
}
