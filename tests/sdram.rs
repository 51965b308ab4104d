//! SDRAM timing rules (each illegal one cycle early, legal on time), closed-form latencies of a
//! module, the overtaking FIFO, and the cycle model with SDRAM against the functional model.

mod common;

use vizsim::arch::address_map::{AddressMap, Mapping, MemoryConfig, RowPolicy, WordAddress};
use vizsim::arch::pipeline::simulate;
use vizsim::arch::sdram::{read_path_rules, timing_rules, Command, SdramDevice, SdramTiming};
use vizsim::arch::sdram_module::{PendingWrite, SdramMemory, SdramModule};
use vizsim::camera::{Projection, View};
use vizsim::config::HardwareConfig;
use vizsim::functional::renderer::{FixedRenderer, Leaping};
use vizsim::occupancy::OccupancyKind;
use vizsim::render::RenderSettings;

fn timing() -> SdramTiming {
    HardwareConfig::default_config().sdram
}

fn memory_config() -> MemoryConfig {
    HardwareConfig::default_config().memory
}

/// `follow` is illegal at `at - 1` and legal at `at`, after `setup` ran on a fresh device.
fn assert_tight(setup: &[(Command, u64)], follow: Command, at: u64, rule: &str) {
    let mut d = SdramDevice::new(4, &timing());
    for &(cmd, t) in setup {
        d.issue(cmd, t);
    }
    assert!(!d.is_legal(follow, at - 1), "{rule}: legal one cycle early");
    assert!(d.is_legal(follow, at), "{rule}: illegal on time");
    assert_eq!(d.earliest(follow), at, "{rule}");
}

#[test]
fn every_timing_rule_is_tight() {
    let t = timing();
    let act = |bank, row| Command::Act { bank, row };
    let read = |bank| Command::Read { bank, column: 0 };
    let pre = |bank| Command::Pre { bank };
    let t0 = 10u64;
    let c = |x: u32| x as u64;
    assert_tight(
        &[(act(0, 1), t0)],
        read(0),
        t0 + c(t.t_rcd),
        "ACT->READ tRCD",
    );
    assert_tight(&[(act(0, 1), t0)], pre(0), t0 + c(t.t_ras), "ACT->PRE tRAS");
    assert_tight(
        &[(act(0, 1), t0)],
        act(1, 1),
        t0 + c(t.t_rrd),
        "ACT->ACT other bank tRRD",
    );
    // ACT->ACT same bank: tRC, and the bank must be closed again (PRE at tRAS; tRP after it).
    let pre_at = t0 + c(t.t_ras);
    assert_tight(
        &[(act(0, 1), t0), (pre(0), pre_at)],
        act(0, 2),
        (t0 + c(t.t_rc)).max(pre_at + c(t.t_rp)),
        "ACT->ACT same bank tRC / PRE->ACT tRP",
    );
    assert_tight(
        &[(act(0, 1), t0), (pre(0), pre_at)],
        Command::Ref,
        pre_at + c(t.t_rp),
        "PRE->REF tRP",
    );
    let read_at = t0 + c(t.t_rcd);
    assert_tight(
        &[
            (act(0, 1), t0),
            (act(1, 1), t0 + c(t.t_rrd)),
            (read(0), read_at + 2),
        ],
        read(1),
        read_at + 2 + c(t.t_ccd).max(1),
        "READ->READ tCCD",
    );
    assert_tight(
        &[(Command::Ref, t0)],
        act(2, 5),
        t0 + c(t.t_rfc),
        "REF->ACT tRFC",
    );
    assert_tight(
        &[(Command::Ref, t0)],
        Command::Ref,
        t0 + c(t.t_rfc),
        "REF->REF tRFC",
    );
    // READ->PRE (1 cycle) hides behind tRAS at PC100 timing: show it with a short tRAS.
    let mut short = t.clone();
    short.t_ras = 1;
    let mut d = SdramDevice::new(4, &short);
    d.issue(act(0, 1), t0);
    d.issue(read(0), t0 + c(t.t_rcd));
    assert!(!d.is_legal(pre(0), t0 + c(t.t_rcd)));
    assert_eq!(d.earliest(pre(0)), t0 + c(t.t_rcd) + 1, "READ->PRE");
    // The ten read-path rules of the table, each exercised above; the five write rules in
    // `every_write_timing_rule_is_tight`.
    assert_eq!(read_path_rules(&t).len(), 10);
    assert_eq!(timing_rules(&t).len(), 15);
}

