//! Charts of sweep results (`vizsim plot`, issue 13 §4): a swept field splits the charts
//! instead of being averaged over, one-point series are drawn, and the demo's contact sheets
//! carry their labels.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use serde_json::{json, Value};
use vizsim::figures::ChartKind;
use vizsim::plot::{contact_sheet, label_strip_height, LineChart, Series, SHEET_STRIP_BACKGROUND};
use vizsim::render::Frame;

fn scratch(name: &str) -> PathBuf {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-figures-{}-{name}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

/// One result line as a sweep writes it (the fields the charts read).
fn line(mode: &str, frame: u32, axes: Value, fps: f64, skippable: f64) -> Value {
    let subcube = mode
        .split('+')
        .find_map(|t| t.strip_prefix("leap")?.parse::<u32>().ok())
        .unwrap_or(0);
    let mut l = json!({
        "dataset": "phantom:sphere:64",
        "dataset_label": "phantom:sphere:64",
        "tf": "class",
        "mode": mode,
        "model": "cycle",
        "frame": frame,
        "view": format!("orbit:{frame}/72"),
        "axes": axes,
        "subcube": subcube,
        "hierarchy": mode.contains("hier"),
        "ert": mode.contains("ert"),
        "fps": fps,
        "cycles": 1e8 / fps,
        "steps": 1e7 / fps,
    });
    if subcube > 0 {
        l["skippable_subcubes_percent"] = json!(skippable);
    }
    l
}

const MODES: [&str; 5] = ["none", "ert", "ert+leap4", "ert+leap8", "ert+leap8+hier"];

/// Frames 0 and 1 of every mode for each value of `ray_queue.rays` (a constant
/// `ray_queue.selection` alongside); the frame rate scales with the rays, so an average over
/// them would be a value no run had.
fn rays_sweep(rays: &[u32]) -> Vec<Value> {
    let mut lines = Vec::new();
    for &r in rays {
        for (m, mode) in MODES.iter().enumerate() {
            for frame in 0..2 {
                let axes = json!({"ray_queue.rays": r, "ray_queue.selection": "lagging-first"});
                let fps = (100 + 10 * m as u32 + frame) as f64 * r as f64;
                lines.push(line(mode, frame, axes, fps, 40.0 + m as f64));
            }
        }
    }
    lines
}

fn charts(dir: &Path) -> BTreeSet<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .collect()
}

fn svg(dir: &Path, stem: &str) -> String {
    std::fs::read_to_string(dir.join(format!("{stem}.svg")))
        .unwrap_or_else(|e| panic!("{stem}.svg: {e}; there are {:?}", charts(dir)))
}

