//! Leap values integrated into the volume (steps 1–4) and the distance volume (step 5):
//! hand-made volumes with known answers, brute-force checks on random volumes, the checkers'
//! own tests (an injected overestimate must be caught), the ray protocol the guard distance is
//! derived for, and bad input.

use proptest::prelude::*;
use vizsim::error::Error;
use vizsim::functional::arith::{interpolate, ClassificationTable};
use vizsim::leapvalues::{
    classify, distance_steps, distance_volume, encode_volume, leap_steps, leap_values, preprocess,
    range_from_fraction, segment, verify_distance_volume, verify_leap_values, EncodedVolume,
    GuardDistance, LeapValueParams, Preprocessed, SegmentationParams, VolumeWord, VoxelClass,
};
use vizsim::transfer::{ControlPoint, TransferFunction};
use vizsim::volume::phantom::{generate, PhantomKind, PhantomSpec};
use vizsim::volume::Volume;

// ---------------------------------------------------------------- helpers

fn volume(dims: [usize; 3], mut f: impl FnMut(usize, usize, usize) -> u16) -> Volume {
    let mut data = Vec::with_capacity(dims.iter().product());
    for z in 0..dims[2] {
        for y in 0..dims[1] {
            for x in 0..dims[0] {
                data.push(f(x, y, z));
            }
        }
    }
    Volume::new("test", dims, [1.0; 3], 8, data).unwrap()
}

fn index(dims: [usize; 3], x: usize, y: usize, z: usize) -> usize {
    x + dims[0] * (y + dims[1] * z)
}

fn params(range: u16, min_region_size: u64, max_spacing: f32, spacing: f32) -> LeapValueParams {
    LeapValueParams {
        segmentation: SegmentationParams {
            range,
            min_region_size,
        },
        max_spacing,
        spacing,
        layout: VolumeWord::default(),
    }
}

/// The field an `Error::Config` names, or panics.
fn config_field(error: Error) -> String {
    match error {
        Error::Config { field, .. } => field,
        other => panic!("expected a configuration error, got {other}"),
    }
}

/// A small deterministic generator for the random volumes.
struct Rng(u64);

impl Rng {
    fn next(&mut self) -> u64 {
        self.0 = self
            .0
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        self.0 >> 33
    }
    fn below(&mut self, n: u64) -> u64 {
        self.next() % n
    }
    fn unit(&mut self) -> f64 {
        self.next() as f64 / (1u64 << 31) as f64
    }
}

/// A block of material (value 150 ± noise) in air (0 ± noise) with a few boxes of other values
/// (holes, inclusions): big homogeneous regions with defects, like the cast phantom.
fn random_part(dims: [usize; 3], seed: u64, noise: u64) -> Volume {
    let mut rng = Rng(seed);
    let lo = dims.map(|d| rng.below(d as u64 / 3 + 1) as usize);
    let hi = dims.map(|d| d - 1 - rng.below(d as u64 / 3 + 1) as usize);
    let boxes: Vec<([usize; 3], [usize; 3], u16)> = (0..rng.below(4))
        .map(|_| {
            let a = dims.map(|d| rng.below(d as u64) as usize);
            let size = [0; 3].map(|_| rng.below(3) as usize);
            let value = [0, 60, 100, 220][rng.below(4) as usize];
            (a, [a[0] + size[0], a[1] + size[1], a[2] + size[2]], value)
        })
        .collect();
    let mut values = Rng(seed ^ 0x5555);
    volume(dims, |x, y, z| {
        let p = [x, y, z];
        let inside = |a: [usize; 3], b: [usize; 3]| (0..3).all(|i| p[i] >= a[i] && p[i] <= b[i]);
        let base = boxes
            .iter()
            .find(|(a, b, _)| inside(*a, *b))
            .map(|b| b.2)
            .unwrap_or(if inside(lo, hi) { 150 } else { 0 });
        let n = if noise == 0 {
            0
        } else {
            values.below(2 * noise + 1)
        };
        (base + n as u16).saturating_sub(noise as u16).min(255)
    })
}

/// Squared Euclidean distance from voxel p to the nearest voxel outside its region or to the
/// outside of the volume, by brute force.
fn true_distance2(labels: &[u32], dims: [usize; 3], p: usize) -> u64 {
    let c = |i: usize| {
        [
            (i % dims[0]) as i64,
            (i / dims[0] % dims[1]) as i64,
            (i / (dims[0] * dims[1])) as i64,
        ]
    };
    let pc = c(p);
    let mut best = (0..3)
        .map(|a| (pc[a] + 1).min(dims[a] as i64 - pc[a]).pow(2) as u64)
        .min()
        .unwrap();
    for q in 0..labels.len() {
        if labels[q] != labels[p] {
            let qc = c(q);
            best = best.min((0..3).map(|a| (pc[a] - qc[a]).pow(2) as u64).sum());
        }
    }
    best
}

// ---------------------------------------------------------------- step 1: segmentation

#[test]
fn two_halves_make_two_regions_with_their_boundaries() {
    let dims = [8, 4, 4];
    let v = volume(dims, |x, _, _| if x < 4 { 10 } else { 100 });
    let s = segment(
        &v,
        SegmentationParams {
            range: 5,
            min_region_size: 1,
        },
    )
    .unwrap();
    assert_eq!(s.regions.len(), 2);
    let (left, right) = (&s.regions[0], &s.regions[1]);
    assert_eq!((left.seed, left.voxels, left.mean), (0, 64, 10));
    assert_eq!((right.seed, right.voxels, right.mean), (4, 64, 100));
    // Each region's boundary is the other half's face next to it.
    let face = |x: usize| -> Vec<u32> {
        let mut f: Vec<u32> = (0..4)
            .flat_map(|z| (0..4).map(move |y| index(dims, x, y, z) as u32))
            .collect();
        f.sort();
        f
    };
    assert_eq!(left.boundary, face(4));
    assert_eq!(right.boundary, face(3));
    assert_eq!(s.labels[index(dims, 3, 2, 1)], 1);
    assert_eq!(s.labels[index(dims, 4, 2, 1)], 2);
}

