//! Volume updates (issue 16): writes through the SDRAM model fed by the host link, and the
//! occupancy maps built during the update, by a scan and from the min/max table after a
//! transfer-function change, against `OccupancyMap::build` on the volume in memory.

mod common;

use vizsim::arch::address_map::Mapping;
use vizsim::arch::update::{PartialMapPolicy, Region, UpdateEngine, VolumeUpdate};
use vizsim::config::HardwareConfig;
use vizsim::functional::arith::ClassificationTable;
use vizsim::occupancy::{OccupancyKind, OccupancyMap};
use vizsim::transfer::TransferFunction;
use vizsim::volume::phantom::{generate, PhantomKind, PhantomSpec};
use vizsim::volume::Volume;

fn metaballs(size: usize, time: f32) -> Volume {
    generate(&PhantomSpec {
        time,
        size,
        ..PhantomSpec::default_for(PhantomKind::Metaballs)
    })
}

fn config(mapping: Mapping) -> HardwareConfig {
    let mut hw = HardwareConfig::default_config();
    hw.memory.mapping = mapping;
    hw
}

/// A transfer function opaque only in a middle band, so that [min, max] matters.
fn band_tf(lo: f32, hi: f32) -> TransferFunction {
    common::tf(&[
        (0.0, [0.0; 4]),
        (lo, [0.0; 4]),
        (lo + 1.0, [1.0, 0.5, 0.2, 0.6]),
        (hi - 1.0, [1.0, 0.5, 0.2, 0.6]),
        (hi, [0.0; 4]),
        (255.0, [0.0; 4]),
    ])
}

fn table(tf: &TransferFunction) -> ClassificationTable {
    ClassificationTable::build(tf, 256, 12, 1.0)
}

/// Every bit of `map` equals `reference`'s (exact), or is set where the reference's is
/// (conservative).
fn compare(map: &OccupancyMap, reference: &OccupancyMap, exact: bool, what: &str) -> usize {
    assert_eq!(map.dims, reference.dims, "{what}");
    let mut extra = 0;
    for z in 0..map.dims[2] {
        for y in 0..map.dims[1] {
            for x in 0..map.dims[0] {
                let (a, b) = (map.occupied([x, y, z]), reference.occupied([x, y, z]));
                assert!(
                    a || !b,
                    "{what}: sub-cube {x},{y},{z} empty but the volume's is not"
                );
                if exact {
                    assert_eq!(a, b, "{what}: sub-cube {x},{y},{z}");
                }
                extra += (a && !b) as usize;
            }
        }
    }
    extra
}

fn assert_maps(
    engine: &UpdateEngine,
    volume: &Volume,
    log2: u32,
    reach: usize,
    tf: &ClassificationTable,
    exact: bool,
    what: &str,
) -> usize {
    let zero = OccupancyMap::build(volume, OccupancyKind::Zero, log2, reach, |_, _| true);
    let class = OccupancyMap::build(volume, OccupancyKind::Class, log2, reach, |lo, hi| {
        tf.any_visible(lo, hi)
    });
    let visible = |lo, hi| tf.any_visible(lo, hi);
    compare(
        &engine.map(OccupancyKind::Zero, visible),
        &zero,
        exact,
        &format!("{what} '0'"),
    ) + compare(
        &engine.map(OccupancyKind::Class, visible),
        &class,
        exact,
        &format!("{what} class"),
    )
}

