//! Occupancy maps: one bit per sub-cube of s³ voxels saying whether anything in it can
//! contribute to the image, plus the two-level hierarchy that groups 2×2×2 sub-cubes (aligned at
//! even sub-cube addresses) into one byte (brief, section 2).
//!
//! **Conservativeness.** A sample inside sub-cube c interpolates voxels up to +1 along each axis,
//! so the bit of c covers the voxel block [s·c - g, s·c + s + g] per axis (clamped to the
//! volume), where g is the extra reach of the gradient stencil (0 without shading). Kind '0':
//! empty when every voxel of that block is 0. Kind class: empty when the classifier gives zero
//! opacity over the whole [min, max] range of the block, because a trilinear sample can take any
//! value between the minimum and maximum of its neighbours.

use crate::error::{Error, Result};
use crate::volume::Volume;

/// Published sub-cube sizes vizsim supports (log2 1..=6).
pub const SUBCUBE_SIZES: [usize; 6] = [2, 4, 8, 16, 32, 64];

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum OccupancyKind {
    /// '0': empty when all voxels are 0 (classification independent).
    Zero,
    /// class: empty when the transfer function maps the whole value range to zero opacity.
    Class,
}

impl OccupancyKind {
    /// The map an experiment's (or the advisor's) transfer function gets: `zero` the '0' map,
    /// any other (`class`, a preset, a file) the class map built from its opacities.
    pub fn for_tf(tf: &str) -> OccupancyKind {
        if tf == "zero" {
            OccupancyKind::Zero
        } else {
            OccupancyKind::Class
        }
    }

    /// As written in a configuration (`occupancy.kind`).
    pub fn name(self) -> &'static str {
        match self {
            OccupancyKind::Zero => "zero",
            OccupancyKind::Class => "class",
        }
    }

    pub fn label(self) -> &'static str {
        match self {
            OccupancyKind::Zero => "0",
            OccupancyKind::Class => "class",
        }
    }
}

/// SRAM bits of a map of `subcube`³ sub-cubes of a volume of `dims`, before it is built
/// (experiments, `advise`, `structure_memory`): one per sub-cube; with the hierarchy, one byte
/// per 2×2×2 group, padded to whole groups. `OccupancyMap::storage_bits` counts a built map
/// alike (`tests/distance.rs` checks the two agree).
pub fn map_bits(dims: [usize; 3], subcube: usize, hierarchy: bool) -> u64 {
    let cells = dims.map(|d| d.div_ceil(subcube));
    if hierarchy {
        8 * cells.iter().map(|c| c.div_ceil(2) as u64).product::<u64>()
    } else {
        cells.iter().map(|&c| c as u64).product()
    }
}

/// Why the two-level hierarchy over `subcube`³ sub-cubes can group nothing in a volume of `dims`
/// (None when it can): the volume is one sub-cube along every axis, so each 2×2×2 group holds
/// that one sub-cube and leaps exactly as far as the map does. (A map with two or more sub-cubes
/// along some axis has groups of several.)
pub fn hierarchy_without_effect(dims: [usize; 3], subcube: usize) -> Option<String> {
    (subcube > 0 && dims.iter().all(|&d| d.div_ceil(subcube) <= 1)).then(|| {
        format!(
            "the 2×2×2 group of {subcube}³ sub-cubes is larger than the volume {dims:?}: every \
             group holds one sub-cube, so the hierarchy leaps no further than the map"
        )
    })
}

#[derive(Clone, Debug)]
pub struct OccupancyMap {
    /// log2 of the sub-cube edge s.
    pub cube_log2: u32,
    /// Map extent in sub-cubes per axis: ceil(dim / s).
    pub dims: [usize; 3],
    /// One entry per sub-cube (1 = occupied), x fastest. A byte per bit keeps lookups cheap.
    cells: Vec<u8>,
    /// Group extent (2×2×2 sub-cubes per group): ceil(dims / 2).
    pub group_dims: [usize; 3],
    /// One entry per group (1 = some sub-cube of the group occupied): the OR of its byte.
    groups: Vec<u8>,
}

/// The voxels (inclusive, per axis) whose values decide the bit of sub-cube `c` along an axis of
/// `dim` voxels: [s·c − reach, s·c + s + reach] clamped to the volume (s = 2^cube_log2), the
/// one-voxel dilation of trilinear interpolation plus the gradient stencil's reach.
#[inline]
pub fn dilated_range(c: usize, cube_log2: u32, reach: usize, dim: usize) -> (usize, usize) {
    let s = 1usize << cube_log2;
    let lo = (c * s).saturating_sub(reach);
    let hi = (c * s + s + reach).min(dim - 1);
    (lo, hi)
}

/// Checks a sub-cube size against the supported sizes and the volume.
pub fn check_subcube_size(size: usize, volume_dims: [usize; 3]) -> Result<u32> {
    if !SUBCUBE_SIZES.contains(&size) {
        return Err(Error::Invalid(format!(
            "sub-cube size {size}: must be a power of two in {SUBCUBE_SIZES:?}"
        )));
    }
    let largest = *volume_dims.iter().max().unwrap_or(&0);
    if size > largest {
        return Err(Error::Invalid(format!(
            "sub-cube size {size} exceeds the volume ({volume_dims:?})"
        )));
    }
    Ok(size.trailing_zeros())
}

