//! Grid stage: integer lattice coordinates from neighbourhood topology, then board
//! indices from the marker circles.
//!
//! 1. Seed: a blob whose four nearest size-compatible neighbours form two opposite
//!    pairs (a lattice "cross"); they define the local lattice vectors.
//! 2. Growth: every unassigned lattice position next to the grid is predicted by a
//!    weighted affine fit of the assigned positions within two lattice steps; the
//!    nearest unassigned blob within 0.3 local pitches (of a compatible size) takes it.
//!    Rounds repeat until nothing is added, so holes (occluded or missing circles) are
//!    grown around. Nothing depends on the image orientation.
//! 3. Check: each node is predicted from its neighbours without itself
//!    (leave-one-out); a node farther than 0.2 local pitches is dropped.
//! 4. Markers: a node is a marker when its area over the median area of its
//!    neighbours (two lattice steps) is closer, in log scale, to the board's marker
//!    area ratio than to 1. A node in between is an error, not a guess.
//! 5. Indices: the marker set is matched against the board's markers under the 8
//!    lattice symmetries plus a translation. Matches that mirror the board are
//!    rejected: with `u` right and `v` down, the image direction of increasing column
//!    crossed with that of increasing row must be positive (board z = x cross y points
//!    away from the camera, spec/DATASET.md). Exactly one match with every node inside
//!    the board is accepted.

use std::collections::HashMap;

use super::blobs::{Blob, BlobStats};
use crate::board::Board;
use crate::error::{Error, Result};

/// Assigned nodes of the grid: `(blob, row, col)`.
pub(crate) struct GridResult {
    pub nodes: Vec<(usize, usize, usize)>,
    /// Nodes grown before the leave-one-out check.
    pub grown: usize,
    /// Nodes dropped by the leave-one-out check.
    pub outliers: usize,
    /// Board symmetries the view cannot decide.
    pub alternatives: Vec<crate::board::Symmetry>,
}

type Coord = (i32, i32);

/// Affine prediction of lattice position `t` from assigned nodes within Chebyshev
/// radius `rad` (excluding `t` itself): `(position, local pitch, median area)`.
fn predict(
    at: &HashMap<Coord, usize>,
    blobs: &[Blob],
    t: Coord,
    rad: i32,
) -> Option<([f64; 2], f64, f64)> {
    let mut n = [[0f64; 3]; 3];
    let mut bx = [0f64; 3];
    let mut by = [0f64; 3];
    let mut areas: Vec<f64> = Vec::with_capacity(24);
    for di in -rad..=rad {
        for dj in -rad..=rad {
            if di == 0 && dj == 0 {
                continue;
            }
            let Some(&b) = at.get(&(t.0 + di, t.1 + dj)) else {
                continue;
            };
            let wgt = 1.0 / (di * di + dj * dj) as f64;
            let f = [di as f64, dj as f64, 1.0];
            for r in 0..3 {
                for c in 0..3 {
                    n[r][c] += wgt * f[r] * f[c];
                }
                bx[r] += wgt * f[r] * blobs[b].cx;
                by[r] += wgt * f[r] * blobs[b].cy;
            }
            areas.push(blobs[b].area);
        }
    }
    if areas.len() < 3 {
        return None;
    }
    let m = nalgebra::Matrix3::from_fn(|r, c| n[r][c]);
    // Collinear support: the 2x2 lattice part is (near) singular.
    let scale = m[(0, 0)] + m[(1, 1)];
    let det2 = {
        // Schur complement of the constant term.
        let s = m[(2, 2)];
        let a = m[(0, 0)] - m[(0, 2)] * m[(0, 2)] / s;
        let b = m[(0, 1)] - m[(0, 2)] * m[(1, 2)] / s;
        let d = m[(1, 1)] - m[(1, 2)] * m[(1, 2)] / s;
        a * d - b * b
    };
    if det2.is_nan() || det2 <= 1e-3 * scale * scale {
        return None;
    }
    let inv = m.try_inverse()?;
    let px = inv * nalgebra::Vector3::from(bx);
    let py = inv * nalgebra::Vector3::from(by);
    let e1 = (px[0] * px[0] + py[0] * py[0]).sqrt();
    let e2 = (px[1] * px[1] + py[1] * py[1]).sqrt();
    areas.sort_by(f64::total_cmp);
    let med = areas[areas.len() / 2];
    Some(([px[2], py[2]], e1.min(e2), med))
}

