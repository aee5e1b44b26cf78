//! The sub-pixel centres of eight scan lines at once: [`super::peak::subpixel`] lane by
//! lane, the same `f32` operations in the same order on each lane, so each lane's result
//! is bit for bit the scalar one. One scan line's centre is a chain of dependent steps
//! (flank means, divisions, half-maximum walks, the iterated window centroid) whose
//! data-dependent loop exits the CPU mispredicts, so scan lines one after the other
//! barely overlap; eight in lock step run their chains side by side (the walks of all
//! lanes read the same segment offsets and vectorise).
//!
//! Only the common case runs here: a segment of `SHORT_REACH` pixels either side of the
//! peak inside the scan line, a peak below full scale (no saturated support, no
//! plateau), the centroid method. A lane that meets anything else (a failed check, a
//! walk to the segment's end) is handed back undecided and the caller runs the scalar
//! code on it, which gives the same answer it always gave (an error included).

use super::peak::{Params, Sub, ROUNDS, SHORT_REACH};
use super::{StripeMethod, FLAG_LOW_SIGNAL, FLAG_UNEVEN_BACKGROUND};

/// Scan lines computed together.
pub(super) const LANES: usize = 8;
/// Pixels of a lane's segment: the peak at index [`SHORT_REACH`] and as many either side
/// (the scalar code's first, short segment).
pub(super) const SEG: usize = 2 * SHORT_REACH + 1;
/// The peak's index in a segment.
const PK: usize = SHORT_REACH;
/// Largest flank the lanes handle (the safe indices of a failed lane need room).
const MAX_FLANK: usize = 4;

/// One `f32` per lane.
type V = [f32; LANES];

/// Segments of the lanes: `s[k][lane]` is pixel `k` of the lane's segment.
pub(super) type Segments = [V; SEG];

/// Whether the lanes can take scan lines with these parameters (otherwise every scan
/// line takes the scalar path).
pub(super) fn lanes_apply(p: &Params) -> bool {
    p.method == StripeMethod::Centroid && p.d < SHORT_REACH && p.flank <= MAX_FLANK
}

/// The sub-pixel results of the lanes' segments into `out` (`None`: undecided, run the
/// scalar code). Requires [`lanes_apply`]. Compiled again for AVX2 where the CPU has it
/// (element-wise IEEE operations: the same results).
pub(super) fn subpixel_lanes(s: &Segments, p: &Params, out: &mut [Option<Sub>; LANES]) {
    debug_assert!(lanes_apply(p));
    #[cfg(target_arch = "x86_64")]
    if crate::vision::has_avx2() {
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
        // calling a `#[target_feature(enable = "avx2")]` function.
        unsafe { subpixel_lanes_avx2(s, p, out) };
        return;
    }
    subpixel_lanes_generic(s, p, out)
}

#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn subpixel_lanes_avx2(s: &Segments, p: &Params, out: &mut [Option<Sub>; LANES]) {
    subpixel_lanes_generic(s, p, out)
}

/// The linear background `bl + slope * (x - xl)` of each lane (`Background::at`).
#[derive(Clone, Copy)]
struct Bg {
    xl: V,
    bl: V,
    slope: V,
}

/// `crossing` of the peak module on every lane still `ok`: the position where the
/// residual falls to `half` walking from the peak by `step`; a lane that walks off the
/// segment or past `limit` is no longer `ok`.
#[inline(always)]
fn crossings(
    s: &Segments,
    step: isize,
    bg: &Bg,
    half: &V,
    limit: usize,
    ok: &mut [bool; LANES],
) -> V {
    let mut res = [0f32; LANES];
    let mut done = [false; LANES];
    for i in 0..LANES {
        done[i] = !ok[i];
    }
    for j in 1..=SHORT_REACH {
        let x = (PK as isize + step * (j as isize - 1)) as usize;
        let nx = (PK as isize + step * j as isize) as usize;
        let (fx, fnx) = (x as isize as f32, nx as isize as f32);
        // (the scalar walk tests its length before the pixel)
        let fail = j - 1 > limit;
        let mut all = true;
        for i in 0..LANES {
            let yn = s[nx][i] - (bg.bl[i] + bg.slope[i] * (fnx - bg.xl[i]));
            let yx = s[x][i] - (bg.bl[i] + bg.slope[i] * (fx - bg.xl[i]));
            let q = (yx - half[i]) / (yx - yn);
            let t = if yx > yn { q } else { 0.5 };
            let c = fx + step as f32 * t.clamp(0.0, 1.0);
            let hit = yn <= half[i];
            let open = !done[i];
            res[i] = if open & !fail & hit { c } else { res[i] };
            ok[i] &= !(open & fail);
            done[i] |= fail | hit;
            all &= done[i];
        }
        if all {
            return res;
        }
    }
    // walked to the segment's end: the scalar code's border case
    for i in 0..LANES {
        ok[i] &= done[i];
    }
    res
}

