//! Runs a one-dimensional operation over every line of a 3D grid along one axis, lines in
//! parallel. Every separable pass of this module (erosion, distance transform, cell min–max,
//! dilation) is one call per axis.
//!
//! Each line is processed on its own, so the result does not depend on the thread count.
//! Lines along y and z are gathered into a contiguous buffer, processed and scattered back; for
//! z the rows of one y are handed to one task, so no two tasks ever share a value.

use rayon::prelude::*;

/// Calls `op(state, labels, values)` once per line along `axis` (0 = x, 1 = y, 2 = z).
/// `values` is the line's values (read and write), `labels` the same line of `labels` (empty
/// when `labels` is None). `init` makes one scratch state per task.
pub(crate) fn for_each_line<T, S, I, F>(
    dims: [usize; 3],
    axis: usize,
    labels: Option<&[u32]>,
    values: &mut [T],
    init: I,
    op: F,
) where
    T: Copy + Send + Sync,
    S: Send,
    I: Fn() -> S + Sync + Send,
    F: Fn(&mut S, &[u32], &mut [T]) + Sync + Send,
{
    let [nx, ny, nz] = dims;
    let plane = nx * ny;
    debug_assert_eq!(values.len(), plane * nz);
    match axis {
        0 => values
            .par_chunks_mut(nx)
            .enumerate()
            .for_each_init(&init, |state, (row, line)| {
                let labels = labels.map_or(&[][..], |l| &l[row * nx..(row + 1) * nx]);
                op(state, labels, line)
            }),
        1 => values.par_chunks_mut(plane).enumerate().for_each_init(
            || (init(), Vec::new(), Vec::new()),
            |(state, label_line, line), (z, slice)| {
                for x in 0..nx {
                    line.clear();
                    line.extend((0..ny).map(|y| slice[x + nx * y]));
                    label_line.clear();
                    if let Some(l) = labels {
                        label_line.extend((0..ny).map(|y| l[x + nx * y + plane * z]));
                    }
                    op(state, label_line, line);
                    for (y, &v) in line.iter().enumerate() {
                        slice[x + nx * y] = v;
                    }
                }
            },
        ),
        _ => {
            // rows_by_y[y][z] is row (y, z): the rows of one y go to one task.
            let mut rows_by_y: Vec<Vec<&mut [T]>> =
                (0..ny).map(|_| Vec::with_capacity(nz)).collect();
            for slice in values.chunks_mut(plane) {
                for (y, row) in slice.chunks_mut(nx).enumerate() {
                    rows_by_y[y].push(row);
                }
            }
            rows_by_y.into_par_iter().enumerate().for_each_init(
                || (init(), Vec::new(), Vec::new()),
                |(state, label_line, line), (y, mut rows)| {
                    for x in 0..nx {
                        line.clear();
                        line.extend(rows.iter().map(|row| row[x]));
                        label_line.clear();
                        if let Some(l) = labels {
                            label_line.extend((0..nz).map(|z| l[x + nx * y + plane * z]));
                        }
                        op(state, label_line, line);
                        for (row, &v) in rows.iter_mut().zip(line.iter()) {
                            row[x] = v;
                        }
                    }
                },
            )
        }
    }
}

/// Calls `f(start, end_inclusive)` for every maximal run of consecutive indices `i` of a line of
/// length `n` on which `key(i)` is `Some` and equal.
#[inline]
pub(crate) fn for_each_run<K: PartialEq>(
    n: usize,
    key: impl Fn(usize) -> Option<K>,
    mut f: impl FnMut(usize, usize),
) {
    let mut a = 0;
    while a < n {
        let Some(k) = key(a) else {
            a += 1;
            continue;
        };
        let mut b = a;
        while b + 1 < n && key(b + 1).as_ref() == Some(&k) {
            b += 1;
        }
        f(a, b);
        a = b + 1;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_axis_visits_every_line_in_order() {
        let dims = [3, 4, 5];
        let n = 60;
        let labels: Vec<u32> = (0..n as u32).collect();
        for axis in 0..3 {
            let mut values: Vec<u32> = vec![0; n];
            for_each_line(
                dims,
                axis,
                Some(&labels),
                &mut values,
                || (),
                |_, labels, line| {
                    assert_eq!(labels.len(), dims[axis]);
                    assert_eq!(line.len(), dims[axis]);
                    // Each value becomes its position along the line; labels must step by
                    // the axis stride.
                    let stride = [1, 3, 12][axis];
                    for i in 0..line.len() {
                        line[i] = i as u32;
                        if i > 0 {
                            assert_eq!(labels[i] - labels[i - 1], stride);
                        }
                    }
                },
            );
            for z in 0..5 {
                for y in 0..4 {
                    for x in 0..3 {
                        assert_eq!(values[x + 3 * (y + 4 * z)], [x, y, z][axis] as u32);
                    }
                }
            }
        }
    }

    #[test]
    fn runs_are_maximal() {
        let keys = [None, Some(1), Some(1), Some(2), None, Some(2), Some(2)];
        let mut runs = Vec::new();
        for_each_run(keys.len(), |i| keys[i], |a, b| runs.push((a, b)));
        assert_eq!(runs, vec![(1, 2), (3, 3), (5, 6)]);
    }
}
