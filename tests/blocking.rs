//! 2-way blocking (issue 16, part 5; docs/model.md, "Blocking"), through the one run path:
//!
//! - the blocked image equals the unblocked image bit for bit (functional and cycle model;
//!   phantoms with both classifications, shading, an orbit view; fuel and neghip with their
//!   class and zero transfer functions when the data is present);
//! - inactive blocks are never read: every memory read belongs to a sample of an active block,
//!   and the blocked layout gives every stored (slot, voxel) its own word inside the slots;
//! - the table lookup's latency changes cycles, not the image (with ideal memory exactly as
//!   much as a longer memory latency);
//! - a volume too large for the memory without blocking: a clear error that says blocking
//!   would make it fit and how many blocks it needs; with blocking it renders;
//! - bad block sizes: clear errors, no panic.

mod common;

use std::collections::HashMap;
use std::sync::Arc;

use vizsim::arch::address_map::{AddressMap, Mapping};
use vizsim::blocking::{BlockTable, BlockingStats};
use vizsim::config::HardwareConfig;
use vizsim::occupancy::OccupancyKind;
use vizsim::run::{execute, prepare, Memory, Model, Probes, RunDescription, RunReport};
use vizsim::volume::Volume;

const SIZE: u32 = 32;

/// A word's place: module, bank, row, column.
type WordKey = (u32, u32, u32, u32);

fn description(volume: &Volume, tf: &str, model: Model, sets: &[String]) -> RunDescription {
    let config = HardwareConfig::load(None, sets).unwrap_or_else(|e| panic!("{sets:?}: {e}"));
    let mut run = RunDescription::new(&volume.name, tf, model, config);
    run.size = (SIZE, SIZE);
    run
}

fn render_run(volume: &Volume, run: &RunDescription) -> RunReport {
    let prepared = prepare(run, volume).unwrap_or_else(|e| panic!("{run:?}: {e}"));
    execute(run, &prepared, Probes::default()).unwrap_or_else(|e| panic!("{e}"))
}

fn render(volume: &Volume, tf: &str, model: Model, sets: &[String]) -> RunReport {
    render_run(volume, &description(volume, tf, model, sets))
}

fn phantom(spec: &str) -> Volume {
    vizsim::volume::dataset::load(spec, None).unwrap()
}

fn sets(list: &[&str]) -> Vec<String> {
    list.iter().map(|s| s.to_string()).collect()
}

fn blocked(size: usize, extra: &[&str]) -> Vec<String> {
    let mut s = sets(extra);
    s.push("blocking.enabled=true".into());
    s.push(format!("blocking.block_size={size}"));
    s
}

/// Blocked and unblocked runs of one setting: the same image and (functional) the same steps;
/// returns the blocked report.
fn assert_blocked_equals_unblocked(
    volume: &Volume,
    tf: &str,
    model: Model,
    size: usize,
    extra: &[&str],
    shading: bool,
    view: &str,
) -> RunReport {
    let mut plain = description(volume, tf, model, &sets(extra));
    plain.shading = shading;
    plain.view = view.into();
    let mut run = description(volume, tf, model, &blocked(size, extra));
    run.shading = shading;
    run.view = view.into();
    let a = render_run(volume, &plain);
    let b = render_run(volume, &run);
    let what = format!(
        "{} tf {tf} {model:?} block {size} {extra:?} shading {shading} {view}",
        volume.name
    );
    assert!(
        a.stats.rays_hit > 0 && a.stats.samples > 0,
        "{what}: nothing rendered"
    );
    let differing = (a.frame.pixels.iter())
        .zip(&b.frame.pixels)
        .filter(|(p, q)| p != q)
        .count();
    assert_eq!(differing, 0, "{what}: pixels differ");
    // Samples composited (the cycle model's issued samples less those discarded after ERT,
    // which depend on timing) and leaps.
    let composited =
        |r: &RunReport| r.measurements.samples - r.measurements.discarded_after_ert.unwrap_or(0);
    assert_eq!(composited(&a), composited(&b), "{what}: samples composited");
    assert_eq!(a.measurements.leaps, b.measurements.leaps, "{what}: leaps");
    let stats = b.measurements.blocking.clone().expect("blocking figures");
    assert!(stats.active_blocks <= stats.blocks);
    assert!(a.measurements.blocking.is_none());
    b
}