#[test]
fn the_criterion_is_relative_to_the_seed() {
    // A ramp 0, 1, ..., 7 along x, range 2: seed 0 takes {0, 1, 2}, then seed 3 takes
    // {3, 4, 5}, seed 6 takes {6, 7}. (A running-mean criterion would creep further.)
    let v = volume([8, 2, 2], |x, _, _| x as u16);
    let s = segment(
        &v,
        SegmentationParams {
            range: 2,
            min_region_size: 1,
        },
    )
    .unwrap();
    let row: Vec<u32> = (0..8).map(|x| s.labels[x]).collect();
    assert_eq!(row, vec![1, 1, 1, 2, 2, 2, 3, 3]);
    assert_eq!(
        s.regions.iter().map(|r| r.seed_value).collect::<Vec<_>>(),
        vec![0, 3, 6]
    );
    assert_eq!((s.regions[1].min, s.regions[1].max), (3, 5));
}

#[test]
fn regions_are_six_connected() {
    // Two cubes of 100 touching only along an edge: two regions; the air around is a third.
    let v = volume([6, 6, 2], |x, y, _| {
        if (x < 3 && y < 3) || (x >= 3 && y >= 3) {
            100
        } else {
            0
        }
    });
    let s = segment(
        &v,
        SegmentationParams {
            range: 0,
            min_region_size: 1,
        },
    )
    .unwrap();
    assert_eq!(s.regions.len(), 4); // cube, air (x >= 3, y < 3), air (x < 3, y >= 3), cube
    assert_ne!(
        s.labels[index([6, 6, 2], 2, 2, 0)],
        s.labels[index([6, 6, 2], 3, 3, 0)]
    );
}

#[test]
fn small_regions_are_dissolved_and_not_seeds_again() {
    // A lone voxel of 50 in a block of 10: with min size 2 it belongs to no region, and it is
    // in the block's boundary (tried and refused).
    let dims = [5, 5, 5];
    let v = volume(dims, |x, y, z| if (x, y, z) == (2, 2, 2) { 50 } else { 10 });
    let s = segment(
        &v,
        SegmentationParams {
            range: 5,
            min_region_size: 2,
        },
    )
    .unwrap();
    assert_eq!(s.regions.len(), 1);
    assert_eq!((s.dissolved_regions, s.dissolved_voxels), (1, 1));
    let lone = index(dims, 2, 2, 2);
    assert_eq!(s.labels[lone], 0);
    assert!(s.region_of(lone).is_none());
    assert_eq!(s.regions[0].boundary, vec![lone as u32]);
    // A dissolved region seeded first is not absorbed later: voxel 0 alone at 30, then 10s.
    let v = volume(dims, |x, y, z| if (x, y, z) == (0, 0, 0) { 30 } else { 10 });
    let s = segment(
        &v,
        SegmentationParams {
            range: 5,
            min_region_size: 2,
        },
    )
    .unwrap();
    assert_eq!(s.labels[0], 0);
    assert_eq!(s.regions.len(), 1);
    assert_eq!(s.regions[0].voxels, 124);
}

#[test]
fn a_single_region_volume_is_bounded_by_the_volume_faces() {
    // Documented behaviour: a volume that is one region has no refused voxels (empty boundary
    // list), and the outside of the volume plays the boundary: guards along the faces, leap
    // values measured to the faces.
    let dims = [16, 16, 16];
    let v = volume(dims, |_, _, _| 77);
    let p = preprocess(&v, &params(0, 1, 1.0, 1.0)).unwrap();
    assert_eq!(p.segmentation.regions.len(), 1);
    assert!(p.segmentation.regions[0].boundary.is_empty());
    assert_eq!(p.classification.leaps, 10 * 10 * 10); // [3, 12]^3
    let centre = index(dims, 7, 7, 7);
    assert_eq!(p.leap_values.values[centre], 5); // 8 to the face x = -1, minus 3
    verify_leap_values(&p.segmentation, &p.classification, &p.leap_values).unwrap();
}

#[test]
fn the_fill_is_iterative_on_a_large_serpentine() {
    // A 1-voxel-wide path that snakes through a 96x96x8 volume: a recursive fill would need
    // recursion depth in the tens of thousands.
    let dims = [96, 96, 8];
    let v = volume(dims, |x, y, z| {
        let path = if y % 2 == 0 {
            true
        } else if (y / 2) % 2 == 0 {
            x == dims[0] - 1
        } else {
            x == 0
        };
        if path && z == 0 {
            200
        } else {
            0
        }
    });
    let s = segment(
        &v,
        SegmentationParams {
            range: 0,
            min_region_size: 1,
        },
    )
    .unwrap();
    let path_label = s.labels[0];
    let path_voxels = s.regions[path_label as usize - 1].voxels;
    assert_eq!(path_voxels, 48 * 96 + 48);
}

#[test]
fn segmentation_rejects_bad_parameters() {
    let v = volume([4, 4, 4], |_, _, _| 1);
    let bad = |range, min_region_size| {
        config_field(
            segment(
                &v,
                SegmentationParams {
                    range,
                    min_region_size,
                },
            )
            .unwrap_err(),
        )
    };
    assert_eq!(bad(256, 1), "leap_values.range");
    assert_eq!(bad(10, 0), "leap_values.min_region_size");
    assert_eq!(range_from_fraction(0.05, &v).unwrap(), 13);
    for f in [-0.1, 1.5, f64::NAN] {
        assert_eq!(
            config_field(range_from_fraction(f, &v).unwrap_err()),
            "leap_values.range_fraction"
        );
    }
}

// ---------------------------------------------------------------- step 2: classification

