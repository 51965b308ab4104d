//! Exact squared Euclidean distance transform of a labelled grid (Felzenszwalb & Huttenlocher's
//! separable lower-envelope algorithm, in exact integer arithmetic, written for vizsim).
//!
//! **What it computes.** For every voxel v with label ℓ(v) ≠ 0: the squared Euclidean distance
//! to the nearest voxel whose label differs from ℓ(v) (label 0 or another label) — and, when
//! `border_counts` is set, to the nearest position just outside the grid. Label-0 voxels get 0.
//! With one label per region this is, for every region voxel, the distance to the nearest
//! voxel outside its own region, for all regions in one transform.
//!
//! **Why per-label runs suffice.** The separable transform minimises, one axis at a time,
//! f(w) + (x − w)² over the voxels w of a line. For a query of label ℓ, a voxel of another label
//! has f = 0 (it is itself a target). Take the maximal run [a, b] of label ℓ containing x: the
//! voxels a − 1 and b + 1 have another label (or are outside the grid), so any site beyond them
//! is farther than they are and can be ignored. So each run is transformed on its own, with
//! f = 0 sites at a − 1 and b + 1 (when they lie inside the grid, or when the border counts).
//!
//! **Exactness.** Distances are integers; the envelope's breakpoints are computed with floor
//! division on integers (v wins over q, v < q, at x iff 2x(q − v) <= f(q) + q² − f(v) − v²), so
//! no floating-point rounding is involved. `tests` checks it against brute force.

use super::lines::{for_each_line, for_each_run};

/// Squared distance of a voxel that has no target in reach (no other label on any of its
/// lines and the border not counting).
pub const UNREACHABLE: u32 = u32::MAX;

/// See the module documentation. `labels` is x fastest with `dims`.
pub fn squared_distance_to_other_label(
    dims: [usize; 3],
    labels: &[u32],
    border_counts: bool,
) -> Vec<u32> {
    let mut f: Vec<u32> = labels
        .iter()
        .map(|&l| if l == 0 { 0 } else { UNREACHABLE })
        .collect();
    for axis in 0..3 {
        for_each_line(
            dims,
            axis,
            Some(labels),
            &mut f,
            Envelope::default,
            |envelope, labels, line| transform_line(envelope, labels, line, border_counts),
        );
    }
    f
}

/// One line: every run of a non-zero label transformed on its own (module documentation).
fn transform_line(envelope: &mut Envelope, labels: &[u32], f: &mut [u32], border_counts: bool) {
    let n = f.len();
    for_each_run(
        n,
        |i| (labels[i] != 0).then_some(labels[i]),
        |a, b| {
            envelope.clear();
            if a > 0 || border_counts {
                envelope.push(a as i64 - 1, 0);
            }
            for (q, &fq) in f.iter().enumerate().take(b + 1).skip(a) {
                if fq != UNREACHABLE {
                    envelope.push(q as i64, fq as i64);
                }
            }
            if b + 1 < n || border_counts {
                envelope.push(b as i64 + 1, 0);
            }
            envelope.evaluate(a, &mut f[a..=b]);
        },
    );
}

/// Lower envelope of the parabolas f(q) + (x − q)², sites pushed in increasing q.
#[derive(Default)]
struct Envelope {
    /// Site positions and values, the envelope's parabolas left to right.
    position: Vec<i64>,
    value: Vec<i64>,
    /// start[j]: the first integer x at which parabola j is the lowest.
    start: Vec<i64>,
}

impl Envelope {
    fn clear(&mut self) {
        self.position.clear();
        self.value.clear();
        self.start.clear();
    }

