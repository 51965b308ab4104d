//! Sampled simulation (issue 18, part 2; docs/sampling.md): time a sample of the frame in
//! detail and estimate the frame's cycles with a 95 % confidence interval.
//!
//! The frame's rays, in the pipeline's issue order (tiles), are cut into **units** of
//! `unit_rays` consecutive rays. The first and the last unit are always simulated (the frame's
//! fill and drain); the units between them are split into n equal **strata** of about 1/rate
//! units each and one unit per stratum is simulated, at a pseudo-random place in its stratum
//! fixed by the run's seed (jittered systematic sampling: one unit every ~1/rate, but never in
//! step with the image's rows). Each sampled unit is simulated after a **detailed warm-up** of
//! the `warmup_rays` rays before it, whose cycles are not measured, in a fresh pipeline and
//! memory whose refresh counter starts at a pseudo-random phase (`Warm`); sampled units close
//! enough to share rays are simulated in one segment.
//!
//! A unit's cycles are the cycles between the admissions of its first ray and of the next
//! unit's first ray to the ray queue (`pipeline::Checkpoints`); over all units they add up to
//! the frame's cycles exactly, and a segment stops at the next unit's admission. The middle
//! units' cycles are estimated by a **ratio estimator**: cycles per unit of work issued in the
//! sampled windows (steps, plus rays that miss the volume) times the middle units' work, known
//! from the functional model. The 95 % interval comes from the residuals between strata
//! (successive differences or simple random sampling, the larger), plus an allowance for the
//! warm-up's bias. When every middle unit is measured (rate 1, or a frame of few units) their
//! counters are summed instead: the frame's exactly, with no interval. A frame of fewer than
//! `MIN_SAMPLED_UNITS` units is simulated whole so.

use std::ops::Range;

use rayon::prelude::*;
use serde::{Deserialize, Serialize};
use serde_json::Value;

use super::pipeline::{Checkpoint, Checkpoints, CycleStats, StallCycles};
use crate::error::{Error, Result};

/// Rays per sampling unit: 16 tiles of the default 4×2 (docs/sampling.md: why this size).
pub const DEFAULT_UNIT_RAYS: usize = 128;
/// Rays simulated before a sampled unit to warm the pipeline and the memory, unmeasured: one
/// ray queue's worth at the default R = 16 (docs/sampling.md: 0 to 128 were measured; below 16
/// the estimate was biased low, from 16 on the bias was within the sample's noise).
pub const DEFAULT_WARMUP_RAYS: usize = 16;
/// The fewest units a frame must have to be sampled: a frame with fewer is simulated whole (every
/// unit measured, the exact cycles). Sampling was validated on 256×256 frames (512 units); on
/// smaller ones the estimates fell low (by 1.1–1.3 % on average at 128×128 and 192×192, 4 % at
/// 64×64) and their intervals covered 85–90 % of the exact figures; the exact simulation of such
/// a frame takes a second or less (docs/sampling.md, "Limits").
pub const MIN_SAMPLED_UNITS: usize = 512;
/// The fewest strata a sampled frame is cut into, whatever the rate: the interval rests on the
/// spread of one unit per stratum, and a handful can agree by chance (2 strata gave ±2 % about
/// an estimate 4.8× too high). The validated rate 0.05 gives 26 at 256×256.
pub const MIN_STRATA: usize = 20;
/// The warm-up before a sampled unit when a ray waits for its own reads before each step (a
/// distance volume's word): the rays then drift far apart under lagging-first, and 16 rays of
/// history rebuild too little of that (estimates 8–15 % low, outside their intervals, on
/// neghip at 256×256); 256 rays brought every one of 48 runs inside (docs/sampling.md).
pub const LONG_WARMUP_RAYS: usize = 256;
/// Relative allowance for the warm-up's bias, added to the interval in quadrature (scaled by
/// the share of middle units not simulated): calibrated with the 16-ray warm-up on half of the
/// validation runs so that 95 % of them were covered, checked on the other half
/// (docs/sampling.md).
pub const DEFAULT_BIAS_ALLOWANCE: f64 = 0.025;