#[test]
fn guard_distance_follows_the_largest_spacing() {
    for (s, g) in [
        (1.0 / 64.0, 3),
        (0.5, 3),
        (1.0, 3),
        (1.9, 3),
        (2.0, 4),
        (2.5, 4),
        (3.0, 5),
        (16.0, 18),
    ] {
        let guard = GuardDistance::for_max_spacing(s).unwrap();
        assert_eq!(guard.voxels(), g, "S_max {s}");
    }
    for s in [0.0, -1.0, 0.01, 16.5, f32::NAN, f32::INFINITY] {
        assert_eq!(
            config_field(GuardDistance::for_max_spacing(s).unwrap_err()),
            "leap_values.max_spacing"
        );
    }
    let guard = GuardDistance::for_max_spacing(1.0).unwrap();
    guard.check_spacing(0.5).unwrap();
    guard.check_spacing(1.0).unwrap();
    let e = guard.check_spacing(1.25).unwrap_err();
    assert!(
        e.to_string()
            .contains("larger than the guard distance allows"),
        "{e}"
    );
}

#[test]
fn a_hole_removes_leap_voxels_within_the_guard_cube() {
    // 16^3 of 100 with one voxel of 0 at (8, 8, 8), dissolved (min size 2). g = 3: leap
    // voxels are [3, 12]^3 minus the cube [5, 11]^3 around the hole.
    let dims = [16, 16, 16];
    let v = volume(dims, |x, y, z| if (x, y, z) == (8, 8, 8) { 0 } else { 100 });
    let s = segment(
        &v,
        SegmentationParams {
            range: 10,
            min_region_size: 2,
        },
    )
    .unwrap();
    let c = classify(&s, GuardDistance::for_max_spacing(1.0).unwrap());
    assert_eq!(c.leaps, 1000 - 343);
    assert_eq!(c.guards, 16 * 16 * 16 - 1 - c.leaps);
    let class = |x, y, z| c.classes[index(dims, x, y, z)];
    assert_eq!(class(8, 8, 8), VoxelClass::NoRegion);
    assert_eq!(class(11, 8, 8), VoxelClass::Guard); // 3 from the hole
    assert_eq!(class(12, 8, 8), VoxelClass::Leap); // 4 from the hole, 3 from the face
    assert_eq!(class(13, 8, 8), VoxelClass::Guard); // 3 from the outside (x = 16)
    assert_eq!(class(4, 4, 4), VoxelClass::Leap); // Chebyshev 4 from the hole
    assert_eq!(class(5, 5, 5), VoxelClass::Guard); // Chebyshev 3 from the hole

    // Step 3 on the same volume, S = 1.
    let l = leap_values(&s, &c, 1.0, &VolumeWord::default()).unwrap();
    let value = |x, y, z| l.values[index(dims, x, y, z)];
    assert_eq!(value(12, 8, 8), 1); // 4 to the hole, 4 to the face: 4 - 3
    assert_eq!(value(4, 8, 8), 1); // 4 to the hole, 5 to the face
    assert_eq!(value(4, 4, 4), 2); // 5 to the face x = -1; hole at sqrt(48) = 6.93
    assert_eq!(value(11, 8, 8), 0); // a guard
    verify_leap_values(&s, &c, &l).unwrap();
    // S = 0.5 doubles the steps; S = 0.3 counts floor(distance - 3) / 0.3.
    let guard = GuardDistance::for_max_spacing(1.0).unwrap();
    let c = classify(&s, guard);
    let l = leap_values(&s, &c, 0.5, &VolumeWord::default()).unwrap();
    assert_eq!(l.values[index(dims, 4, 4, 4)], 4);
    let l = leap_values(&s, &c, 0.3, &VolumeWord::default()).unwrap();
    assert_eq!(l.values[index(dims, 4, 4, 4)], 6);
}

// ---------------------------------------------------------------- step 3: leap values

#[test]
fn leap_steps_round_down_exactly() {
    // (squared distance, g, S, steps): L·S + g <= distance, the largest such L.
    for (d2, g, s, expected) in [
        (25, 3, 1.0, 2),
        (25, 3, 0.5, 4),
        (26, 3, 1.0, 2),
        (36, 3, 1.5, 2), // exactly 3·... 2·1.5 + 3 = 6: equality is allowed
        (35, 3, 1.5, 1),
        (9, 3, 1.0, 0),
        (8, 3, 1.0, 0),
        (32, 3, 0.25, 10), // 5.657 - 3 = 2.657 -> 10.6 steps
        (100, 4, 0.1, 59), // 0.1f32 is a little above 0.1, so 60 steps are 6.0000001 > 6
    ] {
        assert_eq!(leap_steps(d2, g, s), expected, "d2 {d2}, g {g}, S {s}");
    }
    assert_eq!(leap_steps(100, 3, f32::NAN), 0);
}

#[test]
fn leap_values_saturate_to_the_field() {
    let dims = [40, 40, 40];
    let v = volume(dims, |_, _, _| 9);
    let layout = VolumeWord::new(32, 8, 2).unwrap();
    let p = preprocess(
        &v,
        &LeapValueParams {
            layout,
            ..params(0, 1, 1.0, 1.0)
        },
    )
    .unwrap();
    assert_eq!(p.leap_values.max, 3);
    assert!(p.leap_values.saturated > 0);
    assert_eq!(p.leap_values.values[index(dims, 20, 20, 20)], 3); // 17 would be exact
    assert_eq!(p.leap_values.values[index(dims, 4, 20, 20)], 2);
}

#[test]
fn spacing_beyond_the_guard_distance_is_an_error() {
    let v = volume([8, 8, 8], |_, _, _| 1);
    let e = preprocess(&v, &params(0, 1, 1.0, 2.0)).unwrap_err();
    assert_eq!(config_field(e), "leap_values.max_spacing");
    let s = segment(
        &v,
        SegmentationParams {
            range: 0,
            min_region_size: 1,
        },
    )
    .unwrap();
    let c = classify(&s, GuardDistance::for_max_spacing(1.0).unwrap());
    let e = leap_values(&s, &c, 1.5, &VolumeWord::default()).unwrap_err();
    assert!(e.to_string().contains("guard distance"), "{e}");
    let e = leap_values(&s, &c, 0.0, &VolumeWord::default()).unwrap_err();
    assert_eq!(config_field(e), "leap_values.spacing");
}