fn predict_any(
    at: &HashMap<Coord, usize>,
    blobs: &[Blob],
    t: Coord,
) -> Option<([f64; 2], f64, f64)> {
    predict(at, blobs, t, 2).or_else(|| predict(at, blobs, t, 3))
}

struct Grown {
    at: HashMap<Coord, usize>,
}

/// The board's marker area ratio `R` (marker over ordinary) and `R' = max(R, 1/R)`.
fn size_ratio(board: &Board) -> (f64, f64) {
    let r = (board.marker_diameter_mm / board.circle_diameter_mm).powi(2);
    (r, r.max(1.0 / r))
}

fn grow(
    blobs: &[Blob],
    seed: usize,
    cross: [usize; 4],
    board: &Board,
    taken_global: &[bool],
) -> Grown {
    let (_, rr) = size_ratio(board);
    let size_lo = 1.0 / (2.5 * rr);
    let size_hi = 2.5 * rr;
    let mut at: HashMap<Coord, usize> = HashMap::new();
    let mut taken = taken_global.to_vec();
    at.insert((0, 0), seed);
    taken[seed] = true;
    for (c, b) in [(1, 0), (-1, 0), (0, 1), (0, -1)].into_iter().zip(cross) {
        at.insert(c, b);
        taken[b] = true;
    }
    let big = board.rows.max(board.cols) as i32;
    let small = board.rows.min(board.cols) as i32;
    let (mut imin, mut imax, mut jmin, mut jmax) = (-1i32, 1i32, -1i32, 1i32);
    loop {
        let mut targets: Vec<Coord> = Vec::new();
        for &(i, j) in at.keys() {
            for d in [(1, 0), (-1, 0), (0, 1), (0, -1)] {
                let t = (i + d.0, j + d.1);
                if !at.contains_key(&t) {
                    targets.push(t);
                }
            }
        }
        targets.sort_unstable();
        targets.dedup();
        let mut proposals: Vec<(f64, Coord, usize)> = Vec::new();
        for t in targets {
            let ei = imax.max(t.0) - imin.min(t.0) + 1;
            let ej = jmax.max(t.1) - jmin.min(t.1) + 1;
            let fits = (ei <= big && ej <= small) || (ei <= small && ej <= big);
            if !fits {
                continue;
            }
            let Some((p, pitch, med_area)) = predict_any(&at, blobs, t) else {
                continue;
            };
            let tol = 0.3 * pitch;
            let mut best: Option<(f64, usize)> = None;
            for (k, b) in blobs.iter().enumerate() {
                if taken[k] {
                    continue;
                }
                let d2 = (b.cx - p[0]).powi(2) + (b.cy - p[1]).powi(2);
                if d2 < tol * tol && best.is_none_or(|(bd, _)| d2 < bd) {
                    best = Some((d2, k));
                }
            }
            if let Some((d2, k)) = best {
                let ratio = blobs[k].area / med_area;
                if ratio >= size_lo && ratio <= size_hi {
                    proposals.push((d2.sqrt() / pitch, t, k));
                }
            }
        }
        if proposals.is_empty() {
            break;
        }
        proposals.sort_by(|a, b| a.0.total_cmp(&b.0));
        let mut added = 0;
        for (_, t, k) in proposals {
            if taken[k] || at.contains_key(&t) {
                continue;
            }
            let ei = imax.max(t.0) - imin.min(t.0) + 1;
            let ej = jmax.max(t.1) - jmin.min(t.1) + 1;
            if !((ei <= big && ej <= small) || (ei <= small && ej <= big)) {
                continue;
            }
            at.insert(t, k);
            taken[k] = true;
            imin = imin.min(t.0);
            imax = imax.max(t.0);
            jmin = jmin.min(t.1);
            jmax = jmax.max(t.1);
            added += 1;
        }
        if added == 0 {
            break;
        }
    }
    Grown { at }
}

