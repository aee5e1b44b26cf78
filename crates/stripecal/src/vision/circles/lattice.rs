//! Lattice stage: integer lattice coordinates for the blobs from neighbourhood
//! topology alone (nothing depends on the image orientation).
//!
//! 1. Seed: a blob whose four nearest size-compatible neighbours form two opposite
//!    pairs (a lattice "cross"); they define the local lattice vectors. For an
//!    asymmetric grid the four nearest neighbours are the diagonal ones, so the grown
//!    lattice is the board's lattice turned by 45 degrees; [`Grid::board_coords`] maps
//!    it back (`a = i + j`, `r = i - j`, spec/DATASET.md's lattice of the kind).
//! 2. Growth: every unassigned lattice position next to the grid is predicted by a
//!    weighted affine fit of the assigned positions within two (else three) lattice
//!    steps; the nearest free blob within 0.3 local pitches whose area is that of a
//!    circle or of a marker there takes it. Rounds repeat until nothing is added, so
//!    holes (occluded or missing circles) are grown around. Growth stops one line
//!    beyond the board's size in each direction: a grid that still grows past the board
//!    is a board larger than rig.json says.
//! 3. Check: each node is predicted from its neighbours without itself
//!    (leave-one-out); a node farther than 0.2 local pitches is dropped.
//! 4. Size: a grid larger than the board in every orientation is an error (the board in
//!    rig.json is the wrong size), after a sparse outer line (a few blobs of clutter in
//!    line with the grid) is trimmed.
//! 5. A second grid grown from the remaining seeds, as large as a quarter of the board
//!    and not on the first grid's lattice, is a second board: an error.

use super::blobs::Blob;
use crate::error::{Error, Result};
use crate::model::board::{Board, BoardKind};
use crate::vision::affine::{neighbourhood, spans_plane, AffineFit};

pub(crate) use crate::vision::coord::{Coord, CoordMap};

/// The grown grid: lattice coordinate -> blob index.
pub(crate) struct Grid {
    pub at: CoordMap<usize>,
    /// Nodes grown before the leave-one-out check.
    pub grown: usize,
    /// Nodes dropped by the leave-one-out check.
    pub outliers: usize,
    pub kind: BoardKind,
}

impl Grid {
    /// Board-lattice coordinates of grown coordinate `c` (module docs, step 1), up to a
    /// rotation or mirror of the board's lattice.
    #[inline]
    pub fn board_coords(kind: BoardKind, c: Coord) -> Coord {
        match kind {
            BoardKind::AsymmetricCircles => (c.0 + c.1, c.0 - c.1),
            _ => c,
        }
    }
}

/// Affine prediction of lattice position `t` from assigned nodes within Chebyshev
/// radius `rad` (excluding `t` itself): `(position, local pitch, median area)`.
pub(crate) fn predict(
    at: &CoordMap<usize>,
    blobs: &[Blob],
    t: Coord,
    rad: i32,
) -> Option<([f64; 2], f64, f64)> {
    let mut fit = AffineFit::new();
    let mut areas: Vec<f64> = Vec::with_capacity(24);
    for (di, dj) in neighbourhood(rad) {
        let Some(&b) = at.get(&(t.0 + di, t.1 + dj)) else {
            continue;
        };
        let wgt = 1.0 / (di * di + dj * dj) as f64;
        fit.add_weighted((di as f64, dj as f64), (blobs[b].cx, blobs[b].cy), wgt);
        areas.push(blobs[b].area);
    }
    if areas.len() < 3 {
        return None;
    }
    // Collinear support: the 2x2 lattice part is (near) singular.
    if !spans_plane(&fit.n) {
        return None;
    }
    let (px, py) = fit.solve()?;
    let e1 = px[0].hypot(py[0]);
    let e2 = px[1].hypot(py[1]);
    let m = areas.len() / 2;
    let med = *areas.select_nth_unstable_by(m, f64::total_cmp).1;
    Some(([px[2], py[2]], e1.min(e2), med))
}

pub(crate) fn predict_any(
    at: &CoordMap<usize>,
    blobs: &[Blob],
    t: Coord,
) -> Option<([f64; 2], f64, f64)> {
    predict(at, blobs, t, 2).or_else(|| predict(at, blobs, t, 3))
}