#[test]
fn blocked_image_equals_unblocked_on_phantoms() {
    let mut some_inactive = 0;
    let mut zero_samples = 0;
    for spec in ["phantom:metaballs:64", "phantom:jet:64", "phantom:tube:64"] {
        let volume = phantom(spec);
        for tf in ["class", "zero"] {
            for size in [8, 16, 32] {
                for model in [Model::Step, Model::Cycle] {
                    let b = assert_blocked_equals_unblocked(
                        &volume,
                        tf,
                        model,
                        size,
                        &[],
                        false,
                        "front",
                    );
                    let stats = b.measurements.blocking.unwrap();
                    if stats.active_blocks < stats.blocks {
                        some_inactive += 1;
                    }
                    zero_samples += stats.zero_samples.unwrap_or(0);
                }
            }
        }
    }
    // The comparison is not vacuous: blocks were inactive and samples read zero.
    assert!(some_inactive > 10, "{some_inactive}");
    assert!(zero_samples > 1000, "{zero_samples}");
}

#[test]
fn blocked_image_equals_unblocked_with_shading_leaping_bricks_and_other_mappings() {
    let volume = phantom("phantom:metaballs:64");
    for (extra, shading, view) in [
        (&[][..], true, "orbit:3/8"),
        (&["occupancy.subcube=8"][..], false, "orbit:1/8"),
        (
            &["occupancy.subcube=4", "occupancy.kind=zero"][..],
            true,
            "front",
        ),
        (&["bricks.size=8"][..], false, "orbit:5/8"),
        (&["memory.mapping=interleaved8"][..], false, "orbit:2/8"),
        (&["memory.mapping=linear4"][..], true, "front"),
        (&["compositing.ert=false"][..], false, "front"),
    ] {
        for model in [Model::Step, Model::Cycle] {
            assert_blocked_equals_unblocked(&volume, "class", model, 16, extra, shading, view);
        }
    }
}

/// Fuel and neghip with their class and zero transfer functions (skipped with a message when
/// the data is absent).
#[test]
fn blocked_image_equals_unblocked_on_fuel_and_neghip() {
    let Some(dir) = common::data_dir() else {
        eprintln!("blocked_image_equals_unblocked_on_fuel_and_neghip: no data directory; skipped");
        return;
    };
    for name in ["fuel", "neghip"] {
        let volume = match vizsim::volume::dataset::load(name, Some(&dir)) {
            Ok(v) => v,
            Err(e) => {
                eprintln!("{name}: {e}; skipped");
                continue;
            }
        };
        for tf in [format!("{name}-class"), format!("{name}-zero")] {
            for size in [8, 16] {
                for model in [Model::Step, Model::Cycle] {
                    let b = assert_blocked_equals_unblocked(
                        &volume,
                        &tf,
                        model,
                        size,
                        &[],
                        false,
                        "orbit:1/8",
                    );
                    let s = b.measurements.blocking.unwrap();
                    eprintln!(
                        "{name} {tf} block {size} {model:?}: {} of {} blocks active",
                        s.active_blocks, s.blocks
                    );
                }
            }
        }
    }
}