/// Seed candidates: `(score, blob, [+e1, -e1, +e2, -e2] neighbours)`, best first.
fn seeds(blobs: &[Blob], board: &Board) -> Vec<(f64, usize, [usize; 4])> {
    let (_, rr) = size_ratio(board);
    let mut out = Vec::new();
    let mut near: Vec<(f64, usize)> = Vec::with_capacity(blobs.len());
    for (s, bs) in blobs.iter().enumerate() {
        near.clear();
        for (k, b) in blobs.iter().enumerate() {
            if k == s {
                continue;
            }
            let ratio = b.area / bs.area;
            if ratio < 1.0 / (2.0 * rr) || ratio > 2.0 * rr {
                continue;
            }
            near.push(((b.cx - bs.cx).powi(2) + (b.cy - bs.cy).powi(2), k));
        }
        if near.len() < 4 {
            continue;
        }
        near.select_nth_unstable_by(3, |a, b| a.0.total_cmp(&b.0));
        let mut four = [near[0], near[1], near[2], near[3]];
        four.sort_by(|a, b| a.0.total_cmp(&b.0));
        let v: Vec<[f64; 2]> = four
            .iter()
            .map(|&(_, k)| [blobs[k].cx - bs.cx, blobs[k].cy - bs.cy])
            .collect();
        let len = |a: [f64; 2]| (a[0] * a[0] + a[1] * a[1]).sqrt();
        let cos = |a: [f64; 2], b: [f64; 2]| (a[0] * b[0] + a[1] * b[1]) / (len(a) * len(b));
        if len(v[3]) > 2.5 * len(v[0]) || len(v[0]) < 1e-9 {
            continue;
        }
        // v0's opposite among v1..v3
        let Some(opp) = (1..4).min_by(|&a, &b| cos(v[0], v[a]).total_cmp(&cos(v[0], v[b]))) else {
            continue;
        };
        let rest: Vec<usize> = (1..4).filter(|&k| k != opp).collect();
        let (c, d) = (rest[0], rest[1]);
        let pair_ok = |a: usize, b: usize| {
            let ratio = len(v[a]) / len(v[b]);
            cos(v[a], v[b]) < -0.85 && (0.6..=1.0 / 0.6).contains(&ratio)
        };
        if !pair_ok(0, opp) || !pair_ok(c, d) || cos(v[0], v[c]).abs() > 0.8 {
            continue;
        }
        let sum = |a: usize, b: usize| len([v[a][0] + v[b][0], v[a][1] + v[b][1]]) / len(v[a]);
        let score = sum(0, opp) + sum(c, d);
        out.push((score, s, [four[0].1, four[opp].1, four[c].1, four[d].1]));
    }
    out.sort_by(|a, b| a.0.total_cmp(&b.0));
    out
}

/// Log-area residuals of the nodes against a smooth model of the ordinary circles'
/// log-area over the lattice (perspective makes areas vary smoothly): a quadratic in
/// the lattice coordinates (a plane for small grids, a constant for tiny ones),
/// fitted with the markers excluded iteratively (residuals beyond half the marker
/// log-ratio `lr`).
fn area_residuals(
    coords: &[Coord],
    at: &HashMap<Coord, usize>,
    blobs: &[Blob],
    lr: f64,
) -> Vec<f64> {
    let n = coords.len();
    let la: Vec<f64> = coords.iter().map(|t| blobs[at[t]].area.ln()).collect();
    let (mi, mj) = (
        coords.iter().map(|c| c.0 as f64).sum::<f64>() / n as f64,
        coords.iter().map(|c| c.1 as f64).sum::<f64>() / n as f64,
    );
    let terms = if n >= 15 {
        6
    } else if n >= 6 {
        3
    } else {
        1
    };
    let feat = |c: &Coord| {
        let (i, j) = (c.0 as f64 - mi, c.1 as f64 - mj);
        [1.0, i, j, i * i, i * j, j * j]
    };
    let mut keep = vec![true; n];
    let mut res = vec![0.0; n];
    for _ in 0..4 {
        let mut m = nalgebra::DMatrix::<f64>::zeros(terms, terms);
        let mut r = nalgebra::DVector::<f64>::zeros(terms);
        for k in (0..n).filter(|&k| keep[k]) {
            let f = feat(&coords[k]);
            for a in 0..terms {
                for b in 0..terms {
                    m[(a, b)] += f[a] * f[b];
                }
                r[a] += f[a] * la[k];
            }
        }
        let coef = match m.cholesky() {
            Some(ch) => ch.solve(&r),
            None => {
                // too few kept nodes for the model: a median level
                let mut v: Vec<f64> = (0..n).filter(|&k| keep[k]).map(|k| la[k]).collect();
                if v.is_empty() {
                    v = la.clone();
                }
                v.sort_by(f64::total_cmp);
                let mut c = nalgebra::DVector::<f64>::zeros(terms);
                c[0] = v[v.len() / 2];
                c
            }
        };
        for k in 0..n {
            let f = feat(&coords[k]);
            let pred: f64 = (0..terms).map(|a| coef[a] * f[a]).sum();
            res[k] = la[k] - pred;
        }
        let new_keep: Vec<bool> = res.iter().map(|&x| x / lr < 0.5).collect();
        if new_keep == keep {
            break;
        }
        keep = new_keep;
    }
    res
}

