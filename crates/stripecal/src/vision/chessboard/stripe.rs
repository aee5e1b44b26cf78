//! Bright stripes (a laser line) across a corner's window: bright pixels over the
//! light squares, over the dark sectors, or above the fitted model, counted only when
//! they form a connected piece of line (bright grain and glare come in small clumps).

use super::image::Gray;
use super::lattice::{cross, norm, CoordSet, Local};
use super::model::{values, window, Vec11};

/// The image pixels of the window samples `px` (offsets `[dx, dy, value, ..]` from `c`)
/// that pass `keep`.
fn pixels_where(px: &[[f64; 4]], c: [f64; 2], keep: impl Fn(&[f64; 4]) -> bool) -> Vec<(i32, i32)> {
    px.iter()
        .filter(|q| keep(q))
        .map(|q| pixel_of(q, c))
        .collect()
}

/// The image pixel of window sample `q` (offsets from `c`).
fn pixel_of(q: &[f64; 4], c: [f64; 2]) -> (i32, i32) {
    ((q[0] + c[0]).round() as i32, (q[1] + c[1]).round() as i32)
}

/// The image pixels of the window of radius `r` around `c` whose samples pass `keep`.
fn window_pixels_where(
    g: &Gray,
    c: [f64; 2],
    r: f64,
    keep: impl Fn(&[f64; 4]) -> bool,
) -> Vec<(i32, i32)> {
    let mut px = Vec::new();
    window(g, c, r, &CoordSet::default(), &mut px);
    pixels_where(&px, c, keep)
}

/// A bright stripe in the window around `c`: the pixels brighter than the light
/// squares by half the contrast (and 8 noise sigmas), see [`stripe_of`].
pub(crate) fn stripe_mask(
    g: &Gray,
    c: [f64; 2],
    r: f64,
    light: f64,
    dark: f64,
    noise: f64,
) -> CoordSet {
    if !(light.is_finite() && dark.is_finite()) {
        return CoordSet::default();
    }
    let thr = light + (0.5 * (light - dark)).max(8.0 * noise);
    let bright = window_pixels_where(g, c, r + 1.0, |q| q[2] > thr);
    stripe_of(bright, r)
}

/// A stripe over the dark squares: pixels of the window around `l.p` inside a dark
/// sector (more than 3.5 px from the edges along the lattice directions `l.di`, `l.dj`)
/// brighter than the middle of the dark and light levels, see [`stripe_of`]. The dark
/// squares are the quietest part of the window (no grain, no glare reaches half the
/// contrast there), so a stripe no brighter than the light squares shows here.
pub(crate) fn dark_sector_stripe(
    g: &Gray,
    l: &Local,
    r: f64,
    light_ij: Option<bool>,
    light: f64,
    dark: f64,
) -> CoordSet {
    let (c, di, dj) = (l.p, l.di, l.dj);
    let det = cross(di, dj);
    let (Some(light_ij), true) = (
        light_ij,
        light.is_finite() && dark.is_finite() && det.abs() > 1e-9,
    ) else {
        return CoordSet::default();
    };
    let thr = 0.5 * (light + dark);
    let (ni, nj) = (norm(di), norm(dj));
    let bright = window_pixels_where(g, c, r, |q| {
        // lattice coordinates of the offset, and distances to the two edges
        let a = cross([q[0], q[1]], dj) / det;
        let b = cross(di, [q[0], q[1]]) / det;
        let (to_i_edge, to_j_edge) = ((b * det / ni).abs(), (a * det / nj).abs());
        // the sectors of (+i, +j) and (-i, -j) have the colour of light_ij
        let like_ij = (a > 0.0) == (b > 0.0);
        let in_dark = like_ij != light_ij;
        to_i_edge > 3.5 && to_j_edge > 3.5 && in_dark && q[2] > thr
    });
    stripe_of(bright, 0.5 * r)
}

/// A stripe seen in the fit's residuals: pixels brighter than the fitted model by 3/4
/// of the contrast (a stripe over the dark squares that is no brighter than the light
/// ones), see [`stripe_of`].
pub(crate) fn residual_stripe(th: &Vec11, px: &[[f64; 4]], r: f64, noise: f64) -> CoordSet {
    let thr = (1.5 * th[6].abs()).max(8.0 * noise);
    let mut fm = Vec::new();
    values(th, px, 1.0 / r, &mut fm);
    let c = [th[0], th[1]];
    let bright = px
        .iter()
        .zip(&fm)
        .filter(|(q, v)| q[2] - v[0] > thr)
        .map(|(q, _)| pixel_of(q, c))
        .collect();
    stripe_of(bright, r)
}