#[test]
fn the_checker_catches_an_injected_overestimate() {
    let dims = [16, 16, 16];
    let v = volume(dims, |x, y, z| if (x, y, z) == (8, 8, 8) { 0 } else { 100 });
    let mut p = preprocess(&v, &params(10, 2, 1.0, 1.0)).unwrap();
    verify_leap_values(&p.segmentation, &p.classification, &p.leap_values).unwrap();
    // One more step than the distance allows, at one voxel.
    let i = index(dims, 4, 4, 4);
    p.leap_values.values[i] += 1;
    let e = verify_leap_values(&p.segmentation, &p.classification, &p.leap_values).unwrap_err();
    assert!(e.to_string().contains("overestimates"), "{e}");
    assert!(e.to_string().contains("1 violation"), "{e}");
    p.leap_values.values[i] -= 1;
    // A guard made a leap voxel is caught too.
    let j = index(dims, 5, 5, 5);
    p.classification.classes[j] = VoxelClass::Leap;
    let e = verify_leap_values(&p.segmentation, &p.classification, &p.leap_values).unwrap_err();
    assert!(e.to_string().contains("expected Guard"), "{e}");
}

#[test]
fn the_checker_refuses_large_volumes() {
    let v = volume([40, 40, 40], |_, _, _| 1);
    let p = preprocess(&v, &params(0, 1, 1.0, 1.0)).unwrap();
    let e = verify_leap_values(&p.segmentation, &p.classification, &p.leap_values).unwrap_err();
    assert!(e.to_string().contains("at most"), "{e}");
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// Leap values never overestimate: L·S + g <= the true Euclidean distance to the nearest
    /// voxel outside the region (or the volume), on random small volumes; and the checker
    /// agrees.
    #[test]
    fn leap_values_never_overestimate(
        seed in any::<u64>(),
        dims in prop::array::uniform3(4usize..=12),
        noise in 0u64..=4,
        range in 0u16..=12,
        min_region_size in 1u64..=6,
        max_spacing in 0.25f32..=3.0,
        spacing_fraction in 0.1f32..=1.0,
        leap_bits in 1u32..=10,
    ) {
        let v = random_part(dims, seed, noise);
        let spacing = (max_spacing * spacing_fraction).max(1.0 / 64.0);
        let p = preprocess(&v, &LeapValueParams {
            layout: VolumeWord::new(32, 8, leap_bits).unwrap(),
            ..params(range, min_region_size, max_spacing, spacing)
        }).unwrap();
        let g = p.classification.guard.voxels() as f64;
        for i in 0..v.data.len() {
            if p.classification.classes[i] == VoxelClass::Leap {
                let distance = (true_distance2(&p.segmentation.labels, dims, i) as f64).sqrt();
                let l = p.leap_values.values[i] as f64;
                prop_assert!(l * spacing as f64 + g <= distance + 1e-9,
                    "voxel {i}: L {l} S {spacing} g {g} distance {distance}");
                // Quantised down by less than one step (unless saturated).
                if p.leap_values.values[i] < (1 << leap_bits) - 1 {
                    prop_assert!((l + 1.0) * spacing as f64 + g > distance - 1e-9);
                }
            }
        }
        prop_assert!(verify_leap_values(&p.segmentation, &p.classification, &p.leap_values).is_ok());
    }

    /// The geometric promise behind the leap values (docs/leapvalues.md, claim B): a ray at P
    /// whose nearest voxel is leap voxel p with value L, advancing max(L, 1) steps, passes and
    /// lands only on samples whose trilinear neighbourhood lies inside p's region.
    #[test]
    fn leaps_pass_only_region_neighbourhoods(
        seed in any::<u64>(),
        dims in prop::array::uniform3(8usize..=16),
        max_spacing in 0.25f32..=3.0,
        spacing_fraction in 0.1f32..=1.0,
    ) {
        let v = random_part(dims, seed, 2);
        let spacing = (max_spacing * spacing_fraction).max(1.0 / 64.0);
        let p = preprocess(&v, &params(6, 4, max_spacing, spacing)).unwrap();
        let mut rng = Rng(seed ^ 0xabcdef);
        let leap_voxels: Vec<usize> = (0..v.data.len())
            .filter(|&i| p.classification.classes[i] == VoxelClass::Leap)
            .collect();
        for _ in 0..40 {
            if leap_voxels.is_empty() {
                break;
            }
            let i = leap_voxels[rng.below(leap_voxels.len() as u64) as usize];
            let pc = [i % dims[0], i / dims[0] % dims[1], i / (dims[0] * dims[1])];
            let start = pc.map(|c| c as f64 + rng.unit() - 0.5);
            let dir = random_direction(&mut rng);
            let result = check_leap(&p, i, start, dir, spacing as f64);
            prop_assert!(result.is_ok(), "{}", result.unwrap_err());
        }
    }

    /// The ray protocol the guard distance is derived for (docs/leapvalues.md, claim A): rays
    /// entering through the box faces never read a flagged word in trilinear mode.
    #[test]
    fn trilinear_mode_never_reads_a_leap_word(
        seed in any::<u64>(),
        dims in prop::array::uniform3(8usize..=18),
        max_spacing in 0.25f32..=3.0,
        spacing_fraction in 0.1f32..=1.0,
        noise in 0u64..=2,
    ) {
        let v = random_part(dims, seed, noise);
        let spacing = (max_spacing * spacing_fraction).max(1.0 / 64.0);
        let p = preprocess(&v, &params(4, 4, max_spacing, spacing)).unwrap();
        let mut rng = Rng(seed ^ 0x1234);
        for _ in 0..60 {
            let result = walk_protocol(&p.encoded, &mut rng, spacing as f64);
            prop_assert!(result.is_ok(), "{}", result.unwrap_err());
        }
    }
}

