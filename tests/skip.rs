//! The skip calculator against exact arithmetic: no leap overshoots, in 3D and in the two-level
//! hierarchy (property tests), and the exhaustive verifier both passes the shipped rounding and
//! catches the unsafe one.

use proptest::prelude::*;
use vizsim::skip::{
    exact_steps_to_leave, leap_steps, ray_reciprocals, verify_exhaustive, ReciprocalRounding,
    SkipWidths, VerifyParams, VerifyReport,
};

/// A ray at `p` with increment `v`, both in position units.
#[derive(Debug, Clone)]
struct Ray {
    widths: SkipWidths,
    cube_log2: u32,
    p: [i64; 3],
    v: [i64; 3],
}

fn any_widths() -> impl Strategy<Value = SkipWidths> {
    (4u32..=12)
        .prop_flat_map(|pos| (Just(pos), 0..=pos, 2u32..=24, 0..=pos))
        .prop_map(|(pos, inc, reciprocal, distance)| {
            SkipWidths::new(pos, inc, reciprocal, distance).expect("generated in range")
        })
}

/// One increment component in increment LSBs: zero, perspective-like tiny, or anything up to one
/// voxel; either sign.
fn any_component(inc_frac_bits: u32) -> impl Strategy<Value = i64> {
    let one_voxel = 1i64 << inc_frac_bits;
    let magnitude = prop_oneof![
        1 => Just(0),
        1 => 1..=one_voxel.min(3),
        3 => 1..=one_voxel,
    ];
    (magnitude, any::<bool>()).prop_map(|(m, negative)| if negative { -m } else { m })
}

/// A moving ray anywhere in a 256³ volume.
fn any_ray(cube_log2: std::ops::RangeInclusive<u32>) -> impl Strategy<Value = Ray> {
    (any_widths(), cube_log2)
        .prop_flat_map(|(widths, cube_log2)| {
            let volume = 256i64 << widths.pos_frac_bits;
            (
                Just(widths),
                Just(cube_log2),
                prop::array::uniform3(0..volume),
                prop::array::uniform3(any_component(widths.inc_frac_bits)),
            )
        })
        .prop_filter("a ray always moves", |(_, _, _, v)| v != &[0; 3])
        .prop_map(|(widths, cube_log2, p, v_inc)| Ray {
            widths,
            cube_log2,
            p,
            v: v_inc.map(|c| widths.increment_to_pos_units(c)),
        })
}

/// Steps until `p + n·v` first lies in another region than `p`, one sample at a time; `region`
/// maps a coordinate to its region address. Integers are exact rationals, so this is the truth.
fn steps_to_leave_by_stepping(p: [i64; 3], v: [i64; 3], region: impl Fn(i64) -> i64) -> u64 {
    let start = p.map(&region);
    let mut q = p;
    let mut steps = 0;
    loop {
        steps += 1;
        for axis in 0..3 {
            q[axis] += v[axis];
        }
        if q.map(&region) != start {
            return steps;
        }
    }
}

proptest! {
    #![proptest_config(ProptestConfig::with_cases(1024))]

    /// Every sample skipped by a leap lies in the sub-cube of `p`, and the leap never exceeds the
    /// exact count. `truth` is the first step outside, so `n_s ≤ truth` means P + k·V is inside
    /// for every k in 1..n_s.
    #[test]
    fn leap_never_leaves_the_sub_cube(ray in any_ray(1..=6)) {
        let Ray { widths, cube_log2, p, v } = ray;
        let recips = ray_reciprocals(v, &widths, ReciprocalRounding::Down);
        let leap = leap_steps(p, v, &recips, cube_log2, &widths).expect("the ray moves");
        let shift = cube_log2 + widths.pos_frac_bits;
        let truth = steps_to_leave_by_stepping(p, v, |x| x >> shift);
        prop_assert!(leap >= 1);
        prop_assert!(leap <= truth, "leap {leap} overshoots: the ray leaves after {truth}");
        prop_assert_eq!(exact_steps_to_leave(p, v, cube_log2, widths.pos_frac_bits), Some(truth));
    }

    /// The hierarchy's zero byte covers the 2×2×2 sub-cubes at even addresses. A leap at level
    /// k+1 skips only samples inside that group, and is never shorter than the level-k leap
    /// from the same position (the group leap does not stop at an inner sub-cube boundary).
    #[test]
    fn group_leap_stays_in_its_empty_group(ray in any_ray(1..=5)) {
        let Ray { widths, cube_log2, p, v } = ray;
        let recips = ray_reciprocals(v, &widths, ReciprocalRounding::Down);
        let group_leap = leap_steps(p, v, &recips, cube_log2 + 1, &widths).expect("moves");
        let cube_leap = leap_steps(p, v, &recips, cube_log2, &widths).expect("moves");
        let sub_cube_shift = cube_log2 + widths.pos_frac_bits;
        let byte_address = |x: i64| (x >> sub_cube_shift) >> 1;
        let truth = steps_to_leave_by_stepping(p, v, byte_address);
        prop_assert!(group_leap <= truth, "group leap {group_leap} overshoots {truth}");
        prop_assert!(group_leap >= cube_leap, "group {group_leap} < sub-cube {cube_leap}");
    }
}

