//! `vizsim update`: what keeping the occupancy maps of a volume costs on the update engine —
//! a download over the host link with the maps built on the way, a separate scan pass, a
//! transfer-function change (scan against the min/max table) and, with `--next`, a partial
//! update to another volume (docs/dynamic.md). The measuring is `vizsim::dynamic::measure`.

use anyhow::{Context, Result};
use clap::Args;

use super::{DataArgs, DatasetName, HardwareArgs};

#[derive(Args)]
pub struct UpdateArgs {
    /// The volume downloaded.
    #[command(flatten)]
    dataset: DatasetName,
    #[command(flatten)]
    data: DataArgs,
    /// Transfer function of the class map: `class`, `zero`, a preset or a file.
    #[arg(long, default_value = "class")]
    tf: String,
    /// A second volume of the same extent: measure the partial update to it (its changed
    /// bricks), with widened and with rescanned maps.
    #[arg(long)]
    next: Option<String>,
    /// Brick edge of the partial update's regions (1 up to the volume's longest edge; default
    /// 8). Only with --next.
    #[arg(
        long,
        allow_negative_numbers = true,
        value_parser = super::unsigned::<usize>,
    )]
    brick: Option<usize>,
    #[command(flatten)]
    hardware: HardwareArgs,
    /// Print JSON instead of text.
    #[arg(long)]
    json: bool,
}