/// How a cycle-model run samples its frame (`vizsim sim --sample RATE`, `sample = RATE` in an
/// experiment file). Part of the run's key.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct Sampling {
    /// Share of the units between the first and the last that are simulated, in (0, 1];
    /// 1 simulates every unit (the exact simulation).
    pub rate: f64,
    /// Rays per unit, in issue order.
    pub unit_rays: usize,
    /// Rays simulated, unmeasured, before each sampled unit.
    pub warmup_rays: usize,
    /// Relative allowance for the warm-up's bias in the interval.
    pub bias_allowance: f64,
}

impl Sampling {
    /// A sampling at `rate` with the default unit and warm-up; `source` names where the rate
    /// came from in the error (`--sample`, an experiment's `sample`).
    pub fn new(rate: f64, source: &str) -> Result<Sampling> {
        let sampling = Sampling {
            rate,
            unit_rays: DEFAULT_UNIT_RAYS,
            warmup_rays: DEFAULT_WARMUP_RAYS,
            bias_allowance: DEFAULT_BIAS_ALLOWANCE,
        };
        sampling.validate(source)?;
        Ok(sampling)
    }

    pub fn validate(&self, source: &str) -> Result<()> {
        if !(self.rate.is_finite() && self.rate > 0.0 && self.rate <= 1.0) {
            return Err(Error::Invalid(format!(
                "{source} {:?}: the sampling rate must be a number in (0, 1], e.g. 0.05 (1 = \
                 every unit, the exact simulation)",
                self.rate
            )));
        }
        if !(self.bias_allowance.is_finite() && self.bias_allowance >= 0.0) {
            return Err(Error::Invalid(format!(
                "{source}: the bias allowance must be a number >= 0"
            )));
        }
        if self.unit_rays == 0 {
            return Err(Error::Invalid(format!(
                "{source}: a sampling unit needs at least one ray"
            )));
        }
        Ok(())
    }
}

impl Sampling {
    /// The share of a frame of `rays` rays that a sampled run simulates in detail (sampled
    /// units with their warm-ups, the first and the last unit): what a dry run's time estimate
    /// scales the cycle model's cost by. The units' places vary with the run, which changes
    /// the share only where warm-ups merge; the plan of seed 0 stands for them.
    pub fn simulated_share(&self, rays: usize) -> f64 {
        if rays == 0 {
            return 0.0;
        }
        let simulated: usize = plan(rays, self, 0)
            .segments
            .iter()
            .map(|s| s.rays.len())
            .sum();
        simulated as f64 / rays as f64
    }
}

/// What a sampled simulation measured and estimated.
#[derive(Clone, Debug, Serialize)]
pub struct SampledEstimate {
    /// Estimated cycles of the frame (rounded).
    pub cycles: u64,
    /// Half-width of the 95 % confidence interval of `cycles` (0 when every unit is
    /// simulated): the sampling part and the warm-up's bias allowance in quadrature.
    pub cycles_ci95: f64,
    /// The sampling part alone.
    pub cycles_ci95_sampling: f64,
    /// Estimated pipeline stalls, discarded samples (rounded).
    pub stall_cycles: StallCycles,
    pub discarded_after_ert: u64,
    /// The memory's statistics with its counters estimated (per-module figures left out).
    pub memory_stats: Value,
    /// The sample: units in the frame, strata, units simulated (first and last included),
    /// rays and cycles simulated (warm-up included).
    pub units: usize,
    pub strata: usize,
    pub measured_units: usize,
    pub segments: usize,
    pub simulated_rays: usize,
    pub simulated_cycles: u64,
    /// Rays simulated, unmeasured, before each sampled unit (`Sampling::warmup_rays`, raised to
    /// `LONG_WARMUP_RAYS` for a distance volume: `RunDescription::sampling`).
    pub warmup_rays: usize,
}