#[test]
fn every_write_timing_rule_is_tight() {
    let t = timing();
    let act = |bank, row| Command::Act { bank, row };
    let read = |bank| Command::Read { bank, column: 0 };
    let write = |bank| Command::Write { bank, column: 3 };
    let pre = |bank| Command::Pre { bank };
    let t0 = 10u64;
    let c = |x: u32| x as u64;
    assert_tight(
        &[(act(0, 1), t0)],
        write(0),
        t0 + c(t.t_rcd),
        "ACT->WRITE tRCD",
    );
    let w = t0 + 20; // every ACT rule long satisfied
    assert_tight(
        &[(act(0, 1), t0), (act(1, 1), t0 + 5), (write(0), w)],
        write(1),
        w + c(t.t_ccd),
        "WRITE->WRITE tCCD (data bus)",
    );
    assert_tight(
        &[(act(0, 1), t0), (write(0), w)],
        pre(0),
        w + c(t.t_wr),
        "WRITE->PRE tWR",
    );
    assert_tight(
        &[(act(0, 1), t0), (act(1, 1), t0 + 5), (write(0), w)],
        read(1),
        w + c(t.t_wtr),
        "WRITE->READ tWTR",
    );
    assert_tight(
        &[(act(0, 1), t0), (act(1, 1), t0 + 5), (read(0), w)],
        write(1),
        w + c(t.t_rtw),
        "READ->WRITE tRTW",
    );
    // Each rule at a longer setting, so none hides behind another or the command bus.
    let mut long = t.clone();
    (long.t_wr, long.t_wtr, long.t_rtw, long.t_ccd) = (6, 5, 7, 3);
    let tight_with = |setup: &[(Command, u64)], follow: Command, at: u64, rule: &str| {
        let mut d = SdramDevice::new(4, &long);
        for &(cmd, when) in setup {
            d.issue(cmd, when);
        }
        assert!(!d.is_legal(follow, at - 1), "{rule}: legal one cycle early");
        assert!(d.is_legal(follow, at), "{rule}: illegal on time");
    };
    let both = [(act(0, 1), t0), (act(1, 1), t0 + 5)];
    tight_with(&[both[0], (write(0), w)], pre(0), w + 6, "tWR 6");
    tight_with(&[both[0], both[1], (write(0), w)], read(1), w + 5, "tWTR 5");
    tight_with(&[both[0], both[1], (read(0), w)], write(1), w + 7, "tRTW 7");
    tight_with(
        &[both[0], both[1], (write(0), w)],
        write(1),
        w + 3,
        "tCCD 3",
    );
    // State: a WRITE needs its bank's row open.
    let d = SdramDevice::new(4, &t);
    assert!(!d.is_legal(write(0), 100), "WRITE on a closed bank");
}

#[test]
fn write_timing_is_validated_and_optional_in_files() {
    let err = HardwareConfig::load(None, &["sdram.t_wr=0".into()])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("sdram.t_wr") && err.contains("1..=64"),
        "{err}"
    );
    let err = HardwareConfig::load(None, &["sdram.t_rtw=2".into()])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("sdram.t_rtw") && err.contains("cl + 1"),
        "{err}"
    );
    // A CAS latency at the fields' bound leaves t_rtw (> cl, <= 64) no value: the error names
    // cl and a range that exists (it said `sdram.t_rtw` ... "allowed cl + 1 (65)..=64").
    let err = HardwareConfig::load(None, &["sdram.cl=64".into()])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("field `sdram.cl`") && err.contains("sdram.t_rtw") && err.contains("1..=63"),
        "{err}"
    );
    assert!(!err.contains("(65)"), "{err}");
    // Below the bound, t_rtw is still what is too small, and the message says which cl.
    let err = HardwareConfig::load(None, &["sdram.cl=40".into()])
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("field `sdram.t_rtw`")
            && err.contains("sdram.cl = 40")
            && err.contains("(41)..=64"),
        "{err}"
    );
    for field in ["memory.host_link_bits=0", "memory.host_link_mhz=0.0"] {
        let err = HardwareConfig::load(None, &[field.into()])
            .unwrap_err()
            .to_string();
        let name = field.split('=').next().unwrap();
        assert!(err.contains(name) && err.contains("zero"), "{err}");
    }
    // A file without the new fields (an older configuration) reads with the defaults, and the
    // resolved configuration serialises without them: run keys are unchanged.
    let old: String = vizsim::config::DEFAULT_TOML
        .lines()
        .filter(|l| {
            !["t_wr", "t_wtr", "t_rtw", "host_link_"]
                .iter()
                .any(|f| l.starts_with(f))
        })
        .map(|l| format!("{l}\n"))
        .collect();
    let config = HardwareConfig::from_toml_str(&old, "old.toml", &[]).unwrap();
    assert_eq!(config, HardwareConfig::default_config());
    let json = serde_json::to_string(&config).unwrap();
    for field in ["t_wr", "t_wtr", "t_rtw", "host_link"] {
        assert!(!json.contains(field), "{field} in {json}");
    }
    assert_eq!(config.memory.host_link_bytes_per_second(), 132e6);
}