#[test]
fn inactive_blocks_are_never_read() {
    let volume = phantom("phantom:jet:64");
    for mapping in ["replicated4", "interleaved8"] {
        let mapping_set = format!("memory.mapping={mapping}");
        let run = description(
            &volume,
            "class",
            Model::Cycle,
            &blocked(16, &["compositing.ert=false", &mapping_set]),
        );
        let report = render_run(&volume, &run);
        let ms = report.memory_stats.as_ref().unwrap();
        let lookups = ms["block_lookups"].as_u64().unwrap();
        let zero = ms["zero_samples"].as_u64().unwrap();
        let reads = ms["reads"].as_u64().unwrap();
        let words_per_sample = run.hardware.memory.modules() as u64;
        // Every sample request is looked up once; only those of active blocks are read.
        assert_eq!(lookups, report.measurements.samples, "{mapping}");
        assert!(zero > 0 && zero < lookups, "{mapping}: {zero} of {lookups}");
        assert_eq!(reads, words_per_sample * (lookups - zero), "{mapping}");
        // The functional model agrees on which samples those are: the samples whose lower
        // corner lies in an inactive block.
        let renderer = prepare(&run, &volume).unwrap();
        let renderer = renderer.fixed().unwrap();
        let table = renderer.blocks.as_ref().unwrap();
        let camera = run.camera(&volume).unwrap();
        let mut inactive = 0u64;
        for py in 0..SIZE {
            for px in 0..SIZE {
                let ray = renderer.setup(&camera, px, py);
                let mut pos = ray.start;
                for _ in 0..ray.samples {
                    if table.slot_at(renderer.base_voxel(pos)).is_none() {
                        inactive += 1;
                    }
                    for (p, step) in pos.iter_mut().zip(ray.step) {
                        *p += step;
                    }
                }
            }
        }
        assert_eq!(zero, inactive, "{mapping}");
    }
}

/// The blocked layout: every (slot, voxel) a sample of an active block reads has a word of its
/// own (no two stored voxels share a word), one per module, inside the slots' rows; samples
/// of inactive blocks have no words.
#[test]
fn the_blocked_layout_gives_every_stored_voxel_its_own_word() {
    let volume = phantom("phantom:jet:64");
    let base_config = HardwareConfig::default_config().memory;
    for (mapping, block, banks) in [
        (Mapping::Replicated4, [8, 8, 8], 4),
        (Mapping::Replicated4, [4, 8, 16], 8),
        (Mapping::Interleaved8, [8, 8, 8], 4),
        (Mapping::Linear4, [8, 8, 8], 2),
    ] {
        for size in [8usize, 16, 32] {
            let config = vizsim::arch::address_map::MemoryConfig {
                mapping,
                block,
                banks,
                ..base_config.clone()
            };
            let table = Arc::new(BlockTable::build(
                &volume,
                OccupancyKind::Zero,
                size.trailing_zeros(),
                false,
                |_, _| true,
            ));
            let stats = BlockingStats::new(&table, &config, volume.dims, 0);
            let map = AddressMap::blocked(&config, volume.dims, table.clone());
            let mut owner: HashMap<WordKey, (u32, [usize; 3])> = HashMap::new();
            let (mut active_samples, mut inactive_samples) = (0, 0);
            let d = volume.dims;
            for z in 0..d[2] - 1 {
                for y in 0..d[1] - 1 {
                    for x in 0..d[0] - 1 {
                        let base = [x, y, z];
                        let (words, n) = map.sample_words(base);
                        let Some(slot) = table.slot_at(base) else {
                            assert_eq!(n, 0);
                            inactive_samples += 1;
                            continue;
                        };
                        active_samples += 1;
                        assert_eq!(n, config.modules());
                        let mut modules: Vec<u32> = words[..n].iter().map(|w| w.module).collect();
                        modules.sort();
                        modules.dedup();
                        assert_eq!(modules.len(), n, "{mapping:?}: one word per module");
                        let mut i = 0;
                        let dzs = if mapping == Mapping::Interleaved8 {
                            2
                        } else {
                            1
                        };
                        for dz in 0..dzs {
                            for dy in 0..2 {
                                for dx in 0..2 {
                                    let w = words[i];
                                    i += 1;
                                    assert!((w.row as u64) < stats.rows_blocked);
                                    assert!(w.column < config.columns);
                                    let voxel = [x + dx, y + dy, z + dz];
                                    let key = (w.module, w.bank, w.row, w.column);
                                    let old = owner.entry(key).or_insert((slot, voxel));
                                    assert_eq!(
                                        *old,
                                        (slot, voxel),
                                        "{mapping:?} block {size}: {key:?} holds two voxels"
                                    );
                                }
                            }
                        }
                    }
                }
            }
            assert!(active_samples > 0);
            if size == 8 {
                assert!(inactive_samples > 0);
            }
        }
    }
}