#[test]
fn a_download_writes_every_copy_and_builds_the_exact_maps() {
    let volume = metaballs(32, 0.0);
    let tf = table(&band_tf(60.0, 140.0));
    for mapping in [
        Mapping::Replicated4,
        Mapping::Interleaved8,
        Mapping::Linear4,
    ] {
        for (log2, reach) in [(2, 0), (3, 0), (3, 1), (1, 0)] {
            let hw = config(mapping);
            let mut engine = UpdateEngine::new(&hw, volume.dims, 8, log2, reach).unwrap();
            let report = engine
                .update(&VolumeUpdate::full(&volume), PartialMapPolicy::Widen)
                .unwrap();
            let what = format!("{mapping:?} s={} reach {reach}", 1 << log2);
            assert!(report.map_exact, "{what}");
            assert_eq!(report.subcubes_partial, 0, "{what}");
            assert_eq!(
                engine.memory_volume("mem").unwrap().data,
                volume.data,
                "{what}: memory image"
            );
            assert_maps(&engine, &volume, log2, reach, &tf, true, &what);
            // Every copy written: the voxel-pair layouts write z = 1.. twice.
            let voxels = 32u64 * 32 * 32;
            let copies = match mapping {
                Mapping::Interleaved8 => voxels,
                _ => 2 * voxels - 32 * 32,
            };
            assert_eq!(report.writes, copies, "{what}");
            assert!(report.write_cycles >= report.host_link_cycles, "{what}");
            assert!(
                report.write_cycles as f64 >= report.writes as f64 / 4.0,
                "{what}"
            );
        }
    }
}

#[test]
fn a_tiled_download_writes_whole_words_once_and_builds_the_exact_maps() {
    let volume = metaballs(40, 0.4); // not a multiple of the 16×16×8 tiles
    let tf = table(&band_tf(60.0, 140.0));
    for mapping in [
        Mapping::Replicated4,
        Mapping::Interleaved8,
        Mapping::Linear4,
    ] {
        let hw = config(mapping);
        let update = VolumeUpdate::full_tiled(&volume, &hw.memory);
        let mut engine = UpdateEngine::new(&hw, volume.dims, 8, 3, 1).unwrap();
        let tiled = engine.update(&update, PartialMapPolicy::Widen).unwrap();
        let what = format!("{mapping:?} tiled");
        assert!(tiled.map_exact && tiled.subcubes_partial == 0, "{what}");
        assert_eq!(
            engine.memory_volume("m").unwrap().data,
            volume.data,
            "{what}"
        );
        assert_maps(&engine, &volume, 3, 1, &tf, true, &what);
        // One WRITE per word: the volume's voxels (z .. z+1 pairs and the top slice).
        assert_eq!(tiled.writes, 40 * 40 * 40, "{what}");
        let mut plain = UpdateEngine::new(&hw, volume.dims, 8, 3, 1).unwrap();
        let ordered = plain
            .update(&VolumeUpdate::full(&volume), PartialMapPolicy::Widen)
            .unwrap();
        // Tiles are the cubic layouts' rows (linear4's rows run along x: volume order suits it).
        if mapping != Mapping::Linear4 {
            assert!(
                tiled.write_row_misses < ordered.write_row_misses,
                "{what}: {tiled:?} against {ordered:?}"
            );
        }
        if mapping == Mapping::Replicated4 {
            // The border slices cost host bytes (one slice in 9 here).
            assert!(tiled.host_bytes > ordered.host_bytes);
            assert!(
                tiled.write_cycles < ordered.write_cycles,
                "{tiled:?} {ordered:?}"
            );
        }
    }
    // Word pairs cannot be partial, and need a voxel-pair layout.
    let mut engine =
        UpdateEngine::new(&config(Mapping::Replicated4), volume.dims, 8, 3, 0).unwrap();
    let mut partial = VolumeUpdate::full_tiled(&volume, &config(Mapping::Replicated4).memory);
    partial.regions.truncate(3);
    let err = engine
        .update(&partial, PartialMapPolicy::Widen)
        .unwrap_err()
        .to_string();
    assert!(err.contains("missing"), "{err}");
    partial.whole_volume = false;
    let err = engine
        .update(&partial, PartialMapPolicy::Widen)
        .unwrap_err()
        .to_string();
    assert!(err.contains("whole-volume"), "{err}");
    let mut engine =
        UpdateEngine::new(&config(Mapping::Interleaved8), volume.dims, 8, 3, 0).unwrap();
    let pairs = VolumeUpdate::full_tiled(&volume, &config(Mapping::Replicated4).memory);
    let err = engine
        .update(&pairs, PartialMapPolicy::Widen)
        .unwrap_err()
        .to_string();
    assert!(err.contains("interleaved8"), "{err}");
}