/// One detailed simulation: the issue-order positions `rays` (a contiguous range), snapshots at
/// the positions `checkpoints` (relative to the frame's issue order).
struct Segment {
    rays: Range<usize>,
    checkpoints: Vec<usize>,
}

/// How a segment's memory starts (`simulate_sampled`'s `simulate`).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Warm {
    /// The segment starts with the frame (its first ray): the memory as the frame finds it.
    Cold,
    /// The segment starts inside the frame: `phase` is a pseudo-random number (from the run's
    /// seed and the segment's first ray) that the memory model reduces modulo its refresh
    /// interval to the cycles since its last refresh (docs/sampling.md, "Warming").
    Inside { phase: u64 },
}

/// The sample of a frame of `total` rays: units, which are measured, the segments simulated.
struct Plan {
    units: Vec<Range<usize>>,
    /// Unit indices simulated: 0, one per stratum, the last (ascending, distinct).
    measured: Vec<usize>,
    /// Middle units per stratum and the unit chosen in each.
    strata: Vec<(Range<usize>, usize)>,
    segments: Vec<Segment>,
}

fn plan(total: usize, sampling: &Sampling, seed: u64) -> Plan {
    let u = sampling.unit_rays;
    let units: Vec<Range<usize>> = (0..total.div_ceil(u))
        .map(|i| i * u..((i + 1) * u).min(total))
        .collect();
    let count = units.len();
    let middle = count.saturating_sub(2);
    // n strata of near-equal size; at least MIN_STRATA, at most every unit (a frame of fewer
    // than MIN_SAMPLED_UNITS units: every unit, the exact simulation).
    let n = if count < MIN_SAMPLED_UNITS {
        middle
    } else {
        ((sampling.rate * middle as f64).ceil() as usize)
            .max(MIN_STRATA)
            .min(middle)
    };
    let strata: Vec<(Range<usize>, usize)> = (0..n)
        .map(|j| {
            let range = 1 + j * middle / n..1 + (j + 1) * middle / n;
            let offset = splitmix64(seed ^ (j as u64).wrapping_mul(0x9e37_79b9_7f4a_7c15))
                % range.len() as u64;
            (range.clone(), range.start + offset as usize)
        })
        .collect();
    let mut measured: Vec<usize> = std::iter::once(0)
        .chain(strata.iter().map(|(_, unit)| *unit))
        .chain((count > 1).then_some(count - 1))
        .collect();
    measured.dedup();
    // Segments: a measured unit with its warm-up, up to the next unit's first ray (whose
    // admission ends the unit) or the frame's end. A unit whose warm-up would start inside the
    // segment before it continues that segment (cheaper, and warm by the real history).
    let mut segments: Vec<Segment> = Vec::new();
    for &i in &measured {
        let Range { start, end } = units[i].clone();
        let from = start.saturating_sub(sampling.warmup_rays);
        let to = (end + 1).min(total);
        match segments.last_mut() {
            Some(last) if from < last.rays.end => {
                last.rays.end = to;
                last.checkpoints.extend([start, end]);
            }
            _ => segments.push(Segment {
                rays: from..to,
                checkpoints: vec![start, end],
            }),
        }
    }
    for s in &mut segments {
        s.checkpoints.dedup();
    }
    Plan {
        units,
        measured,
        strata,
        segments,
    }
}

/// A well-mixed 64-bit hash (splitmix64's finaliser), for the strata's offsets.
fn splitmix64(x: u64) -> u64 {
    let mut z = x.wrapping_add(0x9e37_79b9_7f4a_7c15);
    z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
    z ^ (z >> 31)
}

/// A seed from any text (FNV-1a): the same run description gives the same sample.
pub fn seed_of(text: &str) -> u64 {
    text.bytes().fold(0xcbf2_9ce4_8422_2325, |h, b| {
        (h ^ b as u64).wrapping_mul(0x0100_0000_01b3)
    })
}

/// The additive counters of one unit or segment: cycles, pipeline stalls and discards, and
/// the memory's counters by name.
#[derive(Clone, Debug, Default, PartialEq)]
struct Counters(Vec<f64>);