/// Runs a module until its FIFOs are empty; returns the last cycle stepped.
fn drain(m: &mut SdramModule, from: u64) -> u64 {
    for now in from..from + 10_000 {
        m.step_with_writes(now);
        m.pop_word(now);
        if m.is_idle() {
            return now;
        }
    }
    panic!("module never idle");
}

#[test]
fn writes_store_their_data_and_cost_what_the_timing_says() {
    let mut t = timing();
    t.refresh = false;
    let config = memory_config();
    let mut m = SdramModule::new(&config, &t).with_image(config.banks, 4, config.columns);
    let word = |bank, row, column, data, mask| PendingWrite {
        addr: WordAddress {
            module: 0,
            bank,
            row,
            column,
        },
        data,
        mask,
    };
    // Closed bank: pushed at 0, seen at 1: ACT at 1, WRITE at 1 + tRCD.
    m.push_write(word(0, 2, 5, 0x0011_0022, 3), 0);
    let done = drain(&mut m, 1);
    assert_eq!(
        done,
        1 + t.t_rcd as u64,
        "closed bank: ACT then WRITE tRCD later"
    );
    // Byte masks: only the high half changes.
    m.push_write(word(0, 2, 5, 0x0077_0099, 2), done);
    let hit = drain(&mut m, done + 1);
    assert_eq!(hit, done + 1, "row hit: WRITE the cycle it is seen");
    let image = m.image().unwrap();
    assert_eq!(image.word(word(0, 2, 5, 0, 0).addr), 0x0077_0022);
    // A write to another row of the bank: PRE waits for tWR after the last WRITE.
    m.push_write(word(0, 3, 0, 1, 1), hit);
    let conflict = drain(&mut m, hit + 1);
    assert_eq!(
        conflict,
        (hit + t.t_wr as u64).max(hit + 1) + (t.t_rp + t.t_rcd) as u64,
        "row conflict: tWR, then tRP + tRCD"
    );
    let stats = m.final_stats();
    assert_eq!((stats.writes, stats.write_row_misses), (3, 2));
    // Reads go first; a write after a read waits for tRTW.
    m.push(9, addr(0, 3), conflict);
    m.push_write(word(0, 3, 1, 1, 1), conflict);
    let mut read_at = None;
    for now in conflict + 1..conflict + 100 {
        m.step_with_writes(now);
        if let Some(c) = m.issued_at(now) {
            match c.kind {
                vizsim::arch::sdram::CommandKind::Read => read_at = Some(now),
                vizsim::arch::sdram::CommandKind::Write => {
                    assert_eq!(now, read_at.unwrap() + t.t_rtw as u64, "READ->WRITE tRTW");
                    return;
                }
                k => panic!("unexpected {k:?}"),
            }
        }
        m.pop_word(now);
    }
    panic!("no WRITE");
}

#[test]
fn state_rules_and_the_command_bus() {
    let mut d = SdramDevice::new(4, &timing());
    assert!(
        !d.is_legal(Command::Read { bank: 0, column: 0 }, 100),
        "READ on a closed bank"
    );
    d.issue(Command::Act { bank: 0, row: 3 }, 100);
    assert!(
        !d.is_legal(Command::Act { bank: 0, row: 4 }, 200),
        "ACT on an open bank"
    );
    assert!(!d.is_legal(Command::Ref, 200), "REF with a bank open");
    // One command per cycle per module: nothing else at 100.
    assert!(!d.is_legal(Command::Act { bank: 3, row: 1 }, 100));
}

