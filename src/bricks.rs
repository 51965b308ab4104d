//! Bounding bricks (brief, section 7): per-ray start and end positions.
//!
//! The volume is cut into bricks of `bricks.size`³ voxels. A brick is **active** when a sample
//! inside it can have non-zero opacity: exactly the occupancy map's test (`occupancy.rs`), with
//! the brick as the sub-cube — the brick's voxel block dilated by the interpolation stencil
//! (+1 voxel per axis), '0' kind: any non-zero voxel, class kind: the classification table's
//! conservative min–max test (`ClassificationTable::any_visible`). A ray then starts at its
//! first sample position inside an active brick and ends after its last one; the samples cut
//! off all lie in inactive bricks, so they have zero opacity and the image is unchanged bit for
//! bit.
//!
//! - Fixed point (functional and cycle model): `fixed_span` walks the brick grid along the
//!   ray's exact positions P0 + k·V (a 3D DDA whose brick exits are found by integer division,
//!   as the sample count is), so both models get the same start and end and the same count of
//!   bricks visited (the traversal's cost).
//! - Float reference: `FloatBricks::span` takes the float model's own sample positions and the
//!   brick of the cell each sample interpolates in, with a brick map built from the float
//!   transfer-function table, so it too only cuts samples of zero float opacity.
//!
//! Both models also apply the scene's clip planes, clip box and opaque geometry
//! (`crate::clip`) before the bricks: those are a range of sample indices k computed once from
//! the float camera ray, identical in every model.

use glam::{Vec3A, Vec4};

use crate::clip::{Scene, SurfaceColour};
use crate::config::{BrickSetup, HardwareConfig, BRICK_SIZES};
use crate::error::{Error, Result};
use crate::functional::arith::{to_accumulator, ClassificationTable};
use crate::functional::setup::FixedRay;
use crate::occupancy::{OccupancyKind, OccupancyMap};
use crate::volume::Volume;

/// Checks a brick edge against the allowed sizes and the volume; returns log2 of the edge.
pub fn check_brick_size(size: usize, volume_dims: [usize; 3]) -> Result<u32> {
    if !BRICK_SIZES.contains(&size) {
        return Err(Error::config(
            "hardware configuration",
            "bricks.size",
            format!("{size} is not allowed; allowed a power of two in {BRICK_SIZES:?}"),
        ));
    }
    let largest = *volume_dims.iter().max().unwrap_or(&0);
    if size > largest {
        return Err(Error::config(
            "hardware configuration",
            "bricks.size",
            format!("{size} is larger than the volume ({volume_dims:?})"),
        ));
    }
    Ok(size.trailing_zeros())
}

/// Builds the brick flags: the occupancy map's construction with the brick as sub-cube.
pub fn build_brick_map(
    volume: &Volume,
    kind: OccupancyKind,
    size: usize,
    visible: impl Fn(u16, u16) -> bool,
) -> Result<OccupancyMap> {
    let log2 = check_brick_size(size, volume.dims)?;
    Ok(OccupancyMap::build(volume, kind, log2, 0, visible))
}

/// Where a ray's active bricks are, in positions 0..n of the ray.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct BrickSpan {
    /// First position inside an active brick (= end when there is none).
    pub first: u64,
    /// One past the last position inside an active brick.
    pub end: u64,
    /// Bricks the setup visits: from the entry forward to the first active brick and from the
    /// exit back to the last one (every brick along the ray when none is active).
    pub visited: u32,
}

/// The fixed-point brick walk along positions `start + k·step`, k in 0..n (all inside the box,
/// as `setup_ray` guarantees). `shift` = log2(brick) + position fraction bits; the brick of a
/// position is `pos >> shift` per axis, as `OccupancyLeaping` finds a sub-cube.
pub fn fixed_span(
    map: &OccupancyMap,
    shift: u32,
    start: [i64; 3],
    step: [i64; 3],
    n: u64,
) -> BrickSpan {
    let mut k = 0u64;
    let mut segments = 0u32;
    let mut first: Option<(u64, u32)> = None;
    let mut last = (0u64, 0u32);
    while k < n {
        let p = [0, 1, 2].map(|a| start[a] + k as i64 * step[a]);
        let cell = p.map(|x| x >> shift);
        // Positions until the ray leaves this brick on some axis (>= 1).
        let mut leave = u64::MAX;
        for a in 0..3 {
            let v = step[a];
            let j = if v > 0 {
                let boundary = (cell[a] + 1) << shift;
                (boundary - p[a] + v - 1) / v
            } else if v < 0 {
                let boundary = cell[a] << shift;
                (p[a] - boundary + 1 - v - 1) / -v
            } else {
                continue;
            };
            leave = leave.min(j as u64);
        }
        let next = k.saturating_add(leave).min(n);
        if map.occupied(cell.map(|c| c as usize)) {
            if first.is_none() {
                first = Some((k, segments));
            }
            last = (next, segments);
        }
        segments += 1;
        k = next;
    }
    match first {
        Some((f, fs)) => BrickSpan {
            first: f,
            end: last.0,
            visited: (fs + 1) + (segments - last.1),
        },
        None => BrickSpan {
            first: n,
            end: n,
            visited: segments,
        },
    }
}