/// Claim B for one leap: from `start` (whose nearest voxel is leap voxel `i`) along `dir`, the
/// max(L, 1) + 1 sample positions passed and landed on have their whole 2×2×2 neighbourhood in
/// voxel i's region.
fn check_leap(
    p: &Preprocessed,
    i: usize,
    start: [f64; 3],
    dir: [f64; 3],
    spacing: f64,
) -> Result<(), String> {
    let dims = p.encoded.dims;
    let labels = &p.segmentation.labels;
    let steps = p.leap_values.values[i].max(1) as usize;
    for j in 0..=steps {
        let q = [0, 1, 2].map(|a| start[a] + j as f64 * spacing * dir[a]);
        if (0..3).any(|a| q[a] < 0.0 || q[a] > (dims[a] - 1) as f64) {
            return Err(format!(
                "sample {j} of a leap of {steps} left the box at {q:?}"
            ));
        }
        let base = [0, 1, 2].map(|a| (q[a].floor() as usize).min(dims[a] - 2));
        for corner in 0..8 {
            let u = index(
                dims,
                base[0] + (corner & 1),
                base[1] + (corner >> 1 & 1),
                base[2] + (corner >> 2),
            );
            if labels[u] != labels[i] {
                return Err(format!(
                    "sample {j} of a leap of {steps} from voxel {i} at {q:?} reads voxel {u} of another region"
                ));
            }
        }
    }
    Ok(())
}

#[test]
fn a_diagonal_leap_towards_a_hole_stays_in_the_region() {
    // The worst case of claim B: the ray starts half a voxel off its leap voxel p and heads
    // straight along the diagonal at a hole 4 voxels away on each axis (distance 6.93). With
    // g = 3 the leap stops short of every cell that touches the hole; with g = 2 (below
    // 1.5·sqrt(3) = 2.6) a passed sample's cell would have the hole as a corner. S_max = 0.5,
    // so g = 3 comes from this bound, not from the spacing.
    let dims = [24, 24, 24];
    let v = volume(
        dims,
        |x, y, z| if (x, y, z) == (12, 12, 12) { 0 } else { 100 },
    );
    let p = preprocess(&v, &params(10, 2, 0.5, 0.1)).unwrap();
    let i = index(dims, 8, 8, 8);
    assert_eq!(p.classification.classes[i], VoxelClass::Leap);
    let d = 1.0 / 3f64.sqrt();
    check_leap(&p, i, [8.49; 3], [d; 3], 0.1f32 as f64).unwrap();
    assert_eq!(p.leap_values.values[i], 39); // (6.93 - 3) / 0.1
}

fn random_direction(rng: &mut Rng) -> [f64; 3] {
    loop {
        let d = [0; 3].map(|_| rng.unit() * 2.0 - 1.0);
        let n = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if n > 0.1 && n <= 1.0 {
            return d.map(|c| c / n);
        }
    }
}

/// One ray through the encoded volume under the documented protocol. Trilinear mode: when the
/// cell's eight words are identical and unflagged, enter region mode with their density. Region
/// mode (value m): the nearest voxel's word; flagged: m := its density, advance max(L, 1)
/// steps; unflagged with density m: one step; else leave region mode and process this sample
/// in trilinear mode. Err when a trilinear-mode sample sees a flagged word.
fn walk_protocol(encoded: &EncodedVolume, rng: &mut Rng, spacing: f64) -> Result<(), String> {
    let dims = encoded.dims;
    let hi = dims.map(|d| (d - 1) as f64);
    let centre = hi.map(|h| h / 2.0);
    let radius = (hi[0] * hi[0] + hi[1] * hi[1] + hi[2] * hi[2]).sqrt();
    let out = random_direction(rng);
    let origin: Vec<f64> = (0..3).map(|a| centre[a] + radius * out[a]).collect();
    let target: Vec<f64> = (0..3).map(|a| rng.unit() * hi[a]).collect();
    let mut dir: Vec<f64> = (0..3).map(|a| target[a] - origin[a]).collect();
    let n = (dir[0] * dir[0] + dir[1] * dir[1] + dir[2] * dir[2]).sqrt();
    dir.iter_mut().for_each(|c| *c /= n);
    // Slab clipping against [0, dims - 1].
    let (mut t0, mut t1) = (0.0f64, f64::INFINITY);
    for a in 0..3 {
        if dir[a].abs() < 1e-12 {
            if origin[a] < 0.0 || origin[a] > hi[a] {
                return Ok(());
            }
            continue;
        }
        let (ta, tb) = ((0.0 - origin[a]) / dir[a], (hi[a] - origin[a]) / dir[a]);
        t0 = t0.max(ta.min(tb));
        t1 = t1.min(ta.max(tb));
    }
    if t0 > t1 {
        return Ok(());
    }
    // Samples on a grid t = offset + k·S fixed to the ray, the first at or after entry.
    let offset = rng.unit() * spacing;
    let mut k = ((t0 - offset) / spacing).ceil() as i64;
    let last = ((t1 - offset) / spacing).floor() as i64;
    let word = |x: usize, y: usize, z: usize| encoded.decode(index(dims, x, y, z));
    let mut region: Option<u16> = None;
    while k <= last {
        let t = offset + k as f64 * spacing;
        let pos: Vec<f64> = (0..3)
            .map(|a| (origin[a] + t * dir[a]).clamp(0.0, hi[a]))
            .collect();
        let base: Vec<usize> = (0..3)
            .map(|a| (pos[a].floor() as usize).min(dims[a] - 2))
            .collect();
        let nearest: Vec<usize> = (0..3).map(|a| pos[a].round() as usize).collect();
        let mut advance = 1;
        let mut trilinear = region.is_none();
        if let Some(m) = region {
            let w = word(nearest[0], nearest[1], nearest[2]);
            if let Some(l) = w.leap {
                region = Some(w.density);
                advance = l.max(1) as i64;
            } else if w.density != m {
                region = None;
                trilinear = true;
            }
        }
        if trilinear {
            let corners: Vec<_> = (0..8)
                .map(|c| {
                    word(
                        base[0] + (c & 1),
                        base[1] + (c >> 1 & 1),
                        base[2] + (c >> 2),
                    )
                })
                .collect();
            if corners.iter().any(|w| w.leap.is_some()) {
                return Err(format!(
                    "trilinear sample at {pos:?} (t = {t}) reads a leap word; cell {base:?}"
                ));
            }
            if corners.iter().all(|w| *w == corners[0]) {
                region = Some(corners[0].density);
            }
        }
        k += advance;
    }
    Ok(())
}

