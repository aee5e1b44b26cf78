//! Smoothing along the line: each pixel averaged with its neighbours across the scan
//! lines (`n` scan lines, centred; clipped at the image's border), before the centre
//! is taken. Laser speckle is a random brightness pattern of a few pixels' grain; along
//! a straight line the average of neighbouring scan lines' profiles is centred where
//! the middle scan line's is (each profile is the same shape shifted in proportion to
//! its distance), so the centre keeps its place while the speckle averages down.
//!
//! The result is a 16-bit image on the input's scale times `257` for 8-bit input (the
//! extractor's gray options scale with it), so a pixel is at full scale only where
//! every averaged pixel is.

use crate::model::image::{ImageView, Pixel};
use crate::model::StripeDirection;

/// 16-bit levels per input level: 257 for 8-bit input, 1 for 16-bit.
#[inline]
pub(super) fn scale_of<T: Pixel>() -> u32 {
    if <T as Pixel>::MAX > 255.0 {
        1
    } else {
        257
    }
}

/// Division by a small count `d` (1..=31) as a multiplication by its reciprocal in
/// `f32`: `floor(x / d) = trunc((x + 0.5) * fl(1 / d))` for every numerator below
/// `2^21` (the averages' numerators are below `31 * 65535 + 15 < 2^21`). Why it is
/// exact: `x + 0.5` is exact in `f32` (23 bits), and `(x + 0.5) / d` lies at least
/// `0.5 / d` away from every integer (its fraction is `(r + 0.5) / d` with the remainder
/// `0 <= r < d`), while the two roundings (of `1 / d` and of the product) move it by at
/// most `2^-23` of its value, below `2^21 / d * 2^-23 = 0.25 / d` (the floor taken
/// by rounding, see [`DivBy::div`]). Eight lanes per AVX2
/// register (the integer multiply-shift this replaced needed 64-bit products, four
/// lanes, and shuffles). A division instruction per pixel cost more than the rest of the
/// extraction of a frame. The test checks every numerator of the averages.
#[derive(Debug, Clone, Copy)]
struct DivBy {
    r: f32,
}

/// Numerators of [`DivBy`] are below `2^NUM_BITS`.
const NUM_BITS: u32 = 21;

impl DivBy {
    #[inline(always)]
    fn new(d: u32) -> DivBy {
        debug_assert!((1..=32).contains(&d));
        DivBy { r: 1.0 / d as f32 }
    }

    /// `x / d` rounded down, for `x < 2^21`.
    #[inline(always)]
    fn div(self, x: u32) -> u32 {
        debug_assert!(x < 1 << NUM_BITS);
        // (through i32: x < 2^21, and the signed conversion is the vector one)
        let q = (x as i32 as f32 + 0.5) * self.r;
        // floor(q) without a float-to-integer cast (Rust's saturating cast does not
        // vectorise): q is at least 0.25 / d from every integer, so q - 0.5 (exact,
        // above -0.5) is as far from every half-integer and rounds to floor(q), which
        // adding 1.5 * 2^23 does (the sum lies in [2^23, 2^24), where the float spacing
        // is 1: one rounding to the nearest integer): its bits less those of 1.5 * 2^23
        // are floor(q)
        (q - 0.5 + 12_582_912.0).to_bits() - 0x4B40_0000
    }
}