/// The same span found by looking at every position (the reference `fixed_span` is tested
/// against; not used by the models).
pub fn fixed_span_by_scan(
    map: &OccupancyMap,
    shift: u32,
    start: [i64; 3],
    step: [i64; 3],
    n: u64,
) -> (u64, u64) {
    let active = |k: u64| {
        let p = [0, 1, 2].map(|a| start[a] + k as i64 * step[a]);
        map.occupied(p.map(|x| (x >> shift) as usize))
    };
    match (0..n).find(|&k| active(k)) {
        Some(first) => (first, (0..n).rev().find(|&k| active(k)).unwrap() + 1),
        None => (n, n),
    }
}

/// The fixed-point models' ray range: bricks and the scene (clip planes, clip box, geometry).
pub struct FixedRange {
    /// Brick flags and the position shift to a brick address.
    bricks: Option<(OccupancyMap, u32)>,
    pub scene: Option<Scene>,
    /// Accumulator unit of the compositor (to convert a surface colour).
    unit: u32,
}

impl FixedRange {
    /// The range the configuration asks for; None when bricks, clipping and geometry are off.
    pub fn from_config(
        volume: &Volume,
        config: &HardwareConfig,
        table: &ClassificationTable,
        pos_frac_bits: u32,
        unit: u32,
    ) -> Result<Option<FixedRange>> {
        let scene = Scene::from_config(config)?;
        let bricks = if config.bricks.is_off() {
            None
        } else {
            let map =
                build_brick_map(volume, config.occupancy.kind, config.bricks.size, |l, h| {
                    table.any_visible(l, h)
                })?;
            let shift = map.cube_log2 + pos_frac_bits;
            Some((map, shift))
        };
        if bricks.is_none() && scene.is_none() {
            return Ok(None);
        }
        Ok(Some(FixedRange {
            bricks,
            scene,
            unit,
        }))
    }

    /// The brick flags, when bricks are on.
    pub fn brick_map(&self) -> Option<&OccupancyMap> {
        self.bricks.as_ref().map(|(m, _)| m)
    }

    /// Replaces the brick flags by `map` (built elsewhere: a dynamic sequence's, from the
    /// update engine's table, conservative for the volume). An error without bricks or for a
    /// map of another grid.
    pub fn set_brick_map(&mut self, map: OccupancyMap) -> Result<()> {
        match &mut self.bricks {
            Some((old, _)) if old.dims == map.dims && old.cube_log2 == map.cube_log2 => {
                *old = map;
                Ok(())
            }
            _ => Err(Error::Invalid(format!(
                "the run has no bricks of edge {} over {:?}",
                map.subcube_size(),
                map.dims
            ))),
        }
    }

    /// Clamps a fixed ray (from `setup_ray`) to its start and end: first the scene's sample
    /// range (computed from the float camera ray `ray` of pixel (px, py)), then the active
    /// bricks.
    pub fn apply(
        &self,
        ray: &crate::camera::Ray,
        mut fixed: FixedRay,
        (px, py): (u32, u32),
        spacing: f32,
    ) -> FixedRay {
        let in_box = fixed.samples;
        if let Some(scene) = &self.scene {
            let limits = scene.limits(ray, px, py, spacing);
            fixed = clamp_global(fixed, limits.k_lo, limits.k_end);
            fixed.surface = limits
                .surface
                .map(|c| c.map(|x| to_accumulator(x, self.unit)));
        }
        if let Some((map, shift)) = &self.bricks {
            if fixed.samples > 0 {
                let span = fixed_span(map, *shift, fixed.start, fixed.step, fixed.samples as u64);
                fixed = clamp_relative(fixed, span.first, span.end);
                fixed.bricks_visited = span.visited;
                fixed.refinable_start = span.first > 0 && fixed.samples > 0;
            }
        }
        fixed.cut = in_box - fixed.samples;
        fixed
    }
}

/// Keeps the positions with global grid index k (t = k·S) in [k_lo, k_end).
pub fn clamp_global(ray: FixedRay, k_lo: i64, k_end: i64) -> FixedRay {
    let n = ray.samples as i64;
    let lo = (k_lo - ray.first_k).clamp(0, n);
    let hi = (k_end - ray.first_k).clamp(lo, n);
    clamp_relative(ray, lo as u64, hi as u64)
}