    fn push(&mut self, q: i64, fq: i64) {
        while let (Some(&v), Some(&fv), Some(&sv)) =
            (self.position.last(), self.value.last(), self.start.last())
        {
            // v is at most q's parabola for x <= floor(num / (2 (q - v))); q wins from s on.
            let num = fq + q * q - fv - v * v;
            let s = num.div_euclid(2 * (q - v)) + 1;
            if s > sv {
                self.position.push(q);
                self.value.push(fq);
                self.start.push(s);
                return;
            }
            // q is lower than v wherever v was lowest: v leaves the envelope. (The first
            // parabola starts at i64::MIN and is never removed: far left, v < q is nearer.)
            self.position.pop();
            self.value.pop();
            self.start.pop();
        }
        self.position.push(q);
        self.value.push(fq);
        self.start.push(i64::MIN);
    }

    /// Writes min over the sites of f(q) + (x − q)² for x = first, first + 1, ... into `out`
    /// (`UNREACHABLE` when there is no site).
    fn evaluate(&self, first: usize, out: &mut [u32]) {
        if self.position.is_empty() {
            out.fill(UNREACHABLE);
            return;
        }
        let mut j = 0;
        for (i, o) in out.iter_mut().enumerate() {
            let x = (first + i) as i64;
            while j + 1 < self.start.len() && self.start[j + 1] <= x {
                j += 1;
            }
            let d = x - self.position[j];
            *o = (self.value[j] + d * d) as u32;
        }
    }
}

/// floor(sqrt(n)), exactly.
pub fn isqrt(n: u64) -> u64 {
    let mut r = (n as f64).sqrt() as u64;
    while r * r > n {
        r -= 1;
    }
    while (r + 1) * (r + 1) <= n {
        r += 1;
    }
    r
}

#[cfg(test)]
mod tests {
    use super::*;

    fn brute_force(dims: [usize; 3], labels: &[u32], border_counts: bool) -> Vec<u32> {
        let idx = |x: usize, y: usize, z: usize| x + dims[0] * (y + dims[1] * z);
        let mut out = vec![0; labels.len()];
        for z in 0..dims[2] {
            for y in 0..dims[1] {
                for x in 0..dims[0] {
                    let l = labels[idx(x, y, z)];
                    if l == 0 {
                        continue;
                    }
                    let mut best = u64::MAX;
                    if border_counts {
                        let p = [x, y, z];
                        for a in 0..3 {
                            let d = (p[a] + 1).min(dims[a] - p[a]) as u64;
                            best = best.min(d * d);
                        }
                    }
                    for qz in 0..dims[2] {
                        for qy in 0..dims[1] {
                            for qx in 0..dims[0] {
                                if labels[idx(qx, qy, qz)] != l {
                                    let d = |a: usize, b: usize| (a as i64 - b as i64).pow(2);
                                    let d2 = (d(x, qx) + d(y, qy) + d(z, qz)) as u64;
                                    best = best.min(d2);
                                }
                            }
                        }
                    }
                    out[idx(x, y, z)] = if best == u64::MAX {
                        UNREACHABLE
                    } else {
                        best as u32
                    };
                }
            }
        }
        out
    }

    #[test]
    fn matches_brute_force_on_pseudo_random_labels() {
        let mut state = 12345u64;
        let mut next = || {
            state = state
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (state >> 33) as u32
        };
        for case in 0..40 {
            let dims = [
                2 + next() as usize % 9,
                2 + next() as usize % 9,
                2 + next() as usize % 9,
            ];
            let n = dims.iter().product();
            // Few labels, mostly one, so there are long runs and deep interiors.
            let labels: Vec<u32> = (0..n)
                .map(|_| match next() % 20 {
                    0 => 0,
                    1 => 2,
                    2 => 3,
                    _ => 1,
                })
                .collect();
            for border in [false, true] {
                assert_eq!(
                    squared_distance_to_other_label(dims, &labels, border),
                    brute_force(dims, &labels, border),
                    "case {case}, dims {dims:?}, border {border}"
                );
            }
        }
    }

    #[test]
    fn isqrt_is_exact() {
        for n in 0..10_000u64 {
            let r = isqrt(n);
            assert!(r * r <= n && (r + 1) * (r + 1) > n);
        }
        assert_eq!(isqrt(u32::MAX as u64), 65535);
    }
}