#[test]
fn the_host_link_bounds_a_download_at_its_bandwidth() {
    let volume = metaballs(32, 0.0);
    let update = VolumeUpdate::full(&volume);
    let mut cycles = Vec::new();
    for mhz in [33.0, 8.0] {
        let mut hw = config(Mapping::Interleaved8);
        hw.memory.host_link_mhz = mhz;
        let mut engine = UpdateEngine::new(&hw, volume.dims, 8, 3, 0).unwrap();
        let r = engine.update(&update, PartialMapPolicy::Widen).unwrap();
        // 32 bits at `mhz` against a 100 MHz clock: 1.32 or 0.32 bytes per cycle.
        assert_eq!(r.host_bytes, 32 * 32 * 32 + 12);
        let bound = (r.host_bytes as f64 / (4.0 * mhz / 100.0)).ceil() as u64;
        assert!(r.host_link_cycles.abs_diff(bound) <= 1, "{r:?}");
        assert!(r.write_cycles >= r.host_link_cycles, "{r:?}");
        cycles.push((r.write_cycles, r.host_link_cycles));
    }
    // At 8 MHz the link is the bottleneck: the update takes its time within a few cycles.
    let (slow, bound) = cycles[1];
    assert!(slow - bound < 64, "{cycles:?}");
    // The fastest link the ranges allow (2^32 bytes per cycle and more) overflowed the
    // engine's byte credit (a panic in a debug build): now the link is simply never the bound.
    let mut hw = config(Mapping::Interleaved8);
    hw.memory.host_link_bits = 1024;
    hw.memory.host_link_mhz = 1e5;
    hw.clock.frequency_mhz = 1e-3;
    hw.validate("test").unwrap();
    let mut engine = UpdateEngine::new(&hw, volume.dims, 8, 3, 0).unwrap();
    let r = engine.update(&update, PartialMapPolicy::Widen).unwrap();
    assert_eq!(r.host_link_cycles, 1, "{r:?}");
    assert!(r.write_cycles > 1, "{r:?}");
}

#[test]
fn a_scan_through_the_read_path_rebuilds_the_exact_maps() {
    let volume = metaballs(32, 0.3);
    let tf = table(&band_tf(30.0, 90.0));
    for mapping in [Mapping::Replicated4, Mapping::Interleaved8] {
        let mut engine = UpdateEngine::new(&config(mapping), volume.dims, 8, 2, 1).unwrap();
        engine
            .update(&VolumeUpdate::full(&volume), PartialMapPolicy::Widen)
            .unwrap();
        let scan = engine.scan();
        assert_eq!(scan.requests, 16 * 16 * 16, "{mapping:?}");
        assert_eq!(scan.words_read, scan.requests * engine_modules(mapping));
        assert!(scan.cycles >= scan.requests, "{scan:?}");
        assert!(scan.row_hit_rate > 0.9, "{mapping:?}: {scan:?}");
        assert_maps(
            &engine,
            &volume,
            2,
            1,
            &tf,
            true,
            &format!("{mapping:?} scan"),
        );
    }
}

fn engine_modules(mapping: Mapping) -> u64 {
    if mapping == Mapping::Interleaved8 {
        8
    } else {
        4
    }
}

/// The partial update of one time step: the changed voxels' 4³ bricks as regions, a region
/// that empties a corner, and single voxels, one written twice.
fn partial_update(before: &Volume, after: &Volume) -> VolumeUpdate {
    let d = after.dims;
    let mut regions = Vec::new();
    for bz in (0..d[2]).step_by(4) {
        for by in (0..d[1]).step_by(4) {
            for bx in (0..d[0]).step_by(4) {
                let changed = (bz..bz + 4).any(|z| {
                    (by..by + 4).any(|y| {
                        (bx..bx + 4).any(|x| {
                            let i = after.index(x, y, z);
                            before.data[i] != after.data[i]
                        })
                    })
                });
                if changed {
                    regions.push(VolumeUpdate::region_of(after, [bx, by, bz], [4, 4, 4]));
                }
            }
        }
    }
    regions.push(Region {
        origin: [3, 5, 2],
        dims: [13, 9, 11],
        values: vec![0; 13 * 9 * 11],
    });
    let mut update = VolumeUpdate {
        regions,
        ..VolumeUpdate::default()
    };
    update.regions.extend(
        VolumeUpdate::voxels(&[
            ([20, 20, 20], 7),
            ([1, 30, 0], 200),
            ([20, 20, 20], 99),
            ([31, 31, 31], 255),
        ])
        .regions,
    );
    update
}

