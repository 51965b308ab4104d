//! Image comparison: what `vizsim compare` reports and what tests use to relate two frames.

use std::path::Path;

use crate::error::{Error, Result};

#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct Comparison {
    pub width: u32,
    pub height: u32,
    /// Largest absolute difference per channel (R, G, B, A), in 8-bit steps.
    pub max_abs_error: [u8; 4],
    /// Mean absolute difference over all channels of all pixels.
    pub mean_abs_error: f64,
    /// Peak signal-to-noise ratio over the RGB channels in dB; infinite for identical images
    /// (written as null in JSON).
    pub psnr_db: f64,
    /// Pixels where some channel differs by more than 1 LSB.
    pub pixels_over_1_lsb: u64,
    pub identical: bool,
}

impl Comparison {
    /// The PSNR as printed, with `decimals` decimals: over R, G, B, so a frame that differs in
    /// alpha only has none ("inf dB (R, G, B identical)").
    pub fn psnr_text(&self, decimals: usize) -> String {
        if self.psnr_db.is_finite() {
            format!("{:.decimals$} dB", self.psnr_db)
        } else {
            "inf dB (R, G, B identical)".to_string()
        }
    }
}

/// Compares two RGBA8 buffers of the same size.
pub fn compare(a: &[[u8; 4]], b: &[[u8; 4]], width: u32, height: u32) -> Result<Comparison> {
    if a.len() != b.len() || a.len() != (width * height) as usize {
        return Err(Error::Invalid(format!(
            "images differ in size: {} and {} pixels for {width}x{height}",
            a.len(),
            b.len()
        )));
    }
    let mut max_abs_error = [0u8; 4];
    let mut sum_abs = 0u64;
    let mut sum_sq_rgb = 0u64;
    let mut pixels_over_1_lsb = 0u64;
    for (p, q) in a.iter().zip(b) {
        let mut over = false;
        for c in 0..4 {
            let d = p[c].abs_diff(q[c]);
            max_abs_error[c] = max_abs_error[c].max(d);
            sum_abs += d as u64;
            if c < 3 {
                sum_sq_rgb += (d as u64) * (d as u64);
            }
            over |= d > 1;
        }
        pixels_over_1_lsb += over as u64;
    }
    let n = a.len().max(1) as f64;
    let mse = sum_sq_rgb as f64 / (3.0 * n);
    Ok(Comparison {
        width,
        height,
        max_abs_error,
        mean_abs_error: sum_abs as f64 / (4.0 * n),
        psnr_db: if mse == 0.0 {
            f64::INFINITY
        } else {
            10.0 * (255.0f64 * 255.0 / mse).log10()
        },
        pixels_over_1_lsb,
        identical: sum_abs == 0,
    })
}

/// A difference image: per channel |a - b| scaled by `gain`, alpha opaque.
pub fn difference_image(a: &[[u8; 4]], b: &[[u8; 4]], gain: u32) -> Vec<[u8; 4]> {
    a.iter()
        .zip(b)
        .map(|(p, q)| {
            let d = |c: usize| (p[c].abs_diff(q[c]) as u32 * gain).min(255) as u8;
            [d(0), d(1), d(2), 255]
        })
        .collect()
}

/// Loads a PNG (or any format the image crate reads) as RGBA8.
pub fn load_rgba(path: &Path) -> Result<(u32, u32, Vec<[u8; 4]>)> {
    // Only a regular file: image::open would block on a FIFO. The decoder's own limits bound
    // the memory a hostile header asks for.
    use image::ImageDecoder;
    let file = crate::input::open_regular(path)?;
    let unreadable = |e: image::ImageError| Error::format(path, format!("cannot read image: {e}"));
    let mut reader = image::ImageReader::new(std::io::BufReader::new(file))
        .with_guessed_format()
        .map_err(|e| Error::io(path, e))?;
    // The memory budget bounds the decoder, not its fixed 512 MiB default (which refused
    // the 16384² frames vizsim itself writes, whatever the budget); with no budget known the
    // default stays.
    let mut limits = match crate::budget::budget()? {
        Some(budget) => {
            let mut limits = image::Limits::no_limits();
            limits.max_alloc = Some(budget);
            limits
        }
        None => image::Limits::default(),
    };
    reader.limits(limits.clone());
    let decoder = reader.into_decoder().map_err(unreadable)?;
    let (w, h) = decoder.dimensions();
    // Decoded, converted to RGBA8 and split into pixels: about three copies at 4 bytes each.
    crate::budget::check(
        &format!("{}: a {w}x{h} image", path.display()),
        (w as u64).saturating_mul(h as u64).saturating_mul(12),
    )?;
    // The decoded buffer itself, which `from_decoder` does not check against the limits.
    limits.reserve(decoder.total_bytes()).map_err(unreadable)?;
    let img = image::DynamicImage::from_decoder(decoder)
        .map_err(unreadable)?
        .to_rgba8();
    let (w, h) = img.dimensions();
    let pixels = img
        .into_raw()
        .chunks_exact(4)
        .map(|c| [c[0], c[1], c[2], c[3]])
        .collect();
    Ok((w, h, pixels))
}