/// The memory counters estimated (top-level fields of `stats_json`, and two sums over its
/// `modules`); fields a memory does not have are left out.
const MEMORY_COUNTERS: [&str; 7] = [
    "reads",
    "row_hits",
    "row_misses",
    "refreshes",
    "requests",
    "block_lookups",
    "zero_samples",
];
const MODULE_SUMS: [&str; 2] = ["busy_cycles", "total_latency_cycles"];
const PIPELINE_COUNTERS: usize = 10;
/// Positions of the issued samples and leaps among the counters.
const ISSUED_SAMPLES: usize = 8;
const ISSUED_LEAPS: usize = 9;
const DISCARDED: usize = 7;

fn counters(cycle: u64, stats: &CycleStats, memory: &Value) -> Counters {
    let s = &stats.stall_cycles;
    let mut v = vec![
        cycle as f64,
        s.ray_queue_empty as f64,
        s.skip_unit_busy as f64,
        s.memory as f64,
        s.compositing_buffer_full as f64,
        s.distance_word as f64,
        s.leap_word as f64,
        stats.discarded_after_ert as f64,
        stats.samples as f64,
        stats.leaps as f64,
    ];
    for name in MEMORY_COUNTERS {
        v.push(memory[name].as_u64().unwrap_or(0) as f64);
    }
    for name in MODULE_SUMS {
        let sum: u64 = memory["modules"]
            .as_array()
            .map_or(0, |m| m.iter().filter_map(|x| x[name].as_u64()).sum());
        v.push(sum as f64);
    }
    Counters(v)
}

fn of_checkpoint(c: &Checkpoint) -> Counters {
    counters(c.cycle, &c.stats, &c.memory)
}

impl Counters {
    fn minus(&self, other: &Counters) -> Counters {
        Counters(self.0.iter().zip(&other.0).map(|(a, b)| a - b).collect())
    }
}

