//! `vizsim verify-skip`: the exhaustive check of the skip calculator at given widths.

use anyhow::Result;
use clap::Args;

#[derive(Args)]
pub struct VerifySkipArgs {
    /// Fraction bits of the increment V.
    #[arg(
        long,
        default_value_t = 8,
        allow_negative_numbers = true,
        value_parser = super::unsigned::<u32>,
    )]
    increment_bits: u32,
    /// Fraction bits of positions (default: = increment bits).
    #[arg(long, allow_negative_numbers = true, value_parser = super::unsigned::<u32>)]
    position_bits: Option<u32>,
    /// Significant bits of the reciprocal 1/|V|.
    #[arg(
        long,
        default_value_t = 8,
        allow_negative_numbers = true,
        value_parser = super::unsigned::<u32>,
    )]
    reciprocal_bits: u32,
    /// Fraction bits kept of the boundary distance (default: = position bits).
    #[arg(long, allow_negative_numbers = true, value_parser = super::unsigned::<u32>)]
    distance_bits: Option<u32>,
    /// Sub-cube edge in voxels (2, 4, 8, 16, 32 or 64); several allowed, repeated or as a
    /// list: --subcube 2,16.
    #[arg(
        long,
        default_values_t = [16],
        value_delimiter = ',',
        allow_negative_numbers = true,
        value_parser = super::unsigned::<usize>,
    )]
    subcube: Vec<usize>,
    /// Reciprocal rounding: `down` (shipped, safe) or `nearest` (unsafe, shows the checker
    /// works). Any violation makes the exit status 1.
    #[arg(long, value_enum, default_value = "down")]
    rounding: RoundingArg,
    /// Largest increment enumerated, in voxels (default 1: one sample per voxel or finer).
    #[arg(
        long,
        default_value_t = 1,
        allow_negative_numbers = true,
        value_parser = super::unsigned::<u64>,
    )]
    max_increment_voxels: u64,
    /// Largest number of cases (offsets × increments × 2 directions, summed over the sub-cubes)
    /// run without asking: the count doubles with every position or increment bit, and a run
    /// over this bound is refused up front with its count and estimated time.
    #[arg(
        long,
        default_value_t = DEFAULT_MAX_CASES,
        allow_negative_numbers = true,
        value_parser = super::unsigned::<u64>,
    )]
    max_cases: u64,
    /// Print JSON.
    #[arg(long)]
    json: bool,
}

/// The default `--max-cases`: about a minute at [`CASES_PER_SECOND`].
const DEFAULT_MAX_CASES: u64 = 10_000_000_000;

/// Cases checked per second, for the estimate: one core of the reference machine (the shipped
/// 12/12/8/4 widths, 536,870,912 cases at 16³, in about 3 s).
const CASES_PER_SECOND: f64 = 180e6;

/// A duration for the estimate, in the unit that reads best.
fn duration_text(seconds: f64) -> String {
    if seconds < 120.0 {
        format!("{seconds:.0} s")
    } else if seconds < 7200.0 {
        format!("{:.0} minutes", seconds / 60.0)
    } else if seconds < 2.0 * 86400.0 {
        format!("{:.0} hours", seconds / 3600.0)
    } else {
        format!("{:.0} days", seconds / 86400.0)
    }
}

#[derive(clap::ValueEnum, Clone, Copy)]
enum RoundingArg {
    Down,
    Nearest,
}