/// The lanes between the phases of [`subpixel_lanes_generic`]: which are still `ok`, the
/// peak's height over the background `a`, the half maximum, the background, the
/// half-maximum crossings `l` and `r`, the centroid window's half width `h`, the first
/// pixels of the left and right flanks `f0` and `f1`, and the flanks' unevenness flag.
struct State {
    ok: [bool; LANES],
    a: V,
    half: V,
    bg: Bg,
    l: V,
    r: V,
    h: V,
    f0: [usize; LANES],
    f1: [usize; LANES],
    uneven: [bool; LANES],
}

/// The window's residual sums (`residual_sums` of the peak module) on the whole segment
/// at once: `res[x]` pixel x's residual, `pre0[x + 1]` and `pre1[x + 1]` the sums of `y`
/// and `y * k` from `xmin` to x (`k = x - xmin`).
struct Sums {
    res: [V; SEG],
    pre0: [V; SEG + 1],
    pre1: [V; SEG + 1],
}

#[inline(always)]
fn subpixel_lanes_generic(s: &Segments, p: &Params, out: &mut [Option<Sub>; LANES]) {
    let mut st = first_guess(s, p);
    // Both rounds in full on every lane: where the scalar code skips its second round
    // (the same window), recomputing it gives the same values.
    for _ in 0..ROUNDS {
        round(s, p, &mut st);
    }
    let n = SEG;
    let mut w = [0f32; LANES];
    let mut xmin = [0usize; LANES];
    let mut last = [0usize; LANES];
    let mut c0 = [0f32; LANES];
    for i in 0..LANES {
        w[i] = st.r[i] - st.l[i];
        st.ok[i] &= (w[i] >= p.min_width) & (w[i] <= p.max_width);
        // residuals over the window's pixels, relative to xmin (`subpixel`)
        xmin[i] = st.f0[i] + p.flank;
        let xmax = st.f1[i] - 1;
        last[i] = xmax.saturating_sub(xmin[i]).min(n - 1);
        c0[i] = 0.5 * ((st.l[i] - xmin[i] as f32) + (st.r[i] - xmin[i] as f32));
    }
    let sums = residual_sums(s, &st.bg, &xmin);
    let c = window_centroid(&sums, &mut st, (&xmin, &last), &c0, &w);
    for i in 0..LANES {
        out[i] = st.ok[i].then(|| {
            let cf = c[i] as f64 + xmin[i] as f64;
            let cc = c[i] + xmin[i] as f32;
            let mut flags = 0u8;
            if st.uneven[i] {
                flags |= FLAG_UNEVEN_BACKGROUND;
            }
            if st.a[i] < p.low_signal {
                flags |= FLAG_LOW_SIGNAL;
            }
            Sub {
                c: cf,
                peak: st.a[i],
                width: w[i],
                support: (cc - st.f0[i] as f32 + 0.5)
                    .max(st.f1[i] as f32 + p.flank as f32 - 0.5 - cc),
                flags,
            }
        });
    }
}

/// `peak_window`'s first guess from the ridge test's flank pixels, and its half-maximum
/// crossings.
#[inline(always)]
fn first_guess(s: &Segments, p: &Params) -> State {
    let d = p.d;
    let vpk = s[PK];
    let mut ok = [true; LANES];
    let mut a = [0f32; LANES];
    let mut half = [0f32; LANES];
    let mut bg = Bg {
        xl: [0.0; LANES],
        bl: [0.0; LANES],
        slope: [0.0; LANES],
    };
    for i in 0..LANES {
        let b0 = 0.5 * (s[PK - d][i] + s[PK + d][i]);
        a[i] = vpk[i] - b0;
        // (a peak at full scale may have a saturated support: the scalar code)
        // (the scalar test: `a < min_contrast` rejects)
        let weak = a[i] < p.min_contrast;
        ok[i] = (vpk[i] < p.sat_level) & !weak;
        bg.bl[i] = b0;
        half[i] = 0.5 * a[i];
    }
    let l = crossings(s, -1, &bg, &half, p.limit, &mut ok);
    let r = crossings(s, 1, &bg, &half, p.limit, &mut ok);
    State {
        ok,
        a,
        half,
        bg,
        l,
        r,
        h: [0.0; LANES],
        f0: [0; LANES],
        f1: [0; LANES],
        uneven: [false; LANES],
    }
}

