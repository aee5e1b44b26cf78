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
    let n = w - 2 * MARGIN;
    let mut s = vec![[0f32; 16]; n];
    for y in MARGIN..h - MARGIN {
        for (k, &(dx, dy)) in RING.iter().enumerate() {
            let yy = (y as i32 + dy) as usize;
            let x0 = (MARGIN as i32 + dx) as usize;
            let row = &g.px[yy * w + x0..yy * w + x0 + n];
            for (sv, &v) in s.iter_mut().zip(row) {
                sv[k] = v;
            }
        }
        let c = &g.px[y * w + MARGIN..y * w + MARGIN + n];
        let up = &g.px[(y - 1) * w + MARGIN..(y - 1) * w + MARGIN + n];
        let dn = &g.px[(y + 1) * w + MARGIN..(y + 1) * w + MARGIN + n];
        let l = &g.px[y * w + MARGIN - 1..y * w + MARGIN - 1 + n];
        let r = &g.px[y * w + MARGIN + 1..y * w + MARGIN + 1 + n];
        let orow = &mut out[y * w + MARGIN..y * w + MARGIN + n];
        for x in 0..n {
            let v = &s[x];
            let mut sum = 0f32;
            for &a in v {
                sum += a;
            }
            let mean = sum * (1.0 / 16.0);
            let mut nrm = 0f32;
            for &a in v {
                nrm += (a - mean).abs();
            }
            if nrm < min_n {
                continue;
            }
            let mut sr = 0f32;
            for k in 0..4 {
                sr += ((v[k] + v[k + 8]) - (v[k + 4] + v[k + 12])).abs();
            }
            let mut dr = 0f32;
            for k in 0..8 {
                dr += (v[k] - v[k + 8]).abs();
            }
            let centre = 0.2 * (c[x] + up[x] + dn[x] + l[x] + r[x]);
            let mr = 16.0 * (mean - centre).abs();
            orow[x] = (sr - dr - mr) / nrm;
        }
    }
    out
}

/// Light axis (doubled angle) and contrast of the ring at integer `(x, y)`.
fn ring_shape(g: &Gray, x: usize, y: usize) -> ([f32; 2], f32) {
    let mut v = [0f32; 16];
    for (k, &(dx, dy)) in RING.iter().enumerate() {
        v[k] = g.at((x as i32 + dx) as usize, (y as i32 + dy) as usize);
    }
    let mean = v.iter().sum::<f32>() / 16.0;
    let (mut c, mut s, mut nrm) = (0f32, 0f32, 0f32);
    for (k, &(dx, dy)) in RING.iter().enumerate() {
        let a = (dy as f32).atan2(dx as f32);
        c += (v[k] - mean) * (2.0 * a).cos();
        s += (v[k] - mean) * (2.0 * a).sin();
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
            let (dir, contrast) = ring_shape(g, x, y);
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