/// A sleeping module against one whose controller decides every cycle, on random requests over
/// 4 banks and 3 rows, in bursts with quiet stretches between: the same command and the same
/// word every cycle and the same statistics, with and without overtaking, a voxel FIFO that
/// fills, both row policies, a READ-to-READ gap, and frequent refreshes with a 3-deep address
/// FIFO.
#[test]
fn sleeping_equals_ticking_on_random_requests() {
    for case in 0..6 {
        let mut config = memory_config();
        let mut t = timing();
        match case {
            1 => config.overtaking = false,
            2 => config.voxel_fifo_depth = 2,
            3 => config.row_policy = RowPolicy::Close,
            4 => t.t_ccd = 2,
            5 => {
                t.refresh_interval = 40;
                config.address_fifo_depth = 3;
            }
            _ => {}
        }
        let mut fast = SdramModule::new(&config, &t);
        let mut reference = SdramModule::new(&config, &t).without_sleeping();
        let mut state = 0x2545_f491_4f6c_dd1du64 + case;
        let mut next = |n: u64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state % n
        };
        let mut tag = 0;
        for now in 0..30_000u64 {
            fast.step(now);
            reference.step(now);
            assert_eq!(
                fast.issued_at(now),
                reference.issued_at(now),
                "case {case}, cycle {now}"
            );
            assert_eq!(
                fast.pop_word(now),
                reference.pop_word(now),
                "case {case}, cycle {now}"
            );
            assert_eq!(fast.can_accept(), reference.can_accept());
            // Bursts of pushes, then quiet stretches in which the modules drain and sleep.
            if (now / 500) % 4 != 3 && next(4) != 0 && fast.can_accept() {
                tag += 1;
                let addr = WordAddress {
                    module: 0,
                    bank: next(4) as u32,
                    row: next(3) as u32,
                    column: next(512) as u32,
                };
                fast.push(tag, addr, now);
                reference.push(tag, addr, now);
            }
            fast.account_cycles(1);
            reference.account_cycles(1);
        }
        let stats = fast.final_stats();
        assert_eq!(stats, reference.final_stats(), "case {case}");
        assert!(
            stats.reads > 2_000 && stats.row_misses > 500,
            "case {case}: {stats:?}"
        );
    }
}

/// Cycles from pushing one request at cycle 0 to its word leaving the module.
fn isolated_latency(prepare: impl Fn(&mut SdramModule) -> u64, addr: WordAddress) -> u64 {
    let mut t = timing();
    t.refresh = false;
    let mut m = SdramModule::new(&memory_config(), &t);
    let start = prepare(&mut m);
    m.push(7, addr, start);
    for now in start + 1..start + 100 {
        m.step(now);
        if let Some(tag) = m.pop_word(now) {
            assert_eq!(tag, 7);
            return now - start;
        }
    }
    panic!("no data");
}

fn addr(bank: u32, row: u32) -> WordAddress {
    WordAddress {
        module: 0,
        bank,
        row,
        column: 0,
    }
}

#[test]
fn isolated_accesses_cost_what_the_timing_says() {
    let t = timing();
    // The address FIFO adds one cycle: a request pushed at t is seen at t + 1.
    let hit = isolated_latency(
        |m| {
            m.push(1, addr(0, 5), 0);
            (1..40).for_each(|now| {
                m.step(now);
                m.pop_word(now);
            });
            40
        },
        addr(0, 5),
    );
    assert_eq!(hit, 1 + t.cl as u64, "row hit");
    let closed = isolated_latency(|_| 0, addr(0, 5));
    assert_eq!(
        closed,
        1 + (t.t_rcd + t.cl) as u64,
        "closed bank: tRCD + CL"
    );
    let conflict = isolated_latency(
        |m| {
            m.push(1, addr(0, 9), 0);
            (1..40).for_each(|now| {
                m.step(now);
                m.pop_word(now);
            });
            40
        },
        addr(0, 5),
    );
    assert_eq!(
        conflict,
        1 + (t.t_rp + t.t_rcd + t.cl) as u64,
        "row conflict: tRP + tRCD + CL"
    );
}