#[test]
fn partial_updates_keep_the_last_value_and_a_conservative_or_exact_map() {
    let tf = table(&band_tf(40.0, 120.0));
    let start = metaballs(32, 0.0);
    for mapping in [Mapping::Replicated4, Mapping::Interleaved8] {
        let mut stale = [0, 0];
        for (p, policy) in [PartialMapPolicy::Widen, PartialMapPolicy::Rescan]
            .into_iter()
            .enumerate()
        {
            let mut engine = UpdateEngine::new(&config(mapping), start.dims, 8, 2, 0).unwrap();
            engine.update(&VolumeUpdate::full(&start), policy).unwrap();
            let mut reference = start.clone();
            for step in 1..=3 {
                let next = metaballs(32, 0.15 * step as f32);
                let update = partial_update(&reference, &next);
                let report = engine.update(&update, policy).unwrap();
                update.apply_to(&mut reference);
                let what = format!("{mapping:?} {policy:?} step {step}");
                assert_eq!(reference.data[reference.index(20, 20, 20)], 99);
                let memory = engine.memory_volume("mem").unwrap();
                assert_eq!(memory.data, reference.data, "{what}: memory image");
                assert!(report.subcubes_partial > 0, "{what}");
                assert_eq!(
                    report.map_exact,
                    policy == PartialMapPolicy::Rescan,
                    "{what}"
                );
                assert_eq!(report.rescan_cycles > 0, policy == PartialMapPolicy::Rescan);
                stale[p] += assert_maps(
                    &engine,
                    &reference,
                    2,
                    0,
                    &tf,
                    policy == PartialMapPolicy::Rescan,
                    &what,
                );
            }
        }
        // Widening leaves bits set over the emptied corner; the rescan clears them.
        assert!(stale[0] > 0, "{mapping:?}: {stale:?}");
        assert_eq!(stale[1], 0, "{mapping:?}");
    }
}

#[test]
fn a_transfer_function_change_from_the_table_equals_a_rebuild() {
    let volume = metaballs(32, 0.7);
    let mut engine =
        UpdateEngine::new(&config(Mapping::Replicated4), volume.dims, 8, 3, 0).unwrap();
    engine
        .update(&VolumeUpdate::full(&volume), PartialMapPolicy::Widen)
        .unwrap();
    for (lo, hi) in [(10.0, 50.0), (100.0, 180.0), (200.0, 250.0)] {
        let tf = table(&band_tf(lo, hi));
        assert_maps(
            &engine,
            &volume,
            3,
            0,
            &tf,
            true,
            &format!("band {lo}..{hi}"),
        );
    }
    let scan = engine.scan();
    let costs = engine.tf_change_costs(scan.cycles);
    assert_eq!(costs.table_pass_cycles, 4 * 4 * 4);
    assert_eq!(costs.table_bits, 4 * 4 * 4 * 16);
    assert_eq!(costs.prefix_cycles, 256);
    assert!(costs.table_pass_cycles + costs.prefix_cycles < costs.scan_cycles);
}