// ---------------------------------------------------------------- step 4: the voxel word

#[test]
fn the_word_layout_is_validated_field_by_field() {
    let layout = VolumeWord::default();
    assert_eq!(
        (
            layout.word_bits(),
            layout.density_bits(),
            layout.leap_bits(),
            layout.flag_bit()
        ),
        (32, 16, 15, 31)
    );
    VolumeWord::new(16, 8, 7).unwrap();
    VolumeWord::new(32, 8, 1).unwrap();
    for ((w, d, l), field) in [
        ((32, 16, 0), "volume_word.leap_bits"),
        ((32, 16, 16), "volume_word.leap_bits"),
        ((16, 8, 8), "volume_word.leap_bits"),
        ((33, 16, 15), "volume_word.word_bits"),
        ((1, 1, 1), "volume_word.word_bits"),
        ((32, 0, 15), "volume_word.density_bits"),
        ((32, 17, 10), "volume_word.density_bits"),
    ] {
        assert_eq!(
            config_field(VolumeWord::new(w, d, l).unwrap_err()),
            field,
            "{w} {d} {l}"
        );
    }
    let e = VolumeWord::new(32, 16, 16).unwrap_err().to_string();
    assert!(e.contains("at most 15 leap bits"), "{e}");
}

#[test]
fn words_encode_and_decode() {
    let layout = VolumeWord::default();
    let w = layout.encode(1234, Some(77)).unwrap();
    assert_eq!(w, 0x8000_0000 | 77 << 16 | 1234);
    let d = layout.decode(w);
    assert_eq!((d.density, d.leap), (1234, Some(77)));
    let w = layout.encode(65535, None).unwrap();
    assert_eq!(w, 0xffff);
    assert_eq!(layout.decode(w).leap, None);
    let small = VolumeWord::new(16, 8, 7).unwrap();
    for density in [0u16, 1, 128, 255] {
        for leap in [None, Some(0), Some(1), Some(127)] {
            let d = small.decode(small.encode(density, leap).unwrap());
            assert_eq!((d.density, d.leap), (density, leap));
        }
    }
    assert!(small.encode(256, None).is_err());
    assert!(small.encode(0, Some(128)).is_err());
}

#[test]
fn the_encoded_volume_holds_densities_means_and_leap_values() {
    let dims = [16, 16, 16];
    // 100 ± 2 with a 0-voxel hole at (8, 8, 8); the mean is what guards and leap voxels hold.
    let v = volume(dims, |x, y, z| {
        if (x, y, z) == (8, 8, 8) {
            0
        } else {
            98 + ((x + 2 * y + 3 * z) % 5) as u16
        }
    });
    let p = preprocess(&v, &params(4, 2, 1.0, 1.0)).unwrap();
    assert_eq!(p.segmentation.regions.len(), 1);
    let mean = p.segmentation.regions[0].mean;
    assert_eq!(mean, 100);
    for i in 0..v.data.len() {
        let d = p.encoded.decode(i);
        match p.classification.classes[i] {
            VoxelClass::NoRegion => assert_eq!((d.density, d.leap), (v.data[i], None)),
            VoxelClass::Guard => assert_eq!((d.density, d.leap), (mean, None)),
            VoxelClass::Leap => {
                assert_eq!((d.density, d.leap), (mean, Some(p.leap_values.values[i])))
            }
        }
    }
    let densities = p.encoded.density_volume(&v).unwrap();
    assert_eq!(densities.get(8, 8, 8), 0);
    assert_eq!(densities.get(0, 0, 0), 100);
}

#[test]
fn encoding_rejects_a_density_field_too_narrow_for_the_volume() {
    let data = vec![1000u16; 4 * 4 * 4];
    let v = Volume::new("wide", [4, 4, 4], [1.0; 3], 16, data).unwrap();
    let e = preprocess(
        &v,
        &LeapValueParams {
            layout: VolumeWord::new(32, 8, 10).unwrap(),
            ..params(0, 1, 1.0, 1.0)
        },
    )
    .unwrap_err();
    assert_eq!(config_field(e), "volume_word.density_bits");
    // Mismatched pieces are an error, not a panic.
    let small = volume([4, 4, 4], |_, _, _| 1);
    let other = volume([5, 4, 4], |_, _, _| 1);
    let p = preprocess(&small, &params(0, 1, 1.0, 1.0)).unwrap();
    assert!(encode_volume(
        &other,
        &p.segmentation,
        &p.classification,
        &p.leap_values,
        VolumeWord::default()
    )
    .is_err());
}

// ---------------------------------------------------------------- step 5: distance volume

fn table_for(tf: &TransferFunction, spacing: f32) -> ClassificationTable {
    ClassificationTable::build(tf, 256, 12, spacing)
}

