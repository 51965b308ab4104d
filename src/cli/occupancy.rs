//! `vizsim occupancy`: occupancy maps per sub-cube size: storage, SRAM fit, skippable sub-cubes.

use anyhow::Result;
use clap::Args;

use super::{DataArgs, DatasetName, HardwareArgs};
use vizsim::text::percent;

#[derive(Args)]
pub struct OccupancyArgs {
    #[command(flatten)]
    dataset: DatasetName,
    #[command(flatten)]
    data: DataArgs,
    /// Transfer function for the class map: `class`, `zero`, a preset or a file.
    #[arg(long, default_value = "class")]
    tf: String,
    #[command(flatten)]
    hardware: HardwareArgs,
    /// Print JSON instead of a table.
    #[arg(long)]
    json: bool,
}

#[derive(serde::Serialize)]
struct OccupancyRow {
    subcube: usize,
    /// Map bits: one per sub-cube.
    bits: u64,
    /// Map bits with the two-level hierarchy (padded to whole bytes of 2x2x2 sub-cubes).
    bits_with_hierarchy: u64,
    fits_sram: bool,
    fits_sram_with_hierarchy: bool,
    /// Percentage of sub-cubes that are empty, '0' map.
    skippable_zero_percent: f64,
    /// Percentage of sub-cubes that are empty, class map.
    skippable_class_percent: f64,
    /// Percentage of 2x2x2 groups that are empty (whole-group leaps), '0' and class maps.
    empty_groups_zero_percent: f64,
    empty_groups_class_percent: f64,
}

pub fn run(args: OccupancyArgs) -> Result<()> {
    let (spec, data, tf_arg, hardware, json) = (
        args.dataset.spec(),
        &args.data,
        &args.tf,
        &args.hardware,
        args.json,
    );
    use vizsim::functional::arith::ClassificationTable;
    use vizsim::occupancy::{OccupancyKind, OccupancyMap, SUBCUBE_SIZES};
    anyhow::ensure!(
        !hardware.asks_for_leaping() && hardware.bricks.is_none(),
        "occupancy lists every sub-cube size, both maps, with and without the hierarchy: \
         --subcube, --hierarchy, --occupancy and --bricks do not apply"
    );
    let config = hardware.load(&[])?;
    let volume = data.load(spec)?;
    let tf = vizsim::transfer::resolve_for(tf_arg, &volume)?;
    let table = ClassificationTable::build(
        &tf,
        volume.max_value() as usize + 1,
        config.classification.lut_bits,
        1.0,
    );
    let sram = config.occupancy.sram_bits;
    let largest = *volume.dims.iter().max().unwrap_or(&0);
    let pct = |part: usize, whole: usize| 100.0 * part as f64 / whole.max(1) as f64;
    let rows: Vec<OccupancyRow> = SUBCUBE_SIZES
        .iter()
        .filter(|&&s| s <= largest)
        .map(|&s| {
            let log2 = s.trailing_zeros();
            let zero = OccupancyMap::build(&volume, OccupancyKind::Zero, log2, 0, |_, _| true);
            let class = OccupancyMap::build(&volume, OccupancyKind::Class, log2, 0, |lo, hi| {
                table.any_visible(lo, hi)
            });
            let groups = zero.group_dims.iter().product::<usize>();
            OccupancyRow {
                subcube: s,
                bits: zero.storage_bits(false),
                bits_with_hierarchy: zero.storage_bits(true),
                fits_sram: zero.storage_bits(false) <= sram,
                fits_sram_with_hierarchy: zero.storage_bits(true) <= sram,
                skippable_zero_percent: pct(zero.empty_subcubes(), zero.subcubes()),
                skippable_class_percent: pct(class.empty_subcubes(), class.subcubes()),
                empty_groups_zero_percent: pct(zero.empty_groups(), groups),
                empty_groups_class_percent: pct(class.empty_groups(), groups),
            }
        })
        .collect();
    if json {
        #[derive(serde::Serialize)]
        struct Report<'a> {
            dataset: &'a str,
            transfer_function: &'a str,
            sram_bits: u64,
            sizes: &'a [OccupancyRow],
        }
        let report = Report {
            dataset: &volume.name,
            transfer_function: &tf.name,
            sram_bits: sram,
            sizes: &rows,
        };
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    println!(
        "{}: occupancy maps '0' and class (the class map by transfer function {}), SRAM {sram} bit",
        volume.name, tf.name
    );
    println!("| sub-cube | map bits | fits SRAM | skippable '0' | skippable class | empty groups '0' | empty groups class |");
    println!("|---:|---:|:---:|---:|---:|---:|---:|");
    for r in &rows {
        println!(
            "| {}³ | {} | {} | {} % | {} % | {} % | {} % |",
            r.subcube,
            r.bits,
            if r.fits_sram { "yes" } else { "no" },
            percent(r.skippable_zero_percent, 2),
            percent(r.skippable_class_percent, 2),
            percent(r.empty_groups_zero_percent, 2),
            percent(r.empty_groups_class_percent, 2)
        );
    }
    println!(
        "skippable: sub-cubes the map marks empty (nothing visible: every sample there is \
         leapt over); empty groups: 2×2×2 groups of sub-cubes all empty, which the two-level \
         hierarchy (--hierarchy) leaps whole, as an empty sub-cube of twice the edge \
         (docs/model.md)"
    );
    Ok(())
}
