//! Labelling stage: board indices for the lattice nodes, from what the image shows and
//! nothing else.
//!
//! 1. Node states: with markers on the board, a node is a `Marker` when its area over
//!    a smooth model of the ordinary circles' areas (perspective makes areas vary
//!    smoothly) is closer, in log scale, to the board's marker area ratio than to 1, an
//!    `Ordinary` circle when it is clearly not, and `Unknown` in between (no constraint;
//!    a circle half hidden by a stripe, say).
//! 2. Cut circles: a lattice site next to the grid whose circle touches the image
//!    border has no measurable centre, but its visible part may still tell a marker: its
//!    pixel count and centroid are compared with the visible parts of both ellipses the
//!    neighbouring circles predict there (clipped to the image). It counts as a marker
//!    only when the two predictions differ by at least 30 % in area and the marker's
//!    fits; it then constrains the labelling but is not measured.
//! 3. Placements: every rotation of the board's lattice (mirror images rejected: with
//!    `u` right and `v` down, the image direction of increasing column crossed with that
//!    of increasing row must be positive, since board z points away from the camera)
//!    and every translation that puts all nodes on board points, with every `Marker`
//!    node on a marker and every `Ordinary` node on an ordinary circle.
//! 4. One placement: the labelling. Several, all images of one under the board's own
//!    symmetries ([`Board::symmetries`]): the labelling of the first, with the others as
//!    alternatives for the calibration to decide from the robot poses. Several otherwise
//!    (a part of a board without markers, whose place on the board is unknown): an
//!    error saying so. None: an error saying what was found.

use super::blobs::Blob;
use super::lattice::{marker_area_ratio, predict_any, Coord, CoordMap, Grid};
use crate::error::{Error, Result};
use crate::model::board::{Board, Symmetry};
use crate::vision::affine::AffineFit;

/// What a node shows.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum State {
    Marker,
    Ordinary,
    Unknown,
}

/// The labelling: `(blob, row, col)` of every node, and the alternatives.
pub(crate) struct Labels {
    pub nodes: Vec<(usize, usize, usize)>,
    pub alternatives: Vec<Symmetry>,
    /// Markers seen (measured blobs and cut ones).
    pub markers_seen: usize,
}

