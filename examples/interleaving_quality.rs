//! Interleaved sampling quality (issue 15, part 4): float reference images at sample spacings
//! 1, 2 and 4, with and without interleaving, against a float reference at 8× the sampling
//! rate of spacing 1 (spacing 1/8, no interleaving). Writes `table.md` and `side-by-side.png`
//! to the output folder.
//!
//!     cargo run --example interleaving_quality -- DATASET VIEW N OUT_DIR
//!     (e.g. bonsai orbit:0/72 4 reports/interleaving; scripts/interleaving-quality.sh)
//!
//! Figures per image (RGB, 0..255):
//! - PSNR against the reference (peak 255, mean squared error over all channels and pixels);
//! - low-frequency error: the RMS of the error (luminance, mean of R, G, B) averaged over 8×8
//!   pixel blocks: wood-grain rings are errors that keep their sign over many pixels, so they
//!   survive the averaging; interleaving turns them into pixel-scale noise that averages out;
//! - neighbour correlation: the correlation coefficient of the luminance error between
//!   horizontally and vertically adjacent pixels (1 = smooth, structured error; near 0 or
//!   negative = noise).

use std::path::PathBuf;

use vizsim::camera::Projection;
use vizsim::config::HardwareConfig;
use vizsim::render::Frame;
use vizsim::run::{execute, prepare, Model, Probes, RunDescription};

const SIZE: u32 = 256;

fn render(volume: &vizsim::volume::Volume, view: &str, spacing: f32, interleave: u32) -> Frame {
    let sets = vec![format!("ray.interleave={interleave}")];
    let config = HardwareConfig::load(None, &sets).expect("configuration");
    let mut run = RunDescription::new(&volume.name, "class", Model::Float, config);
    run.size = (SIZE, SIZE);
    run.view = view.to_string();
    run.projection = Projection::Ortho;
    run.sample_spacing = spacing;
    let prepared = prepare(&run, volume).expect("prepare");
    execute(&run, &prepared, Probes::default())
        .expect("render")
        .frame
}

/// Luminance error per pixel (mean of R, G, B differences).
fn error(image: &Frame, reference: &Frame) -> Vec<f64> {
    image
        .pixels
        .iter()
        .zip(&reference.pixels)
        .map(|(a, b)| (0..3).map(|c| a[c] as f64 - b[c] as f64).sum::<f64>() / 3.0)
        .collect()
}

fn psnr(image: &Frame, reference: &Frame) -> f64 {
    let mut sum = 0.0;
    for (a, b) in image.pixels.iter().zip(&reference.pixels) {
        for c in 0..3 {
            let d = a[c] as f64 - b[c] as f64;
            sum += d * d;
        }
    }
    let mse = sum / (image.pixels.len() * 3) as f64;
    if mse == 0.0 {
        f64::INFINITY
    } else {
        10.0 * (255.0 * 255.0 / mse).log10()
    }
}

fn low_frequency_rms(e: &[f64], w: usize, h: usize, block: usize) -> f64 {
    let mut sum = 0.0;
    let mut count = 0;
    for by in 0..h / block {
        for bx in 0..w / block {
            let mut mean = 0.0;
            for y in 0..block {
                for x in 0..block {
                    mean += e[(by * block + y) * w + bx * block + x];
                }
            }
            mean /= (block * block) as f64;
            sum += mean * mean;
            count += 1;
        }
    }
    (sum / count as f64).sqrt()
}

fn neighbour_correlation(e: &[f64], w: usize, h: usize) -> f64 {
    let mean = e.iter().sum::<f64>() / e.len() as f64;
    let var = e.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / e.len() as f64;
    if var == 0.0 {
        return 0.0;
    }
    let (mut sum, mut count) = (0.0, 0usize);
    for y in 0..h {
        for x in 0..w {
            let a = e[y * w + x] - mean;
            if x + 1 < w {
                sum += a * (e[y * w + x + 1] - mean);
                count += 1;
            }
            if y + 1 < h {
                sum += a * (e[(y + 1) * w + x] - mean);
                count += 1;
            }
        }
    }
    sum / count as f64 / var
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [dataset, view, n, out] = args.as_slice() else {
        eprintln!("usage: interleaving_quality DATASET VIEW N OUT_DIR");
        std::process::exit(2);
    };
    let n: u32 = n.parse().expect("N: a whole number");
    let out = PathBuf::from(out);
    std::fs::create_dir_all(&out).expect("output folder");
    let data_dir = std::env::var_os("VIZSIM_DATA")
        .map(PathBuf::from)
        .unwrap_or_else(|| PathBuf::from("/work/shared/data"));
    let volume = vizsim::volume::dataset::load(dataset, Some(&data_dir)).expect("dataset");
    let reference = render(&volume, view, 0.125, 1);
    let (w, h) = (SIZE as usize, SIZE as usize);
    let spacings = [1.0f32, 2.0, 4.0];
    let mut table = format!(
        "Dataset `{dataset}`, view `{view}`, {SIZE}×{SIZE}, orthographic, class transfer function, \
         ERT 0.95, float reference model. Reference: spacing 1/8 (8× the sampling rate of \
         spacing 1), no interleaving. Interleaving: {n}×{n} pattern (`ray.interleave = {n}`).\n\n\
         | spacing | interleaving | PSNR (dB) | low-frequency error (RMS of 8×8 block means) | neighbour error correlation |\n\
         |---:|---|---:|---:|---:|\n"
    );
    // Side by side: columns reference, off, on; one row per spacing.
    let mut sheet = image::RgbaImage::new(SIZE * 3, SIZE * spacings.len() as u32);
    let put = |sheet: &mut image::RgbaImage, frame: &Frame, col: u32, row: u32| {
        for (i, p) in frame.pixels.iter().enumerate() {
            let (x, y) = (i as u32 % SIZE, i as u32 / SIZE);
            sheet.put_pixel(col * SIZE + x, row * SIZE + y, image::Rgba(*p));
        }
    };
    for (row, &spacing) in spacings.iter().enumerate() {
        put(&mut sheet, &reference, 0, row as u32);
        for (col, interleave) in [(1u32, 1u32), (2, n)] {
            let frame = render(&volume, view, spacing, interleave);
            let e = error(&frame, &reference);
            table += &format!(
                "| {spacing} | {} | {:.2} | {:.3} | {:.3} |\n",
                if interleave == 1 {
                    "off".to_string()
                } else {
                    format!("{n}×{n}")
                },
                psnr(&frame, &reference),
                low_frequency_rms(&e, w, h, 8),
                neighbour_correlation(&e, w, h)
            );
            put(&mut sheet, &frame, col, row as u32);
            frame
                .write_png(&out.join(format!(
                    "{dataset}-spacing{spacing}-interleave{interleave}.png"
                )))
                .expect("png");
        }
    }
    sheet
        .save(out.join("side-by-side.png"))
        .expect("side-by-side png");
    std::fs::write(out.join("table.md"), &table).expect("table");
    print!("{table}");
}