#[test]
fn bad_input_gives_clear_errors() {
    // Host bandwidth 0, by either field.
    for field in ["memory.host_link_mhz=0", "memory.host_link_bits=0"] {
        let err = HardwareConfig::load(None, &[field.into()])
            .unwrap_err()
            .to_string();
        assert!(
            err.contains(field.split('=').next().unwrap()) && err.contains("zero bandwidth"),
            "{err}"
        );
    }
    let hw = HardwareConfig::default_config();
    let mut engine = UpdateEngine::new(&hw, [16, 16, 16], 8, 2, 0).unwrap();
    let outside = VolumeUpdate {
        regions: vec![Region {
            origin: [10, 0, 0],
            dims: [8, 1, 1],
            values: vec![1; 8],
        }],
        ..VolumeUpdate::default()
    };
    let err = engine
        .update(&outside, PartialMapPolicy::Widen)
        .unwrap_err()
        .to_string();
    assert!(err.contains("region 0") && err.contains("leaves"), "{err}");
    let short = VolumeUpdate {
        regions: vec![Region {
            origin: [0; 3],
            dims: [2, 2, 2],
            values: vec![1; 7],
        }],
        ..VolumeUpdate::default()
    };
    let err = engine
        .update(&short, PartialMapPolicy::Widen)
        .unwrap_err()
        .to_string();
    assert!(err.contains("7 values"), "{err}");
    let err = engine
        .update(
            &VolumeUpdate::voxels(&[([0, 0, 0], 300)]),
            PartialMapPolicy::Widen,
        )
        .unwrap_err()
        .to_string();
    assert!(err.contains("300") && err.contains("8-bit"), "{err}");
    // Nothing was written by the rejected updates.
    assert!(engine
        .memory_volume("m")
        .unwrap()
        .data
        .iter()
        .all(|&v| v == 0));
    // A volume too large for the memory.
    let mut small = HardwareConfig::default_config();
    small.memory.rows = 16;
    let err = UpdateEngine::new(&small, [256, 256, 256], 8, 4, 0)
        .err()
        .unwrap()
        .to_string();
    assert!(err.contains("memory.rows"), "{err}");
}

/// A small deterministic generator (xorshift), so the random updates are the same every run.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 ^= self.0 << 13;
        self.0 ^= self.0 >> 7;
        self.0 ^= self.0 << 17;
        self.0
    }
    fn below(&mut self, n: usize) -> usize {
        (self.next() % n as u64) as usize
    }
}

#[test]
fn random_partial_updates_keep_memory_and_maps_right_after_every_step() {
    let tf = table(&band_tf(50.0, 150.0));
    let dims = [24, 20, 28];
    let start = Volume::new(
        "start",
        dims,
        [1.0; 3],
        8,
        (0..dims.iter().product::<usize>())
            .map(|i| ((i * 37) % 5 * 60) as u16)
            .collect(),
    )
    .unwrap();
    let mut rng = Rng(0x9e37_79b9_7f4a_7c15);
    for (mapping, log2, reach) in [
        (Mapping::Replicated4, 2, 0),
        (Mapping::Interleaved8, 1, 1),
        (Mapping::Linear4, 3, 1),
    ] {
        for policy in [PartialMapPolicy::Widen, PartialMapPolicy::Rescan] {
            let what = format!("{mapping:?} s={} reach {reach} {policy:?}", 1 << log2);
            let mut engine = UpdateEngine::new(&config(mapping), dims, 8, log2, reach).unwrap();
            engine.update(&VolumeUpdate::full(&start), policy).unwrap();
            let mut reference = start.clone();
            for step in 0..6 {
                let mut regions = Vec::new();
                for _ in 0..1 + rng.below(6) {
                    let e = [0, 1, 2].map(|a| 1 + rng.below(dims[a].min(12)));
                    let o = [0, 1, 2].map(|a| rng.below(dims[a] - e[a] + 1));
                    // Mostly empty (to clear bits), sometimes a constant, sometimes noise.
                    let kind = rng.below(3);
                    let values = (0..e.iter().product::<usize>())
                        .map(|_| match kind {
                            0 => 0,
                            1 => 100,
                            _ => rng.below(256) as u16,
                        })
                        .collect();
                    regions.push(Region {
                        origin: o,
                        dims: e,
                        values,
                    });
                }
                let update = VolumeUpdate {
                    regions,
                    ..VolumeUpdate::default()
                };
                let report = engine.update(&update, policy).unwrap();
                update.apply_to(&mut reference);
                let what = format!("{what} step {step}");
                assert_eq!(
                    engine.memory_volume("m").unwrap().data,
                    reference.data,
                    "{what}"
                );
                assert_eq!(report.voxels_written, update.voxels_written());
                let exact = report.map_exact;
                assert_eq!(
                    exact,
                    policy == PartialMapPolicy::Rescan || report.subcubes_partial == 0
                );
                assert_maps(&engine, &reference, log2, reach, &tf, exact, &what);
            }
        }
    }
}