fn step_tf(threshold: f32) -> TransferFunction {
    TransferFunction::new(
        "step".into(),
        String::new(),
        vec![
            ControlPoint {
                value: 0.0,
                rgba: [0.0; 4],
            },
            ControlPoint {
                value: threshold,
                rgba: [0.0; 4],
            },
            ControlPoint {
                value: threshold + 1.0,
                rgba: [1.0, 1.0, 1.0, 0.5],
            },
        ],
        "test",
    )
    .unwrap()
}

#[test]
fn distance_volume_of_a_single_bright_voxel() {
    // One voxel of 200 at (6, 6, 6) in zeros; visible above 100: the 8 cells with bases
    // [5, 6]^3 are visible, so cells [4, 7]^3 are at distance 0.
    let dims = [12, 12, 12];
    let v = volume(dims, |x, y, z| if (x, y, z) == (6, 6, 6) { 200 } else { 0 });
    let table = table_for(&step_tf(100.0), 1.0);
    let dv = distance_volume(&v, 8, |lo, hi| table.any_visible(lo, hi)).unwrap();
    assert_eq!(dv.visible_cells, 8);
    assert_eq!(dv.distance([5, 5, 5]), 0);
    assert_eq!(dv.distance([4, 7, 4]), 0);
    assert_eq!(dv.distance([3, 6, 6]), 1);
    assert_eq!(dv.distance([0, 6, 6]), 4);
    assert_eq!(dv.distance([0, 0, 0]), 6); // sqrt(3 · 4²) = 6.93
    assert_eq!(dv.distance([10, 10, 10]), 5); // sqrt(3 · 3²) = 5.20
    assert_eq!(dv.distance([11, 0, 0]), 0); // the last layer is no cell's base
    verify_distance_volume(&v, &dv, |lo, hi| table.any_visible(lo, hi)).unwrap();
    // Saturation at 2 bits.
    let dv2 = distance_volume(&v, 2, |lo, hi| table.any_visible(lo, hi)).unwrap();
    assert_eq!(dv2.distance([0, 0, 0]), 3);
    assert_eq!(dv2.distance([3, 6, 6]), 1);
    // Nothing visible: everything saturated.
    let dv0 = distance_volume(&v, 4, |_, _| false).unwrap();
    assert_eq!(dv0.distance([5, 5, 5]), 15);
    assert_eq!(dv0.visible_cells, 0);
    // Steps: floor(d / S), exactly.
    assert_eq!(dv.steps([0, 0, 0], 1.0), 6);
    assert_eq!(dv.steps([0, 0, 0], 0.5), 12);
    assert_eq!(dv.steps([0, 0, 0], 0.7), 8);
    assert_eq!(distance_steps(3, 1.5), 2);
    assert_eq!(distance_steps(3, 0.1), 29); // 0.1f32 is a little above 0.1
    assert_eq!(distance_steps(0, 1.0), 0);
    assert_eq!(distance_steps(5, f32::NAN), 0);
}

#[test]
fn distance_volume_rejects_bad_widths_and_the_checker_catches_an_overestimate() {
    let v = volume([8, 8, 8], |x, _, _| if x == 4 { 200 } else { 0 });
    for bits in [0, 9, 16] {
        assert_eq!(
            config_field(distance_volume(&v, bits, |_, hi| hi > 100).unwrap_err()),
            "distance_volume.bits"
        );
    }
    let mut dv = distance_volume(&v, 4, |_, hi| hi > 100).unwrap();
    verify_distance_volume(&v, &dv, |_, hi| hi > 100).unwrap();
    // Cell (0, 0, 0) is 2 cells from the visible ones (bases x = 3, 4): distance 2.
    assert_eq!(dv.distance([0, 0, 0]), 2);
    dv.values[0] = 3;
    let e = verify_distance_volume(&v, &dv, |_, hi| hi > 100).unwrap_err();
    assert!(e.to_string().contains("overestimates"), "{e}");
}

/// Brute-force d(b) = min(floor(min gap), cap) over the visible cells.
fn brute_distances(v: &Volume, bits: u32, visible: impl Fn(u16, u16) -> bool) -> Vec<u32> {
    let dims = v.dims;
    let cd = dims.map(|d| d - 1);
    let cells: Vec<[usize; 3]> = (0..cd[2])
        .flat_map(|z| (0..cd[1]).flat_map(move |y| (0..cd[0]).map(move |x| [x, y, z])))
        .collect();
    let shown: Vec<[usize; 3]> = cells
        .iter()
        .copied()
        .filter(|c| {
            let mut vals = Vec::new();
            for k in 0..8 {
                vals.push(v.get(c[0] + (k & 1), c[1] + (k >> 1 & 1), c[2] + (k >> 2)));
            }
            visible(*vals.iter().min().unwrap(), *vals.iter().max().unwrap())
        })
        .collect();
    let cap = (1u32 << bits) - 1;
    cells
        .iter()
        .map(|b| {
            let best = shown
                .iter()
                .map(|c| -> u64 {
                    (0..3)
                        .map(|a| (b[a].abs_diff(c[a]).saturating_sub(1) as u64).pow(2))
                        .sum()
                })
                .min();
            match best {
                None => cap,
                Some(g2) => ((g2 as f64).sqrt().floor() as u32).min(cap),
            }
        })
        .collect()
}