#[test]
fn streaming_row_hits_deliver_one_word_per_cycle() {
    let mut t = timing();
    t.refresh = false;
    let mut m = SdramModule::new(&memory_config(), &t);
    let n = 200u64;
    let (mut pushed, mut got, mut last) = (0u64, 0u64, 0u64);
    for now in 0..1000 {
        m.step(now);
        if m.pop_word(now).is_some() {
            got += 1;
            last = now;
        }
        if pushed < n && m.can_accept() {
            m.push(
                pushed as u32,
                WordAddress {
                    module: 0,
                    bank: 0,
                    row: 3,
                    column: pushed as u32,
                },
                now,
            );
            pushed += 1;
        }
    }
    assert_eq!(got, n);
    // First word after ACT (tRCD) and CL, then one per cycle.
    assert_eq!(last, 1 + (t.t_rcd + t.cl) as u64 + (n - 1), "stream end");
}

#[test]
fn refresh_happens_every_interval_and_costs_its_time() {
    let t = timing();
    let mut m = SdramModule::new(&memory_config(), &t);
    let cycles = 20_000u64;
    for now in 0..cycles {
        m.step(now);
    }
    let expected = cycles / t.refresh_interval as u64;
    assert_eq!(m.final_stats().refreshes, expected);
    let mut off = t.clone();
    off.refresh = false;
    let mut m = SdramModule::new(&memory_config(), &off);
    (0..cycles).for_each(|now| m.step(now));
    assert_eq!(m.final_stats().refreshes, 0);
}

/// Two rows of one bank interleaved, A B A B ...: overtaking groups them.
fn ping_pong(overtaking: bool) -> (u64, Vec<u32>, u32) {
    let mut config = memory_config();
    config.overtaking = overtaking;
    let mut t = timing();
    t.refresh = false;
    let mut m = SdramModule::new(&config, &t);
    let n = 64u32;
    let mut order = Vec::new();
    let mut pushed = 0;
    for now in 0..5000 {
        m.step(now);
        if let Some(tag) = m.pop_word(now) {
            order.push(tag);
        }
        if pushed < n && m.can_accept() {
            m.push(
                pushed,
                WordAddress {
                    module: 0,
                    bank: 1,
                    row: pushed % 2,
                    column: pushed,
                },
                now,
            );
            pushed += 1;
        }
    }
    assert_eq!(order.len(), n as usize);
    // Largest displacement of a request towards the back: how often it was overtaken at most.
    let max_late = order
        .iter()
        .enumerate()
        .map(|(pos, &tag)| pos.saturating_sub(tag as usize) as u32)
        .max()
        .unwrap();
    (m.final_stats().row_misses, order, max_late)
}

#[test]
fn overtaking_saves_row_misses_within_the_bypass_bound() {
    let (misses_plain, order_plain, _) = ping_pong(false);
    let (misses_overtaking, _, max_late) = ping_pong(true);
    assert!(
        misses_overtaking * 2 < misses_plain,
        "{misses_overtaking} vs {misses_plain}"
    );
    assert_eq!(
        order_plain,
        (0..64).collect::<Vec<_>>(),
        "disabled: request order"
    );
    assert!(
        max_late <= memory_config().max_bypass,
        "a request overtaken {max_late} times"
    );
}

#[test]
fn mappings_touch_one_word_per_module_and_check_capacity() {
    for (mapping, words) in [
        (Mapping::Replicated4, 4),
        (Mapping::Interleaved8, 8),
        (Mapping::Linear4, 4),
    ] {
        let mut config = memory_config();
        config.mapping = mapping;
        let map = AddressMap::new(&config, [64, 64, 64]);
        let (w, n) = map.sample_words([11, 20, 33]);
        assert_eq!(n, words, "{mapping:?}");
        let mut modules: Vec<u32> = w[..n].iter().map(|a| a.module).collect();
        modules.sort();
        modules.dedup();
        assert_eq!(modules.len(), words, "{mapping:?}: distinct modules");
    }
    // replicated4, 8x8x8-word blocks: a 16x16x8-voxel neighbourhood lies in one row per module.
    let map = AddressMap::new(&memory_config(), [64, 64, 64]);
    let mut rows = std::collections::HashSet::new();
    for z in 0..7 {
        for y in (0..15).step_by(3) {
            for x in (0..15).step_by(3) {
                let (w, n) = map.sample_words([x, y, z]);
                for a in &w[..n] {
                    rows.insert((a.module, a.bank, a.row));
                }
            }
        }
    }
    assert_eq!(rows.len(), 4);
    let mut small = memory_config();
    small.rows = 2;
    let err = small
        .check_covers([256, 256, 256], "test")
        .unwrap_err()
        .to_string();
    assert!(err.contains("memory.rows"), "{err}");
    let mut bad = memory_config();
    bad.address_fifo_depth = 0;
    assert!(bad
        .validate("t")
        .unwrap_err()
        .to_string()
        .contains("memory.address_fifo_depth"));
    bad = memory_config();
    bad.banks = 3;
    assert!(bad
        .validate("t")
        .unwrap_err()
        .to_string()
        .contains("memory.banks"));
    bad = memory_config();
    bad.overtaking_window = 17;
    assert!(bad
        .validate("t")
        .unwrap_err()
        .to_string()
        .contains("memory.overtaking_window"));
    bad = memory_config();
    bad.row_policy = RowPolicy::Close;
    bad.validate("t").unwrap();
}