#[test]
fn sleeping_controllers_equal_ticking_ones_for_writes_and_scans() {
    let volume = metaballs(24, 0.5);
    let next = metaballs(24, 0.8);
    let run = |sleeping: bool, link_mhz: f64| {
        let mut hw = config(Mapping::Replicated4);
        hw.memory.host_link_mhz = link_mhz;
        let engine = UpdateEngine::new(&hw, volume.dims, 8, 2, 0).unwrap();
        let mut engine = if sleeping {
            engine
        } else {
            engine.without_sleeping()
        };
        let a = engine
            .update(&VolumeUpdate::full(&volume), PartialMapPolicy::Widen)
            .unwrap();
        let b = engine
            .update(
                &VolumeUpdate::full_tiled(&volume, &hw.memory),
                PartialMapPolicy::Widen,
            )
            .unwrap();
        let update = vizsim::dynamic::changed_bricks(&volume, &next, 4).unwrap();
        let c = engine.update(&update, PartialMapPolicy::Rescan).unwrap();
        let d = engine.scan();
        (a, b, c, d, engine.module_stats(), engine.now())
    };
    // At 0.5 MHz the link is the bound (0.02 bytes per cycle) and the sleeping engine jumps
    // over the cycles that wait for it; ticking controllers never let it jump.
    for link_mhz in [33.0, 0.5] {
        let (sleeping, ticking) = (run(true, link_mhz), run(false, link_mhz));
        assert!(sleeping.4.iter().all(|s| s.refreshes > 0));
        assert_eq!(
            format!("{sleeping:?}"),
            format!("{ticking:?}"),
            "{link_mhz} MHz"
        );
    }
}

fn vizsim(args: &[&str]) -> std::process::Output {
    std::process::Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args(args)
        .output()
        .unwrap()
}

#[test]
fn the_update_command_prints_the_costs_and_rejects_bad_input() {
    let out = vizsim(&[
        "update",
        "phantom:metaballs:32",
        "--subcube",
        "4",
        "--next",
        "phantom:metaballs:32:t=0.2",
        "--brick",
        "4",
        "--json",
    ]);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let report: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(report["scan"]["requests"], 16 * 16 * 16);
    assert_eq!(report["download"]["map_exact"], true);
    assert_eq!(report["partial"]["rescan"]["map_exact"], true);
    assert_eq!(report["partial"]["widen"]["map_exact"], false);
    for (args, wanted) in [
        (
            vec![
                "update",
                "phantom:sphere:32",
                "--subcube",
                "4",
                "--set",
                "memory.host_link_mhz=0",
            ],
            "memory.host_link_mhz",
        ),
        (
            vec![
                "update",
                "phantom:sphere:32",
                "--subcube",
                "4",
                "--next",
                "phantom:sphere:16",
            ],
            "--next phantom:sphere:16: [16, 16, 16] voxels of 8 bits, but phantom:sphere:32",
        ),
        (vec!["update", "phantom:sphere:32"], "--subcube"),
        // A voxel's two copies could never enter a 1-entry write FIFO: the update waited
        // forever (found by probing the validated extremes).
        (
            vec![
                "update",
                "phantom:sphere:32",
                "--subcube",
                "4",
                "--set",
                "memory.address_fifo_depth=1",
                "--set",
                "memory.overtaking_window=1",
            ],
            "memory.address_fifo_depth",
        ),
        // A link so slow the update would take 3.5e12 cycles: refused up front, not simulated.
        (
            vec![
                "update",
                "phantom:sphere:32",
                "--subcube",
                "4",
                "--set",
                "clock.frequency_mhz=100000",
                "--set",
                "memory.host_link_mhz=0.001",
                "--set",
                "memory.host_link_bits=1",
            ],
            "2^36",
        ),
        // Flags that would change nothing (found by probing: the output was identical).
        (
            vec![
                "update",
                "phantom:sphere:32",
                "--subcube",
                "4",
                "--hierarchy",
            ],
            "--hierarchy",
        ),
        (
            vec!["occupancy", "phantom:sphere:32", "--subcube", "8"],
            "--subcube",
        ),
        (
            vec![
                "update",
                "phantom:sphere:32",
                "--subcube",
                "4",
                "--brick",
                "0",
            ],
            "brick",
        ),
    ] {
        let out = vizsim(&args);
        let err = String::from_utf8_lossy(&out.stderr);
        assert!(
            !out.status.success() && err.contains(wanted),
            "{args:?}: {err}"
        );
        assert!(!err.contains("panicked"), "{err}");
    }
}