#[test]
fn lookup_latency_changes_cycles_not_the_image() {
    let volume = phantom("phantom:metaballs:64");
    let cycles = |latency: u32, memory: Memory| {
        let mut run = description(
            &volume,
            "class",
            Model::Cycle,
            &blocked(32, &[&format!("blocking.lookup_latency={latency}")]),
        );
        run.memory = memory;
        let report = render_run(&volume, &run);
        (report.measurements.cycles.unwrap(), report)
    };
    let (c0, r0) = cycles(0, Memory::Sdram);
    let (c16, r16) = cycles(16, Memory::Sdram);
    assert!(r0.frame.pixels == r16.frame.pixels);
    assert!(c16 > c0, "{c16} <= {c0}");
    // Every block of this phantom is active at 32³ (nothing reads as zero), and ideal memory
    // takes every request: a lookup of L cycles costs exactly what L more memory latency does.
    assert_eq!(
        r0.measurements.blocking.as_ref().unwrap().zero_samples,
        Some(0)
    );
    for latency in [1, 4, 12] {
        let (blocked_cycles, report) = cycles(latency, Memory::Ideal { latency: 6 });
        let mut plain = description(&volume, "class", Model::Cycle, &[]);
        plain.memory = Memory::Ideal {
            latency: 6 + latency as u64,
        };
        let plain = render_run(&volume, &plain);
        assert!(report.frame.pixels == plain.frame.pixels);
        assert_eq!(
            blocked_cycles,
            plain.measurements.cycles.unwrap(),
            "latency {latency}"
        );
    }
}

/// A volume that does not fit the configured memory without blocking (128 rows per bank for
/// a 128³ phantom that needs 256): a clear error that says blocking makes it fit and how many
/// blocks it needs; the blocked run renders the unblocked image (rendered with the default
/// rows); too few rows even for blocking: an error that says so.
#[test]
fn a_volume_too_large_without_blocking_renders_with_it() {
    let volume = phantom("phantom:jet:128");
    let rows = "memory.rows=128";
    let run = description(&volume, "class", Model::Cycle, &sets(&[rows]));
    let e = prepare(&run, &volume)
        .err()
        .expect("does not fit")
        .to_string();
    assert!(e.contains("memory.rows"), "{e}");
    assert!(e.contains("needs 256 rows per bank"), "{e}");
    assert!(e.contains("does not fit without blocking"), "{e}");
    assert!(
        e.contains("with blocking (block 32) it needs") && e.contains("active blocks of 64"),
        "{e}"
    );
    assert!(e.contains("blocking.enabled=true"), "{e}");
    // With block 16 (the hint names the configured size).
    let run16 = description(
        &volume,
        "class",
        Model::Cycle,
        &sets(&[rows, "blocking.block_size=16"]),
    );
    let e16 = prepare(&run16, &volume)
        .err()
        .expect("does not fit")
        .to_string();
    assert!(
        e16.contains("with blocking (block 16) it needs 81 active blocks of 512"),
        "{e16}"
    );

    let blocked_run = description(&volume, "class", Model::Cycle, &blocked(16, &[rows]));
    let b = render_run(&volume, &blocked_run);
    let plain = render(&volume, "class", Model::Cycle, &[]);
    assert!(b.frame.pixels == plain.frame.pixels);
    let s = b.measurements.blocking.unwrap();
    assert_eq!((s.active_blocks, s.blocks), (81, 512));
    assert!(s.rows_blocked <= 128 && s.rows_unblocked == 256, "{s:?}");
    assert!(
        s.memory_words_blocked < s.memory_words_unblocked / 2,
        "{s:?}"
    );

    let tiny = description(
        &volume,
        "class",
        Model::Cycle,
        &blocked(16, &["memory.rows=32"]),
    );
    let e = prepare(&tiny, &volume)
        .err()
        .expect("does not fit")
        .to_string();
    assert!(e.contains("does not fit with blocking"), "{e}");
    assert!(e.contains("81 active blocks of 512"), "{e}");
    assert!(!e.contains("without blocking it takes"), "{e}");
    // Fits without blocking (256 rows) but not with 4³ blocks, whose slots take whole rows:
    // the error says blocking is what does not fit.
    let small_blocks = description(
        &volume,
        "class",
        Model::Cycle,
        &blocked(4, &["memory.rows=256"]),
    );
    let e = prepare(&small_blocks, &volume)
        .err()
        .expect("4³ slots do not fit")
        .to_string();
    assert!(e.contains("does not fit with blocking"), "{e}");
    assert!(e.contains("without blocking it takes 256"), "{e}");
    assert!(e.contains("larger blocking.block_size"), "{e}");
    // The functional model does not need the memory to fit.
    render(
        &volume,
        "class",
        Model::Step,
        &blocked(16, &["memory.rows=32"]),
    );
}