pub fn run(args: UpdateArgs) -> Result<()> {
    use vizsim::functional::arith::ClassificationTable;
    let brick = args.brick.unwrap_or(vizsim::dynamic::DEFAULT_BRICK);
    anyhow::ensure!(brick >= 1, "--brick 0: the brick edge must be at least 1");
    if args.brick.is_some() && args.next.is_none() {
        vizsim::note!(
            "note: --brick is without effect without --next (it sizes a partial update's regions)"
        );
    }
    anyhow::ensure!(
        args.hardware.occupancy.is_none(),
        "--occupancy: update measures both maps ('0' and class; its cycles do not depend on the \
         map's kind), so it does not apply"
    );
    let config = args.hardware.load(&[])?;
    // Before the volumes load: a configuration the update model does not model.
    vizsim::dynamic::check_modelled(&config, vizsim::dynamic::UpdateUse::Measure)?;
    // The size as configured (--subcube, --set or the file), not only the flag.
    let subcube = config.occupancy.subcube;
    anyhow::ensure!(
        subcube > 0,
        "--subcube: the sub-cube size of the maps is required (or occupancy.subcube by --set or \
         --config)"
    );
    let unread = vizsim::dynamic::unread_by_update(&config);
    if !unread.is_empty() {
        // On standard error: standard output may be JSON (`--json`).
        vizsim::note!(
            "note: without effect in update (it measures writes, maps and scans, and renders no \
             frame): {}",
            unread.join(", ")
        );
    }
    let volume = args.data.load(args.dataset.spec())?;
    let tf = vizsim::transfer::resolve_for(&args.tf, &volume).context("--tf")?;
    let table = ClassificationTable::build(
        &tf,
        1usize << volume.bits,
        config.classification.lut_bits,
        1.0,
    );
    let next = match &args.next {
        Some(spec) => {
            let next = args.data.load(spec).context("--next")?;
            // Here, naming the option and both volumes: later the update engine would only find
            // a voxel too large for the first volume's bits, or the extents unequal.
            anyhow::ensure!(
                next.dims == volume.dims && next.bits == volume.bits,
                "--next {spec}: {:?} voxels of {} bits, but {} is {:?} voxels of {} bits: a \
                 partial update needs the same extent and bit depth",
                next.dims,
                next.bits,
                args.dataset.spec(),
                volume.dims,
                volume.bits
            );
            Some(next)
        }
        None => None,
    };
    let report = vizsim::dynamic::measure(
        &config,
        &volume,
        &table,
        subcube,
        next.as_ref().map(|v| (v, brick)),
    )?;
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
        return Ok(());
    }
    let ms = |cycles: u64| vizsim::text::milliseconds(cycles as f64 / (report.clock_mhz * 1e3));
    let d = &report.download;
    println!(
        "{} {:?}, {} mapping, {}³ sub-cubes, clock {} MHz, host link {:.0} MB/s",
        report.volume,
        report.dims,
        report.mapping,
        subcube,
        report.clock_mhz,
        report.host_link_mb_per_s
    );
    println!(
        "download in volume order: {} voxels, {} host bytes; {} cycles ({}; host link bound {} cycles), \
         {} WRITEs ({:.2} per voxel, {} row misses), write stalls {} cycles; \
         map during the update: +{} cycles, exact; {} in all",
        d.voxels_written,
        d.host_bytes,
        d.write_cycles,
        ms(d.write_cycles),
        d.host_link_cycles,
        d.writes,
        d.writes_per_voxel,
        d.write_row_misses,
        d.write_stall_cycles,
        d.map_cycles,
        vizsim::text::milliseconds(report.download_ms)
    );
    let d = &report.download_tiled;
    println!(
        "download in tiles: {} regions, {} voxels sent (with the voxel-pair layouts a tile \
         repeats the slice above it), {} host bytes; {} cycles ({}; host link bound {} \
         cycles), {} WRITEs ({:.2} per voxel sent, {} row misses), write stalls {} cycles; \
         with the map {} in all",
        d.regions,
        d.voxels_written,
        d.host_bytes,
        d.write_cycles,
        ms(d.write_cycles),
        d.host_link_cycles,
        d.writes,
        d.writes_per_voxel,
        d.write_row_misses,
        d.write_stall_cycles,
        vizsim::text::milliseconds(report.download_tiled_ms)
    );
    let s = &report.scan;
    println!(
        "scan pass: {} requests, {} cycles = {}{}, row hits {} %",
        s.requests,
        s.cycles,
        vizsim::text::milliseconds(s.ms),
        // The published figure is for a 256³ volume; the scan reads every voxel, so other
        // sizes do not compare with it.
        if report.dims == [256, 256, 256] {
            " (published ~20 ms for 256³)"
        } else {
            ""
        },
        vizsim::text::percent(100.0 * s.row_hit_rate, 1)
    );
    let t = &report.tf_change;
    println!(
        "transfer-function change: scan {} cycles ({}) or min/max table {} + {} cycles \
         ({:.1} µs); table {} bits SRAM (+ prefix table {} bits), map {} bits",
        t.scan_cycles,
        ms(t.scan_cycles),
        t.prefix_cycles,
        t.table_pass_cycles,
        report.tf_change_table_us,
        t.table_bits,
        t.prefix_bits,
        report.map_bits
    );
    // The table-based rebuild (and the maps built during an update) keep the min/max table
    // on chip beside the map: say when the SRAM the configuration names cannot hold them.
    if let Some(note) = vizsim::dynamic::table_sram_note(
        report.table_on_chip_bits,
        report.map_bits,
        config.occupancy.sram_bits,
        "the table-based rebuild and the maps built during updates",
        "the scan pass",
    ) {
        println!("{note}");
    }
    if let Some(p) = &report.partial {
        for (name, r) in [("widen", &p.widen), ("rescan", &p.rescan)] {
            println!(
                "partial update to {} ({}³ bricks), {name}: {} regions, {} voxels, {} cycles \
                 ({}) + rescan {} + map {} cycles; map {}",
                p.next,
                p.brick,
                r.regions,
                r.voxels_written,
                r.write_cycles,
                ms(r.write_cycles),
                r.rescan_cycles,
                r.map_cycles,
                if r.map_exact { "exact" } else { "conservative" }
            );
        }
        println!(
            "  widened class map: {} sub-cubes set that the new volume leaves empty",
            p.widen_stale_subcubes
        );
        // The rescan reads the changed regions with their stencil borders: when most of the
        // volume changed, one scan pass over all of it is the cheaper way to an exact map.
        if p.rescan.rescan_cycles > report.scan.cycles {
            println!(
                "  the rescan ({} cycles) costs more than a full scan pass ({} cycles): with {} of \
                 {} voxels changed, scanning the whole volume is the cheaper exact map",
                p.rescan.rescan_cycles,
                report.scan.cycles,
                p.rescan.voxels_written,
                report.dims.iter().product::<usize>()
            );
        }
    }
    println!("maps checked against OccupancyMap::build: equal after each download and the scan");
    Ok(())
}