#[test]
fn a_swept_field_splits_the_charts_one_per_value() {
    let dir = scratch("facets");
    let lines = rays_sweep(&[4, 8]);
    let written = vizsim::figures::write_all(&lines, &dir, &ChartKind::ALL).unwrap();
    let names = charts(&dir);
    let stems: BTreeSet<&str> = names
        .iter()
        .filter_map(|n| n.strip_suffix(".png"))
        .collect();
    for stem in &stems {
        assert!(names.contains(&format!("{stem}.svg")), "{stem}: no SVG");
    }
    let expected: BTreeSet<&str> = [
        "cycle-per-frame-phantom-sphere-64-class-ray_queue.rays=4",
        "cycle-per-frame-phantom-sphere-64-class-ray_queue.rays=8",
        "cycle-fps-vs-subcube-phantom-sphere-64-ray_queue.rays=4",
        "cycle-fps-vs-subcube-phantom-sphere-64-ray_queue.rays=8",
        "cycle-fps-by-mode-phantom-sphere-64-ray_queue.rays=4",
        "cycle-fps-by-mode-phantom-sphere-64-ray_queue.rays=8",
        // Its own x axis: one chart, not split by it; the constant selection splits nothing.
        "cycle-fps-vs-ray_queue.rays-phantom-sphere-64",
        // The map does not depend on the rays: one chart.
        "skippable-vs-subcube",
    ]
    .into_iter()
    .collect();
    assert_eq!(stems, expected);
    assert_eq!(written, expected.len());
    assert_eq!(names.len(), 2 * written, "{names:?}");
    // Titles name the value, and only that value.
    for r in [4, 8] {
        let other = if r == 4 { 8 } else { 4 };
        for stem in [
            format!("cycle-per-frame-phantom-sphere-64-class-ray_queue.rays={r}"),
            format!("cycle-fps-vs-subcube-phantom-sphere-64-ray_queue.rays={r}"),
        ] {
            let text = svg(&dir, &stem);
            assert!(text.contains(&format!("ray_queue.rays = {r}")), "{stem}");
            assert!(
                !text.contains(&format!("ray_queue.rays = {other}")),
                "{stem}"
            );
            assert!(
                !text.contains("ray_queue.selection"),
                "{stem}: a constant field named"
            );
        }
    }
    // The one mean left is over frames, and the label says so; the per-frame chart has none.
    let subcube = svg(
        &dir,
        "cycle-fps-vs-subcube-phantom-sphere-64-ray_queue.rays=4",
    );
    assert!(subcube.contains("mean over 2 frames"), "{subcube}");
    let per_frame = svg(
        &dir,
        "cycle-per-frame-phantom-sphere-64-class-ray_queue.rays=4",
    );
    assert!(!per_frame.contains("mean over"));
    // Sub-cube ticks are the sizes, not their logarithms.
    for tick in ["4³", "8³"] {
        assert!(subcube.contains(tick), "no tick {tick}");
    }
    assert!(!subcube.contains("log2"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// `plot --only` draws the kinds asked for and no other: each kind alone gives exactly its own
/// charts of the full set, and together they give the full set.
#[test]
fn only_the_kinds_asked_for_are_drawn() {
    let lines = rays_sweep(&[4, 8]);
    let all = scratch("kinds-all");
    vizsim::figures::write_all(&lines, &all, &ChartKind::ALL).unwrap();
    let every = charts(&all);
    let prefix = |kind: ChartKind| match kind {
        ChartKind::PerFrame => "cycle-per-frame-",
        ChartKind::ByMode => "cycle-fps-by-mode-",
        ChartKind::VsSubcube => "cycle-fps-vs-subcube-",
        ChartKind::VsField => "cycle-fps-vs-ray_queue.rays-",
        ChartKind::Skippable => "skippable-vs-subcube",
    };
    let mut union = BTreeSet::new();
    for kind in ChartKind::ALL {
        let dir = scratch(&format!("kinds-{kind:?}"));
        let written = vizsim::figures::write_all(&lines, &dir, &[kind]).unwrap();
        let names = charts(&dir);
        let expected: BTreeSet<String> = every
            .iter()
            .filter(|n| n.starts_with(prefix(kind)))
            .cloned()
            .collect();
        assert!(written > 0, "{kind:?}: nothing drawn");
        assert_eq!(names, expected, "{kind:?}");
        union.extend(names);
    }
    assert_eq!(union, every);
}

#[test]
fn no_chart_averages_two_values_of_a_swept_field() {
    // With the rays at 4 and 8, every frame rate drawn is one of the runs' (or the mean of two
    // frames of one configuration), never the mean over the rays: the largest tick of the
    // rays=4 chart stays below the smallest rate at rays=8.
    let dir = scratch("no-mixing");
    let lines = rays_sweep(&[4, 8]);
    vizsim::figures::write_all(&lines, &dir, &ChartKind::ALL).unwrap();
    let text = svg(
        &dir,
        "cycle-fps-vs-subcube-phantom-sphere-64-ray_queue.rays=4",
    );
    let numbers: Vec<f64> = text
        .split(['>', '<'])
        .filter_map(|t| t.trim().parse::<f64>().ok())
        .collect();
    assert!(!numbers.is_empty(), "no tick labels found");
    // Rates at rays=4 are 480..=584; at rays=8 960 and more. Ticks stay near the data.
    assert!(
        numbers.iter().all(|&n| n < 700.0),
        "rays=4 chart reaches {numbers:?}"
    );
    // Three values split into three charts each.
    let three = scratch("three-values");
    vizsim::figures::write_all(&rays_sweep(&[4, 8, 16]), &three, &ChartKind::ALL).unwrap();
    let per_frame: Vec<String> = charts(&three)
        .into_iter()
        .filter(|n| n.starts_with("cycle-per-frame") && n.ends_with(".png"))
        .collect();
    assert_eq!(per_frame.len(), 3, "{per_frame:?}");
    for r in [4, 8, 16] {
        assert!(per_frame
            .iter()
            .any(|n| n.contains(&format!("rays={r}.png"))));
    }
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&three);
}

#[test]
fn a_field_that_changes_the_map_splits_the_skippable_chart() {
    let dir = scratch("map-field");
    let mut lines = Vec::new();
    for dilate in [0, 1] {
        for mode in ["ert+leap4", "ert+leap8"] {
            for frame in 0..2 {
                let axes = json!({"occupancy.dilation": dilate});
                lines.push(line(mode, frame, axes, 500.0, 50.0 - 20.0 * dilate as f64));
            }
        }
    }
    vizsim::figures::write_all(&lines, &dir, &ChartKind::ALL).unwrap();
    let names = charts(&dir);
    assert!(
        names.contains("skippable-vs-subcube-occupancy.dilation=0.png"),
        "{names:?}"
    );
    assert!(
        names.contains("skippable-vs-subcube-occupancy.dilation=1.png"),
        "{names:?}"
    );
    assert!(!names.contains("skippable-vs-subcube.png"), "{names:?}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn fields_that_advance_together_are_named_not_split() {
    // A zip: t_rcd and t_rp advance together; charts against one name the other.
    let dir = scratch("zip");
    let mut lines = Vec::new();
    for t in [2, 3, 4] {
        for frame in 0..2 {
            let axes = json!({"sdram.t_rcd": t, "sdram.t_rp": t});
            lines.push(line(
                "ert+leap8",
                frame,
                axes,
                600.0 - 50.0 * t as f64,
                40.0,
            ));
        }
    }
    vizsim::figures::write_all(&lines, &dir, &ChartKind::ALL).unwrap();
    let names = charts(&dir);
    assert!(
        names.contains("cycle-fps-vs-sdram.t_rcd-phantom-sphere-64.png"),
        "{names:?}"
    );
    // One chart for the pair, not the same chart again against t_rp (a probe found both).
    assert!(
        !names.contains("cycle-fps-vs-sdram.t_rp-phantom-sphere-64.png"),
        "{names:?}"
    );
    let text = svg(&dir, "cycle-fps-vs-sdram.t_rcd-phantom-sphere-64");
    assert!(text.contains("sdram.t_rp advancing with it"), "{text}");
    // Three values within a decade: a linear axis.
    assert!(!text.contains("log scale"), "{text}");
    // The per-frame charts are split by both (one combination per value).
    assert_eq!(
        names
            .iter()
            .filter(|n| n.starts_with("cycle-per-frame") && n.ends_with(".png"))
            .count(),
        3
    );
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn a_text_valued_field_is_a_category_axis() {
    let dir = scratch("categories");
    let mut lines = Vec::new();
    for policy in ["leap-only", "sample-then-leap"] {
        for frame in 0..2 {
            let axes = json!({"skip.policy": policy});
            let fps = if policy == "leap-only" { 700.0 } else { 650.0 };
            lines.push(line("ert+leap8", frame, axes, fps, 40.0));
        }
    }
    vizsim::figures::write_all(&lines, &dir, &ChartKind::ALL).unwrap();
    let text = svg(&dir, "cycle-fps-vs-skip.policy-phantom-sphere-64");
    assert!(text.contains("leap-only") && text.contains("sample-then-leap"));
    let _ = std::fs::remove_dir_all(&dir);
}

/// A map mode with bricks or an iso-surface beside plain maps of several sizes is a series of
/// its own in the chart against the sub-cube size (a probe found `plot` refusing the whole
/// folder: the 8³ point would have averaged `ert+leap8` with `ert+leap8+bricks16`).
#[test]
fn what_a_mode_adds_to_its_map_is_a_series_of_its_own() {
    let dir = scratch("map-extras");
    let mut lines = Vec::new();
    for (m, mode) in [
        "ert",
        "ert+leap4",
        "ert+leap8",
        "ert+leap8+bricks16",
        "ert+leap8+iso4",
    ]
    .iter()
    .enumerate()
    {
        lines.push(line(mode, 0, json!({}), 100.0 + m as f64, 40.0));
    }
    vizsim::figures::write_all(&lines, &dir, &ChartKind::ALL).unwrap();
    let text = svg(&dir, "cycle-fps-vs-subcube-phantom-sphere-64");
    let labels: BTreeSet<&str> = text.lines().map(str::trim).collect();
    for name in ["class", "class + bricks16", "class + iso4"] {
        assert!(labels.contains(name), "{name} in {text}");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// The bar chart of every mode: the modes in the tables' column order, a bar per transfer
/// function with its frame rate, the fastest of each marked (both when tied), no chart where
/// there is one mode only.
#[test]
fn every_mode_side_by_side_with_the_fastest_marked() {
    let dir = scratch("by-mode");
    let mut lines = Vec::new();
    // Deliberately not in column order; distance volumes after maps, leap values last.
    let modes = [
        ("ert+leapvalues", 150.0, 140.0),
        ("ert+distance8", 420.0, 300.0),
        ("ert+leap8+hier", 410.0, 300.0),
        ("none", 100.0, 100.0),
        ("ert", 110.0, 105.0),
        ("ert+leap8", 380.0, 250.0),
    ];
    for (mode, class, zero) in modes {
        for (tf, fps) in [("class", class), ("zero", zero)] {
            let mut l = line(mode, 0, json!({}), fps, 40.0);
            l["tf"] = json!(tf);
            // The 8³ map with the hierarchy ran with the SRAM raised.
            l["fits_default_sram"] = json!(mode != "ert+leap8+hier");
            lines.push(l);
        }
    }
    vizsim::figures::write_all(&lines, &dir, &ChartKind::ALL).unwrap();
    let text = svg(&dir, "cycle-fps-by-mode-phantom-sphere-64");
    // Each text element's height on the canvas and its words.
    let placed: Vec<(f64, String)> = text
        .split("<text")
        .skip(1)
        .filter_map(|element| {
            let y = element
                .split("y=\"")
                .nth(1)?
                .split('"')
                .next()?
                .parse()
                .ok()?;
            let words = element.split_once('>')?.1.split("</text>").next()?;
            Some((y, words.trim().replace("&apos;", "'")))
        })
        .collect();
    let texts: Vec<&str> = placed.iter().map(|(_, t)| t.as_str()).collect();
    let height = |label: &str| {
        placed
            .iter()
            .find(|(_, t)| t == label)
            .unwrap_or_else(|| panic!("no {label} in {texts:?}"))
            .0
    };
    // Top to bottom in the tables' column order.
    let heights: Vec<f64> = ["none", "ERT", "8³", "8³+h*", "dist8", "LV"]
        .into_iter()
        .map(height)
        .collect();
    assert!(heights.windows(2).all(|w| w[0] < w[1]), "{placed:?}");
    // The values at the bars' ends, three significant digits; class's fastest is the distance
    // volume, '0''s a tie of the distance volume and the hierarchy.
    assert!(texts.contains(&"420 fastest"), "{texts:?}");
    assert!(texts.contains(&"410"), "{texts:?}");
    assert_eq!(
        texts.iter().filter(|t| **t == "300 fastest").count(),
        2,
        "{texts:?}"
    );
    assert!(texts.contains(&"'0'") && texts.contains(&"class"));
    assert!(
        texts
            .iter()
            .any(|t| t.contains("* map larger than the default SRAM")),
        "{texts:?}"
    );
    // One mode: nothing to compare.
    let one = scratch("by-mode-one");
    vizsim::figures::write_all(
        &[line("ert+leap8", 0, json!({}), 300.0, 40.0)],
        &one,
        &ChartKind::ALL,
    )
    .unwrap();
    assert!(
        !charts(&one).iter().any(|n| n.contains("by-mode")),
        "{:?}",
        charts(&one)
    );
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&one);
}

#[test]
fn a_series_of_one_point_is_drawn() {
    let dir = scratch("one-point");
    let stem = dir.join("single");
    LineChart {
        title: "one point",
        x_label: "x",
        y_label: "y",
        series: vec![Series {
            name: "only".into(),
            points: vec![(3.0, 5.0)],
        }],
        log_y: false,
    }
    .write(&stem)
    .unwrap();
    assert!(dir.join("single.png").is_file());
    let text = svg(&dir, "single");
    // The marker: a line of one point draws nothing.
    assert!(text.contains("<circle"), "{text}");
    // The hierarchy at one size, among results: still charted.
    let results = scratch("one-point-results");
    vizsim::figures::write_all(&rays_sweep(&[4]), &results, &ChartKind::ALL).unwrap();
    let text = svg(&results, "cycle-fps-vs-subcube-phantom-sphere-64");
    assert!(text.contains("class + hierarchy"), "{text}");
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&results);
}

#[test]
fn contact_sheet_panels_carry_a_label_strip() {
    let frame = |rgba: [u8; 4]| Frame {
        width: 96,
        height: 64,
        pixels: vec![rgba; 96 * 64],
        rays: Vec::new(),
    };
    let (a, b, c) = (
        frame([200, 30, 30, 255]),
        frame([30, 200, 30, 255]),
        frame([30, 30, 200, 255]),
    );
    let panels = vec![
        (
            &a,
            vec!["fuel".to_string(), "class, frame 0/72".to_string()],
        ),
        (
            &b,
            vec!["fuel".to_string(), "class, frame 6/72".to_string()],
        ),
        (
            &c,
            vec!["fuel".to_string(), "class, frame 12/72".to_string()],
        ),
    ];
    let sheet = contact_sheet(&panels, 2).unwrap();
    let strip = label_strip_height(2);
    assert!(strip > 0);
    // Two columns, two rows, every panel the frame plus its strip.
    assert_eq!((sheet.width, sheet.height), (2 * 96, 2 * (64 + strip)));
    assert_eq!(sheet.pixels.len(), (sheet.width * sheet.height) as usize);
    let at = |x: u32, y: u32| sheet.pixels[(y * sheet.width + x) as usize];
    for (i, colour) in [[200, 30, 30, 255], [30, 200, 30, 255], [30, 30, 200, 255]]
        .into_iter()
        .enumerate()
    {
        let (ox, oy) = ((i as u32 % 2) * 96, (i as u32 / 2) * (64 + strip));
        // The frame sits under its strip, unchanged.
        assert_eq!(at(ox + 10, oy + strip + 10), colour);
        assert_eq!(at(ox + 95, oy + strip + 63), colour);
        // The strip holds text: pixels other than its background.
        let text_pixels = (oy..oy + strip)
            .flat_map(|y| (ox + 1..ox + 96).map(move |x| (x, y)))
            .filter(|&(x, y)| at(x, y) != SHEET_STRIP_BACKGROUND)
            .count();
        assert!(text_pixels > 20, "panel {i}: {text_pixels} text pixels");
    }
    // The empty fourth cell stays black.
    assert_eq!(at(96 + 10, 64 + strip + 10), [0, 0, 0, 255]);
    // Deterministic.
    let again = contact_sheet(&panels, 2).unwrap();
    assert_eq!(again.pixels, sheet.pixels);
    // Frames of different sizes are refused.
    let small = Frame {
        width: 10,
        height: 10,
        pixels: vec![[0, 0, 0, 255]; 100],
        rays: Vec::new(),
    };
    assert!(contact_sheet(&[(&a, vec![]), (&small, vec![])], 2).is_err());
}

/// Results that a table refuses to mix are refused by the charts too (a probe found a folder
/// resumed at another image size, and exact runs beside sampled ones, plotted as means of
/// both): the image size and the sampling rate are part of a point's configuration.
#[test]
fn charts_refuse_to_average_over_image_sizes_or_sampling() {
    let base = rays_sweep(&[8]);
    for (field, value) in [("width", json!(48)), ("sample_rate", json!(0.25))] {
        let mut lines = base.clone();
        for l in &mut lines {
            l["width"] = json!(64);
        }
        let mut other = lines[0].clone();
        other[field] = value;
        other["key"] = json!("other");
        lines.push(other);
        let dir = scratch(&format!("mixed-{field}"));
        let err = vizsim::figures::write_all(&lines, &dir, &ChartKind::ALL)
            .unwrap_err()
            .to_string();
        assert!(
            err.contains("would average over configurations") && err.contains(field),
            "{field}: {err}"
        );
    }
    // Unmixed, the same lines plot.
    let mut lines = base;
    for l in &mut lines {
        l["width"] = json!(64);
    }
    vizsim::figures::write_all(&lines, &scratch("unmixed"), &ChartKind::ALL).unwrap();
}

/// A swept number spanning a decade or more is drawn on a logarithmic x axis, ticked at its
/// values (a probe found FIFO depths 1 to 64 crowded at the left of a linear axis).
#[test]
fn a_swept_field_over_a_decade_has_a_log_axis() {
    let dir = scratch("log-x");
    let mut lines = Vec::new();
    for depth in [1, 2, 4, 8, 16, 32, 64] {
        for frame in 0..2 {
            let axes = json!({ "memory.address_fifo_depth": depth });
            lines.push(line("ert", frame, axes, 100.0 + depth as f64, 40.0));
        }
    }
    vizsim::figures::write_all(&lines, &dir, &ChartKind::ALL).unwrap();
    let text = svg(
        &dir,
        "cycle-fps-vs-memory.address_fifo_depth-phantom-sphere-64",
    );
    assert!(
        text.contains("memory.address_fifo_depth (log scale)"),
        "{text}"
    );
    // The x ticks are the swept values, in order, after the y axis's labels.
    let labels: Vec<String> = text
        .split("</text>")
        .filter_map(|t| t.rsplit('>').next())
        .map(|t| t.trim().to_string())
        .collect();
    let at = labels.iter().position(|l| l == "1").expect("a tick 1");
    assert_eq!(labels[at..at + 7], ["1", "2", "4", "8", "16", "32", "64"]);
    // Values close together stay points of their own (1562 and 1563 fell into one and were
    // refused as a mean over configurations).
    let close: Vec<Value> = [100, 1562, 1563]
        .iter()
        .map(|&n| {
            line(
                "ert",
                0,
                json!({ "sdram.refresh_interval": n }),
                n as f64,
                40.0,
            )
        })
        .collect();
    vizsim::figures::write_all(&close, &scratch("log-close"), &ChartKind::ALL).unwrap();
}

/// Chart names are made of `file_safe` pieces: a long dataset name (a volume named by a long
/// path) is cut to 80 characters, its start and end with a hash of the whole, so two long names stay distinct and
/// a chart's name stays under the file system's 255 bytes (found by probing: `plot` failed with
/// "File name too long"); short names are unchanged.
#[test]
fn long_names_are_cut_with_a_hash() {
    use vizsim::figures::file_safe;
    assert_eq!(file_safe("phantom:sphere:32"), "phantom-sphere-32");
    let long = |tail: &str| format!("{}/{tail}_64x64x64_uint8.raw", "deep/folder".repeat(30));
    let (a, b) = (file_safe(&long("a")), file_safe(&long("b")));
    assert_eq!(a.len(), 80, "{a}");
    assert_ne!(a, b);
    assert_eq!(a, file_safe(&long("a")), "stable");
    assert!(a.starts_with("deep-folderdeep"), "{a}");
    // The end (the file name, which tells datasets apart) is kept.
    assert!(a.contains("-a_64x64x64_uint8.raw-"), "{a}");
}

/// Lines with `float_reference` (an experiment's `float_reference = true`) also chart the image
/// PSNR against each swept field, with the values the lines hold; lines without it do not.
#[test]
fn lines_with_the_float_reference_chart_the_psnr_against_each_field() {
    let dir = scratch("psnr");
    let mut lines = Vec::new();
    for bits in [4, 8] {
        for frame in 0..2 {
            let axes = json!({"interpolation.weight_bits": bits});
            let mut l = line("ert+leap8", frame, axes, 700.0, 40.0);
            // A PSNR no other figure of the chart has, to find in the drawing's axis labels.
            l["float_reference"] = json!({"psnr_db": if bits == 4 { 31.5 } else { 57.5 }});
            lines.push(l);
        }
    }
    vizsim::figures::write_all(&lines, &dir, &ChartKind::ALL).unwrap();
    let stem = "cycle-psnr-vs-interpolation.weight_bits-phantom-sphere-64";
    let text = svg(&dir, stem);
    assert!(
        text.contains("image PSNR (float reference) against"),
        "{text}"
    );
    assert!(text.contains("PSNR against the float reference (dB)"));
    assert!(charts(&dir).contains("cycle-fps-vs-interpolation.weight_bits-phantom-sphere-64.svg"));
    // Without the figure, no PSNR chart.
    let plain = scratch("no-psnr");
    for l in &mut lines {
        l.as_object_mut().unwrap().remove("float_reference");
    }
    vizsim::figures::write_all(&lines, &plain, &ChartKind::ALL).unwrap();
    assert!(
        !charts(&plain).iter().any(|c| c.contains("psnr")),
        "{:?}",
        charts(&plain)
    );
    let _ = std::fs::remove_dir_all(&dir);
    let _ = std::fs::remove_dir_all(&plain);
}