#[test]
fn cycle_model_with_sdram_equals_the_functional_image() {
    let volume = common::ball(48);
    let tf = common::tf(&[
        (0.0, [0.0; 4]),
        (60.0, [0.0; 4]),
        (200.0, [1.0, 0.8, 0.2, 0.8]),
    ]);
    let mut config = HardwareConfig::default_config();
    config.occupancy.sram_bits = 1 << 24;
    for (view, projection, leaping, policy, overtaking) in [
        (
            View::Front,
            Projection::Ortho,
            Leaping::None,
            RowPolicy::Open,
            true,
        ),
        (
            View::Orbit { k: 7, n: 72 },
            Projection::Persp,
            Leaping::Occupancy {
                subcube: 4,
                hierarchy: true,
                kind: OccupancyKind::Class,
            },
            RowPolicy::Close,
            false,
        ),
    ] {
        config.memory.row_policy = policy;
        config.memory.overtaking = overtaking;
        let cam = common::camera(&volume, view.clone(), projection, 32);
        let renderer =
            FixedRenderer::new(&volume, &tf, &RenderSettings::default(), &config, leaping).unwrap();
        // Fast: the clock jumps over dead cycles and idle controllers sleep. Reference: every
        // unit steps every cycle.
        let run = |fast: bool| {
            let memory = SdramMemory::new(&config.memory, &config.sdram, volume.dims, 100.0);
            let mut memory = if fast {
                memory
            } else {
                memory.without_sleeping()
            };
            let result = simulate(
                &renderer,
                &cam,
                &renderer.skipper(),
                &mut memory,
                &config,
                fast,
                None,
            )
            .unwrap();
            (result, memory.module_stats())
        };
        let ((jumped, fast_modules), (ticked, ticked_modules)) = (run(true), run(false));
        assert_eq!(
            fast_modules, ticked_modules,
            "sleeping controllers equal ticking"
        );
        for m in &fast_modules {
            let total = |h: &[u64]| h.iter().sum::<u64>();
            assert_eq!(total(&m.address_fifo_occupancy), jumped.stats.cycles);
            assert_eq!(total(&m.voxel_fifo_occupancy), jumped.stats.cycles);
            assert!(m.busy_cycles > 0 && m.busy_cycles < jumped.stats.cycles);
            // The memory lower bound: every sample reads one word per module, and a module's
            // command bus carries one command per cycle.
            assert_eq!(m.reads, jumped.stats.samples);
            let commands = m.reads + m.activates + m.precharges + m.refreshes;
            assert!(
                jumped.stats.cycles >= commands,
                "{} cycles < {commands} commands on one module",
                jumped.stats.cycles
            );
            assert!(m.activates >= m.row_misses && m.row_hits + m.row_misses == m.reads);
        }
        assert!(
            jumped.frame.pixels == renderer.render(&cam).pixels,
            "{view:?} {policy:?}"
        );
        let mut a = jumped.stats.clone();
        a.skipped_cycles = 0;
        assert_eq!(a, ticked.stats, "jumping equals ticking with SDRAM");
        assert!(jumped.stats.stall_cycles.memory > 0 || jumped.stats.cycles > jumped.stats.steps);
    }
}