/// One round of `peak_window`: the window from the crossings, the flank pixels, the
/// background through them (`flank_stats`), the peak's height and the new crossings.
#[inline(always)]
fn round(s: &Segments, p: &Params, st: &mut State) {
    let (n, flank) = (SEG, p.flank);
    let vpk = s[PK];
    // the window (lane-wise arithmetic, vectorised)
    let mut lo = [0i32; LANES];
    let mut hi = [0i32; LANES];
    for i in 0..LANES {
        let w = st.r[i] - st.l[i];
        st.ok[i] &= (w >= p.min_width) & (w <= p.max_width);
        let cen = 0.5 * (st.l[i] + st.r[i]);
        st.h[i] = (p.window * w).max(1.5);
        let wl = ((cen - st.h[i] + 0.5) as i32) as i64 - 2;
        let wh = ((cen + st.h[i] + 0.5) as i32) as i64 + 2;
        st.ok[i] &= !((wl < flank as i64) | (wh + flank as i64 >= n as i64));
        // (a lane out already reads safe places; its values are not used)
        lo[i] = if st.ok[i] { wl as i32 } else { flank as i32 };
        hi[i] = if st.ok[i] {
            wh as i32
        } else {
            (n - 1 - flank) as i32
        };
    }
    // the flank pixels (each lane's own place)
    let mut fl = [[0f32; LANES]; MAX_FLANK];
    let mut fr = [[0f32; LANES]; MAX_FLANK];
    for i in 0..LANES {
        st.f0[i] = lo[i] as usize + 1 - flank;
        st.f1[i] = hi[i] as usize;
        for f in 0..flank {
            fl[f][i] = s[st.f0[i] + f][i];
            fr[f][i] = s[st.f1[i] + f][i];
        }
    }
    // `flank_stats` and the background (vectorised)
    let mut sl = [0f32; LANES];
    let mut sr = [0f32; LANES];
    let (mut minl, mut maxl) = ([f32::INFINITY; LANES], [f32::NEG_INFINITY; LANES]);
    let (mut minr, mut maxr) = ([f32::INFINITY; LANES], [f32::NEG_INFINITY; LANES]);
    for f in 0..flank {
        for i in 0..LANES {
            let (vl, vr) = (fl[f][i], fr[f][i]);
            sl[i] += vl;
            minl[i] = minl[i].min(vl);
            maxl[i] = maxl[i].max(vl);
            sr[i] += vr;
            minr[i] = minr[i].min(vr);
            maxr[i] = maxr[i].max(vr);
        }
    }
    for i in 0..LANES {
        let ml = sl[i] / flank as f32;
        let mr = sr[i] / flank as f32;
        let xl = lo[i] as f32 - 0.5 * (flank - 1) as f32;
        let xr = hi[i] as f32 + 0.5 * (flank - 1) as f32;
        st.bg.xl[i] = xl;
        st.bg.bl[i] = ml;
        st.bg.slope[i] = (mr - ml) / (xr - xl);
        st.a[i] = vpk[i] - (st.bg.bl[i] + st.bg.slope[i] * (PK as f32 - st.bg.xl[i]));
        let weak = st.a[i] < p.min_contrast;
        st.ok[i] &= !weak;
        let tol = p.uneven + p.uneven_rel * st.a[i];
        let unevenness = (mr - ml)
            .abs()
            .max(maxl[i] - minl[i])
            .max(maxr[i] - minr[i]);
        st.uneven[i] = unevenness > tol;
        st.half[i] = 0.5 * st.a[i];
    }
    st.l = crossings(s, -1, &st.bg, &st.half, p.limit, &mut st.ok);
    st.r = crossings(s, 1, &st.bg, &st.half, p.limit, &mut st.ok);
}