impl OccupancyMap {
    /// Builds the map. `stencil_reach` is the gradient stencil's extra reach in voxels (0 when
    /// shading is off); `visible(min, max)` says whether any density in [min, max] has non-zero
    /// opacity (class maps) — for '0' maps it is ignored.
    pub fn build(
        volume: &Volume,
        kind: OccupancyKind,
        cube_log2: u32,
        stencil_reach: usize,
        visible: impl Fn(u16, u16) -> bool,
    ) -> OccupancyMap {
        let s = 1usize << cube_log2;
        let vd = volume.dims;
        let dims = vd.map(|d| d.div_ceil(s));
        let mut cells = vec![0u8; dims[0] * dims[1] * dims[2]];
        // Per-axis voxel ranges of each sub-cube's dilated block.
        let ranges: [Vec<(usize, usize)>; 3] = [0, 1, 2].map(|a| {
            (0..dims[a])
                .map(|c| dilated_range(c, cube_log2, stencil_reach, vd[a]))
                .collect()
        });
        for cz in 0..dims[2] {
            for cy in 0..dims[1] {
                for cx in 0..dims[0] {
                    let (mut min, mut max) = (u16::MAX, 0u16);
                    for z in ranges[2][cz].0..=ranges[2][cz].1 {
                        for y in ranges[1][cy].0..=ranges[1][cy].1 {
                            let row = volume.index(0, y, z);
                            let xs = &volume.data[row + ranges[0][cx].0..=row + ranges[0][cx].1];
                            for &v in xs {
                                min = min.min(v);
                                max = max.max(v);
                            }
                        }
                    }
                    let occupied = match kind {
                        OccupancyKind::Zero => max > 0,
                        OccupancyKind::Class => visible(min, max),
                    };
                    cells[cx + dims[0] * (cy + dims[1] * cz)] = occupied as u8;
                }
            }
        }
        Self::from_cells(cube_log2, dims, cells)
    }

    /// A map from its bits (one per sub-cube, x fastest, non-zero = occupied), with the
    /// hierarchy's groups derived from them: maps built elsewhere (`arch::update`, during a
    /// volume update or from a min/max table).
    pub fn from_cells(cube_log2: u32, dims: [usize; 3], cells: Vec<u8>) -> OccupancyMap {
        assert_eq!(
            cells.len(),
            dims[0] * dims[1] * dims[2],
            "one cell per sub-cube"
        );
        let group_dims = dims.map(|d| d.div_ceil(2));
        let mut groups = vec![0u8; group_dims[0] * group_dims[1] * group_dims[2]];
        for cz in 0..dims[2] {
            for cy in 0..dims[1] {
                for cx in 0..dims[0] {
                    if cells[cx + dims[0] * (cy + dims[1] * cz)] != 0 {
                        groups[cx / 2 + group_dims[0] * (cy / 2 + group_dims[1] * (cz / 2))] = 1;
                    }
                }
            }
        }
        OccupancyMap {
            cube_log2,
            dims,
            cells,
            group_dims,
            groups,
        }
    }

    pub fn subcube_size(&self) -> usize {
        1 << self.cube_log2
    }

    /// Whether sub-cube (cx, cy, cz) is occupied.
    #[inline(always)]
    pub fn occupied(&self, c: [usize; 3]) -> bool {
        self.cells[c[0] + self.dims[0] * (c[1] + self.dims[1] * c[2])] != 0
    }

    /// Whether the 2×2×2 group containing sub-cube c has any occupied sub-cube.
    #[inline(always)]
    pub fn group_occupied(&self, c: [usize; 3]) -> bool {
        let g = [c[0] >> 1, c[1] >> 1, c[2] >> 1];
        self.groups[g[0] + self.group_dims[0] * (g[1] + self.group_dims[1] * g[2])] != 0
    }

    pub fn subcubes(&self) -> usize {
        self.cells.len()
    }

    pub fn empty_subcubes(&self) -> usize {
        self.cells.iter().filter(|&&c| c == 0).count()
    }

    pub fn empty_groups(&self) -> usize {
        self.groups.iter().filter(|&&g| g == 0).count()
    }

    /// SRAM bits the map needs: one per sub-cube; with the hierarchy the map is padded to whole
    /// bytes of 2×2×2 sub-cubes (one byte per group).
    pub fn storage_bits(&self, hierarchy: bool) -> u64 {
        if hierarchy {
            8 * self.groups.len() as u64
        } else {
            self.cells.len() as u64
        }
    }

    /// An error when the map does not fit an SRAM of `capacity_bits`.
    pub fn check_fits(&self, hierarchy: bool, capacity_bits: u64, source: &str) -> Result<()> {
        let bits = self.storage_bits(hierarchy);
        if bits > capacity_bits {
            return Err(Error::config(
                source,
                "occupancy.sram_bits",
                format!(
                    "the {}³ occupancy map needs {bits} bits{}, more than the SRAM's {capacity_bits}; \
                     raise occupancy.sram_bits or use larger sub-cubes",
                    self.subcube_size(),
                    if hierarchy { " (with the hierarchy)" } else { "" }
                ),
            ));
        }
        Ok(())
    }
}

#[cfg(test)]
mod tests {
    use super::hierarchy_without_effect;

    /// The hierarchy groups nothing only when the volume is one sub-cube along every axis; two
    /// along any axis make groups of two.
    #[test]
    fn a_hierarchy_groups_nothing_only_over_a_single_sub_cube() {
        assert!(hierarchy_without_effect([64, 64, 64], 64).is_some());
        assert!(hierarchy_without_effect([32, 20, 7], 32).is_some());
        assert!(hierarchy_without_effect([64, 64, 64], 32).is_none());
        assert!(hierarchy_without_effect([64, 64, 65], 64).is_none());
        assert!(hierarchy_without_effect([64, 64, 64], 0).is_none());
    }
}