/// The board's marker area ratio `R` (marker over ordinary; 1 without markers).
pub(crate) fn marker_area_ratio(board: &Board) -> f64 {
    if board.markers.is_empty() {
        1.0
    } else {
        (board.marker_diameter_mm / board.circle_diameter_mm).powi(2)
    }
}

/// Whether a blob of area `a` can be a circle next to circles of median area `med`:
/// within a factor 2.5 of an ordinary circle's or a marker's area (relative to either).
fn size_ok(a: f64, med: f64, ratio: f64) -> bool {
    let x = a / med;
    let band = |c: f64| x >= c / 2.5 && x <= c * 2.5;
    band(1.0) || band(ratio) || band(1.0 / ratio)
}

/// The board's extent in board-lattice coordinates, `(along i, along j)`.
pub(crate) fn board_extent(board: &Board) -> (i32, i32) {
    let (mut imin, mut imax, mut jmin, mut jmax) = (i64::MAX, i64::MIN, i64::MAX, i64::MIN);
    for (r, c) in board.indices() {
        let (i, j) = board.lattice(r, c);
        (imin, imax, jmin, jmax) = (imin.min(i), imax.max(i), jmin.min(j), jmax.max(j));
    }
    ((imax - imin + 1) as i32, (jmax - jmin + 1) as i32)
}

/// Bounding box of a node set in board-lattice coordinates: `(imin, imax, jmin, jmax)`.
pub(crate) fn bbox<'a>(kind: BoardKind, coords: impl Iterator<Item = &'a Coord>) -> [i32; 4] {
    let mut b = [i32::MAX, i32::MIN, i32::MAX, i32::MIN];
    for &c in coords {
        let (i, j) = Grid::board_coords(kind, c);
        b = [b[0].min(i), b[1].max(i), b[2].min(j), b[3].max(j)];
    }
    b
}

fn fits(b: [i32; 4], ext: (i32, i32), slack: i32) -> bool {
    let (ei, ej) = (b[1] - b[0] + 1, b[3] - b[2] + 1);
    (ei <= ext.0 + slack && ej <= ext.1 + slack) || (ei <= ext.1 + slack && ej <= ext.0 + slack)
}

fn grow(blobs: &[Blob], seed: usize, cross: [usize; 4], board: &Board) -> CoordMap<usize> {
    let ratio = marker_area_ratio(board);
    let ext = board_extent(board);
    let mut at: CoordMap<usize> = CoordMap::default();
    let mut taken = vec![false; blobs.len()];
    at.insert((0, 0), seed);
    taken[seed] = true;
    for (c, b) in [(1, 0), (-1, 0), (0, 1), (0, -1)].into_iter().zip(cross) {
        at.insert(c, b);
        taken[b] = true;
    }
    let mut bb = bbox(board.kind, at.keys());
    let with = |b: [i32; 4], t: Coord| {
        let (i, j) = Grid::board_coords(board.kind, t);
        [b[0].min(i), b[1].max(i), b[2].min(j), b[3].max(j)]
    };
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
            if !fits(with(bb, t), ext, 1) {
                continue;
            }
            let Some((p, pitch, med_area)) = predict_any(&at, blobs, t) else {
                continue;
            };
            let tol = 0.3 * pitch;
            let mut best: Option<(f64, usize)> = None;
            for (k, b) in blobs.iter().enumerate() {
                if taken[k] || (b.cx - p[0]).abs() > tol || (b.cy - p[1]).abs() > tol {
                    continue;
                }
                let d2 = (b.cx - p[0]).powi(2) + (b.cy - p[1]).powi(2);
                if d2 < tol * tol && best.is_none_or(|(bd, _)| d2 < bd) {
                    best = Some((d2, k));
                }
            }
            if let Some((d2, k)) = best {
                if size_ok(blobs[k].area, med_area, ratio) {
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
            if taken[k] || at.contains_key(&t) || !fits(with(bb, t), ext, 1) {
                continue;
            }
            at.insert(t, k);
            taken[k] = true;
            bb = with(bb, t);
            added += 1;
        }
        if added == 0 {
            break;
        }
    }
    at
}

