//! Checks that a measured point is a chessboard corner: the four squares around it,
//! the fitted model's parameters and its residuals sector by sector.

use super::image::Gray;
use super::lattice::{norm, Local};
use super::model::{values, Model, Vec11};
use super::refine::{Fail, Settings};

/// Angle difference modulo pi, in [0, pi/2].
fn line_angle_diff(a: f64, b: f64) -> f64 {
    let d = (a - b).rem_euclid(std::f64::consts::PI);
    d.min(std::f64::consts::PI - d)
}

/// The four squares around a corner at `c` (medians over their central parts): the
/// diagonal pairs must agree within `ratio` times their difference from each other
/// (an X-junction, not an L or a T where a board ends: there the ratio is 2), the pair
/// between `+i` and `+j` light iff `light_ij`.
/// Returns the light and dark levels; [`Fail::Border`] when a square is not in the
/// image even near the corner.
pub(crate) fn quadrants(
    g: &Gray,
    c: [f64; 2],
    di: [f64; 2],
    dj: [f64; 2],
    light_ij: Option<bool>,
    noise: f64,
    ratio: f64,
) -> Result<(f64, f64), Fail> {
    // the central part of each square, or of its part nearest the corner when the
    // square leaves the image
    let cell = |a: f64, b: f64| {
        [(0.5, 0.25), (0.3, 0.12)].iter().find_map(|&(at, half)| {
            let e1 = [a * di[0], a * di[1]];
            let e2 = [b * dj[0], b * dj[1]];
            let m = [c[0] + at * (e1[0] + e2[0]), c[1] + at * (e1[1] + e2[1])];
            super::cells::patch_median(g, m, e1, e2, half, 4).map(f64::from)
        })
    };
    let q = [
        cell(1.0, 1.0),
        cell(-1.0, -1.0),
        cell(-1.0, 1.0),
        cell(1.0, -1.0),
    ];
    let [Some(a0), Some(a1), Some(b0), Some(b1)] = q else {
        return Err(Fail::Border);
    };
    let (ma, mb) = (0.5 * (a0 + a1), 0.5 * (b0 + b1));
    let diff = (ma - mb).abs();
    if diff < 4.0 * noise || (a0 - a1).abs() > ratio * diff || (b0 - b1).abs() > ratio * diff {
        return Err(Fail::NotCorner(
            "the four squares around it are not a chessboard corner",
        ));
    }
    if light_ij.is_some_and(|l| l != (ma > mb)) {
        return Err(Fail::NotCorner(
            "the square colours around the corner are swapped",
        ));
    }
    Ok((ma.max(mb), ma.min(mb)))
}

/// Largest absolute mean residual over the four sectors between the fitted edges
/// (pixels more than two blur widths from both edges): about zero at an X-junction,
/// half the contrast where one square is not what the model says (the tip of a
/// square cut by a stripe, an L where the board ends).
pub(crate) fn worst_sector(th: &Vec11, px: &[[f64; 4]], r: f64) -> f64 {
    let (s1a, c1a) = th[2].sin_cos();
    let (s2a, c2a) = th[3].sin_cos();
    let away = (2.0 * th[4].exp() + 0.5).min(0.4 * r);
    let mut fm = Vec::new();
    values(th, px, 1.0 / r, &mut fm);
    let mut acc = [[0f64; 2]; 4];
    for (q, &[f, _]) in px.iter().zip(&fm) {
        let s1 = -s1a * q[0] + c1a * q[1];
        let s2 = -s2a * q[0] + c2a * q[1];
        if s1.abs() < away || s2.abs() < away {
            continue;
        }
        let k = (s1 > 0.0) as usize * 2 + (s2 > 0.0) as usize;
        acc[k][0] += q[3] * (q[2] - f);
        acc[k][1] += q[3];
    }
    acc.iter()
        .map(|a| {
            if a[1] >= 3.0 {
                (a[0] / a[1]).abs()
            } else {
                f64::INFINITY
            }
        })
        .fold(0.0, f64::max)
}

/// Checks the fitted model: position (within `tol` of the start `l.p`), contrast, blur,
/// edge directions, polarity (from the lattice steps `l.di`, `l.dj`).
pub(crate) fn validate(
    th: &Vec11,
    l: &Local,
    angles: [f64; 2],
    r: f64,
    tol: f64,
    light_ij: Option<bool>,
    s: &Settings,
) -> Result<(), Fail> {
    let (start, di, dj) = (l.p, l.di, l.dj);
    let c = [th[0], th[1]];
    if norm([c[0] - start[0], c[1] - start[1]]) > tol {
        return Err(Fail::NotCorner(
            "the saddle point is far from the predicted position",
        ));
    }
    let contrast = 2.0 * th[6].abs();
    if contrast < 4.0 * s.noise {
        return Err(Fail::NotCorner("too little contrast for a corner"));
    }
    let blur = th[4].exp();
    if !(0.15..=0.7 * r + 0.5).contains(&blur) {
        return Err(Fail::NotCorner("the corner is too blurred for its window"));
    }
    let lim = 30f64.to_radians();
    if line_angle_diff(th[2], angles[0]) > lim || line_angle_diff(th[3], angles[1]) > lim {
        return Err(Fail::NotCorner("the edges do not follow the grid"));
    }
    if line_angle_diff(th[2], th[3]) < 15f64.to_radians() {
        return Err(Fail::NotCorner("the edges do not follow the grid"));
    }
    if let Some(light) = light_ij {
        // model sign half-way into the square between +i and +j
        let (ui, uj) = (norm(di), norm(dj));
        let d = [
            0.25 * r * (di[0] / ui + dj[0] / uj),
            0.25 * r * (di[1] / ui + dj[1] / uj),
        ];
        let (_, m) = Model::new(th, 1.0 / r).value(d[0], d[1]);
        if (th[6] * m > 0.0) != light {
            return Err(Fail::NotCorner(
                "the square colours around the corner are swapped",
            ));
        }
    }
    Ok(())
}
