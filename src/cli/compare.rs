//! `vizsim compare`: two images, max error per channel, PSNR, pixels over 1 LSB.

use std::path::PathBuf;

use anyhow::Result;
use clap::Args;

#[derive(Args)]
pub struct CompareArgs {
    /// First image (PNG, or another format the image crate reads), e.g. a render's output.
    a: PathBuf,
    /// Second image, the same size as A (the comparison is symmetric).
    b: PathBuf,
    /// Write the comparison as JSON (`-`: to standard output, the text then to standard error).
    #[arg(long)]
    json: Option<PathBuf>,
    /// Write a difference image as PNG, named .png (|A - B| x 16 in R, G, B).
    #[arg(long)]
    diff: Option<PathBuf>,
}

pub fn run(args: CompareArgs) -> Result<()> {
    use vizsim::compare;
    let (a, b, json, diff) = (&args.a, &args.b, args.json.as_deref(), args.diff.as_deref());
    let outputs: Vec<(&str, &std::path::Path)> = [("--json", json), ("--diff", diff)]
        .into_iter()
        .filter_map(|(option, path)| Some((option, path?)))
        .collect();
    vizsim::output::check_distinct(&[a.as_path(), b.as_path()], &outputs)?;
    if let Some(path) = diff {
        vizsim::output::check_png_name("--diff", path)?;
    }
    // Every output path is checked before the images are read, and the outputs are written
    // together or not at all: a bad --diff must not leave the --json of a run that failed.
    for (_, path) in &outputs {
        vizsim::output::check_writable(path)?;
    }
    let (wa, ha, pa) = compare::load_rgba(a)?;
    let (wb, hb, pb) = compare::load_rgba(b)?;
    anyhow::ensure!(
        (wa, ha) == (wb, hb),
        "{} is {wa}x{ha} but {} is {wb}x{hb}",
        a.display(),
        b.display()
    );
    let result = compare::compare(&pa, &pb, wa, ha)?;
    vizsim::output::all_or_none(|| -> Result<()> {
        if let Some(path) = json {
            vizsim::output::write_json(path, &result)?;
        }
        if let Some(path) = diff {
            let frame = vizsim::render::Frame {
                width: wa,
                height: ha,
                pixels: compare::difference_image(&pa, &pb, 16),
                rays: Vec::new(),
            };
            frame.write_png(path)?;
        }
        Ok(())
    })?;
    // Printed after the outputs are in place (a failed print must not leave their temporaries).
    super::say(json, &format!(
        "max |error| R {} G {} B {} A {}, mean (R, G, B, A) {:.4}, PSNR (R, G, B) {}, {} pixels differ by more than 1 LSB{}\n",
        result.max_abs_error[0],
        result.max_abs_error[1],
        result.max_abs_error[2],
        result.max_abs_error[3],
        result.mean_abs_error,
        result.psnr_text(2),
        result.pixels_over_1_lsb,
        if result.identical { " (identical)" } else { "" }
    ));
    Ok(())
}
