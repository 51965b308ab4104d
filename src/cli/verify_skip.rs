//! `vizsim verify-skip`: the exhaustive check of the skip calculator at given widths.

use anyhow::Result;
use clap::Args;

#[derive(Args)]
pub struct VerifySkipArgs {
    /// Fraction bits of the increment V.
    #[arg(long, default_value_t = 8)]
    increment_bits: u32,
    /// Fraction bits of positions (default: = increment bits).
    #[arg(long)]
    position_bits: Option<u32>,
    /// Significant bits of the reciprocal 1/|V|.
    #[arg(long, default_value_t = 8)]
    reciprocal_bits: u32,
    /// Fraction bits kept of the boundary distance (default: = position bits).
    #[arg(long)]
    distance_bits: Option<u32>,
    /// Sub-cube edge in voxels (2..64); several allowed.
    #[arg(long, default_values_t = [16])]
    subcube: Vec<usize>,
    /// Reciprocal rounding: `down` (shipped, safe) or `nearest` (unsafe, shows the checker
    /// works). Any violation makes the exit status 1.
    #[arg(long, value_enum, default_value = "down")]
    rounding: RoundingArg,
    /// Largest increment enumerated, in voxels (default 1: one sample per voxel or finer).
    #[arg(long, default_value_t = 1)]
    max_increment_voxels: u64,
    /// Print JSON.
    #[arg(long)]
    json: bool,
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
        // Name the options, not the calculator's fields they set.
        let e = e
            .to_string()
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
    let mut reports = Vec::new();
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
            .ok_or_else(|| anyhow::anyhow!("--max-increment-voxels {max_increment_voxels}: too many increments to enumerate"))?;
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