/// [`Sums`] of the lanes' windows from `xmin` (vectorised: the same additions in the same
/// order as the scalar sums over the window's pixels, 0 before `xmin`, where nothing is
/// added).
#[inline(always)]
fn residual_sums(s: &Segments, bg: &Bg, xmin: &[usize; LANES]) -> Sums {
    let mut res = [[0f32; LANES]; SEG];
    let mut pre0 = [[0f32; LANES]; SEG + 1];
    let mut pre1 = [[0f32; LANES]; SEG + 1];
    let mut a0 = [0f32; LANES];
    let mut a1 = [0f32; LANES];
    let mut from = [0f32; LANES];
    for i in 0..LANES {
        from[i] = xmin[i] as f32;
    }
    for x in 0..SEG {
        let xf = x as f32;
        for i in 0..LANES {
            let y = s[x][i] - (bg.bl[i] + bg.slope[i] * (xf - bg.xl[i]));
            let on = xf >= from[i];
            let kf = xf - from[i];
            res[x][i] = y;
            a0[i] = if on { a0[i] + y } else { a0[i] };
            a1[i] = if on { a1[i] + y * kf } else { a1[i] };
            pre0[x + 1][i] = a0[i];
            pre1[x + 1][i] = a1[i];
        }
    }
    Sums { res, pre0, pre1 }
}

/// `window_centroid`: the iterated centroid of a window of half width `st.h` from `c0`
/// (indices relative to `xmin`, read at `xmin + index`, at most `last`); a lane whose
/// step fails or moves more than the width `w` from `c0` is no longer `ok`.
#[inline(always)]
fn window_centroid(
    sums: &Sums,
    st: &mut State,
    (xmin, last): (&[usize; LANES], &[usize; LANES]),
    c0: &V,
    w: &V,
) -> V {
    let (n, h) = (SEG, st.h);
    let Sums { res, pre0, pre1 } = sums;
    let mut c = *c0;
    let mut done = st.ok.map(|o| !o);
    for _ in 0..6 {
        // the window's ends (vectorised)
        let (mut lo, mut hi) = ([0f32; LANES], [0f32; LANES]);
        let (mut i0, mut i1) = ([0usize; LANES], [0usize; LANES]);
        let (mut j0, mut j1) = ([0usize; LANES], [0usize; LANES]);
        let mut bad = [false; LANES];
        for i in 0..LANES {
            (lo[i], hi[i]) = (c[i] - h[i], c[i] + h[i]);
            i0[i] = ((lo[i] + 0.5) as i32).max(0) as usize;
            i1[i] = (((hi[i] + 0.5) as i32).max(0) as usize).min(last[i]);
            bad[i] = i1[i] <= i0[i];
            // (safe indices for a lane that fails here or failed before)
            j0[i] = (xmin[i] + i0[i]).min(n - 1);
            j1[i] = (xmin[i] + i1[i]).min(n - 1);
        }
        // the sums at them (each lane's own place)
        let (mut p0a, mut p0b, mut p1a, mut p1b) =
            ([0f32; LANES], [0f32; LANES], [0f32; LANES], [0f32; LANES]);
        let (mut r0, mut r1) = ([0f32; LANES], [0f32; LANES]);
        for i in 0..LANES {
            p0a[i] = pre0[j0[i] + 1][i];
            p0b[i] = pre0[j1[i]][i];
            p1a[i] = pre1[j0[i] + 1][i];
            p1b[i] = pre1[j1[i]][i];
            r0[i] = res[j0[i]][i];
            r1[i] = res[j1[i]][i];
        }
        // the centroid step (vectorised)
        let mut all = true;
        for i in 0..LANES {
            let mut sum = p0b[i] - p0a[i];
            let mut sx = (p1b[i] - p1a[i]) - c[i] * sum;
            let w0 = (i0[i] as f32 + 0.5 - lo[i]).clamp(0.0, 1.0) * r0[i];
            let w1 = (hi[i] - (i1[i] as f32 - 0.5)).clamp(0.0, 1.0) * r1[i];
            sum += w0 + w1;
            sx += w0 * (i0[i] as f32 - c[i]) + w1 * (i1[i] as f32 - c[i]);
            let mut bad = bad[i] | (sum <= 0.0);
            let dc = sx / sum;
            let cn = c[i] + dc;
            bad |= (cn - c0[i]).abs() > w[i];
            let open = !done[i];
            st.ok[i] &= !(open & bad);
            c[i] = if open & !bad { cn } else { c[i] };
            done[i] |= bad | (dc.abs() < 1e-3);
            all &= done[i];
        }
        if all {
            break;
        }
    }
    c
}