/// The image `img` averaged over `n` scan lines across `dir`'s scan lines, into `out`
/// (`width * height` 16-bit pixels, row-major). `Cols`: each smoothed row goes to
/// `on_row(y, row)` as soon as it is written (while it is in the cache; `Rows` calls
/// it for none). Compiled a second time with AVX2, chosen at run time where the CPU
/// has it (integer arithmetic: the same result).
pub(super) fn smooth_along<T: Pixel>(
    img: &ImageView<'_, T>,
    dir: StripeDirection,
    n: usize,
    out: &mut Vec<u16>,
    acc: &mut Vec<u32>,
    on_row: impl FnMut(usize, &[u16]),
) {
    #[cfg(target_arch = "x86_64")]
    if crate::vision::has_avx2() {
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
        // calling a `#[target_feature(enable = "avx2")]` function.
        unsafe { smooth_along_avx2(img, dir, n, out, acc, on_row) };
        return;
    }
    smooth_along_generic(img, dir, n, out, acc, on_row)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn smooth_along_avx2<T: Pixel>(
    img: &ImageView<'_, T>,
    dir: StripeDirection,
    n: usize,
    out: &mut Vec<u16>,
    acc: &mut Vec<u32>,
    on_row: impl FnMut(usize, &[u16]),
) {
    smooth_along_generic(img, dir, n, out, acc, on_row)
}

#[inline(always)]
fn smooth_along_generic<T: Pixel>(
    img: &ImageView<'_, T>,
    dir: StripeDirection,
    n: usize,
    out: &mut Vec<u16>,
    acc: &mut Vec<u32>,
    mut on_row: impl FnMut(usize, &[u16]),
) {
    let (w, h) = (img.width(), img.height());
    // (every pixel is written below: the buffer of the last image is not cleared)
    if out.len() != w * h {
        out.clear();
        out.resize(w * h, 0);
    }
    let k = (n / 2) as isize;
    let scale = scale_of::<T>();
    // the counts of a window: 1..=n (fewer at the border)
    let divs: [DivBy; 32] = std::array::from_fn(|d| DivBy::new((d as u32).max(1)));
    if dir == StripeDirection::Rows {
        // scan lines are columns: average along the rows (the line runs along them)
        for y in 0..h {
            let row = img.row(y);
            let o = &mut out[y * w..(y + 1) * w];
            let mut s: u32 = 0;
            let mut cnt: u32 = 0;
            // running sum over the window x - k ..= x + k, clipped
            for v in &row[..(k as usize).min(w)] {
                s += v.to_u32();
                cnt += 1;
            }
            for (x, ox) in o.iter_mut().enumerate() {
                let add = x as isize + k;
                if (add as usize) < w {
                    s += row[add as usize].to_u32();
                    cnt += 1;
                }
                let sub = x as isize - k - 1;
                if sub >= 0 {
                    s -= row[sub as usize].to_u32();
                    cnt -= 1;
                }
                *ox = divs[cnt as usize].div(s * scale + cnt / 2) as u16;
            }
        }
    } else {
        // scan lines are rows: average down the columns
        acc.clear();
        acc.resize(w, 0);
        let mut cnt: u32 = 0;
        for y in 0..(k as usize).min(h) {
            for (a, v) in acc.iter_mut().zip(img.row(y)) {
                *a += v.to_u32();
            }
            cnt += 1;
        }
        for y in 0..h {
            let add = y as isize + k;
            let sub = y as isize - k - 1;
            if (add as usize) < h && sub >= 0 {
                // inside the image: the window moves by a row, the count stays; one pass
                // (the same integer sums as the passes below)
                let (ra, rs) = (img.row(add as usize), img.row(sub as usize));
                let (div, half) = (divs[cnt as usize], cnt / 2);
                let o = &mut out[y * w..(y + 1) * w];
                for (((o, a), va), vs) in o.iter_mut().zip(acc.iter_mut()).zip(ra).zip(rs) {
                    *a = *a + va.to_u32() - vs.to_u32();
                    *o = div.div(*a * scale + half) as u16;
                }
                on_row(y, o);
                continue;
            }
            if (add as usize) < h {
                for (a, v) in acc.iter_mut().zip(img.row(add as usize)) {
                    *a += v.to_u32();
                }
                cnt += 1;
            }
            if sub >= 0 {
                for (a, v) in acc.iter_mut().zip(img.row(sub as usize)) {
                    *a -= v.to_u32();
                }
                cnt -= 1;
            }
            let (div, half) = (divs[cnt as usize], cnt / 2);
            for (o, a) in out[y * w..(y + 1) * w].iter_mut().zip(acc.iter()) {
                *o = div.div(a * scale + half) as u16;
            }
            on_row(y, &out[y * w..(y + 1) * w]);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The reciprocal division equals the division on every numerator of the averages
    /// (a window of `d` pixels sums to at most `d * 65535`, plus `d / 2` for the
    /// rounding), for every count, and on the largest numerators of its domain.
    #[test]
    fn div_by_equals_division() {
        let top = 31 * 65535 + 15;
        assert!(top < 1 << NUM_BITS);
        for d in 1..=31u32 {
            let dv = DivBy::new(d);
            let check = |x: u32| assert_eq!(dv.div(x), x / d, "{x} / {d}");
            (0..=d * 65535 + d / 2).for_each(check);
            (top - 5000..=top).for_each(check);
            ((1u32 << NUM_BITS) - 5000..1u32 << NUM_BITS).for_each(check);
        }
    }

    #[test]
    fn averages_across_the_scan_lines_and_keeps_full_scale() {
        let (w, h) = (7, 6);
        let img: Vec<u8> = (0..w * h)
            .map(|i| if i % w == 3 { 255 } else { (i % 5) as u8 * 10 })
            .collect();
        let v = ImageView::from_slice(&img, w, h).unwrap();
        let (mut out, mut acc) = (Vec::new(), Vec::new());
        smooth_along(&v, StripeDirection::Cols, 3, &mut out, &mut acc, |_, _| {});
        for y in 0..h {
            for x in 0..w {
                let ys: Vec<usize> = (y.saturating_sub(1)..=(y + 1).min(h - 1)).collect();
                let s: u32 = ys.iter().map(|&yy| img[yy * w + x] as u32).sum();
                let want = (s * 257 + ys.len() as u32 / 2) / ys.len() as u32;
                assert_eq!(out[y * w + x] as u32, want, "({x}, {y})");
            }
            assert_eq!(out[y * w + 3], 65535);
        }
        smooth_along(&v, StripeDirection::Rows, 3, &mut out, &mut acc, |_, _| {});
        for y in 0..h {
            for x in 0..w {
                let xs: Vec<usize> = (x.saturating_sub(1)..=(x + 1).min(w - 1)).collect();
                let s: u32 = xs.iter().map(|&xx| img[y * w + xx] as u32).sum();
                let want = (s * 257 + xs.len() as u32 / 2) / xs.len() as u32;
                assert_eq!(out[y * w + x] as u32, want, "({x}, {y})");
            }
        }
    }
}