#[test]
fn bad_block_sizes_give_clear_errors() {
    // Configuration: not a power of two, out of range, smaller than bricks or sub-cubes,
    // a leaping structure stored in volume memory.
    for (list, field, text) in [
        (
            &["blocking.block_size=24"][..],
            "blocking.block_size",
            "power of two",
        ),
        (
            &["blocking.block_size=2"][..],
            "blocking.block_size",
            "power of two",
        ),
        (
            &["blocking.block_size=512"][..],
            "blocking.block_size",
            "power of two",
        ),
        (
            &["blocking.lookup_latency=65"][..],
            "blocking.lookup_latency",
            "out of range",
        ),
        (
            &[
                "blocking.enabled=true",
                "blocking.block_size=8",
                "bricks.size=16",
            ][..],
            "blocking.block_size",
            "smaller than bricks.size (16)",
        ),
        (
            &[
                "blocking.enabled=true",
                "blocking.block_size=8",
                "occupancy.subcube=16",
            ][..],
            "blocking.block_size",
            "smaller than occupancy.subcube (16)",
        ),
        (
            &["blocking.enabled=true", "occupancy.structure=distance"][..],
            "blocking.enabled",
            "map",
        ),
    ] {
        let e = HardwareConfig::load(None, &sets(list))
            .err()
            .unwrap_or_else(|| panic!("{list:?} accepted"))
            .to_string();
        assert!(e.contains(field) && e.contains(text), "{list:?}: {e}");
    }
    // A block size that does not divide the volume (48³, block 32): every model says so.
    let volume = phantom("phantom:metaballs:48");
    for model in [Model::Step, Model::Cycle] {
        let run = description(&volume, "class", model, &blocked(32, &[]));
        let e = prepare(&run, &volume).err().expect("rejected").to_string();
        assert!(
            e.contains("blocking.block_size") && e.contains("does not divide"),
            "{e}"
        );
        assert!(e.contains("48"), "{e}");
        assert!(e.contains("at most 16"), "{e}");
    }
    // 16 divides it.
    render(&volume, "class", Model::Cycle, &blocked(16, &[]));
    // An odd dimension: no power of two divides it, and the error does not ask for one.
    let e = vizsim::blocking::check_block_size(32, [103, 94, 161])
        .expect_err("rejected")
        .to_string();
    assert!(
        e.contains("no block size does") && !e.contains("use a block size"),
        "{e}"
    );
}

/// The section is written out only when not at its defaults, so run keys stay unchanged.
#[test]
fn the_blocking_section_is_written_only_when_set() {
    let default = HardwareConfig::default_config();
    let text = toml::to_string(&default).unwrap();
    assert!(!text.contains("blocking"), "{text}");
    let on = HardwareConfig::load(None, &blocked(16, &[])).unwrap();
    let text = toml::to_string(&on).unwrap();
    assert!(text.contains("[blocking]"), "{text}");
    let back = HardwareConfig::from_toml_str(&text, "round trip", &[]).unwrap();
    assert_eq!(back, on);
    assert_eq!(
        on.differences_from_default(),
        vec!["blocking.block_size = 16", "blocking.enabled = true"]
    );
}