#[test]
fn a_sixteen_bit_volume_costs_two_link_bytes_per_voxel_and_keeps_exact_maps() {
    let dims = [20, 18, 22];
    let data: Vec<u16> = (0..dims.iter().product::<usize>())
        .map(|i| if i % 7 < 3 { 0 } else { (i * 2654) as u16 })
        .collect();
    let volume = Volume::new("sixteen", dims, [1.0; 3], 16, data).unwrap();
    let tf = common::tf(&[
        (0.0, [0.0; 4]),
        (20000.0, [0.0; 4]),
        (30000.0, [1.0, 1.0, 1.0, 0.5]),
        (40000.0, [0.0; 4]),
        (65535.0, [0.0; 4]),
    ]);
    let table = ClassificationTable::build(&tf, 65536, 12, 1.0);
    for mapping in [Mapping::Replicated4, Mapping::Interleaved8] {
        let hw = config(mapping);
        let mut engine = UpdateEngine::new(&hw, dims, 16, 2, 0).unwrap();
        let r = engine
            .update(
                &VolumeUpdate::full_tiled(&volume, &hw.memory),
                PartialMapPolicy::Widen,
            )
            .unwrap();
        assert_eq!(r.host_bytes, 2 * r.voxels_written + 12 * r.regions);
        assert_eq!(engine.memory_volume("m").unwrap().data, volume.data);
        assert_maps(
            &engine,
            &volume,
            2,
            0,
            &table,
            true,
            &format!("{mapping:?} 16-bit"),
        );
        let scan = engine.scan();
        let costs = engine.tf_change_costs(scan.cycles);
        assert_eq!(costs.table_bits, 5 * 5 * 6 * 32);
        assert_eq!(costs.prefix_cycles, 65536);
        assert_maps(
            &engine,
            &volume,
            2,
            0,
            &table,
            true,
            &format!("{mapping:?} scan"),
        );
    }
}

