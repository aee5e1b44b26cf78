//! Where the grid ends: for each of its four sides, whether the image shows the
//! board's outer squares followed by the plain plate (the board ends there), more
//! alternating squares (it goes on, corners are missing), or cannot tell.
//!
//! A homography fitted to the last four lines of corners of the side extrapolates the
//! lattice outwards. Along the side, for each cell between two corners of the last
//! line, three cells are sampled (medians over their central parts): the *inner* square
//! (between the last two lines), the *outer* square (between the last line and the next
//! one: a real square of the board whatever happens, since the last line's corners are
//! inner corners) and a *beyond* band just past the outer square. The light and dark
//! levels come from the inner and outer squares of that side.
//!
//! - `End`: every outer square has its colour, and every beyond sample inside the image
//!   is light, including those where a continued chessboard would be dark (at least one
//!   of them seen, and at least half the band).
//! - `Continues`: the beyond samples alternate as a continued chessboard would.
//! - `Unknown` otherwise: the band leaves the image, a bright stripe or glare lies on it,
//!   the stripe hid corners of the next line, or the samples are mixed.
//!
//! Only `End` is used to place a partial grid on the board; `Continues` can only refuse
//! a labelling (a side the labelling puts at the board's edge while squares go on).

use nalgebra::Vector2;

use super::image::Gray;
use super::lattice::{cell_dark, extent, Coord, CoordMap, CoordSet};
use crate::numerics::robust::median;

/// What lies beyond one side of the grid.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Side {
    End,
    Continues,
    Unknown,
}

/// Outward lattice directions of the sides, in order `-i, +i, -j, +j`.
pub(crate) const OUTWARD: [Coord; 4] = [(-1, 0), (1, 0), (0, -1), (0, 1)];

/// Median of samples of `g` at `h(lattice point)` for points on an `na x nb` grid over
/// `[a0, a1] x [b0, b1]` in side coordinates (`t = a n + b e`); `None` when any sample
/// falls outside the image.
fn band_median(
    g: &Gray,
    h: &nalgebra::Matrix3<f64>,
    n: Coord,
    e: Coord,
    a: (f64, f64),
    b: (f64, f64),
) -> Option<f32> {
    let mut v: Vec<f32> = Vec::with_capacity(25);
    for ka in 0..5 {
        let aa = a.0 + (a.1 - a.0) * ka as f64 / 4.0;
        for kb in 0..5 {
            let bb = b.0 + (b.1 - b.0) * kb as f64 / 4.0;
            let li = aa * n.0 as f64 + bb * e.0 as f64;
            let lj = aa * n.1 as f64 + bb * e.1 as f64;
            let p = crate::numerics::homography::apply(h, &Vector2::new(li, lj))?;
            v.push(g.bilinear(p.x, p.y)?);
        }
    }
    let mid = v.len() / 2;
    let (_, m, _) = v.select_nth_unstable_by(mid, f32::total_cmp);
    Some(*m)
}