/// A transfer function that shows density 0 (faintly) and hides 1..=150: a block whose values
/// all lie in 1..=150 classifies empty, but reading it as zero would show. So every block is
/// active then, and the image is still the unblocked one; without that rule some blocks of the
/// ball would be inactive.
#[test]
fn when_density_zero_is_visible_every_block_is_active() {
    let volume = common::ball(64);
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-blocking-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let tf_path = dir.join("zero-visible.toml");
    std::fs::write(
        &tf_path,
        "name = \"zero-visible\"\n\
         [[points]]\nvalue = 0\nrgba = [0.5, 0.5, 1, 0.02]\n\
         [[points]]\nvalue = 1\nrgba = [0, 0, 0, 0]\n\
         [[points]]\nvalue = 150\nrgba = [0, 0, 0, 0]\n\
         [[points]]\nvalue = 200\nrgba = [1, 0.5, 0.2, 0.8]\n",
    )
    .unwrap();
    let tf = tf_path.display().to_string();
    for model in [Model::Step, Model::Cycle] {
        let b = assert_blocked_equals_unblocked(
            &volume,
            &tf,
            model,
            8,
            &["compositing.ert=false"],
            false,
            "front",
        );
        let s = b.measurements.blocking.unwrap();
        assert_eq!(s.active_blocks, s.blocks, "{model:?}");
    }
    // The rule matters here: without it the class test alone leaves blocks inactive.
    let run = description(&volume, &tf, Model::Step, &blocked(8, &[]));
    let prepared = prepare(&run, &volume).unwrap();
    let table = &prepared.fixed().unwrap().table;
    assert!(table.any_visible(0, 0));
    let without_rule = BlockTable::build(&volume, OccupancyKind::Class, 3, false, |lo, hi| {
        table.any_visible(lo, hi)
    });
    assert!(
        without_rule.active < without_rule.blocks(),
        "{} of {}",
        without_rule.active,
        without_rule.blocks()
    );
}

/// The command line: `sim` of a volume too large without blocking fails with the hint and
/// writes nothing; with `--set blocking.enabled=true` it renders and prints and saves the
/// blocking figures.
#[test]
fn sim_says_blocking_makes_it_fit_and_reports_the_memory_saved() {
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-blocking-cli-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let png = dir.join("jet.png");
    let json = dir.join("jet.json");
    let _ = std::fs::remove_file(&png);
    let run = |extra: &[&str]| {
        let mut args = vec![
            "sim",
            "--dataset",
            "phantom:jet:128",
            "--size",
            "32x32",
            "--set",
            "memory.rows=128",
            "--set",
            "blocking.block_size=16",
            "-o",
            png.to_str().unwrap(),
            "--json",
            json.to_str().unwrap(),
        ];
        args.extend_from_slice(extra);
        std::process::Command::new(env!("CARGO_BIN_EXE_vizsim"))
            .args(&args)
            .output()
            .unwrap()
    };
    let out = run(&[]);
    let stderr = String::from_utf8_lossy(&out.stderr);
    assert!(!out.status.success());
    assert!(!stderr.contains("panicked"), "{stderr}");
    assert!(
        stderr.contains("does not fit without blocking")
            && stderr.contains("81 active blocks of 512"),
        "{stderr}"
    );
    assert!(!png.exists());
    let out = run(&["--set", "blocking.enabled=true"]);
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(
        stdout.contains("blocking: 81 of 512 blocks of 16³ active"),
        "{stdout}"
    );
    assert!(png.exists());
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(&json).unwrap()).unwrap();
    let b = &report["blocking"];
    assert_eq!(b["active_blocks"], 81);
    assert_eq!(b["rows_unblocked"], 256);
    assert!(b["rows_blocked"].as_u64().unwrap() <= 128);
    assert!(b["zero_samples"].as_u64().unwrap() > 0);
    assert_eq!(report["run"]["hardware"]["blocking"]["enabled"], true);
}