fn detection(msg: String) -> Error {
    Error::Detection(msg)
}

/// Orders the blobs into the board's grid.
pub(crate) fn order(blobs: &[Blob], board: &Board, stats: &BlobStats) -> Result<GridResult> {
    let found = || {
        format!(
            "{} blobs passed the filters ({} components: {} touching the border, {} too small, {} too \
             large, {} not elliptical, {} not surrounded by background)",
            blobs.len(),
            stats.components,
            stats.touching_border,
            stats.too_small,
            stats.too_large,
            stats.bad_shape,
            stats.not_surrounded
        )
    };
    let cap = (10 * board.len()).max(4000);
    if blobs.len() > cap {
        return Err(detection(format!(
            "no circle grid: {} (more than {cap}: the image does not look like a circle board)",
            found()
        )));
    }
    if blobs.len() < 4 {
        return Err(detection(format!("no circle grid: {}", found())));
    }
    let cands = seeds(blobs, board);
    if cands.is_empty() {
        return Err(detection(format!(
            "no circle grid: {}, none with four lattice neighbours",
            found()
        )));
    }
    // Grow from the best seeds not yet inside a grown grid; keep the largest grid.
    let mut taken = vec![false; blobs.len()];
    let mut best: Option<Grown> = None;
    let mut tries = 0;
    for &(_, s, cross) in &cands {
        if tries >= 6 {
            break;
        }
        if taken[s] || cross.iter().any(|&k| taken[k]) {
            continue;
        }
        tries += 1;
        let g = grow(blobs, s, cross, board, &vec![false; blobs.len()]);
        for &b in g.at.values() {
            taken[b] = true;
        }
        if best.as_ref().is_none_or(|b| g.at.len() > b.at.len()) {
            best = Some(g);
        }
        if best.as_ref().is_some_and(|b| b.at.len() * 2 > blobs.len()) {
            break;
        }
    }
    let Some(grown) = best else {
        return Err(detection(format!("no circle grid: {}", found())));
    };
    let grown_n = grown.at.len();

    // Leave-one-out check.
    let mut at = grown.at;
    let mut bad: Vec<Coord> = Vec::new();
    let mut keys: Vec<Coord> = at.keys().copied().collect();
    keys.sort_unstable();
    for t in keys {
        let Some(b) = at.remove(&t) else { continue };
        let pred = predict_any(&at, blobs, t);
        at.insert(t, b);
        match pred {
            Some((p, pitch, _)) => {
                let d = ((blobs[b].cx - p[0]).powi(2) + (blobs[b].cy - p[1]).powi(2)).sqrt();
                if d > 0.2 * pitch {
                    bad.push(t);
                }
            }
            None => bad.push(t),
        }
    }
    for t in &bad {
        at.remove(t);
    }
    if at.len() < 4 {
        return Err(detection(format!(
            "no circle grid: {}; the largest lattice has {grown_n} nodes, {} inconsistent",
            found(),
            bad.len()
        )));
    }

    // Markers by relative size.
    let (ratio, rr) = size_ratio(board);
    if board.markers.is_empty() || rr < 1.3 {
        return Err(Error::InvalidInput(format!(
            "the board's markers cannot fix the grid: {} markers, marker / circle diameter {} / {} mm \
             (markers must be at least 14 % larger or smaller than the circles)",
            board.markers.len(),
            board.marker_diameter_mm,
            board.circle_diameter_mm
        )));
    }
    let lr = ratio.ln();
    let mut coords: Vec<Coord> = at.keys().copied().collect();
    coords.sort_unstable();
    let resid = area_residuals(&coords, &at, blobs, lr);
    let mut markers: Vec<Coord> = Vec::new();
    for (&t, &res) in coords.iter().zip(&resid) {
        let b = at[&t];
        let x = res / lr;
        if (0.3..=0.7).contains(&x) {
            return Err(detection(format!(
                "ambiguous marker: the blob at ({:.1}, {:.1}) px is {:.2} times the area the \
                 grid predicts there (circles 1, markers {ratio:.2})",
                blobs[b].cx,
                blobs[b].cy,
                res.exp()
            )));
        }
        if x > 0.5 {
            markers.push(t);
        }
    }
    let marker_px = |ms: &[Coord]| {
        ms.iter()
            .map(|t| format!("({:.0}, {:.0})", blobs[at[t]].cx, blobs[at[t]].cy))
            .collect::<Vec<_>>()
            .join(", ")
    };
    let ext = |f: fn(&Coord) -> i32| {
        let v: Vec<i32> = at.keys().map(f).collect();
        v.iter().max().copied().unwrap_or(0) - v.iter().min().copied().unwrap_or(0) + 1
    };
    let (ni, nj) = (ext(|c| c.0), ext(|c| c.1));
    let summary = |what: &str| {
        format!(
            "{what}: {}; grid of {} nodes spanning {ni} x {nj} ({grown_n} grown, {} inconsistent), {} \
             markers found at [{}] px, the board has {}",
            found(),
            at.len(),
            bad.len(),
            markers.len(),
            marker_px(&markers),
            board.markers.len()
        )
    };
    if markers.len() != board.markers.len() {
        return Err(detection(summary("markers not matched")));
    }

    // Global affine of the lattice (for handedness).
    let mut n = nalgebra::Matrix3::<f64>::zeros();
    let mut bx = nalgebra::Vector3::<f64>::zeros();
    let mut by = nalgebra::Vector3::<f64>::zeros();
    for (&(i, j), &b) in &at {
        let f = nalgebra::Vector3::new(i as f64, j as f64, 1.0);
        n += f * f.transpose();
        bx += f * blobs[b].cx;
        by += f * blobs[b].cy;
    }
    let Some(inv) = n.try_inverse() else {
        return Err(detection(summary("degenerate grid")));
    };
    let (ax, ay) = (inv * bx, inv * by);
    let img_dir = |di: f64, dj: f64| [ax[0] * di + ax[1] * dj, ay[0] * di + ay[1] * dj];

    let mut bm: Vec<Coord> = board
        .markers
        .iter()
        .map(|m| (m[0] as i32, m[1] as i32))
        .collect();
    bm.sort_unstable();
    let mut matches: Vec<([[i32; 2]; 2], Coord)> = Vec::new();
    let mut mirrored = 0;
    for perm in [false, true] {
        for si in [1i32, -1] {
            for sj in [1i32, -1] {
                // (row, col) = S (i, j) + t
                let s: [[i32; 2]; 2] = if perm {
                    [[0, sj], [si, 0]]
                } else {
                    [[si, 0], [0, sj]]
                };
                let map = |(i, j): Coord| (s[0][0] * i + s[0][1] * j, s[1][0] * i + s[1][1] * j);
                let mut mm: Vec<Coord> = markers.iter().map(|&c| map(c)).collect();
                mm.sort_unstable();
                let t = (bm[0].0 - mm[0].0, bm[0].1 - mm[0].1);
                if !mm
                    .iter()
                    .zip(&bm)
                    .all(|(a, b)| (a.0 + t.0, a.1 + t.1) == *b)
                {
                    continue;
                }
                // Image directions of increasing row and column: (i, j) = S^T (r, c).
                let d_row = img_dir(s[0][0] as f64, s[0][1] as f64);
                let d_col = img_dir(s[1][0] as f64, s[1][1] as f64);
                let cross = d_col[0] * d_row[1] - d_col[1] * d_row[0];
                if cross <= 0.0 {
                    mirrored += 1;
                    continue;
                }
                let inside = at.keys().all(|&c| {
                    let (r, cc) = map(c);
                    r + t.0 >= 0
                        && cc + t.1 >= 0
                        && ((r + t.0) as usize) < board.rows
                        && ((cc + t.1) as usize) < board.cols
                });
                if !inside {
                    continue;
                }
                matches.push((s, t));
            }
        }
    }
    match matches.len() {
        1 => {}
        0 => {
            return Err(detection(summary(&format!(
            "the markers do not match the board's marker pattern with the grid inside the board \
                 ({mirrored} mirror-image matches rejected)"
        ))))
        }
        k => {
            return Err(detection(summary(&format!(
                "ambiguous grid: {k} orientations match the markers"
            ))))
        }
    }
    let (s, t) = matches[0];
    let mut nodes: Vec<(usize, usize, usize)> = at
        .iter()
        .map(|(&(i, j), &b)| {
            let r = s[0][0] * i + s[0][1] * j + t.0;
            let c = s[1][0] * i + s[1][1] * j + t.1;
            (b, r as usize, c as usize)
        })
        .collect();
    nodes.sort_by_key(|&(_, r, c)| (r, c));
    Ok(GridResult {
        nodes,
        grown: grown_n,
        outliers: bad.len(),
        alternatives: Vec::new(),
    })
}