/// Keeps the ray's positions first..end (relative to its start).
pub fn clamp_relative(ray: FixedRay, first: u64, end: u64) -> FixedRay {
    let end = end.min(ray.samples as u64);
    let first = first.min(end);
    FixedRay {
        start: [0, 1, 2].map(|a| ray.start[a] + first as i64 * ray.step[a]),
        samples: (end - first) as u32,
        first_k: ray.first_k + first as i64,
        ..ray
    }
}

/// The float reference's ray range: its own brick flags (from the float table) and the scene.
pub struct FloatRange {
    bricks: Option<OccupancyMap>,
    scene: Option<Scene>,
    dims: [usize; 3],
}

/// What the float reference's range gives one ray.
pub struct FloatLimits {
    pub first: i64,
    /// The first index after the box and the scene, before bricks: an iso hit at `first`
    /// refines back to `first - 1` when that is not below this (only bricks cut it).
    pub scene_first: i64,
    pub end: i64,
    pub surface: Option<SurfaceColour>,
}

impl FloatRange {
    /// `table` is the float renderer's table (RGBA per integer density, plus one extra copy of
    /// the last entry): a brick is active when a density in its [min, max] has opacity > 0.
    pub fn from_config(
        volume: &Volume,
        config: &HardwareConfig,
        table: &[Vec4],
    ) -> Result<Option<FloatRange>> {
        let scene = Scene::from_config(config)?;
        let bricks = if config.bricks.is_off() {
            None
        } else {
            if config.occupancy.kind == OccupancyKind::Zero && table[0].w > 0.0 {
                return Err(crate::functional::renderer::zero_kind_refused());
            }
            let mut prefix = Vec::with_capacity(table.len() + 1);
            prefix.push(0u32);
            for e in table {
                prefix.push(prefix.last().unwrap() + (e.w > 0.0) as u32);
            }
            Some(build_brick_map(
                volume,
                config.occupancy.kind,
                config.bricks.size,
                |lo, hi| prefix[hi as usize + 1] > prefix[lo as usize],
            )?)
        };
        if bricks.is_none() && scene.is_none() {
            return Ok(None);
        }
        Ok(Some(FloatRange {
            bricks,
            scene,
            dims: volume.dims,
        }))
    }

    pub fn scene(&self) -> Option<&Scene> {
        self.scene.as_ref()
    }

    /// Clamps the box's sample range [first, end) of `ray` (pixel (px, py)): scene, then bricks.
    /// `position(k)` must be the float model's own sample position for index k.
    pub fn limits(
        &self,
        ray: &crate::camera::Ray,
        (px, py): (u32, u32),
        spacing: f32,
        mut first: i64,
        mut end: i64,
        position: impl Fn(i64) -> Vec3A,
    ) -> FloatLimits {
        let mut surface = None;
        if let Some(scene) = &self.scene {
            let l = scene.limits(ray, px, py, spacing);
            first = first.max(l.k_lo);
            end = end.min(l.k_end).max(first);
            surface = l.surface;
        }
        let scene_first = first;
        if let Some(map) = &self.bricks {
            let s = map.cube_log2;
            let d = self.dims;
            let active = |k: i64| {
                let p = position(k);
                // The brick of the cell the sample interpolates in (as `interpolate` finds it).
                let cell = [0, 1, 2].map(|a| {
                    let x = p[a].clamp(0.0, (d[a] - 1) as f32);
                    ((x as usize).min(d[a] - 2)) >> s
                });
                map.occupied(cell)
            };
            match (first..end).find(|&k| active(k)) {
                Some(f) => {
                    let e = (f..end).rev().find(|&k| active(k)).unwrap_or(f) + 1;
                    first = f;
                    end = e;
                }
                None => first = end,
            }
        }
        FloatLimits {
            first,
            scene_first,
            end,
            surface,
        }
    }
}

/// Frame totals of the ray range (reported only when bricks, clipping or geometry are on).
#[derive(Clone, Debug, Default, PartialEq, serde::Serialize)]
pub struct RayRangeStats {
    /// Sample positions inside the volume box over all rays (what plain stepping visits).
    pub positions_in_box: u64,
    /// Positions between the rays' starts and ends (what the rays step through).
    pub positions_in_range: u64,
    /// positions_in_box - positions_in_range: steps saved for plain stepping.
    pub positions_cut: u64,
    /// Cycle model, `bricks.setup = "traversal"`: bricks visited by ray setup, and its cycles.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub bricks_visited: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub setup_cycles: Option<u64>,
    /// Cycle model, `bricks.setup = "table"`: the per-pixel start/end table's bytes and the
    /// cycles loading it takes before the first ray (included in `cycles`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub table_bytes: Option<u64>,
    #[serde(skip_serializing_if = "Option::is_none")]
    pub table_load_cycles: Option<u64>,
}

