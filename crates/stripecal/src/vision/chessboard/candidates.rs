//! Corner candidates on one pyramid level: a ChESS-style ring response divided by the
//! ring's own contrast, then non-maximum suppression.
//!
//! Sixteen samples `I_0..I_15` on a ring of radius about 4 px around each pixel (exact
//! quarter-turn symmetry: `I_{n+4}` is `I_n` turned by 90 degrees). At an X-junction
//! opposite samples agree and samples a quarter turn apart differ, so
//!
//! - `SR = sum_{n<4} |(I_n + I_{n+8}) - (I_{n+4} + I_{n+12})|` is large,
//! - `DR = sum_{n<8} |I_n - I_{n+8}|` is small (it is large on a straight edge),
//! - `MR = 16 |ring mean - centre mean|` is small (it is large on a line or a blob).
//!
//! The response is `(SR - DR - MR) / N` with `N = sum |I_n - ring mean|`: about 1 at
//! an ideal corner whatever its contrast or the illumination (no global threshold),
//! negative on edges, lines and blobs. Pixels whose ring contrast is not clearly above
//! the noise get no response. Each candidate also carries its *light axis* as a
//! doubled-angle unit vector (the phase of the ring's second harmonic): the light
//! sectors of neighbouring chessboard corners are a quarter turn apart, those of
//! diagonal neighbours agree.

use super::image::Gray;

/// Ring offsets `(dx, dy)`, `n = 0..16` counter-clockwise from +x (v down, so the
/// angles are as seen in image coordinates).
const RING: [(i32, i32); 16] = {
    let q = [(4, 0), (4, 2), (3, 3), (2, 4)];
    let mut out = [(0, 0); 16];
    let mut k = 0;
    while k < 4 {
        let (x, y) = q[k];
        out[k] = (x, y);
        out[k + 4] = (-y, x);
        out[k + 8] = (-x, -y);
        out[k + 12] = (y, -x);
        k += 1;
    }
    out
};

/// Margin (px) a pixel needs from the border for its ring.
pub(crate) const MARGIN: usize = 5;

/// One candidate, in the level's pixel coordinates.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Cand {
    pub x: f32,
    pub y: f32,
    /// Normalised response (about 1 at an ideal corner).
    pub resp: f32,
    /// Light axis as `(cos 2a, sin 2a)`.
    pub dir: [f32; 2],
    /// Ring contrast: light minus dark level, about `N / 8`.
    pub contrast: f32,
}

/// Normalised response of every pixel of `g` (0 where not computed).
fn response(g: &Gray, min_n: f32) -> Vec<f32> {
    let (w, h) = (g.w, g.h);
    let mut out = vec![0f32; w * h];
    if w < 2 * MARGIN + 1 || h < 2 * MARGIN + 1 {
        return out;
    }
    #[cfg(target_arch = "x86_64")]
    if crate::vision::has_avx2() {
        // SAFETY: the CPU supports AVX2 (checked just above), the only requirement for
        // calling a `#[target_feature(enable = "avx2")]` function.
        unsafe { response_avx2(g, min_n, &mut out) };
        return out;
    }
    response_rows(g, min_n, &mut out);
    out
}

/// [`response_rows`] compiled for AVX2 (eight `f32` lanes per register instead of four;
/// no fused multiply-adds, so the results are the same bit for bit).
#[cfg(target_arch = "x86_64")]
#[target_feature(enable = "avx2")]
fn response_avx2(g: &Gray, min_n: f32, out: &mut [f32]) {
    response_rows(g, min_n, out)
}

/// Pixels per step of [`response_rows`].
const RL: usize = 8;

/// [`response`] on any CPU, row by row, [`RL`] pixels at a time: the ring's 16 samples
/// and the 5 centre samples of a step are 21 contiguous runs of the image rows.
#[inline(always)]
fn response_rows(g: &Gray, min_n: f32, out: &mut [f32]) {
    let (w, h) = (g.w, g.h);
    let n = w - 2 * MARGIN;
    // the centre's cross: the pixel, above, below, left, right
    const CROSS: [(i32, i32); 5] = [(0, 0), (0, -1), (0, 1), (-1, 0), (1, 0)];
    for y in MARGIN..h - MARGIN {
        let run = |(dx, dy): (i32, i32)| {
            let start = (y as i32 + dy) as usize * w + (MARGIN as i32 + dx) as usize;
            &g.px[start..start + n]
        };
        let ring: [&[f32]; 16] = RING.map(run);
        let cross: [&[f32]; 5] = CROSS.map(run);
        let orow = &mut out[y * w + MARGIN..y * w + MARGIN + n];
        for x0 in (0..n).step_by(RL) {
            let len = RL.min(n - x0);
            let mut v = [[0f32; RL]; 16];
            let mut c = [[0f32; RL]; 5];
            for (vk, r) in v.iter_mut().zip(&ring) {
                vk[..len].copy_from_slice(&r[x0..x0 + len]);
            }
            for (ck, r) in c.iter_mut().zip(&cross) {
                ck[..len].copy_from_slice(&r[x0..x0 + len]);
            }
            let resp = ring_response(&v, &c, min_n);
            orow[x0..x0 + len].copy_from_slice(&resp[..len]);
        }
    }
}