fn random_tf(rng: &mut Rng) -> TransferFunction {
    let mut values: Vec<f32> = (0..2 + rng.below(4))
        .map(|_| rng.below(256) as f32)
        .collect();
    values.sort_by(f32::total_cmp);
    values.dedup();
    let points = values
        .into_iter()
        .map(|value| ControlPoint {
            value,
            rgba: [0.5, 0.5, 0.5, [0.0, 0.0, 0.4][rng.below(3) as usize]],
        })
        .collect();
    TransferFunction::new("random".into(), String::new(), points, "test").unwrap()
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(96))]

    /// The distance volume is exactly the brute-force distance to the visible cells (so
    /// conservative) on random small volumes and transfer functions, and the checker agrees.
    #[test]
    fn distance_volume_matches_brute_force(
        seed in any::<u64>(),
        dims in prop::array::uniform3(2usize..=11),
        bits in 1u32..=8,
    ) {
        let mut rng = Rng(seed);
        let v = random_part(dims, seed, 3);
        let tf = random_tf(&mut rng);
        let table = table_for(&tf, 1.0);
        let visible = |lo, hi| table.any_visible(lo, hi);
        let dv = distance_volume(&v, bits, visible).unwrap();
        let expected = brute_distances(&v, bits, visible);
        let mut k = 0;
        for z in 0..dims[2] - 1 {
            for y in 0..dims[1] - 1 {
                for x in 0..dims[0] - 1 {
                    prop_assert_eq!(dv.distance([x, y, z]), expected[k], "cell {:?}", [x, y, z]);
                    k += 1;
                }
            }
        }
        prop_assert!(verify_distance_volume(&v, &dv, visible).is_ok());
    }

    /// End to end: fixed-point rays that follow the rule (advance floor(d / S) steps at a
    /// position whose cell stores d) skip only samples the classification table makes fully
    /// transparent.
    #[test]
    fn distance_leaps_skip_only_transparent_samples(
        seed in any::<u64>(),
        dims in prop::array::uniform3(6usize..=14),
        spacing in 0.2f32..=3.0,
    ) {
        let mut rng = Rng(seed);
        let v = random_part(dims, seed, 3);
        let tf = random_tf(&mut rng);
        let table = table_for(&tf, spacing);
        let dv = distance_volume(&v, 8, |lo, hi| table.any_visible(lo, hi)).unwrap();
        let (pf, wb) = (16u32, 9u32);
        let one = (1i64 << pf) as f64;
        let top = dims.map(|d| ((d - 1) as i64) << pf);
        for _ in 0..100 {
            let start = [0; 3].map(|a| (rng.unit() * (dims[a] - 1) as f64 * one) as i64);
            let dir = random_direction(&mut rng);
            let step = dir.map(|c| (c * spacing as f64 * one).round() as i64);
            let inside = |p: [i64; 3]| (0..3).all(|a| p[a] >= 0 && p[a] <= top[a]);
            let mut p = start;
            let mut leaps = 0;
            while inside(p) && leaps < 200 {
                let base = [0, 1, 2].map(|a| ((p[a] >> pf) as usize).min(dims[a] - 2));
                let n = dv.steps(base, spacing) as i64;
                if n == 0 {
                    p = [0, 1, 2].map(|a| p[a] + step[a]);
                    continue;
                }
                for j in 0..n {
                    let q = [0, 1, 2].map(|a| p[a] + j * step[a]);
                    if inside(q) {
                        // The cell of the skipped sample is invisible, so is the sample.
                        let cell = [0, 1, 2].map(|a| ((q[a] >> pf) as usize).min(dims[a] - 2));
                        let corners: Vec<u16> = (0..8)
                            .map(|c| v.get(cell[0] + (c & 1), cell[1] + (c >> 1 & 1), cell[2] + (c >> 2)))
                            .collect();
                        let (lo, hi) = (*corners.iter().min().unwrap(), *corners.iter().max().unwrap());
                        prop_assert!(!table.any_visible(lo, hi),
                            "skipped sample {} of {} at {:?} lies in visible cell {:?}", j, n, q, cell);
                        let density = interpolate(&v, q, pf, wb);
                        prop_assert_eq!(table.lookup(density)[3], 0,
                            "skipped sample {} of {} at {:?} has opacity", j, n, q);
                    }
                }
                p = [0, 1, 2].map(|a| p[a] + n * step[a]);
                leaps += 1;
            }
        }
    }
}

// ---------------------------------------------------------------- the cast phantom

#[test]
fn the_cast_phantom_keeps_its_blowholes_out_of_the_metal() {
    let v = generate(&PhantomSpec {
        size: 64,
        ..PhantomSpec::default_for(PhantomKind::Cast)
    });
    let p: Preprocessed = preprocess(&v, &params(12, 8, 1.0, 1.0)).unwrap();
    let s = &p.segmentation;
    // The largest region apart from the air is the metal, mean 180.
    let air = s.labels[0];
    let metal = s
        .regions
        .iter()
        .enumerate()
        .filter(|&(k, _)| k as u32 + 1 != air)
        .max_by_key(|(_, r)| r.voxels)
        .map(|(k, _)| k as u32 + 1)
        .unwrap();
    let metal_region = &s.regions[metal as usize - 1];
    assert!((176..=184).contains(&metal_region.mean), "{metal_region:?}");
    assert!(p.classification.leaps > 0);
    // No blowhole core (value 0 inside the part's bounding box, not air) is a metal voxel,
    // and no metal leap voxel has a non-metal voxel within the guard cube.
    let dims = v.dims;
    let g = p.classification.guard.voxels() as i64;
    for z in 0..64 {
        for y in 0..64 {
            for x in 0..64 {
                let i = index(dims, x, y, z);
                if v.data[i] == 0 {
                    assert_ne!(s.labels[i], metal);
                }
                if s.labels[i] == metal && p.classification.classes[i] == VoxelClass::Leap {
                    for dz in -g..=g {
                        for dy in -g..=g {
                            for dx in -g..=g {
                                let q = index(
                                    dims,
                                    (x as i64 + dx) as usize,
                                    (y as i64 + dy) as usize,
                                    (z as i64 + dz) as usize,
                                );
                                assert_eq!(s.labels[q], metal);
                            }
                        }
                    }
                }
            }
        }
    }
    // The checker on the 32^3 cast.
    let v = generate(&PhantomSpec {
        size: 32,
        ..PhantomSpec::default_for(PhantomKind::Cast)
    });
    let p = preprocess(&v, &params(12, 8, 1.0, 0.5)).unwrap();
    verify_leap_values(&p.segmentation, &p.classification, &p.leap_values).unwrap();
}
