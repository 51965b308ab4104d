//! `vizsim info`: a dataset's dimensions, spacing, value histogram and occupied percentage.

use anyhow::Result;
use clap::Args;

use super::{DataArgs, DatasetName};
use vizsim::text::percent;

#[derive(Args)]
pub struct InfoArgs {
    #[command(flatten)]
    dataset: DatasetName,
    #[command(flatten)]
    data: DataArgs,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

pub fn run(args: InfoArgs) -> Result<()> {
    let (spec, data, json) = (args.dataset.spec(), &args.data, args.json);
    let volume = data.load(spec)?;
    let info = volume.info();
    if json {
        println!("{}", serde_json::to_string_pretty(&info)?);
    } else {
        println!("dataset   {}", info.name);
        println!(
            "dims      {} x {} x {} ({} voxels, {} bit)",
            info.dims[0], info.dims[1], info.dims[2], info.voxels, info.bits
        );
        println!(
            "spacing   {} {} {}",
            info.spacing[0], info.spacing[1], info.spacing[2]
        );
        println!(
            "values    min {} max {} mean {:.2}",
            info.min, info.max, info.mean
        );
        println!(
            "occupied  {} % of voxels > 0",
            percent(info.occupied_percent, 2)
        );
        let total = info.voxels.max(1) as f64;
        let bin = (volume.max_value() as usize + 1) / 16;
        for (i, count) in info.histogram16.iter().enumerate() {
            let pct = 100.0 * *count as f64 / total;
            println!(
                "  {:>5}..{:<5} {:>8} % {}",
                i * bin,
                (i + 1) * bin - 1,
                percent(pct, 3),
                "#".repeat((pct / 2.0).ceil() as usize)
            );
        }
    }
    Ok(())
}