/// The normalised response of [`RL`] pixels from their ring samples `v` and centre
/// crosses `c` (0 where the ring's contrast `N` is below `min_n`).
#[inline(always)]
#[allow(clippy::needless_range_loop)]
fn ring_response(v: &[[f32; RL]; 16], c: &[[f32; RL]; 5], min_n: f32) -> [f32; RL] {
    let mut out = [0f32; RL];
    for l in 0..RL {
        let mut sum = 0f32;
        for vk in v {
            sum += vk[l];
        }
        let mean = sum * (1.0 / 16.0);
        let mut nrm = 0f32;
        for vk in v {
            nrm += (vk[l] - mean).abs();
        }
        let mut sr = 0f32;
        for k in 0..4 {
            sr += ((v[k][l] + v[k + 8][l]) - (v[k + 4][l] + v[k + 12][l])).abs();
        }
        let mut dr = 0f32;
        for k in 0..8 {
            dr += (v[k][l] - v[k + 8][l]).abs();
        }
        let centre = 0.2 * (c[0][l] + c[1][l] + c[2][l] + c[3][l] + c[4][l]);
        let mr = 16.0 * (mean - centre).abs();
        let resp = (sr - dr - mr) / nrm;
        out[l] = if nrm < min_n { 0.0 } else { resp };
    }
    out
}

/// `(cos 2a, sin 2a)` of each ring sample's angle `a`.
fn ring_harmonic() -> [[f32; 2]; 16] {
    RING.map(|(dx, dy)| {
        let a = (dy as f32).atan2(dx as f32);
        [(2.0 * a).cos(), (2.0 * a).sin()]
    })
}

/// Light axis (doubled angle) and contrast of the ring at integer `(x, y)` (`harm`:
/// [`ring_harmonic`]).
fn ring_shape(g: &Gray, x: usize, y: usize, harm: &[[f32; 2]; 16]) -> ([f32; 2], f32) {
    let mut v = [0f32; 16];
    for (k, &(dx, dy)) in RING.iter().enumerate() {
        v[k] = g.at((x as i32 + dx) as usize, (y as i32 + dy) as usize);
    }
    let mean = v.iter().sum::<f32>() / 16.0;
    let (mut c, mut s, mut nrm) = (0f32, 0f32, 0f32);
    for (k, h) in harm.iter().enumerate() {
        c += (v[k] - mean) * h[0];
        s += (v[k] - mean) * h[1];
        nrm += (v[k] - mean).abs();
    }
    let len = (c * c + s * s).sqrt().max(1e-20);
    ([c / len, s / len], nrm / 8.0)
}