/// `--next` with the same extent but 16-bit samples was caught only by the update engine, as
/// "update region 0: value 5072 exceeds the 8-bit volume's 255", naming neither the option nor
/// the file (found by probing). Now it is caught when the file is loaded.
#[test]
fn a_next_volume_of_another_bit_depth_is_refused_naming_the_option_and_file() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-next-bits-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    let eight = dir.join("vol_8x8x8_uint8.raw");
    let sixteen = dir.join("other_8x8x8_uint16.raw");
    std::fs::write(
        &eight,
        (0..512).map(|i| (i % 200) as u8).collect::<Vec<_>>(),
    )
    .unwrap();
    let values: Vec<u8> = (0..512u16)
        .flat_map(|i| (i * 37 % 6000).to_le_bytes())
        .collect();
    std::fs::write(&sixteen, values).unwrap();
    let out = vizsim(&[
        "update",
        eight.to_str().unwrap(),
        "--subcube",
        "2",
        "--tf",
        "zero",
        "--next",
        sixteen.to_str().unwrap(),
    ]);
    let err = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success(), "accepted: {err}");
    assert!(!err.contains("panicked"), "{err}");
    for needle in [
        format!("--next {}", sixteen.display()),
        "16 bits".to_string(),
        "bit depth".to_string(),
    ] {
        assert!(err.contains(&needle), "lacks {needle:?}: {err}");
    }
    assert!(out.stdout.is_empty(), "printed before refusing");
    // The library says so too, for callers other than the command.
    let a = Volume::new("a", [4, 4, 4], [1.0; 3], 8, vec![1; 64]).unwrap();
    let b = Volume::new("b", [4, 4, 4], [1.0; 3], 16, vec![300; 64]).unwrap();
    let e = vizsim::dynamic::changed_bricks(&a, &b, 2)
        .expect_err("another bit depth accepted")
        .to_string();
    assert!(e.contains("bit depths"), "{e}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// Bounding bricks' flags from the min/max table (`MinMaxTable::coarse_map`): a brick's range
/// is its sub-cubes' hull, so after a download (exact table) the flags equal
/// `bricks::build_brick_map` on the volume at every brick edge ≥ the sub-cube's, for a volume
/// that is no multiple of the bricks; after a partial update widened, they are conservative;
/// a brick below the sub-cube has no flags from the table.
#[test]
fn brick_flags_from_the_table_equal_the_bricks_built_from_the_volume() {
    let volume = metaballs(40, 0.0);
    let next = metaballs(40, 0.3);
    let tf = table(&band_tf(60.0, 140.0));
    let visible = |lo, hi| tf.any_visible(lo, hi);
    for (log2, bricks) in [(2u32, [4usize, 8, 16, 32]), (3, [8, 16, 32, 32])] {
        let mut engine =
            UpdateEngine::new(&config(Mapping::Replicated4), volume.dims, 8, log2, 0).unwrap();
        engine
            .update(&VolumeUpdate::full(&volume), PartialMapPolicy::Widen)
            .unwrap();
        for kind in [OccupancyKind::Zero, OccupancyKind::Class] {
            for brick in bricks {
                let what = format!("{kind:?} sub-cube {} brick {brick}", 1 << log2);
                let ours = engine
                    .table()
                    .coarse_map(kind, brick.trailing_zeros(), visible)
                    .unwrap();
                let exact = vizsim::bricks::build_brick_map(&volume, kind, brick, visible).unwrap();
                compare(&ours, &exact, true, &what);
            }
        }
        assert!(engine
            .table()
            .coarse_map(OccupancyKind::Zero, log2 - 1, visible)
            .is_none());
        let update = vizsim::dynamic::changed_bricks(&volume, &next, 4).unwrap();
        let report = engine.update(&update, PartialMapPolicy::Widen).unwrap();
        assert!(
            report.subcubes_partial > 0,
            "the test needs a widened table"
        );
        let exact =
            vizsim::bricks::build_brick_map(&next, OccupancyKind::Class, 16, visible).unwrap();
        let ours = engine
            .table()
            .coarse_map(OccupancyKind::Class, 4, visible)
            .unwrap();
        compare(&ours, &exact, false, "widened");
    }
}

/// A partial update's brick edge runs from 1 to the volume's longest edge, in `update` and in
/// sequences alike: a review's `--brick 99999999999` was accepted and printed as the update's
/// brick, which no hardware sends.
#[test]
fn a_brick_larger_than_the_volume_is_refused() {
    let a = metaballs(16, 0.0);
    let b = metaballs(16, 0.3);
    assert!(vizsim::dynamic::changed_bricks(&a, &b, 16).is_ok());
    for brick in [0, 17, 99_999_999_999] {
        let e = vizsim::dynamic::changed_bricks(&a, &b, brick)
            .expect_err("accepted")
            .to_string();
        assert!(
            e.contains(&format!("brick size {brick}")) && e.contains("1..=16"),
            "{e}"
        );
    }
    let memory = HardwareConfig::default_config().memory;
    let mut sequence = vizsim::dynamic::Sequence::open("phantom:metaballs:16", 2, 0.1, 17).unwrap();
    let e = match sequence.next_step(&memory) {
        Ok(_) => panic!("a 17³ brick accepted on a 16³ volume"),
        Err(e) => e.to_string(),
    };
    assert!(e.contains("brick size 17") && e.contains("1..=16"), "{e}");
    let mut sequence = vizsim::dynamic::Sequence::open("phantom:metaballs:16", 2, 0.1, 16).unwrap();
    assert!(sequence.next_step(&memory).unwrap().is_some());
}