/// Status of side `side` (index into [`OUTWARD`]) of the grid `at` (positions `pos`,
/// colour phase `phase`). `stripe_sites`: lattice sites whose corner a stripe hid.
pub(crate) fn side_status(
    g: &Gray,
    at: &CoordMap<usize>,
    pos: &[[f64; 2]],
    phase: u8,
    side: usize,
    noise: f32,
    stripe_sites: &CoordSet,
) -> Side {
    let Some(&n) = OUTWARD.get(side) else {
        return Side::Unknown;
    };
    let e: Coord = if n.0 != 0 { (0, 1) } else { (1, 0) };
    let a_of = |t: &Coord| t.0 * n.0 + t.1 * n.1;
    let b_of = |t: &Coord| t.0 * e.0 + t.1 * e.1;
    let Some(amax) = at.keys().map(a_of).max() else {
        return Side::Unknown;
    };
    if stripe_sites
        .iter()
        .any(|t| a_of(t) >= amax && a_of(t) <= amax + 1)
    {
        return Side::Unknown;
    }
    let line: Vec<i32> = at.keys().filter(|t| a_of(t) == amax).map(b_of).collect();
    let (Some(&bmin), Some(&bmax)) = (line.iter().min(), line.iter().max()) else {
        return Side::Unknown;
    };
    // local homography of the last four lines
    let (mut plane, mut image) = (Vec::new(), Vec::new());
    for (t, &k) in at {
        if a_of(t) >= amax - 3 {
            plane.push(Vector2::new(t.0 as f64, t.1 as f64));
            image.push(Vector2::new(pos[k][0], pos[k][1]));
        }
    }
    if plane.len() < 6 || extent(at.keys().filter(|t| a_of(t) >= amax - 3)).is_none() {
        return Side::Unknown;
    }
    let Ok(h) = crate::numerics::homography::dlt(&plane, &image) else {
        return Side::Unknown;
    };
    let am = amax as f64;
    let dark_at = |a: f64, b: f64| {
        let (li, lj) = (
            a * n.0 as f64 + b * e.0 as f64,
            a * n.1 as f64 + b * e.1 as f64,
        );
        cell_dark(li.floor() as i32, lj.floor() as i32, phase)
    };
    let (mut light, mut dark) = (Vec::new(), Vec::new());
    let mut outer: Vec<(bool, f32)> = Vec::new();
    let mut beyond: Vec<(bool, f32)> = Vec::new();
    let cells = (bmax - bmin).max(0) as usize;
    for b in bmin..bmax {
        let bb = (b as f64 + 0.25, b as f64 + 0.75);
        let inner_dark = dark_at(am - 0.5, b as f64 + 0.5);
        if let Some(v) = band_median(g, &h, n, e, (am - 0.75, am - 0.25), bb) {
            if inner_dark {
                dark.push(v)
            } else {
                light.push(v)
            }
        }
        if let Some(v) = band_median(g, &h, n, e, (am + 0.25, am + 0.75), bb) {
            if inner_dark {
                light.push(v)
            } else {
                dark.push(v)
            }
            outer.push((!inner_dark, v));
        }
        if let Some(v) = band_median(
            g,
            &h,
            n,
            e,
            (am + 1.1, am + 1.4),
            (b as f64 + 0.2, b as f64 + 0.8),
        ) {
            // a continued chessboard would repeat the inner square's colour
            beyond.push((inner_dark, v));
        }
    }
    decide(light, dark, &outer, &beyond, cells, noise)
}

/// The side's status from the light and dark squares' samples, the outer squares
/// `(dark, value)` and the beyond band `(dark if continued, value)` (module docs).
fn decide(
    mut light: Vec<f32>,
    mut dark: Vec<f32>,
    outer: &[(bool, f32)],
    beyond: &[(bool, f32)],
    cells: usize,
    noise: f32,
) -> Side {
    let (Some(lv), Some(dv)) = (median(&mut light), median(&mut dark)) else {
        return Side::Unknown;
    };
    let c = lv - dv;
    if c < 4.0 * noise || outer.is_empty() {
        return Side::Unknown;
    }
    let fits = |&(is_dark, v): &(bool, f32)| {
        if is_dark {
            v <= dv + 0.35 * c
        } else {
            v >= lv - 0.35 * c
        }
    };
    if !outer.iter().all(fits) || beyond.is_empty() {
        return Side::Unknown;
    }
    if beyond.iter().any(|&(_, v)| v > lv + 0.6 * c) {
        return Side::Unknown;
    }
    let dark_seen = beyond.iter().filter(|x| x.0).count();
    let all_light = beyond.iter().all(|&(_, v)| v >= lv - 0.3 * c);
    if all_light && dark_seen >= 1 && 2 * beyond.len() >= cells {
        Side::End
    } else if dark_seen >= 1 && beyond.iter().all(fits) {
        Side::Continues
    } else {
        Side::Unknown
    }
}