/// Log-area residuals of the nodes against a smooth model of the ordinary circles'
/// log-area over the lattice: a quadratic in the lattice coordinates (a plane for
/// small grids, a constant for tiny ones), fitted with the markers excluded
/// iteratively (residuals beyond half the marker log-ratio `lr`).
fn area_residuals(coords: &[Coord], at: &CoordMap<usize>, blobs: &[Blob], lr: f64) -> Vec<f64> {
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

/// Node states from their areas (step 1).
fn node_states(at: &CoordMap<usize>, blobs: &[Blob], board: &Board) -> CoordMap<State> {
    let ratio = marker_area_ratio(board);
    if board.markers.is_empty() {
        return at.keys().map(|&c| (c, State::Ordinary)).collect();
    }
    let lr = ratio.ln();
    let mut coords: Vec<Coord> = at.keys().copied().collect();
    coords.sort_unstable();
    let res = area_residuals(&coords, at, blobs, lr);
    coords
        .iter()
        .zip(&res)
        .map(|(&c, &r)| {
            let x = r / lr;
            let s = if x > 0.7 {
                State::Marker
            } else if x < 0.3 {
                State::Ordinary
            } else {
                State::Unknown
            };
            (c, s)
        })
        .collect()
}

/// Pixel count, visible count and visible centroid of the ellipse `d^T S^-1 d <= 4`
/// (a filled ellipse of covariance `S`) centred at `p`, within a `w x h` image.
fn clipped_ellipse(p: [f64; 2], s: [f64; 3], w: usize, h: usize) -> Option<(f64, f64, [f64; 2])> {
    let det = s[0] * s[1] - s[2] * s[2];
    if det.is_nan() || det <= 0.0 {
        return None;
    }
    let (ia, ib, ic) = (s[1] / det, s[0] / det, -s[2] / det);
    let (hx, hy) = (2.0 * s[0].sqrt(), 2.0 * s[1].sqrt());
    let (x0, x1) = ((p[0] - hx).floor() as i64, (p[0] + hx).ceil() as i64);
    let (y0, y1) = ((p[1] - hy).floor() as i64, (p[1] + hy).ceil() as i64);
    if (x1 - x0) * (y1 - y0) > 4_000_000 {
        return None;
    }
    let (mut total, mut vis, mut sx, mut sy) = (0.0, 0.0, 0.0, 0.0);
    for y in y0..=y1 {
        for x in x0..=x1 {
            let (dx, dy) = (x as f64 - p[0], y as f64 - p[1]);
            if ia * dx * dx + 2.0 * ic * dx * dy + ib * dy * dy <= 4.0 {
                total += 1.0;
                if x >= 0 && y >= 0 && (x as usize) < w && (y as usize) < h {
                    vis += 1.0;
                    sx += x as f64;
                    sy += y as f64;
                }
            }
        }
    }
    (vis > 0.0).then(|| (total, vis, [sx / vis, sy / vis]))
}

/// Cut circles at lattice sites next to the grid (step 2): site -> state.
fn cut_states(
    grid: &Grid,
    states: &CoordMap<State>,
    blobs: &[Blob],
    cut: &[Blob],
    board: &Board,
    (w, h): (usize, usize),
) -> CoordMap<State> {
    let mut out = CoordMap::default();
    let ratio = marker_area_ratio(board);
    if board.markers.is_empty() || cut.is_empty() {
        return out;
    }
    let at = &grid.at;
    let mut sites: Vec<Coord> = at
        .keys()
        .flat_map(|&(i, j)| [(i + 1, j), (i - 1, j), (i, j + 1), (i, j - 1)])
        .filter(|t| !at.contains_key(t))
        .collect();
    sites.sort_unstable();
    sites.dedup();
    for t in sites {
        let Some((p, pitch, _)) = predict_any(at, blobs, t) else {
            continue;
        };
        // the nearest ordinary node gives the local circle shape and area
        let Some(nb) = (1..=3).find_map(|r: i32| {
            let mut best: Option<(i32, usize)> = None;
            for di in -r..=r {
                for dj in -r..=r {
                    let c = (t.0 + di, t.1 + dj);
                    if let (Some(&b), Some(State::Ordinary)) = (at.get(&c), states.get(&c)) {
                        let d = di * di + dj * dj;
                        if best.is_none_or(|(bd, _)| d < bd) {
                            best = Some((d, b));
                        }
                    }
                }
            }
            best.map(|(_, b)| b)
        }) else {
            continue;
        };
        let nb = &blobs[nb];
        let rad_m = (ratio.max(1.0) * nb.area / std::f64::consts::PI).sqrt() * 1.3 + 2.0;
        let near_border = p[0] < rad_m
            || p[1] < rad_m
            || p[0] > w as f64 - 1.0 - rad_m
            || p[1] > h as f64 - 1.0 - rad_m;
        if !near_border {
            continue;
        }
        let Some(c) = cut
            .iter()
            .filter(|c| (c.cx - p[0]).hypot(c.cy - p[1]) < 0.6 * pitch)
            .min_by(|a, b| {
                let da = (a.cx - p[0]).hypot(a.cy - p[1]);
                let db = (b.cx - p[0]).hypot(b.cy - p[1]);
                da.total_cmp(&db)
            })
        else {
            continue;
        };
        let model = |scale: f64| {
            let s = [nb.sxx * scale, nb.syy * scale, nb.sxy * scale];
            clipped_ellipse(p, s, w, h)
                .map(|(total, vis, cen)| (nb.area * scale * vis / total, cen))
        };
        let (Some((e_c, _)), Some((e_m, cen_m))) = (model(1.0), model(ratio)) else {
            continue;
        };
        let lr = (e_m / e_c).ln();
        if lr.is_nan() || lr.abs() < 1.3f64.ln() || c.area <= 0.0 {
            continue;
        }
        let x = (c.area / e_c).ln() / lr;
        let tol = |e: f64| 0.25 * (e / std::f64::consts::PI).sqrt() + 1.0;
        let close = |cen: [f64; 2], e: f64| (c.cx - cen[0]).hypot(c.cy - cen[1]) <= tol(e);
        // Only a cut MARKER is kept as evidence: a cut ordinary circle adds little to the
        // measured nodes, and a dark patch at the border that happens to look like one
        // (the table beyond the plate's corner) must not push the grid off the board.
        if (0.7..1.5).contains(&x) && close(cen_m, e_m) {
            out.insert(t, State::Marker);
        }
    }
    out
}

/// Errors when the grid ends inside the image on a side where the board (as rig.json
/// describes it) goes on: board points of the next line beyond the grid, along the
/// grid's own extent (the points adjacent to it), predicted (homography of the nodes)
/// whole inside the image (two of them, or the one there is), without a circle. The
/// printed pattern is then smaller than rig.json says (or that line is hidden); a
/// partial view cut by the image border is not affected (the grid grows into every
/// circle of the next line that is inside the image). Neither the whole line nor all of
/// the adjacent points need be inside: a board declared far larger than the print (20 x
/// 20, 1000 x 1000 for an 8 x 11) has most of its next line outside the image, and the
/// print near the image border was taken for a partial view.
fn check_not_smaller(
    grid: &Grid,
    blobs: &[Blob],
    board: &Board,
    m0: &[[i64; 2]; 2],
    t0: (i64, i64),
    (w, h): (usize, usize),
    describe: &dyn Fn(&str) -> String,
) -> Result<()> {
    let mut lat = Vec::with_capacity(grid.at.len());
    let mut img = Vec::with_capacity(grid.at.len());
    let (mut lo, mut hi) = ((i64::MAX, i64::MAX), (i64::MIN, i64::MIN));
    for (&c, &b) in &grid.at {
        let (i, j) = Grid::board_coords(grid.kind, c);
        let l = place(m0, t0, (i as i64, j as i64));
        lo = (lo.0.min(l.0), lo.1.min(l.1));
        hi = (hi.0.max(l.0), hi.1.max(l.1));
        lat.push(nalgebra::Vector2::new(l.0 as f64, l.1 as f64));
        img.push(nalgebra::Vector2::new(blobs[b].cx, blobs[b].cy));
    }
    let Ok(hm) = crate::numerics::homography::dlt(&lat, &img) else {
        return Ok(());
    };
    let apply = crate::numerics::homography::apply;
    // the largest circle diameter in lattice units
    let rad_units = (board.circle_diameter_mm.max(if board.markers.is_empty() {
        0.0
    } else {
        board.marker_diameter_mm
    })) / board.lattice_unit_mm();
    // the board's points on lattice line `axis = v`
    let line = |axis: usize, v: i64| -> Vec<(i64, i64)> {
        board
            .indices()
            .map(|(r, c)| board.lattice(r, c))
            .filter(|l| (if axis == 0 { l.0 } else { l.1 }) == v)
            .collect()
    };
    // the nearest line beyond the grid that holds board points (asymmetric grids hold
    // points on every other line of a given parity)
    let beyond = |axis: usize, from: i64, step: i64| -> Option<(i64, Vec<(i64, i64)>)> {
        (1..=2)
            .map(|k| from + k * step)
            .map(|v| (v, line(axis, v)))
            .find(|(_, pts)| !pts.is_empty())
    };
    for (axis, edge, step, name) in [
        (0, lo.0, -1, "column"),
        (0, hi.0, 1, "column"),
        (1, lo.1, -1, "row"),
        (1, hi.1, 1, "row"),
    ] {
        let Some((_, pts)) = beyond(axis, edge, step) else {
            continue;
        };
        // the points beside the grid: within its extent along the line
        let (a, b) = if axis == 0 {
            (lo.1, hi.1)
        } else {
            (lo.0, hi.0)
        };
        let pts: Vec<(i64, i64)> = pts
            .into_iter()
            .filter(|l| (a..=b).contains(if axis == 0 { &l.1 } else { &l.0 }))
            .collect();
        if pts.is_empty() {
            continue;
        }
        // a lattice step in px near the line, for the margin
        let inside = pts.iter().filter(|&&(i, j)| {
            let p = nalgebra::Vector2::new(i as f64, j as f64);
            let (Some(q), Some(qx), Some(qy)) = (
                apply(&hm, &p),
                apply(&hm, &(p + nalgebra::Vector2::new(1.0, 0.0))),
                apply(&hm, &(p + nalgebra::Vector2::new(0.0, 1.0))),
            ) else {
                return false;
            };
            // the circle there, whole, with a few pixels of blur around it
            let step = (qx - q).norm().max((qy - q).norm());
            let m = 0.5 * rad_units * step + 3.0;
            q.x >= m && q.y >= m && q.x <= w as f64 - 1.0 - m && q.y <= h as f64 - 1.0 - m
        });
        // Two circles of the next line whole inside the image and not found: the board
        // ends there (one alone could be a circle missed). A line cut by the image border
        // has none inside: the grid would have grown into those.
        let inside = inside.count();
        if inside >= pts.len().min(2) {
            let (ext_i, ext_j) = (hi.0 - lo.0 + 1, hi.1 - lo.1 + 1);
            return Err(Error::Detection(describe(&format!(
                "the grid ends inside the image where the board goes on: no circle on the next \
                 {name} beyond it, though {inside} of its {} circles beside the grid lie whole \
                 inside the image; the grid found spans {ext_j} x {ext_i} lattice steps, the {} \
                 x {} board of rig.json more (rows and cols in rig.json larger than the printed \
                 pattern, or that {name} hidden)",
                pts.len(),
                board.rows,
                board.cols
            ))));
        }
    }
    Ok(())
}

/// The 8 signed permutations of the lattice: `(row0, row1)` of the matrix.
const LATTICE_MAPS: [[[i64; 2]; 2]; 8] = [
    [[1, 0], [0, 1]],
    [[0, -1], [1, 0]],
    [[-1, 0], [0, -1]],
    [[0, 1], [-1, 0]],
    [[1, 0], [0, -1]],
    [[-1, 0], [0, 1]],
    [[0, 1], [1, 0]],
    [[0, -1], [-1, 0]],
];

type Placement = ([[i64; 2]; 2], (i64, i64));

fn place(m: &[[i64; 2]; 2], t: (i64, i64), c: (i64, i64)) -> (i64, i64) {
    (
        m[0][0] * c.0 + m[0][1] * c.1 + t.0,
        m[1][0] * c.0 + m[1][1] * c.1 + t.1,
    )
}

/// Labels the grid (module docs).
pub(crate) fn label(
    grid: &Grid,
    blobs: &[Blob],
    cut: &[Blob],
    board: &Board,
    size: (usize, usize),
    found: &dyn Fn() -> String,
) -> Result<Labels> {
    let ratio = marker_area_ratio(board);
    if !board.markers.is_empty() && ratio.max(1.0 / ratio) < 1.3 {
        return Err(Error::InvalidInput(format!(
            "the board's markers cannot be told from its circles: marker / circle diameter {} / {} \
             mm (markers must be at least 14 % larger or smaller than the circles)",
            board.marker_diameter_mm, board.circle_diameter_mm
        )));
    }
    let at = &grid.at;
    let states = node_states(at, blobs, board);
    let cuts = cut_states(grid, &states, blobs, cut, board, size);
    // every constrained site in board-lattice coordinates, with its state
    let mut sites: Vec<((i64, i64), State)> = states
        .iter()
        .chain(cuts.iter())
        .map(|(&c, &s)| {
            let (i, j) = Grid::board_coords(grid.kind, c);
            ((i as i64, j as i64), s)
        })
        .collect();
    sites.sort_unstable_by_key(|&(c, _)| c);
    let markers_seen = sites.iter().filter(|s| s.1 == State::Marker).count();
    let describe = |what: &str| {
        format!(
            "{what}: {}; grid of {} circles ({} grown, {} inconsistent), {markers_seen} markers seen \
             (board: {} markers)",
            found(),
            at.len(),
            grid.grown,
            grid.outliers,
            board.markers.len()
        )
    };
    let Some(det_a) = handedness(grid, blobs) else {
        return Err(Error::Detection(describe("degenerate grid")));
    };
    let (placements, mirrored) = placements(&sites, board, det_a);
    let Some(&(m0, t0)) = placements.first() else {
        return Err(Error::Detection(describe(&no_placement(board, mirrored))));
    };
    let alternatives = alternatives(&placements, &sites, board, markers_seen)
        .map_err(|why| Error::Detection(describe(&why)))?;
    check_not_smaller(grid, blobs, board, &m0, t0, size, &describe)?;
    let mut nodes: Vec<(usize, usize, usize)> = at
        .iter()
        .filter_map(|(&c, &b)| {
            let (i, j) = Grid::board_coords(grid.kind, c);
            let (i, j) = place(&m0, t0, (i as i64, j as i64));
            board.from_lattice(i, j).map(|(r, cc)| (b, r, cc))
        })
        .collect();
    nodes.sort_by_key(|&(_, r, c)| (r, c));
    Ok(Labels {
        nodes,
        alternatives,
        markers_seen,
    })
}

/// The determinant of `A` in the affine fit `image = A (i, j) + b` over the measured
/// nodes (its sign is the grid's handedness in the image); `None` for a degenerate grid.
fn handedness(grid: &Grid, blobs: &[Blob]) -> Option<f64> {
    let mut fit = AffineFit::new();
    for (&c, &b) in &grid.at {
        let (i, j) = Grid::board_coords(grid.kind, c);
        fit.add((i as f64, j as f64), (blobs[b].cx, blobs[b].cy));
    }
    let (ax, ay) = fit.solve()?;
    Some(ax[0] * ay[1] - ax[1] * ay[0])
}

/// Every placement of the sites on the board with each site's state matched and the
/// handedness `det_a` of the image kept, in the order of [`LATTICE_MAPS`]; and the
/// number of placements that fit only as a mirror image.
fn placements(sites: &[((i64, i64), State)], board: &Board, det_a: f64) -> (Vec<Placement>, usize) {
    let (lo, hi) = {
        let (mut lo, mut hi) = ((i64::MAX, i64::MAX), (i64::MIN, i64::MIN));
        for (r, c) in board.indices() {
            let (i, j) = board.lattice(r, c);
            lo = (lo.0.min(i), lo.1.min(j));
            hi = (hi.0.max(i), hi.1.max(j));
        }
        (lo, hi)
    };
    let mut placements: Vec<Placement> = Vec::new();
    let mut mirrored = 0;
    for m in &LATTICE_MAPS {
        let det_m = (m[0][0] * m[1][1] - m[0][1] * m[1][0]) as f64;
        let mapped: Vec<(i64, i64)> = sites.iter().map(|&(c, _)| place(m, (0, 0), c)).collect();
        let (mut mlo, mut mhi) = ((i64::MAX, i64::MAX), (i64::MIN, i64::MIN));
        for &(i, j) in &mapped {
            mlo = (mlo.0.min(i), mlo.1.min(j));
            mhi = (mhi.0.max(i), mhi.1.max(j));
        }
        let range = (
            (lo.0 - mlo.0)..=(hi.0 - mhi.0),
            (lo.1 - mlo.1)..=(hi.1 - mhi.1),
        );
        let mut fits_here = 0;
        for (ti, tj) in translations(&mapped, sites, board, range) {
            if fits(&mapped, sites, board, (ti, tj)) {
                fits_here += 1;
                // image directions of increasing board i and j: A M^-1; its
                // determinant has the sign of det(A) det(M)
                if det_a * det_m > 0.0 {
                    placements.push((*m, (ti, tj)));
                }
            }
        }
        if det_a * det_m <= 0.0 {
            mirrored += fits_here;
        }
    }
    (placements, mirrored)
}

/// Whether the sites, mapped to `mapped` and moved by `(ti, tj)`, all land on board
/// points of their state.
fn fits(
    mapped: &[(i64, i64)],
    sites: &[((i64, i64), State)],
    board: &Board,
    (ti, tj): (i64, i64),
) -> bool {
    mapped.iter().zip(sites).all(
        |(&(i, j), &(_, s))| match board.from_lattice(i + ti, j + tj) {
            None => false,
            Some((r, c)) => match s {
                State::Marker => board.is_marker(r, c),
                State::Ordinary => !board.is_marker(r, c),
                State::Unknown => true,
            },
        },
    )
}

/// The translations to try, ascending: every one in `range` (which keeps the mapped
/// sites' bounding box on the board's); with a marker among the sites only those that put
/// it on one of the board's markers (the others cannot fit), so that a large board
/// (rig.json declaring 1000 x 1000 circles, say) costs its markers, not its area.
fn translations(
    mapped: &[(i64, i64)],
    sites: &[((i64, i64), State)],
    board: &Board,
    (ri, rj): (std::ops::RangeInclusive<i64>, std::ops::RangeInclusive<i64>),
) -> Vec<(i64, i64)> {
    let Some(k) = sites.iter().position(|s| s.1 == State::Marker) else {
        return ri
            .flat_map(|ti| rj.clone().map(move |tj| (ti, tj)))
            .collect();
    };
    let mut out: Vec<(i64, i64)> = board
        .markers
        .iter()
        .map(|m| {
            let (i, j) = board.lattice(m[0], m[1]);
            (i - mapped[k].0, j - mapped[k].1)
        })
        .filter(|(ti, tj)| ri.contains(ti) && rj.contains(tj))
        .collect();
    out.sort_unstable();
    out.dedup();
    out
}

/// Why no placement fits (`mirrored` placements fit as a mirror image).
fn no_placement(board: &Board, mirrored: usize) -> String {
    if mirrored > 0 {
        format!(
            "the grid matches the board only as a mirror image ({mirrored} mirrored placements): \
             the board is seen from behind or the image is mirrored"
        )
    } else if board.markers.is_empty() {
        "the grid does not fit on the board".to_string()
    } else {
        "markers not matched: no placement of the grid on the board puts the markers seen \
         on the board's markers"
            .to_string()
    }
}

/// The board symmetries relating every placement after the first to the first; `Err`
/// with the reason when one is not a symmetry image (the labelling is ambiguous).
fn alternatives(
    placements: &[Placement],
    sites: &[((i64, i64), State)],
    board: &Board,
    markers_seen: usize,
) -> std::result::Result<Vec<Symmetry>, String> {
    let (m0, t0) = placements[0];
    let syms = board.symmetries();
    let mut alternatives: Vec<Symmetry> = Vec::new();
    for &(m, t) in &placements[1..] {
        let sym = syms.iter().find(|s| {
            sites
                .iter()
                .all(|&(c, _)| s.apply_lattice(place(&m0, t0, c)) == place(&m, t, c))
        });
        match sym {
            Some(s) => {
                if !alternatives.contains(s) {
                    alternatives.push(*s);
                }
            }
            None if board.markers.is_empty() || markers_seen == 0 => {
                return Err(format!(
                    "cannot tell where on the board this part of it lies: the grid fits the \
                     board in {} places (only part of the board is in the image, and {})",
                    placements.len(),
                    if board.markers.is_empty() {
                        "the board has no markers"
                    } else {
                        "no marker is seen"
                    }
                ));
            }
            None => {
                return Err(format!(
                    "ambiguous grid: {} placements fit the markers seen",
                    placements.len()
                ));
            }
        }
    }
    Ok(alternatives)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The translations tried with a marker among the sites keep every one that fits
    /// (those of the whole range that fit), in the same order.
    #[test]
    fn marker_anchored_translations_keep_every_fit() {
        let board = Board::circles(40, 50, 5.0, 2.5, 3.5).unwrap();
        // a 4 x 5 patch at the marker corner and one away from it, seen in every map
        for (r0, c0) in [(0usize, 0usize), (7, 9)] {
            let sites: Vec<((i64, i64), State)> = (r0..r0 + 4)
                .flat_map(|r| (c0..c0 + 5).map(move |c| (r, c)))
                .map(|(r, c)| {
                    let s = if board.is_marker(r, c) {
                        State::Marker
                    } else {
                        State::Ordinary
                    };
                    (board.lattice(r, c), s)
                })
                .collect();
            for m in &LATTICE_MAPS {
                let mapped: Vec<(i64, i64)> =
                    sites.iter().map(|&(c, _)| place(m, (0, 0), c)).collect();
                let range = (-200..=200, -200..=200);
                let all: Vec<(i64, i64)> = range
                    .0
                    .clone()
                    .flat_map(|ti| range.1.clone().map(move |tj| (ti, tj)))
                    .filter(|&t| fits(&mapped, &sites, &board, t))
                    .collect();
                let tried: Vec<(i64, i64)> = translations(&mapped, &sites, &board, range)
                    .into_iter()
                    .filter(|&t| fits(&mapped, &sites, &board, t))
                    .collect();
                assert_eq!(tried, all, "patch at {r0}, {c0}, map {m:?}");
                if r0 == 0 && *m == LATTICE_MAPS[0] {
                    assert_eq!(all, vec![(0, 0)]);
                }
            }
        }
    }
}