/// Simulates a sample of a frame of `total` rays and estimates its figures. `order` is the
/// frame's issue order (pixel indices), `functional` the frame's samples and leaps by the
/// functional model, `misses(range)` how many rays at those issue-order positions miss the
/// volume (functional model), `simulate(rays, checkpoints)` one detailed simulation of the pixels
/// `rays` in a fresh pipeline and memory; `clock_mhz` gives the memory's ns per access.
/// Segments run in parallel; the result does not depend on the thread count.
pub fn simulate_sampled<F>(
    order: &[usize],
    sampling: &Sampling,
    seed: u64,
    clock_mhz: f64,
    functional: [u64; 2],
    misses: impl Fn(Range<usize>) -> u64,
    simulate: F,
) -> Result<SampledEstimate>
where
    F: Fn(&[usize], &mut Checkpoints, Warm) -> Result<()> + Sync,
{
    let total = order.len();
    if total == 0 {
        return Err(Error::Invalid("a sampled simulation needs rays".into()));
    }
    let plan = plan(total, sampling, seed);
    // Every segment's checkpoints, in segment order.
    let taken: Vec<(usize, Vec<Checkpoint>, u64)> = plan
        .segments
        .par_iter()
        .map(|segment| {
            let start = segment.rays.start;
            let mut checkpoints = Checkpoints {
                at: segment.checkpoints.iter().map(|p| p - start).collect(),
                stop_at_last: segment.rays.end < total,
                taken: Vec::new(),
            };
            let warm = if start == 0 {
                Warm::Cold
            } else {
                Warm::Inside {
                    phase: splitmix64(seed ^ (start as u64).wrapping_mul(0xd6e8_feb8_6659_fd93)),
                }
            };
            simulate(&order[segment.rays.clone()], &mut checkpoints, warm)?;
            if checkpoints.taken.len() != checkpoints.at.len() {
                return Err(Error::Invalid(format!(
                    "internal error: a sampled segment took {} of {} checkpoints",
                    checkpoints.taken.len(),
                    checkpoints.at.len()
                )));
            }
            let cycles = checkpoints.taken.last().map_or(0, |c| c.cycle);
            Ok((start, checkpoints.taken, cycles))
        })
        .collect::<Result<_>>()?;
    // A unit's counters: the difference of the checkpoints at its end and start, taken in
    // the segment that simulated it (the first unit from cycle 0). Measured units next to each
    // other always share a segment, so one segment holds both of a unit's checkpoints.
    let unit_counters = |i: usize| -> Counters {
        let range = &plan.units[i];
        let segment = plan
            .segments
            .iter()
            .position(|s| {
                s.checkpoints.contains(&range.start) && s.checkpoints.contains(&range.end)
            })
            .expect("a measured unit lies in a segment");
        let find = |p: usize| {
            let k = plan.segments[segment]
                .checkpoints
                .iter()
                .position(|&q| q == p)
                .expect("checkpoint of the unit");
            of_checkpoint(&taken[segment].1[k])
        };
        let end = find(range.end);
        if i == 0 {
            end
        } else {
            end.minus(&find(range.start))
        }
    };
    let width = unit_counters(0).0.len();
    let count = plan.units.len();
    let first = unit_counters(0);
    let last = if count > 1 {
        unit_counters(count - 1)
    } else {
        Counters(vec![0.0; width])
    };
    let mut estimate = Counters(first.0.iter().zip(&last.0).map(|(a, b)| a + b).collect());
    let mut ci95 = 0.0;
    // Share of the middle units not simulated (the bias allowance scales with it).
    let mut unsimulated = 0.0;
    if !plan.strata.is_empty() {
        let work = |unit: usize, y: &[f64]| {
            y[ISSUED_SAMPLES] + y[ISSUED_LEAPS] + misses(plan.units[unit].clone()) as f64
        };
        let sampled: Vec<Observation> = plan
            .strata
            .iter()
            .map(|(range, unit)| {
                let y = unit_counters(*unit).0;
                Observation {
                    weight: range.len() as f64,
                    x: work(*unit, &y),
                    y,
                }
            })
            .collect();
        // The middle units' work. The pipeline issues the functional model's steps plus the
        // samples discarded after ERT (issued before the feedback arrived): with d discarded
        // per issued sample (from the sample and the first and last units), samples / (1 − d).
        let known = |c: usize| estimate.0[c];
        let weighted = |c: usize| sampled.iter().map(|o| o.weight * o.y[c]).sum::<f64>();
        let issued = weighted(ISSUED_SAMPLES) + known(ISSUED_SAMPLES);
        let discarded_share = if issued > 0.0 {
            ((weighted(DISCARDED) + known(DISCARDED)) / issued).min(0.5)
        } else {
            0.0
        };
        let issued_steps = functional[0] as f64 / (1.0 - discarded_share) + functional[1] as f64;
        let first_last_work = work(0, &first.0) + work(count - 1, &last.0);
        let x_middle = (issued_steps + misses(0..total) as f64 - first_last_work).max(0.0);
        let middle_units = (count - 2) as f64;
        if sampled.len() == count - 2 {
            // Every middle unit measured (rate 1): their counters add up to the frame's
            // exactly, where the ratio would scale them by the issued steps, which with ERT
            // are estimated from the discarded share.
            for (c, total) in estimate.0.iter_mut().enumerate().take(width) {
                *total += sampled.iter().map(|o| o.y[c]).sum::<f64>();
            }
        } else {
            for (c, total) in estimate.0.iter_mut().enumerate().take(width) {
                *total += ratio(&sampled, c) * x_middle;
            }
            ci95 = ratio_ci95(&sampled, middle_units) * x_middle
                / sampled.iter().map(|o| o.weight * o.x).sum::<f64>().max(1.0);
        }
        unsimulated = (1.0 - sampled.len() as f64 / middle_units).max(0.0);
    }
    let round = |x: f64| x.max(0.0).round() as u64;
    let e = &estimate.0;
    let stall_cycles = StallCycles {
        ray_queue_empty: round(e[1]),
        skip_unit_busy: round(e[2]),
        memory: round(e[3]),
        compositing_buffer_full: round(e[4]),
        distance_word: round(e[5]),
        leap_word: round(e[6]),
    };
    // The memory's statistics: the last segment's constants, the counters estimated, the
    // ratios from the estimated counters.
    let mut memory_stats = taken
        .last()
        .and_then(|(_, c, _)| c.last())
        .map_or(Value::Null, |c| c.memory.clone());
    if let Some(object) = memory_stats.as_object_mut() {
        object.remove("modules");
        for (k, name) in MEMORY_COUNTERS.iter().enumerate() {
            if object.contains_key(*name) {
                object.insert((*name).into(), round(e[PIPELINE_COUNTERS + k]).into());
            }
        }
        // Rates per read are null without a read, as the exact model writes them.
        let reads = e[PIPELINE_COUNTERS];
        let per_read = |total: f64, scale: f64| -> Value {
            if reads > 0.0 {
                (total / reads * scale).into()
            } else {
                Value::Null
            }
        };
        if object.contains_key("row_hit_rate") {
            object.insert(
                "row_hit_rate".into(),
                per_read(e[PIPELINE_COUNTERS + 1], 1.0),
            );
        }
        let sums = PIPELINE_COUNTERS + MEMORY_COUNTERS.len();
        if object.contains_key("avg_ns_per_voxel_access") {
            let period_ns = 1e3 / clock_mhz;
            object.insert(
                "avg_ns_per_voxel_access".into(),
                per_read(e[sums], period_ns),
            );
        }
        if object.contains_key("avg_access_latency_cycles") {
            object.insert(
                "avg_access_latency_cycles".into(),
                per_read(e[sums + 1], 1.0),
            );
        }
    }
    let allowance = sampling.bias_allowance * unsimulated * e[0];
    Ok(SampledEstimate {
        cycles: round(e[0]),
        cycles_ci95: (ci95 * ci95 + allowance * allowance).sqrt(),
        cycles_ci95_sampling: ci95,
        stall_cycles,
        discarded_after_ert: round(e[7]),
        memory_stats,
        units: count,
        strata: plan.strata.len(),
        measured_units: plan.measured.len(),
        segments: plan.segments.len(),
        simulated_rays: plan.segments.iter().map(|s| s.rays.len()).sum(),
        simulated_cycles: taken.iter().map(|(_, _, c)| c).sum(),
        warmup_rays: sampling.warmup_rays,
    })
}