#[test]
fn waveform_records_its_window_and_changes_no_result() {
    use vizsim::arch::trace::Waveform;
    let volume = common::ball(32);
    let tf = common::tf(&[
        (0.0, [0.0; 4]),
        (60.0, [0.0; 4]),
        (200.0, [1.0, 0.8, 0.2, 0.8]),
    ]);
    let config = HardwareConfig::default_config();
    let cam = common::camera(&volume, View::Orbit { k: 3, n: 72 }, Projection::Ortho, 24);
    let renderer = FixedRenderer::new(
        &volume,
        &tf,
        &RenderSettings::default(),
        &config,
        Leaping::None,
    )
    .unwrap();
    let dir = std::path::Path::new(env!("CARGO_TARGET_TMPDIR"))
        .join(format!("vizsim-vcd-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("frame.vcd");
    let run = |waveform: Option<&mut Waveform>| {
        let mut memory = SdramMemory::new(&config.memory, &config.sdram, volume.dims, 100.0);
        simulate(
            &renderer,
            &cam,
            &renderer.skipper(),
            &mut memory,
            &config,
            true,
            waveform,
        )
        .unwrap()
    };
    let mut waveform = Waveform::create(&path, 4, 100..400).unwrap();
    let traced = run(Some(&mut waveform));
    waveform.finish().unwrap();
    let plain = run(None);
    assert_eq!(traced.stats.cycles, plain.stats.cycles);
    assert_eq!(traced.stats.composited, plain.stats.composited);
    assert!(traced.frame.pixels == plain.frame.pixels);
    let text = std::fs::read_to_string(&path).unwrap();
    for signal in [
        "ray_queue_occupancy",
        "issue_valid",
        "compositing_buffer",
        "ert_event",
        "module3",
        "command",
        "address_fifo",
    ] {
        assert!(text.contains(signal), "missing {signal}");
    }
    // 100 MHz: 1 ns timescale, a rising and a falling clock edge per cycle (10 ns apart), and
    // the rising edge that ends the window.
    assert!(text.contains("$timescale 1 ns $end"));
    let stamps: Vec<u64> = text
        .lines()
        .filter_map(|l| l.strip_prefix('#'))
        .map(|t| t.parse().unwrap())
        .collect();
    assert_eq!(stamps.first(), Some(&1000));
    assert_eq!(stamps.last(), Some(&4000));
    assert_eq!(stamps.len(), 2 * 300 + 1, "every cycle of the window");
    let files: Vec<_> = std::fs::read_dir(&dir).unwrap().collect();
    assert_eq!(files.len(), 1, "no temporary file left");
}

/// Lagging-first selection keeps the rays in flight side by side, so on an oblique view their
/// samples share rows: more row hits and fewer cycles than round-robin, the same image.
#[test]
fn lagging_first_keeps_rays_together_in_memory() {
    use vizsim::config::RaySelection;
    let volume = common::uniform([128, 128, 128], 100);
    let tf = common::tf(&[(0.0, [0.0; 4]), (255.0, [1.0, 1.0, 1.0, 0.01])]);
    let cam = common::camera(&volume, View::Orbit { k: 5, n: 72 }, Projection::Ortho, 48);
    let mut config = HardwareConfig::default_config();
    config.compositing.ert = false;
    let renderer = FixedRenderer::new(
        &volume,
        &tf,
        &RenderSettings {
            ert_threshold: None,
            ..RenderSettings::default()
        },
        &config,
        Leaping::None,
    )
    .unwrap();
    let run = |selection| {
        let mut config = config.clone();
        config.ray_queue.selection = selection;
        let mut memory = SdramMemory::new(&config.memory, &config.sdram, volume.dims, 100.0);
        let r = simulate(
            &renderer,
            &cam,
            &renderer.skipper(),
            &mut memory,
            &config,
            true,
            None,
        )
        .unwrap();
        let m = memory.module_stats();
        let hits: u64 = m.iter().map(|s| s.row_hits).sum();
        let reads: u64 = m.iter().map(|s| s.reads).sum();
        (r, hits as f64 / reads as f64)
    };
    let (round_robin, rr_hits) = run(RaySelection::RoundRobin);
    let (lagging, lf_hits) = run(RaySelection::LaggingFirst);
    eprintln!("row hits: lagging-first {lf_hits:.3}, round-robin {rr_hits:.3}");
    assert!(lagging.frame.pixels == round_robin.frame.pixels);
    assert!(
        lf_hits > rr_hits + 0.1 && lf_hits > 0.9,
        "row hits: lagging-first {lf_hits:.3}, round-robin {rr_hits:.3}"
    );
    assert!(lagging.stats.cycles < round_robin.stats.cycles);
}

/// Random requests to many rows keep a module busy with misses: at the shortest refresh
/// interval validation allows (`longest_refresh_wait`, checked here against the formula
/// written out per case), every refresh interval serves at least one READ, for several timing
/// tables and bank counts; one cycle shorter is refused. (Random traffic does not starve at the
/// old bound either; the whole frame below does.)
#[test]
fn the_shortest_allowed_refresh_interval_still_reads() {
    let min_reads_per_interval = |config: &MemoryConfig, t: &SdramTiming| {
        let mut m = SdramModule::new(config, t);
        let mut state = 0x9e37_79b9_7f4a_7c15u64;
        let mut next = |n: u64| {
            state ^= state << 13;
            state ^= state >> 7;
            state ^= state << 17;
            state % n
        };
        let interval = t.refresh_interval as u64;
        let mut reads = vec![0u64; (20_000 / interval) as usize];
        for now in 0..interval * reads.len() as u64 {
            m.step(now);
            if m.issued_at(now)
                .is_some_and(|c| c.kind == vizsim::arch::sdram::CommandKind::Read)
            {
                reads[(now / interval) as usize] += 1;
            }
            m.pop_word(now);
            if m.can_accept() {
                let addr = WordAddress {
                    module: 0,
                    bank: next(config.banks as u64) as u32,
                    row: next(64) as u32,
                    column: next(512) as u32,
                };
                m.push(now as u32, addr, now);
            }
            m.account_cycles(1);
        }
        // The first interval starts with the module empty.
        reads[1..].iter().copied().min().unwrap()
    };
    // (banks, t_ras, t_rp, t_rfc, t_rcd, t_rc, the bound written out)
    for (banks, t_ras, t_rp, t_rfc, t_rcd, t_rc, bound) in [
        (4, 5, 2, 7, 2, 7, 5 + 3 + 2 + 7 + 2),
        (1, 5, 2, 7, 2, 7, 5 + 2 + 7 + 2),
        (16, 5, 2, 7, 2, 7, 5 + 15 + 2 + 7 + 2),
        (4, 9, 3, 10, 4, 12, 9 + 3 + 3 + 10 + 4),
        (4, 2, 1, 1, 2, 40, 40 + 2),
    ] {
        let mut config = memory_config();
        config.banks = banks;
        let mut t = timing();
        (t.t_ras, t.t_rp, t.t_rfc, t.t_rcd, t.t_rc) = (t_ras, t_rp, t_rfc, t_rcd, t_rc);
        assert_eq!(t.longest_refresh_wait(banks), bound);
        t.refresh_interval = bound;
        t.validate("t", banks).unwrap();
        let fewest = min_reads_per_interval(&config, &t);
        assert!(
            fewest >= 1,
            "banks {banks}, {t:?}: an interval without a READ"
        );
        t.refresh_interval -= 1;
        let err = t.validate("t", banks).unwrap_err().to_string();
        assert!(err.contains("sdram.refresh_interval"), "{err}");
    }
    // A whole frame: at the default timing's t_ras + t_rp + t_rfc = 14 (accepted before the
    // bound) a refresh falls due between every ACT and its READ, and the pipeline's watchdog
    // stops the run; at the bound (19 with 4 banks) the frame completes.
    let volume = common::ball(24);
    let tf = common::tf(&[
        (0.0, [0.0; 4]),
        (60.0, [0.0; 4]),
        (200.0, [1.0, 0.8, 0.2, 0.8]),
    ]);
    let mut config = HardwareConfig::default_config();
    let renderer = FixedRenderer::new(
        &volume,
        &tf,
        &RenderSettings::default(),
        &config,
        Leaping::None,
    )
    .unwrap();
    let cam = common::camera(&volume, View::Front, Projection::Ortho, 16);
    let mut frame = |interval: u32| {
        config.sdram.refresh_interval = interval;
        let mut memory = SdramMemory::new(&config.memory, &config.sdram, volume.dims, 100.0);
        simulate(
            &renderer,
            &cam,
            &renderer.skipper(),
            &mut memory,
            &config,
            true,
            None,
        )
    };
    let t = timing();
    let err = match frame(t.t_ras + t.t_rp + t.t_rfc) {
        Ok(_) => panic!("the frame at interval 14 completed"),
        Err(e) => e.to_string(),
    };
    assert!(err.contains("deadlock"), "{err}");
    let bound = t.longest_refresh_wait(memory_config().banks);
    assert_eq!(bound, 19);
    assert!(frame(bound).unwrap().stats.cycles > 0);
}