/// Candidates of one level: local maxima (3 x 3) of the response above `min_resp`,
/// whose ring contrast exceeds `min_contrast` (level units); strongest first, at
/// most `cap`.
pub(crate) fn find(g: &Gray, min_resp: f32, min_contrast: f32, cap: usize) -> Vec<Cand> {
    let r = response(g, 8.0 * min_contrast);
    let harm = ring_harmonic();
    let (w, h) = (g.w, g.h);
    let mut out = Vec::new();
    if w < 2 * MARGIN + 3 || h < 2 * MARGIN + 3 {
        return out;
    }
    for y in MARGIN + 1..h - MARGIN - 1 {
        for x in MARGIN + 1..w - MARGIN - 1 {
            let v = r[y * w + x];
            if v < min_resp {
                continue;
            }
            // strict maximum over the earlier half of the neighbourhood, >= over the
            // later half: one pixel per plateau
            let earlier = [
                r[(y - 1) * w + x - 1],
                r[(y - 1) * w + x],
                r[(y - 1) * w + x + 1],
                r[y * w + x - 1],
            ];
            let later = [
                r[y * w + x + 1],
                r[(y + 1) * w + x - 1],
                r[(y + 1) * w + x],
                r[(y + 1) * w + x + 1],
            ];
            if earlier.iter().any(|&e| e >= v) || later.iter().any(|&e| e > v) {
                continue;
            }
            // sub-pixel peak from a parabola through the 3-pixel profiles
            let sub = |a: f32, b: f32, c: f32| {
                let d = a - 2.0 * b + c;
                if d < 0.0 {
                    (0.5 * (a - c) / d).clamp(-0.5, 0.5)
                } else {
                    0.0
                }
            };
            let ox = sub(r[y * w + x - 1], v, r[y * w + x + 1]);
            let oy = sub(r[(y - 1) * w + x], v, r[(y + 1) * w + x]);
            let (dir, contrast) = ring_shape(g, x, y, &harm);
            out.push(Cand {
                x: x as f32 + ox,
                y: y as f32 + oy,
                resp: v,
                dir,
                contrast,
            });
        }
    }
    out.sort_by(|a, b| b.resp.total_cmp(&a.resp));
    out.truncate(cap);
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ring_has_quarter_turn_symmetry() {
        for k in 0..16 {
            let (x, y) = RING[k];
            assert_eq!(RING[(k + 4) % 16], (-y, x));
            assert_eq!(RING[(k + 8) % 16], (-x, -y));
            assert!(x.abs() <= 4 && y.abs() <= 4);
        }
    }

    /// The response row by row against the formula pixel by pixel, and the AVX2 build
    /// against the portable one bit for bit (a width whose last step is partial).
    #[test]
    fn response_matches_the_formula_per_pixel() {
        let (w, h) = (37, 23);
        // texture and a corner on the left, flat on the right (no ring contrast there)
        let px: Vec<f32> = (0..w * h)
            .map(|i| match (i % w, i / w) {
                (x, _) if x >= 26 => 100.0,
                (x, y) => ((i * 7919) % 251) as f32 + if (x < 13) == (y < 11) { 90.0 } else { 0.0 },
            })
            .collect();
        let g = Gray { w, h, px };
        let min_n = 300.0;
        let r = response(&g, min_n);
        let mut portable = vec![0f32; w * h];
        response_rows(&g, min_n, &mut portable);
        assert!(r
            .iter()
            .zip(&portable)
            .all(|(a, b)| a.to_bits() == b.to_bits()));
        let (mut some, mut none) = (0, 0);
        for y in 0..h {
            for x in 0..w {
                let inside = (MARGIN..w - MARGIN).contains(&x) && (MARGIN..h - MARGIN).contains(&y);
                let want = if inside {
                    let v: Vec<f32> = RING
                        .iter()
                        .map(|&(dx, dy)| g.at((x as i32 + dx) as usize, (y as i32 + dy) as usize))
                        .collect();
                    let mean = v.iter().fold(0f32, |a, &b| a + b) * (1.0 / 16.0);
                    let nrm = v.iter().fold(0f32, |a, &b| a + (b - mean).abs());
                    let sr = (0..4).fold(0f32, |a, k| {
                        a + ((v[k] + v[k + 8]) - (v[k + 4] + v[k + 12])).abs()
                    });
                    let dr = (0..8).fold(0f32, |a, k| a + (v[k] - v[k + 8]).abs());
                    let centre = 0.2
                        * (g.at(x, y)
                            + g.at(x, y - 1)
                            + g.at(x, y + 1)
                            + g.at(x - 1, y)
                            + g.at(x + 1, y));
                    let mr = 16.0 * (mean - centre).abs();
                    if nrm < min_n {
                        0.0
                    } else {
                        (sr - dr - mr) / nrm
                    }
                } else {
                    0.0
                };
                if want == 0.0 {
                    none += 1;
                } else {
                    some += 1;
                }
                assert_eq!(r[y * w + x].to_bits(), want.to_bits(), "({x}, {y})");
            }
        }
        // both branches of the contrast test are exercised
        let border = w * h - (w - 2 * MARGIN) * (h - 2 * MARGIN);
        assert!(some > 50 && none > border + 20, "{some} {none}");
    }

    #[test]
    fn responds_to_a_corner_not_to_an_edge() {
        let (w, h) = (40, 40);
        let mut px = vec![0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                let corner = (x < 20) == (y < 20);
                let edge = x < 20;
                px[y * w + x] = if y < 40 && x < 40 && corner {
                    200.0
                } else {
                    50.0
                };
                let _ = edge;
            }
        }
        let g = Gray { w, h, px };
        let c = find(&g, 0.25, 5.0, 100);
        assert_eq!(c.len(), 1, "{c:?}");
        assert!((c[0].x - 19.5).abs() <= 1.0 && (c[0].y - 19.5).abs() <= 1.0);
        assert!(c[0].resp > 0.25, "{}", c[0].resp);
        // light sectors towards (+,+) and (-,-): light axis at 45 deg, doubled 90 deg
        assert!(c[0].dir[1] > 0.9, "{:?}", c[0].dir);
        let mut px = vec![0f32; w * h];
        for y in 0..h {
            for x in 0..w {
                px[y * w + x] = if x < 20 { 200.0 } else { 50.0 };
            }
        }
        let g = Gray { w, h, px };
        assert!(find(&g, 0.3, 5.0, 100).is_empty());
    }
}