impl RayRangeStats {
    /// Totals from a frame's ray records.
    pub fn from_records(records: &[crate::render::RayRecord]) -> Self {
        let mut s = RayRangeStats::default();
        for r in records {
            let kept = (r.end_sample - r.first_sample).max(0) as u64;
            s.positions_in_range += kept;
            s.positions_cut += r.positions_cut as u64;
        }
        s.positions_in_box = s.positions_in_range + s.positions_cut;
        s
    }
}

/// The cycle model's ray-setup cost of one ray under `[bricks]` (0 when bricks are off or
/// the table supplies start and end).
pub fn setup_cycles(config: &HardwareConfig, ray: &FixedRay) -> u64 {
    let b = &config.bricks;
    if b.is_off() || b.setup != BrickSetup::Traversal {
        return 0;
    }
    b.setup_cycles_per_ray as u64 + b.setup_cycles_per_brick as u64 * ray.bricks_visited as u64
}

/// The start/end table's size in bytes and its load cycles for a `rays`-pixel frame (None
/// unless `bricks.setup = "table"`).
pub fn table_cost(config: &HardwareConfig, rays: u64) -> Option<(u64, u64)> {
    let b = &config.bricks;
    if b.is_off() || b.setup != BrickSetup::Table {
        return None;
    }
    let bytes = rays * b.table_entry_bytes as u64;
    // Over the host link, at its rate and rounding as for a volume update (arch::update).
    let link = config.host_link_per_cycle_q32().max(1) as u128;
    Some((bytes, ((bytes as u128) << 32).div_ceil(link) as u64))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pseudo(seed: &mut u64) -> u64 {
        *seed = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        *seed >> 33
    }

    /// The start/end table loads over the host link at the rate a volume update sees: a wider
    /// or faster link, or a slower pipeline clock, loads it in fewer cycles.
    #[test]
    fn the_table_loads_at_the_host_links_rate() {
        let with = |sets: &[&str]| {
            let mut sets: Vec<String> = sets.iter().map(|s| s.to_string()).collect();
            sets.extend(["bricks.size=8".into(), "bricks.setup=table".into()]);
            let config =
                HardwareConfig::from_toml_str(crate::config::DEFAULT_TOML, "t", &sets).unwrap();
            table_cost(&config, 256 * 256).unwrap()
        };
        let (bytes, cycles) = with(&[]);
        assert_eq!(bytes, 262_144);
        // 32 bits at 33 MHz over a 100 MHz clock: 1.32 bytes per cycle.
        assert_eq!(cycles, (262_144f64 / 1.32).ceil() as u64);
        assert_eq!(with(&["memory.host_link_bits=64"]).1, cycles.div_ceil(2));
        assert_eq!(with(&["clock.frequency_mhz=50.0"]).1, cycles.div_ceil(2));
        assert_eq!(with(&["memory.host_link_mhz=66.0"]).1, cycles.div_ceil(2));
    }

    #[test]
    fn the_brick_walk_finds_the_same_span_as_looking_at_every_position() {
        let n = 40usize;
        let mut seed = 7u64;
        let data: Vec<u16> = (0..n * n * n)
            .map(|_| {
                if pseudo(&mut seed).is_multiple_of(23) {
                    100
                } else {
                    0
                }
            })
            .collect();
        let volume = Volume::new("t", [n, n, n], [1.0; 3], 8, data).unwrap();
        let map = build_brick_map(&volume, OccupancyKind::Zero, 8, |_, _| true).unwrap();
        let pf = 12;
        let shift = 3 + pf;
        let hi = ((n - 1) as i64) << pf;
        let mut checked = 0;
        for _ in 0..3000 {
            let start = [0, 1, 2].map(|_| (pseudo(&mut seed) as i64) % (hi + 1));
            let step = [0, 1, 2].map(|_| (pseudo(&mut seed) as i64 % 8193) - 4096);
            // Positions inside the box only.
            let mut count = 0u64;
            while count < 200 {
                let p = [0, 1, 2].map(|a| start[a] + count as i64 * step[a]);
                if p.iter().any(|&x| x < 0 || x > hi) {
                    break;
                }
                count += 1;
            }
            let span = fixed_span(&map, shift, start, step, count);
            let scan = fixed_span_by_scan(&map, shift, start, step, count);
            assert_eq!(
                (span.first, span.end),
                scan,
                "start {start:?} step {step:?}"
            );
            checked += (scan.0 < scan.1) as u32;
        }
        assert!(
            checked > 100,
            "too few rays with an active brick: {checked}"
        );
    }

    #[test]
    fn brick_sizes_are_checked() {
        assert!(check_brick_size(6, [64; 3]).is_err());
        assert!(check_brick_size(32, [16; 3]).is_err());
        assert_eq!(check_brick_size(16, [16, 20, 8]).unwrap(), 4);
    }
}
