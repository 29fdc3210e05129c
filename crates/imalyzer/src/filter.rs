//! Separable convolution of single-channel planes (row-major), in parallel over rows.
//!
//! Every output value sums its taps in the same order whatever the thread count, so the
//! results are bit-identical on any machine with the same floating-point arithmetic.

use std::ops::{Add, AddAssign, Mul};

use rayon::prelude::*;

/// The floating-point types the filters run in.
pub(crate) trait Real:
    Copy + Send + Sync + Default + Add<Output = Self> + Mul<Output = Self> + AddAssign
{
}
impl Real for f32 {}
impl Real for f64 {}

/// How a filter reads outside the image.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(crate) enum Border {
    /// Mirror about the edge, repeating the edge pixel (`c b a | a b c | c b a`): scipy's
    /// `reflect`, which scikit-image's SSIM uses.
    Reflect,
    /// Repeat the edge pixel (`a a a | a b c | c c c`), as the FLIP reference does.
    Clamp,
}

/// The index read for position `i` of a line of `n` samples.
#[inline]
pub(crate) fn border_index(i: isize, n: usize, border: Border) -> usize {
    let n = n as isize;
    match border {
        Border::Clamp => i.clamp(0, n - 1) as usize,
        Border::Reflect => {
            let m = i.rem_euclid(2 * n);
            (if m < n { m } else { 2 * n - 1 - m }) as usize
        }
    }
}

/// Filters one line `src` with the odd-length kernel `k` into `out`.
fn filter_line<T: Real>(src: &[T], k: &[T], border: Border, out: &mut [T]) {
    let n = src.len();
    let r = k.len() / 2;
    let tap = |x: usize| {
        let mut s = T::default();
        for (j, &kj) in k.iter().enumerate() {
            s += kj * src[border_index(x as isize + j as isize - r as isize, n, border)];
        }
        s
    };
    if n > 2 * r {
        // Interior: tap by tap over the whole run, which the compiler vectorises.
        let inner = &mut out[r..n - r];
        inner.fill(T::default());
        for (j, &kj) in k.iter().enumerate() {
            for (o, &s) in inner.iter_mut().zip(&src[j..j + n - 2 * r]) {
                *o += kj * s;
            }
        }
        for x in (0..r).chain(n - r..n) {
            out[x] = tap(x);
        }
    } else {
        for (x, o) in out.iter_mut().enumerate() {
            *o = tap(x);
        }
    }
}

/// Filters every row of the `w x h` plane `src` with `k`.
pub(crate) fn horizontal<T: Real>(src: &[T], w: usize, k: &[T], border: Border) -> Vec<T> {
    let mut out = vec![T::default(); src.len()];
    out.par_chunks_mut(w)
        .zip(src.par_chunks(w))
        .for_each(|(o, s)| filter_line(s, k, border, o));
    out
}

/// Filters every column of the `w x h` plane `src` with `k`.
pub(crate) fn vertical<T: Real>(src: &[T], w: usize, k: &[T], border: Border) -> Vec<T> {
    let h = src.len() / w;
    let r = k.len() / 2;
    let mut out = vec![T::default(); src.len()];
    out.par_chunks_mut(w).enumerate().for_each(|(y, o)| {
        for (j, &kj) in k.iter().enumerate() {
            let row = border_index(y as isize + j as isize - r as isize, h, border);
            for (o, &s) in o.iter_mut().zip(&src[row * w..(row + 1) * w]) {
                *o += kj * s;
            }
        }
    });
    out
}

/// Filters the plane with `kx` along rows, then `ky` along columns.
pub(crate) fn separable<T: Real>(
    src: &[T],
    w: usize,
    kx: &[T],
    ky: &[T],
    border: Border,
) -> Vec<T> {
    vertical(&horizontal(src, w, kx, border), w, ky, border)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn borders_mirror_and_clamp() {
        let reflect: Vec<usize> = (-3..6)
            .map(|i| border_index(i, 3, Border::Reflect))
            .collect();
        assert_eq!(reflect, [2, 1, 0, 0, 1, 2, 2, 1, 0]);
        let clamp: Vec<usize> = (-2..5).map(|i| border_index(i, 3, Border::Clamp)).collect();
        assert_eq!(clamp, [0, 0, 0, 1, 2, 2, 2]);
        // A line of one sample reads itself everywhere.
        assert!((-5..5).all(|i| border_index(i, 1, Border::Reflect) == 0));
    }

    #[test]
    fn box_filter_by_hand() {
        // 3-tap box on [1 2 3 4] with reflection: edges repeat the end samples.
        let k = [1.0f64 / 3.0; 3];
        let out = horizontal(&[1.0, 2.0, 3.0, 4.0], 4, &k, Border::Reflect);
        let want = [4.0 / 3.0, 2.0, 3.0, 11.0 / 3.0];
        for (o, w) in out.iter().zip(want) {
            assert!((o - w).abs() < 1e-12, "{out:?}");
        }
        // The same line as a column gives the same values.
        let col = vertical(&[1.0, 2.0, 3.0, 4.0], 1, &k, Border::Reflect);
        assert_eq!(out, col);
        // Kernels longer than the line still read mirrored samples.
        let wide = horizontal(&[1.0f64, 5.0], 2, &[0.2; 5], Border::Clamp);
        assert!((wide[0] - (1.0 + 1.0 + 1.0 + 5.0 + 5.0) * 0.2).abs() < 1e-12);
    }
}