/// One sampled unit: its stratum's size (its weight), the work of its window `x` (steps the
/// pipeline issued in it plus rays of the unit that miss the volume: each costs a setup
/// cycle), its counters `y`.
struct Observation {
    weight: f64,
    x: f64,
    y: Vec<f64>,
}

/// The ratio estimator: counter per unit of work in the sample, times the middle units' work.
fn ratio(sample: &[Observation], c: usize) -> f64 {
    let x: f64 = sample.iter().map(|o| o.weight * o.x).sum();
    let y: f64 = sample.iter().map(|o| o.weight * o.y[c]).sum();
    if x > 0.0 {
        y / x
    } else {
        0.0
    }
}

/// Half-width of the 95 % interval of the middle units' weighted residual total (the caller
/// scales it to the estimate): the larger of the successive-difference estimator of the
/// strata's weighted residuals about the ratio (Wolter's v2 for systematic samples) and the
/// simple-random-sampling one, times the finite population correction 1 − n/N, with Student's
/// t at n − 1 degrees of freedom.
fn ratio_ci95(sample: &[Observation], middle_units: f64) -> f64 {
    let n = sample.len();
    if n < 2 {
        return 0.0;
    }
    let r = ratio(sample, 0);
    let residual: Vec<f64> = sample
        .iter()
        .map(|o| o.weight * (o.y[0] - r * o.x))
        .collect();
    let squares: f64 = residual.windows(2).map(|d| (d[1] - d[0]).powi(2)).sum();
    let successive = squares / (2.0 * (n - 1) as f64);
    // The simple-random-sampling estimator too, and the larger of the two: with a score of
    // strata, neighbours that happen to agree make the successive differences too small.
    let mean = residual.iter().sum::<f64>() / n as f64;
    let spread = residual.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / (n - 1) as f64;
    let fpc = (1.0 - n as f64 / middle_units).max(0.0);
    let variance = fpc * n as f64 * successive.max(spread);
    t_quantile_975(n - 1) * variance.sqrt()
}