pub fn run(args: VerifySkipArgs) -> Result<()> {
    let position_bits = args.position_bits.unwrap_or(args.increment_bits);
    let widths = vizsim::skip::SkipWidths::new(
        position_bits,
        args.increment_bits,
        args.reciprocal_bits,
        args.distance_bits.unwrap_or(position_bits),
    )
    .map_err(|e| {
        // Name the options, not the calculator's fields they set; a bound set by the
        // position bits names them as given, or as defaulted.
        let position_option = if args.position_bits.is_some() {
            "--position-bits".to_string()
        } else {
            format!("--position-bits (default: --increment-bits, {position_bits})")
        };
        let e = e
            .to_string()
            .replace(
                ", at most `pos_frac_bits`",
                &format!(", at most {position_option}"),
            )
            .replace(
                "`pos_frac_bits`",
                "--position-bits (default: --increment-bits)",
            )
            .replace("`inc_frac_bits`", "--increment-bits")
            .replace("`reciprocal_bits`", "--reciprocal-bits")
            .replace(
                "`distance_frac_bits`",
                "--distance-bits (default: the position bits)",
            );
        anyhow::anyhow!("verify-skip: {e}")
    })?;
    anyhow::ensure!(
        args.max_increment_voxels >= 1,
        "--max-increment-voxels 0: must be at least 1 (voxels per sample step)"
    );
    let (subcubes, rounding, max_increment_voxels, json) = (
        &args.subcube,
        args.rounding,
        args.max_increment_voxels,
        args.json,
    );
    use vizsim::skip::{verify_exhaustive, ReciprocalRounding, VerifyParams};
    let rounding = match rounding {
        RoundingArg::Down => ReciprocalRounding::Down,
        RoundingArg::Nearest => ReciprocalRounding::Nearest,
    };
    // Every sub-cube's parameters first, so that the whole run's cost is known before it starts.
    let mut runs = Vec::new();
    for &s in subcubes {
        anyhow::ensure!(
            vizsim::occupancy::SUBCUBE_SIZES.contains(&s),
            "--subcube {s}: allowed {:?}",
            vizsim::occupancy::SUBCUBE_SIZES
        );
        let mut params = VerifyParams::new(widths, s.trailing_zeros(), rounding);
        params.max_increment = max_increment_voxels
            .checked_shl(widths.inc_frac_bits)
            .filter(|m| (1..=1 << 24).contains(m))
            .ok_or_else(|| {
                anyhow::anyhow!(
                    "--max-increment-voxels {max_increment_voxels} at --increment-bits {}: \
                     {max_increment_voxels} × 2^{} increments per axis, more than the 2^24 this \
                     check enumerates (lower either)",
                    widths.inc_frac_bits,
                    widths.inc_frac_bits
                )
            })?;
        runs.push((s, params));
    }
    // The run enumerates every offset in the sub-cube for every increment, both directions.
    let cases: u128 = runs.iter().map(|(_, p)| p.cases()).sum();
    let estimate = duration_text(cases as f64 / CASES_PER_SECOND);
    anyhow::ensure!(
        cases <= u128::from(args.max_cases),
        "verify-skip: {} cases (every offset in the sub-cube at --position-bits {position_bits} × \
         every increment up to {max_increment_voxels} voxel at --increment-bits {} × 2 \
         directions, for --subcube {}) would take about {estimate} on one core, over --max-cases \
         {}; use fewer --position-bits or --increment-bits (each bit halves the count), or raise \
         --max-cases to run it anyway",
        super::thousands(cases),
        widths.inc_frac_bits,
        subcubes
            .iter()
            .map(usize::to_string)
            .collect::<Vec<_>>()
            .join(","),
        super::thousands(args.max_cases.into())
    );
    // The cost is said before a run that takes a while (on stderr: --json output stays JSON).
    if cases as f64 > 10.0 * CASES_PER_SECOND {
        vizsim::note!(
            "verify-skip: {} cases, about {estimate} on one core",
            super::thousands(cases)
        );
    }
    if !json {
        println!("{}", widths_line(&widths));
    }
    let mut reports = Vec::new();
    for (s, params) in runs {
        let report = verify_exhaustive(&params).map_err(|e| anyhow::anyhow!("verify-skip: {e}"))?;
        if !json {
            println!(
                "sub-cube {s}³: {} cases, {} violations, worst wasted steps {}, mean {:.4}{}",
                report.cases,
                report.violations,
                report.worst_wasted_steps,
                report.mean_wasted_steps,
                report
                    .first_violation
                    .map(|v| format!(
                        "; first violation: offset {} LSB, increment {} LSB: {} steps computed, {} exact",
                        v.offset, v.increment, v.computed_steps, v.exact_steps
                    ))
                    .unwrap_or_default()
            );
        }
        reports.push(report);
    }
    if json {
        let value = if reports.len() == 1 {
            serde_json::to_value(&reports[0])?
        } else {
            serde_json::to_value(&reports)?
        };
        println!("{}", serde_json::to_string_pretty(&value)?);
    }
    // A violation is a failed check: scripts see it in the exit status.
    let violations: u64 = reports.iter().map(|r| r.violations).sum();
    anyhow::ensure!(
        violations == 0,
        "{violations} violations: the skip calculator leaps past a sample at these widths and \
         this rounding (the report above says where first)"
    );
    Ok(())
}

/// The widths checked, and the shipped configuration's when they differ: the options' defaults
/// are not the shipped widths (a review ran plain `verify-skip` believing it checked them).
fn widths_line(widths: &vizsim::skip::SkipWidths) -> String {
    let config = vizsim::config::HardwareConfig::default_config();
    let shipped = [
        ("--position-bits", config.ray.position_frac_bits),
        ("--increment-bits", config.ray.increment_frac_bits),
        ("--reciprocal-bits", config.skip.reciprocal_bits),
        ("--distance-bits", config.skip.distance_frac_bits),
    ];
    let checked = [
        widths.pos_frac_bits,
        widths.inc_frac_bits,
        widths.reciprocal_bits,
        widths.distance_frac_bits,
    ];
    let line = format!(
        "widths: position {}, increment {}, reciprocal {}, distance {} bits",
        checked[0], checked[1], checked[2], checked[3]
    );
    if shipped.iter().map(|(_, bits)| *bits).eq(checked) {
        format!("{line} (the shipped configuration's)")
    } else {
        format!(
            "{line}; the shipped configuration ({}) has {}",
            vizsim::config::DEFAULT_NAME,
            shipped
                .iter()
                .map(|(option, bits)| format!("{option} {bits}"))
                .collect::<Vec<_>>()
                .join(" ")
        )
    }
}
