//! Iso-surface hitpoint refinement quality (issue 15, part 5): iso images at sample spacings
//! 1 to 5, with and without refinement, against a fine-step float iso reference (spacing 1/8,
//! 6 refinement steps). The published claim: with refinement, spacing 5 looks like spacing 1.
//! Writes `table.md` and, per dataset, `DATASET-side-by-side.png` to the output folder.
//!
//!     cargo run --release --example iso_refinement_quality -- OUT_DIR VIEW DATASET[=VALUE]...
//!     (scripts/iso-refinement-quality.sh; VALUE the iso value, default 0 = half the largest
//!     density)
//!
//! Per image (RGB, 0..255, against the reference): PSNR (peak 255), the largest channel
//! error, the share of pixels off by more than 8 levels, and the samples the functional
//! model takes per ray that meets the box (marching + refinement: the cost).

use std::path::PathBuf;

use vizsim::compare::compare;
use vizsim::config::HardwareConfig;
use vizsim::render::Frame;
use vizsim::run::{execute, prepare, Model, Probes, RunDescription, RunReport};
use vizsim::volume::Volume;

const SIZE: u32 = 256;
const REFINED: u32 = 6;

fn render(
    volume: &Volume,
    view: &str,
    value: f64,
    model: Model,
    spacing: f32,
    steps: u32,
) -> RunReport {
    let sets = vec![
        "iso.enabled=true".to_string(),
        format!("iso.value={value}"),
        format!("iso.refinement_steps={steps}"),
    ];
    let config = HardwareConfig::load(None, &sets).expect("configuration");
    let mut run = RunDescription::new(&volume.name, "class", model, config);
    run.size = (SIZE, SIZE);
    run.view = view.to_string();
    run.sample_spacing = spacing;
    let prepared = prepare(&run, volume).expect("prepare");
    execute(&run, &prepared, Probes::default()).expect("render")
}

/// Pixels where some channel differs by more than `levels`, percent.
fn off_by_more(a: &Frame, b: &Frame, levels: u8) -> f64 {
    let n = a
        .pixels
        .iter()
        .zip(&b.pixels)
        .filter(|(p, q)| (0..3).any(|c| p[c].abs_diff(q[c]) > levels))
        .count();
    100.0 * n as f64 / a.pixels.len() as f64
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [out, view, datasets @ ..] = args.as_slice() else {
        eprintln!("usage: iso_refinement_quality OUT_DIR VIEW DATASET[=VALUE]...");
        std::process::exit(2);
    };
    if datasets.is_empty() {
        eprintln!("usage: iso_refinement_quality OUT_DIR VIEW DATASET[=VALUE]...");
        std::process::exit(2);
    }
    let out = PathBuf::from(out);
    std::fs::create_dir_all(&out).expect("output folder");
    let data_dir = std::env::var_os("VIZSIM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/work/shared/data"));
    let mut table = format!(
        "View `{view}`, {SIZE}×{SIZE}, orthographic, default hardware configuration with \
         `iso.enabled = true`. Reference: the float model at spacing 1/8 with {REFINED} \
         refinement steps. Error figures over R, G, B against it; samples per ray in the box from \
         the same model's ray records (marching samples + refinement samples).\n\n"
    );
    for entry in datasets {
        let (name, value) = match entry.split_once('=') {
            Some((n, v)) => (n, v.parse::<f64>().expect("VALUE: a number")),
            None => (entry.as_str(), 0.0),
        };
        let volume = vizsim::volume::dataset::load(name, Some(&data_dir)).expect("dataset");
        let resolved = if value == 0.0 {
            *volume.data.iter().max().unwrap_or(&0) as f64 / 2.0
        } else {
            value
        };
        let reference = render(&volume, view, resolved, Model::Float, 0.125, REFINED);
        table += &format!(
            "**{name}** ({:?} voxels), iso value {resolved}:\n\n\
             | model | spacing | refinement | PSNR (dB) | max error | pixels off > 8 | samples per ray in the box |\n\
             |---|---:|---:|---:|---:|---:|---:|\n",
            volume.dims
        );
        let spacings = [1.0f32, 2.0, 3.0, 4.0, 5.0];
        // Side by side: columns reference, no refinement, refinement (float); a row per spacing.
        let mut sheet = image::RgbaImage::new(SIZE * 3, SIZE * spacings.len() as u32);
        let put = |sheet: &mut image::RgbaImage, frame: &Frame, col: u32, row: u32| {
            for (i, p) in frame.pixels.iter().enumerate() {
                let (x, y) = (i as u32 % SIZE, i as u32 / SIZE);
                sheet.put_pixel(col * SIZE + x, row * SIZE + y, image::Rgba(*p));
            }
        };
        for model in [Model::Float, Model::Step] {
            for (row, &spacing) in spacings.iter().enumerate() {
                for (col, steps) in [(1u32, 0u32), (2, REFINED)] {
                    let report = render(&volume, view, resolved, model, spacing, steps);
                    let frame = &report.frame;
                    let c = compare(&frame.pixels, &reference.frame.pixels, SIZE, SIZE)
                        .expect("same size");
                    let in_box = frame.rays.iter().filter(|r| r.hit).count().max(1);
                    let samples: u64 = frame.rays.iter().map(|r| r.samples as u64).sum();
                    table += &format!(
                        "| {} | {spacing} | {steps} | {:.2} | {} | {:.2} % | {:.1} |\n",
                        if model == Model::Float {
                            "float"
                        } else {
                            "fixed"
                        },
                        c.psnr_db,
                        c.max_abs_error[..3].iter().max().unwrap_or(&0),
                        off_by_more(frame, &reference.frame, 8),
                        samples as f64 / in_box as f64
                    );
                    if model == Model::Float {
                        put(&mut sheet, frame, col, row as u32);
                    }
                }
                if model == Model::Float {
                    put(&mut sheet, &reference.frame, 0, row as u32);
                }
            }
        }
        table += "\n";
        sheet
            .save(out.join(format!("{}-side-by-side.png", name.replace(':', "-"))))
            .expect("side-by-side png");
    }
    std::fs::write(out.join("table.md"), &table).expect("table");
    print!("{table}");
}