/// Seed candidates: `(score, blob, [+e1, -e1, +e2, -e2] neighbours)`, best first.
fn seeds(blobs: &[Blob], board: &Board) -> Vec<(f64, usize, [usize; 4])> {
    let ratio = marker_area_ratio(board);
    let mut out = Vec::new();
    let mut near: Vec<(f64, usize)> = Vec::with_capacity(blobs.len());
    // Blobs sorted by x: neighbours are searched in a band.
    let mut order: Vec<usize> = (0..blobs.len()).collect();
    order.sort_by(|&a, &b| blobs[a].cx.total_cmp(&blobs[b].cx));
    let xs: Vec<f64> = order.iter().map(|&k| blobs[k].cx).collect();
    for (s, bs) in blobs.iter().enumerate() {
        near.clear();
        // the four nearest lie within a few blob diameters for any real grid
        let reach = 12.0 * bs.a.max(2.0);
        let lo = xs.partition_point(|&x| x < bs.cx - reach);
        let hi = xs.partition_point(|&x| x <= bs.cx + reach);
        for &k in &order[lo..hi] {
            let b = &blobs[k];
            if k == s || (b.cy - bs.cy).abs() > reach || !size_ok(b.area, bs.area, ratio) {
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

/// Drops nodes that their neighbours do not predict (leave-one-out); returns how many.
fn check(at: &mut CoordMap<usize>, blobs: &[Blob]) -> usize {
    let mut bad: Vec<Coord> = Vec::new();
    let mut keys: Vec<Coord> = at.keys().copied().collect();
    keys.sort_unstable();
    for t in keys {
        let Some(b) = at.remove(&t) else { continue };
        let pred = predict_any(at, blobs, t);
        at.insert(t, b);
        match pred {
            Some((p, pitch, _)) => {
                let d = (blobs[b].cx - p[0]).hypot(blobs[b].cy - p[1]);
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
    bad.len()
}

/// Trims a sparse outer line (clutter in line with the grid) while the grid is larger
/// than the board: the outer line with fewer nodes goes when it holds at most a third
/// of the nodes of the line next to it.
fn trim_to_board(at: &mut CoordMap<usize>, board: &Board) {
    let ext = board_extent(board);
    for _ in 0..4 {
        let b = bbox(board.kind, at.keys());
        if fits(b, ext, 0) {
            return;
        }
        // the four outer lines in board-lattice coordinates
        let count = |axis: usize, v: i32| {
            at.keys()
                .filter(|&&c| {
                    let bc = Grid::board_coords(board.kind, c);
                    (if axis == 0 { bc.0 } else { bc.1 }) == v
                })
                .count()
        };
        let step = if board.kind == BoardKind::AsymmetricCircles {
            // neighbouring lines of a line of constant i (or j) lie 1 apart, but hold
            // sites of the other parity: compare with the line two steps in
            2
        } else {
            1
        };
        let mut best: Option<(f64, usize, i32)> = None;
        for (axis, v, inner) in [
            (0, b[0], b[0] + step),
            (0, b[1], b[1] - step),
            (1, b[2], b[2] + step),
            (1, b[3], b[3] - step),
        ] {
            let (n, m) = (count(axis, v), count(axis, inner).max(1));
            let frac = n as f64 / m as f64;
            if best.is_none_or(|(f, _, _)| frac < f) {
                best = Some((frac, axis, v));
            }
        }
        let Some((frac, axis, v)) = best else { return };
        if frac > 1.0 / 3.0 {
            return;
        }
        at.retain(|&c, _| {
            let bc = Grid::board_coords(board.kind, c);
            (if axis == 0 { bc.0 } else { bc.1 }) != v
        });
    }
}

/// Builds the grid of the board's circles.
pub(crate) fn build(blobs: &[Blob], board: &Board, found: &dyn Fn() -> String) -> Result<Grid> {
    let cap = (10 * board.len()).max(4000);
    if blobs.len() > cap {
        return Err(Error::Detection(format!(
            "no circle grid: {} (more than {cap}: the image does not look like a circle board)",
            found()
        )));
    }
    if blobs.len() < 4 {
        return Err(Error::Detection(format!("no circle grid: {}", found())));
    }
    let cands = seeds(blobs, board);
    if cands.is_empty() {
        return Err(Error::Detection(format!(
            "no circle grid: {}, none with four lattice neighbours",
            found()
        )));
    }
    // Grow from the best seeds not yet inside a grown grid; keep the largest.
    let mut taken = vec![false; blobs.len()];
    let mut grids: Vec<CoordMap<usize>> = Vec::new();
    for &(_, s, cross) in &cands {
        if grids.len() >= 6 {
            break;
        }
        if taken[s] || cross.iter().any(|&k| taken[k]) {
            continue;
        }
        let g = grow(blobs, s, cross, board);
        for &b in g.values() {
            taken[b] = true;
        }
        let enough = g.len() * 2 > blobs.len();
        grids.push(g);
        if enough {
            break;
        }
    }
    grids.sort_by_key(|g| std::cmp::Reverse(g.len()));
    let Some(mut at) = grids.first().cloned() else {
        return Err(Error::Detection(format!("no circle grid: {}", found())));
    };
    let grown = at.len();
    let outliers = check(&mut at, blobs);
    if at.len() < 4 {
        return Err(Error::Detection(format!(
            "no circle grid: {}; the largest lattice has {grown} nodes, {outliers} inconsistent",
            found()
        )));
    }
    trim_to_board(&mut at, board);
    let b = bbox(board.kind, at.keys());
    let ext = board_extent(board);
    if !fits(b, ext, 0) {
        let (ei, ej) = (b[1] - b[0] + 1, b[3] - b[2] + 1);
        return Err(Error::Detection(format!(
            "the image shows a grid larger than the board: {} circles spanning {} x {} lattice \
             steps, where a {} x {} board of kind \"{}\" spans {} x {} (rows and cols in rig.json \
             do not match the printed pattern?)",
            at.len(),
            ej,
            ei,
            board.rows,
            board.cols,
            board.kind.name(),
            ext.1,
            ext.0
        )));
    }
    second_board(&grids, &at, blobs, board)?;
    Ok(Grid {
        at,
        grown,
        outliers,
        kind: board.kind,
    })
}

/// Errors when another grown grid is a second board: at least a quarter of the board's
/// points (and 6), and most of its blobs are not where the first grid's lattice,
/// extended by an affine fit, puts its sites.
fn second_board(
    grids: &[CoordMap<usize>],
    main: &CoordMap<usize>,
    blobs: &[Blob],
    board: &Board,
) -> Result<()> {
    let min = (board.len() / 4).max(6);
    if !grids.iter().skip(1).any(|g| g.len() >= min) {
        return Ok(());
    }
    // homography of the main grid: image ~ H (i, j, 1)
    let lat: Vec<nalgebra::Vector2<f64>> = main
        .keys()
        .map(|&(i, j)| nalgebra::Vector2::new(i as f64, j as f64))
        .collect();
    let img: Vec<nalgebra::Vector2<f64>> = main
        .values()
        .map(|&b| nalgebra::Vector2::new(blobs[b].cx, blobs[b].cy))
        .collect();
    let Ok(h) = crate::numerics::homography::dlt(&lat, &img) else {
        return Ok(());
    };
    let Some(hi) = h.try_inverse() else {
        return Ok(());
    };
    let apply = crate::numerics::homography::apply;
    for g in grids.iter().skip(1) {
        if g.len() < min {
            continue;
        }
        // blobs of g on the extended lattice of the main grid
        let on = g
            .values()
            .filter(|&&b| {
                let q = nalgebra::Vector2::new(blobs[b].cx, blobs[b].cy);
                let Some(l) = apply(&hi, &q) else {
                    return false;
                };
                let (i, j) = (l.x.round(), l.y.round());
                let (Some(p), Some(px), Some(py)) = (
                    apply(&h, &nalgebra::Vector2::new(i, j)),
                    apply(&h, &nalgebra::Vector2::new(i + 1.0, j)),
                    apply(&h, &nalgebra::Vector2::new(i, j + 1.0)),
                ) else {
                    return false;
                };
                let pitch = (px - p).norm().min((py - p).norm());
                (p - q).norm() < 0.3 * pitch
            })
            .count();
        if on * 5 < g.len() * 4 {
            let (sx, sy) = g
                .values()
                .fold((0.0, 0.0), |a, &b| (a.0 + blobs[b].cx, a.1 + blobs[b].cy));
            let k = g.len() as f64;
            return Err(Error::Detection(format!(
                "two boards in the image: a second grid of {} circles around ({:.0}, {:.0}) px \
                 besides the first of {} (which one is the target cannot be told)",
                g.len(),
                sx / k,
                sy / k,
                main.len()
            )));
        }
    }
    Ok(())
}