/// A faint stripe above the light squares: pixels of the window around `c` brighter
/// than the light squares' level (their medians, which a stripe does not move, unlike
/// a fit that it pulls up) by a quarter of the contrast (and 6 noise sigmas) that form
/// a long thin line (a connected part of at least `r` pixels, its scatter at least
/// `1.5 r` long and under 0.35 times as wide). Bright grain at that level clumps into
/// round patches, which do not count. Returns the line's pixels grown by one pixel.
pub(crate) fn faint_line(
    g: &Gray,
    c: [f64; 2],
    r: f64,
    light: f64,
    dark: f64,
    noise: f64,
) -> CoordSet {
    let mut out = CoordSet::default();
    if !(light.is_finite() && dark.is_finite()) {
        return out;
    }
    let thr = light + (0.25 * (light - dark)).max(6.0 * noise);
    let bright = window_pixels_where(g, c, r, |q| q[2] > thr);
    for part in components(&bright) {
        if (part.len() as f64) < r || !long_and_thin(&part, 1.5 * r, 0.35) {
            continue;
        }
        for (x, y) in part {
            for dy in -1..=1 {
                for dx in -1..=1 {
                    out.insert((x + dx, y + dy));
                }
            }
        }
    }
    out
}

/// Whether the scatter of a pixel set is at least `len` long (`sqrt(12 var)` along
/// its major axis) and its minor / major standard deviation below `ratio`.
fn long_and_thin(px: &[(i32, i32)], len: f64, ratio: f64) -> bool {
    let n = px.len() as f64;
    let (mx, my) = px
        .iter()
        .fold((0.0, 0.0), |a, p| (a.0 + p.0 as f64, a.1 + p.1 as f64));
    let (mx, my) = (mx / n, my / n);
    let (mut a, mut b, mut c) = (0.0, 0.0, 0.0);
    for p in px {
        let (x, y) = (p.0 as f64 - mx, p.1 as f64 - my);
        a += x * x / n;
        b += x * y / n;
        c += y * y / n;
    }
    let tr = 0.5 * (a + c);
    let d = (0.25 * (a - c) * (a - c) + b * b).sqrt();
    let (l1, l2) = (tr + d, (tr - d).max(0.0));
    (12.0 * l1).sqrt() >= len && (l2 / l1.max(1e-12)).sqrt() < ratio
}

/// The 8-connected components of a pixel set.
fn components(px: &[(i32, i32)]) -> Vec<Vec<(i32, i32)>> {
    let set: CoordSet = px.iter().copied().collect();
    let mut seen: CoordSet = CoordSet::default();
    let mut out = Vec::new();
    let mut stack = Vec::new();
    for &p in px {
        if !seen.insert(p) {
            continue;
        }
        stack.push(p);
        let mut part = Vec::new();
        while let Some((x, y)) = stack.pop() {
            part.push((x, y));
            for dy in -1..=1 {
                for dx in -1..=1 {
                    let q = (x + dx, y + dy);
                    if set.contains(&q) && seen.insert(q) {
                        stack.push(q);
                    }
                }
            }
        }
        out.push(part);
    }
    out
}

/// Size of the largest 8-connected component of a pixel set.
fn largest_component(px: &[(i32, i32)]) -> usize {
    components(px).iter().map(Vec::len).max().unwrap_or(0)
}

/// The pixels grown by one pixel when their largest connected part has at least
/// `max(8, r)` pixels (a stripe crossing the window has about `4 r`; bright grain,
/// a few in small clumps); empty otherwise.
fn stripe_of(px: Vec<(i32, i32)>, r: f64) -> CoordSet {
    let mut out = CoordSet::default();
    if (largest_component(&px) as f64) < r.max(8.0) {
        return out;
    }
    for (x, y) in px {
        for dy in -1..=1 {
            for dx in -1..=1 {
                out.insert((x + dx, y + dy));
            }
        }
    }
    out
}