#[test]
fn boundaries_by_direction() {
    let widths = SkipWidths::new(8, 8, 8, 8).unwrap();
    let recips = |v| ray_reciprocals(v, &widths, ReciprocalRounding::Down);
    let one_voxel = 1 << 8;
    // s = 2 voxels: mask = 511 position LSBs.
    let last_inside = 511;
    // Moving up from the last position inside: one step lands on the boundary, which is outside.
    let up = [1, 0, 0];
    assert_eq!(
        leap_steps([last_inside, 0, 0], up, &recips(up), 1, &widths),
        Some(1)
    );
    assert_eq!(exact_steps_to_leave([last_inside, 0, 0], up, 1, 8), Some(1));
    // Moving down from the lower boundary: it belongs to this sub-cube, the next step does not.
    let down = [-1, 0, 0];
    assert_eq!(
        leap_steps([512, 0, 0], down, &recips(down), 1, &widths),
        Some(1)
    );
    // Half a voxel above a lower boundary, moving down by quarter voxels: the samples at +1/4 and
    // on the boundary stay inside, the third (-1/4) is the first outside.
    let quarter_down = [0, 0, -one_voxel / 4];
    let r = recips(quarter_down);
    assert_eq!(
        leap_steps([0, 0, 512 + 128], quarter_down, &r, 1, &widths),
        Some(3)
    );
    // Whole-voxel steps from the start of a 4-voxel group at level 2 land on the next group.
    let unit = [0, one_voxel, 0];
    assert_eq!(
        leap_steps([0, 4 * one_voxel, 0], unit, &recips(unit), 2, &widths),
        Some(4)
    );
    // Axes with V = 0 are excluded; no moving axis, no leap.
    assert_eq!(exact_steps_to_leave([0; 3], [0; 3], 1, 8), None);
    assert_eq!(
        leap_steps([0; 3], [0; 3], &recips([0; 3]), 1, &widths),
        None
    );
}

fn verify(
    reciprocal_bits: u32,
    distance_frac_bits: u32,
    cube_log2: u32,
    rounding: ReciprocalRounding,
) -> VerifyReport {
    let widths = SkipWidths::new(8, 8, reciprocal_bits, distance_frac_bits).unwrap();
    verify_exhaustive(&VerifyParams::new(widths, cube_log2, rounding)).unwrap()
}

#[test]
fn exhaustive_shipped_rounding_never_overshoots() {
    for reciprocal_bits in [4, 6, 8, 12] {
        for distance_frac_bits in [0, 4, 8] {
            for cube_log2 in 1..=5 {
                let report = verify(
                    reciprocal_bits,
                    distance_frac_bits,
                    cube_log2,
                    ReciprocalRounding::Down,
                );
                assert_eq!(report.cases, (2u64 << (cube_log2 + 8)) * 256);
                assert_eq!(report.violations, 0, "{report:?}");
                assert_eq!(report.first_violation, None);
            }
        }
    }
}

/// If the verifier found nothing wrong with an unsafe rounding it would prove nothing.
#[test]
fn exhaustive_verifier_catches_nearest_rounding() {
    for reciprocal_bits in [4, 6] {
        for cube_log2 in 1..=5 {
            let report = verify(reciprocal_bits, 8, cube_log2, ReciprocalRounding::Nearest);
            assert!(report.violations > 0, "{report:?}");
            let first = report.first_violation.expect("a violation is recorded");
            assert!(first.computed_steps > first.exact_steps);
            // Re-check the recorded case against the exact reference.
            let v = first.increment; // inc_frac = pos_frac: already position units
            let p = [first.offset as i64, 0, 0];
            assert_eq!(
                exact_steps_to_leave(p, [v, 0, 0], cube_log2, 8),
                Some(first.exact_steps)
            );
        }
    }
}

/// A wider reciprocal rounded down is never smaller (flooring to more bits keeps every bit of the
/// shorter one), so every single leap is at least as long: worst and mean waste never grow.
/// They need not shrink, though: narrowing the distance to `distance_frac_bits` truncates up to
/// `2^(pos_frac - distance_frac) - 1` position LSBs, each a whole step for an increment of one LSB,
/// and no reciprocal width wins those back.
#[test]
fn wasted_steps_never_grow_with_reciprocal_bits() {
    for distance_frac_bits in [8, 4, 0] {
        let reports: Vec<VerifyReport> = (4..=12)
            .map(|bits| verify(bits, distance_frac_bits, 4, ReciprocalRounding::Down))
            .collect();
        for pair in reports.windows(2) {
            let (fewer, more) = (&pair[0], &pair[1]);
            assert!(more.worst_wasted_steps <= fewer.worst_wasted_steps);
            assert!(more.mean_wasted_steps <= fewer.mean_wasted_steps);
        }
        let narrowing_floor = (1 << (8 - distance_frac_bits)) - 1;
        assert!(reports
            .iter()
            .all(|r| r.worst_wasted_steps >= narrowing_floor));
    }
    // Without narrowing the reciprocal is the only loss: from tens of steps at 4 bits down to
    // one at 12 (one, not zero: D·R just below an integer D/a still floors one lower).
    let at = |bits| verify(bits, 8, 4, ReciprocalRounding::Down).worst_wasted_steps;
    assert!(at(4) > 10);
    assert_eq!(at(12), 1);
}

#[test]
fn report_serialises_with_its_parameters() {
    let report = verify(4, 8, 1, ReciprocalRounding::Nearest);
    let json = serde_json::to_value(&report).unwrap();
    assert_eq!(json["params"]["widths"]["reciprocal_bits"], 4);
    assert_eq!(json["params"]["rounding"], "Nearest");
    assert_eq!(json["violations"], report.violations);
    assert!(json["first_violation"]["offset"].is_u64());
}