/// The 97.5 % quantile of Student's t with `df` degrees of freedom: tabulated to 30, then the
/// Cornish-Fisher expansion (error below 1e-3 there).
pub fn t_quantile_975(df: usize) -> f64 {
    const TABLE: [f64; 30] = [
        12.706, 4.303, 3.182, 2.776, 2.571, 2.447, 2.365, 2.306, 2.262, 2.228, 2.201, 2.179, 2.160,
        2.145, 2.131, 2.120, 2.110, 2.101, 2.093, 2.086, 2.080, 2.074, 2.069, 2.064, 2.060, 2.056,
        2.052, 2.048, 2.045, 2.042,
    ];
    match df {
        0 => f64::INFINITY,
        1..=30 => TABLE[df - 1],
        _ => {
            let z: f64 = 1.959_964;
            let v = df as f64;
            z + (z.powi(3) + z) / (4.0 * v)
                + (5.0 * z.powi(5) + 16.0 * z.powi(3) + 3.0 * z) / (96.0 * v * v)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn t_quantiles_join_the_table_smoothly() {
        assert!((t_quantile_975(31) - 2.040).abs() < 2e-3);
        assert!((t_quantile_975(1000) - 1.962).abs() < 2e-3);
    }

    #[test]
    fn rate_one_measures_every_unit_in_one_segment() {
        let s = Sampling::new(1.0, "test").unwrap();
        let p = plan(1000, &s, 7);
        assert_eq!(p.measured.len(), p.units.len());
        assert_eq!(p.segments.len(), 1);
        assert_eq!(p.segments[0].rays, 0..1000);
    }

    #[test]
    fn a_low_rate_samples_one_unit_per_stratum_with_its_warm_up() {
        let s = Sampling::new(0.1, "test").unwrap();
        let p = plan(128 * 1002, &s, 7);
        assert_eq!(p.units.len(), 1002);
        assert_eq!(p.strata.len(), 100);
        for (range, unit) in &p.strata {
            assert!(range.contains(unit));
            assert_eq!(range.len(), 10);
        }
        // Every measured unit's warm-up and the next unit's first ray are in its segment.
        for &u in &p.measured {
            let r = &p.units[u];
            assert!(p.segments.iter().any(|seg| seg.rays.start
                <= r.start.saturating_sub(s.warmup_rays)
                && seg.rays.end >= (r.end + 1).min(128 * 1002)));
        }
    }

    #[test]
    fn a_small_frame_is_simulated_whole_and_a_low_rate_keeps_the_fewest_strata() {
        let s = Sampling::new(0.05, "test").unwrap();
        // 64×64: 32 units, every one measured, in one segment (the exact simulation).
        let p = plan(64 * 64, &s, 7);
        assert_eq!(p.measured.len(), p.units.len());
        assert_eq!(p.segments.len(), 1);
        // 511 units: still whole; 512: sampled, 26 strata at 0.05; at 0.01, MIN_STRATA.
        let p = plan(128 * (MIN_SAMPLED_UNITS - 1), &s, 7);
        assert_eq!(p.measured.len(), p.units.len());
        let p = plan(128 * MIN_SAMPLED_UNITS, &s, 7);
        assert_eq!(p.strata.len(), 26);
        let p = plan(
            128 * MIN_SAMPLED_UNITS,
            &Sampling::new(0.01, "t").unwrap(),
            7,
        );
        assert_eq!(p.strata.len(), MIN_STRATA);
    }
}