#[cfg(test)]
mod tests {
    use super::super::peak::subpixel;
    use super::super::StripeOptions;
    use super::*;

    /// Every lane's result is the scalar `subpixel`'s on the same segment, bit for bit,
    /// where the lanes decide; where they leave a lane undecided the scalar code is run
    /// instead (so the only requirement there is that the lanes do not claim a result).
    /// Profiles: Gaussian lines of many widths and heights, sub-pixel offsets, sloped
    /// and stepped backgrounds, noise, near-saturated and saturated peaks, 8 and 16 bits.
    #[test]
    fn lanes_equal_the_scalar_subpixel_bit_for_bit() {
        let mut rng = 0x2545_f491_4f6c_dd1du64;
        let mut next = move || {
            rng = rng
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            (rng >> 40) as f64 / (1u64 << 24) as f64
        };
        let (mut decided, mut total) = (0usize, 0usize);
        for opts in [
            StripeOptions::default(),
            StripeOptions {
                ridge_px: 9,
                window_fwhm: 1.7,
                flank_px: 2,
                max_width_px: 6.0,
                ..StripeOptions::default()
            },
            StripeOptions {
                ridge_px: 3,
                flank_px: 4,
                uneven_gray: 1.0,
                ..StripeOptions::default()
            },
        ] {
            for bits16 in [false, true] {
                let p = if bits16 {
                    Params::new::<u16>(&opts)
                } else {
                    Params::new::<u8>(&opts)
                };
                assert!(lanes_apply(&p));
                let full = if bits16 { 65535.0 } else { 255.0 };
                for _ in 0..1500 {
                    let mut segs: Segments = [[0.0; LANES]; SEG];
                    let mut raw = vec![vec![0u16; SEG]; LANES];
                    for (i, line) in raw.iter_mut().enumerate() {
                        let sigma = 0.4 + 4.0 * next();
                        let centre = PK as f64 + next() - 0.5 + (next() - 0.5) * 2.0;
                        let amp = full * (0.02 + 1.3 * next());
                        let base = full * 0.3 * next();
                        let slope = full * 0.01 * (next() - 0.5);
                        let step = if next() < 0.2 {
                            full * 0.2 * next()
                        } else {
                            0.0
                        };
                        let at = (next() * SEG as f64) as usize;
                        let noise = full * 0.03 * next();
                        for (k, v) in line.iter_mut().enumerate() {
                            let t = (k as f64 - centre) / sigma;
                            let mut y = base
                                + slope * k as f64
                                + amp * (-0.5 * t * t).exp()
                                + noise * (next() - 0.5);
                            if k >= at {
                                y += step;
                            }
                            *v = y.round().clamp(0.0, full) as u16;
                            segs[k][i] = *v as f32;
                        }
                    }
                    let mut out = [None; LANES];
                    subpixel_lanes(&segs, &p, &mut out);
                    let mut scratch = Vec::new();
                    for (i, line) in raw.iter().enumerate() {
                        total += 1;
                        let want = if bits16 {
                            subpixel(line, PK, &p, &mut scratch)
                        } else {
                            let l8: Vec<u8> = line.iter().map(|&v| v as u8).collect();
                            subpixel(&l8, PK, &p, &mut scratch)
                        };
                        if let Some(got) = out[i] {
                            decided += 1;
                            let want = want.expect("the lanes decided a line the scalar rejects");
                            assert_eq!(got.c.to_bits(), want.c.to_bits(), "{line:?}");
                            assert_eq!(got.peak.to_bits(), want.peak.to_bits());
                            assert_eq!(got.width.to_bits(), want.width.to_bits());
                            assert_eq!(got.support.to_bits(), want.support.to_bits());
                            assert_eq!(got.flags, want.flags);
                        }
                    }
                }
            }
        }
        // most lines are decided by the lanes (the others go to the scalar code)
        assert!(2 * decided > total, "{decided} of {total}");
    }
}