/// The lookup stage's `next_event` lets the clock jump only over cycles in which nothing can
/// happen: jumping equals ticking every cycle (with controllers that do not sleep), for lookup
/// latencies 0, 3 and 20, SDRAM and ideal memory.
#[test]
fn jumping_over_dead_cycles_equals_ticking_with_blocking() {
    use vizsim::arch::block_lookup::BlockLookup;
    use vizsim::arch::pipeline::simulate;
    use vizsim::arch::sdram_module::SdramMemory;
    use vizsim::arch::voxel_memory::IdealMemory;
    let volume = phantom("phantom:jet:64");
    for latency in [0u32, 3, 20] {
        let latency_set = format!("blocking.lookup_latency={latency}");
        let run = description(
            &volume,
            "class",
            Model::Cycle,
            &blocked(16, &[&latency_set]),
        );
        let prepared = prepare(&run, &volume).unwrap();
        let renderer = prepared.fixed().unwrap();
        let table = renderer.blocks.clone().unwrap();
        let camera = run.camera(&volume).unwrap();
        let config = &run.hardware;
        let sdram = |fast: bool| {
            let map = AddressMap::blocked(&config.memory, volume.dims, table.clone());
            let memory = SdramMemory::with_map(&config.memory, &config.sdram, map, 100.0);
            let memory = if fast {
                memory
            } else {
                memory.without_sleeping()
            };
            let mut memory = BlockLookup::new(memory, table.clone(), latency);
            let result = simulate(
                renderer,
                &camera,
                &renderer.skipper(),
                &mut memory,
                config,
                fast,
                None,
            )
            .unwrap();
            (result, memory.inner.module_stats(), memory.zero_samples)
        };
        let ((jumped, jm, jz), (ticked, tm, tz)) = (sdram(true), sdram(false));
        assert_eq!(
            jumped.stats.cycles, ticked.stats.cycles,
            "latency {latency}"
        );
        assert!(jumped.frame.pixels == ticked.frame.pixels);
        assert_eq!((jm, jz), (tm, tz), "latency {latency}");
        assert!(jz > 0);
        let ideal = |fast: bool| {
            let mut memory = BlockLookup::new(IdealMemory::new(6), table.clone(), latency);
            let result = simulate(
                renderer,
                &camera,
                &renderer.skipper(),
                &mut memory,
                config,
                fast,
                None,
            )
            .unwrap();
            result.stats.cycles
        };
        assert_eq!(ideal(true), ideal(false), "ideal, latency {latency}");
    }
}

/// When most blocks are active, their borders cost more rows than the inactive blocks save:
/// the summary says how much more, not a negative saving (found by probing: "-225.0 % saved").
#[test]
fn the_summary_says_how_much_more_memory_blocking_takes_when_it_saves_none() {
    let png = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-blocking-more-{}.png", std::process::id()));
    let out = std::process::Command::new(env!("CARGO_BIN_EXE_vizsim"))
        .args([
            "sim",
            "--dataset",
            "phantom:sphere:32",
            "--size",
            "8x8",
            "--set",
            "blocking.enabled=true",
            "--set",
            "blocking.block_size=8",
            "-o",
            png.to_str().unwrap(),
        ])
        .output()
        .unwrap();
    let stdout = String::from_utf8_lossy(&out.stdout);
    assert!(
        out.status.success(),
        "{}",
        String::from_utf8_lossy(&out.stderr)
    );
    let _ = std::fs::remove_file(&png);
    // 13 rows (106,496 words) against 4 (32,768 words) without blocking.
    assert!(
        stdout.contains("(4 without blocking: 32768 words, 225.0 % more)"),
        "{stdout}"
    );
    assert!(!stdout.contains("% saved"), "{stdout}");
    // And why: 8³ slots of 10³ voxels fill half a row, so 16 of the 64 blocks at most.
    assert!(
        stdout.contains("note: blocking costs more memory than it saves here")
            && stdout.contains("250 words per module in 1 row unit(s) of 512 (48.8 % used)")
            && stdout.contains("at most 16 of the 64 blocks active, and 50 are"),
        "{stdout}"
    );
}

/// `sim` says when the occupancy map and the block table together exceed the on-chip SRAM
/// (a review found a 491,520-bit table beside a 131,072-bit SRAM without a word), and says
/// nothing when they fit.
#[test]
fn sim_says_when_the_map_and_the_block_table_exceed_the_sram() {
    let sim = |sram: &str| {
        let out = std::process::Command::new(env!("CARGO_BIN_EXE_vizsim"))
            .args([
                "sim",
                "--dataset",
                "phantom:sphere:32",
                "--size",
                "8x8",
                "--subcube",
                "8",
                "--set",
                "blocking.enabled=true",
                "--set",
                "blocking.block_size=8",
                "--set",
                &format!("occupancy.sram_bits={sram}"),
            ])
            .output()
            .unwrap();
        assert!(
            out.status.success(),
            "{}",
            String::from_utf8_lossy(&out.stderr)
        );
        String::from_utf8_lossy(&out.stdout).into_owned()
    };
    // 64 blocks × (log2 of 64 slots + 1 valid bit) = 960 table bits, and 64 map bits.
    let small = sim("512");
    assert!(
        small.contains("table 960 bits on chip")
            && small.contains(
                "note: the occupancy map (64 bits) and the block table (960 bits) need 1024 \
                 bits on chip, more than occupancy.sram_bits (512)"
            ),
        "{small}"
    );
    let fits = sim("1024");
    assert!(!fits.contains("block table"), "{fits}");
}

/// An experiment's mode sets the leaping structure, the bricks and iso mode after its axes
/// were validated: crossed with blocking, each combination `sim` refuses is refused by the
/// sweep too, naming the run (a sweep reported cycles for blocked leap values, which read no
/// voxel memory for their leap words), and runs once [[exclude]]d.
#[test]
fn a_sweep_refuses_the_blocking_combinations_sim_refuses() {
    let text = |modes: &str, iso: &str, block: usize, exclude: &str| {
        format!(
            "name = \"blocking-modes\"\ndatasets = [\"phantom:sphere:32\"]\ntf = [\"class\"]\n\
             modes = [\"ert+leap8\", {modes}]\nmodels = [\"step\"]\n\
             [frames]\norbit = 72\nselect = [0]\nsize = \"16x16\"\n\
             [axes]\n\"blocking.enabled\" = [false, true]\n\"blocking.block_size\" = [{block}]\n\
             {iso}{exclude}"
        )
    };
    let cases = [
        (
            "\"ert+distance8\"",
            "",
            8,
            "occupancy.structure = \"map\" only",
        ),
        (
            "\"ert+leapvalues\"",
            "",
            8,
            "occupancy.structure = \"map\" only",
        ),
        (
            "\"ert+iso2\"",
            "\"iso.value\" = [100.0]\n",
            8,
            "not modelled in iso mode",
        ),
        (
            "\"ert+bricks16\"",
            "",
            8,
            "8 is smaller than bricks.size (16)",
        ),
    ];
    for (mode, iso, block, expected) in cases {
        let err = vizsim::experiment::spec::expand(&text(mode, iso, block, ""), "test", None)
            .err()
            .unwrap_or_else(|| panic!("{mode} with blocking was accepted"))
            .to_string();
        assert!(
            err.contains(expected)
                && err.contains(&format!("mode {}", mode.trim_matches('"')))
                && err.contains("blocking.enabled=true")
                && err.contains("[[exclude]]"),
            "{mode}: {err}"
        );
        let excluded = format!("[[exclude]]\nmode = {mode}\n\"blocking.enabled\" = true\n");
        let expansion =
            vizsim::experiment::spec::expand(&text(mode, iso, block, &excluded), "test", None)
                .unwrap_or_else(|e| panic!("{mode} excluded: {e}"));
        // ert+leap8 with and without blocking, the other mode without.
        assert_eq!(expansion.runs.len(), 3, "{mode}");
    }
}
