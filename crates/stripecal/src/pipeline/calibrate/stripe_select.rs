//! Step 3: the stripe points on the plane of the board, by consistency with it.
//!
//! The laser is often on the white sheet or plate AROUND the printed pattern, mostly
//! beside it, and crosses the sheet's edge onto whatever lies behind (a table a few mm
//! lower, another object). A stripe point anywhere on the plane of its view's board is a
//! point of the laser plane once intersected with that plane; a point on another surface
//! is not (its ray meets the board plane at a different depth from where the laser lit
//! it). So the points are selected by their consistency with ONE laser plane over all
//! views, not by where they fall on the board: points on the plane of the board are used
//! wherever they lie; the others are rejected and counted per view.
//!
//! ## Method
//!
//! 1. Every stripe pixel is intersected with its view's board plane (`T_cam_board` from
//!    the camera calibration; [`backproject_to_board`]): a 3D point in the camera frame.
//!    A pixel whose ray does not meet the board plane in front of the camera is rejected.
//! 2. Residual of a point against a candidate laser plane: its distance, within its
//!    board plane, from the line where the laser plane meets that board plane (the
//!    point's distance from the plane divided by the sine of the angle between the two
//!    planes, that sine floored at 0.1), converted to pixels at the point's depth
//!    (`* f / z`, `f` the mean focal length): about the image distance of the point from
//!    its predicted stripe, where the extraction noise lives, alike for every view.
//! 3. Noise scale from the data before any plane is known: within each view, the
//!    points sorted along their line, the distance of each point from the chord of its
//!    neighbours [`CHORD_STEP`] places away on either side (in the board plane, in pixels
//!    as above); `sigma_0 = median / (0.6745 * sqrt(1.5))` over all views (a depth step
//!    spoils only the few chords that straddle it).
//! 4. Consensus (MSAC): [`RANSAC_ITERATIONS`] candidate planes, each through two points
//!    of one view and one point of another (deterministic random draws), scored by
//!    `sum min(r^2, t_0^2)` over the points (at most [`MAX_SCORED_POINTS`], evenly
//!    spread over the views), `t_0 = max(K sigma_0, floor)`.
//! 5. Refinement: the total-least-squares plane of the points within the threshold,
//!    `sigma = 1.4826 * median r` of those points, threshold `t = max(K sigma, floor)`,
//!    repeated until the set of points within `t` no longer changes (at most
//!    [`MAX_REFINEMENTS`] rounds).
//! 6. A view keeps its points with `r <= t`; the others are rejected and counted.
//!
//! ## Thresholds
//!
//! `K` = [`THRESHOLD_SIGMAS`] (4 robust sigmas: a Gaussian point is rejected with odds
//! below 1e-4); the floor [`FLOOR_PX`] (0.1 px) keeps clean, nearly noise-free data
//! (a twin's exact points) from being cut at round-off. Nothing else is fixed: the
//! scale comes from the data.
//!
//! ## Requirements
//!
//! What the laser plane needs: points on the board plane in at least 2 views (each with
//! at least [`MIN_POINTS_PER_VIEW`]) whose board planes are not parallel (at least
//! [`MIN_BOARD_ANGLE_DEG`] apart), otherwise [`Error::Degenerate`] saying how many views
//! had stripe points and how many were left. Views without any stripe point are allowed
//! (they serve the camera and hand-eye only); when no view has any, nothing is selected
//! and the caller decides.

use nalgebra::Vector3;

use super::labels::Labelled;
use super::ViewStatus;
use crate::calib::laser_plane::{backproject_to_board, MIN_POINTS_PER_VIEW};
use crate::calib::{kept, ViewObs};
use crate::error::{Error, Result};
use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::numerics::rng::SplitMix64;
use crate::numerics::robust::median;
use crate::numerics::tls;

/// Robust sigmas of the residuals beyond which a point is off the board plane.
pub const THRESHOLD_SIGMAS: f64 = 4.0;
/// The threshold never goes below this, px.
pub const FLOOR_PX: f64 = 0.1;
/// Two views' board planes must be at least this far apart in orientation, degrees.
pub const MIN_BOARD_ANGLE_DEG: f64 = 1.0;
/// Neighbour step of the local noise estimate (chords from `i - k` to `i + k`).
pub const CHORD_STEP: usize = 2;
/// Candidate planes of the consensus.
pub const RANSAC_ITERATIONS: usize = 1500;
/// Points scored per candidate plane (evenly spread over the views).
pub const MAX_SCORED_POINTS: usize = 6000;
/// Rounds of the refinement.
pub const MAX_REFINEMENTS: usize = 20;
/// The least tolerance of a view's offset from the consensus plane, px: a view's board
/// pose comes from the camera stage, off by a pixel or two on a real camera (module
/// docs, step 5).
pub const LOOSE_PX: f64 = 3.0;
/// Sine of the angle between a board and the laser plane is floored at this.
const MIN_SINE: f64 = 0.1;

/// The result of [`select_on_board_plane`].
#[derive(Debug, Clone, PartialEq)]
pub struct StripeSelection {
    /// Per input view, per stripe point: on the board plane (kept).
    pub keep: Vec<Vec<bool>>,
    /// Per input view: points rejected (off the board plane, or whose ray does not meet
    /// it in front of the camera).
    pub off_plane: Vec<usize>,
    /// The consensus laser plane (camera frame) the points were tested against.
    pub plane: Option<Plane>,
    /// Robust sigma of the kept points' residuals, px.
    pub sigma_px: f64,
    /// The threshold applied, px (see the module docs).
    pub threshold_px: f64,
}

impl StripeSelection {
    /// Every point kept, nothing tested (no view has stripe points).
    fn all(views: &[(Iso3, Vec<[f64; 2]>)]) -> Self {
        StripeSelection {
            keep: views.iter().map(|(_, s)| vec![true; s.len()]).collect(),
            off_plane: vec![0; views.len()],
            plane: None,
            sigma_px: 0.0,
            threshold_px: 0.0,
        }
    }
}

/// One back-projected stripe point.
#[derive(Debug, Clone, Copy)]
struct Pt {
    p: Vector3<f64>,
    /// `f / z`: mm in the board plane at this depth to px.
    px_per_mm: f64,
    /// Index of its view among the views with points.
    view: usize,
    /// Index in its view's stripe.
    index: usize,
}

/// The labelled views with the stripe points on their board plane (the rest counted in
/// `status[..].stripe_off_plane`), and their `T_cam_board`.
pub(super) fn select_stripes(
    labelled: &[Labelled],
    camera: &Camera,
    status: &mut [ViewStatus],
) -> Result<(Vec<ViewObs>, Vec<Iso3>)> {
    let views: Vec<(&ViewObs, Iso3)> = labelled
        .iter()
        .filter_map(|l| l.as_ref().ok())
        .map(|(v, cb)| (v, *cb))
        .collect();
    let input: Vec<(Iso3, Vec<[f64; 2]>)> = views
        .iter()
        .map(|(v, cb)| (*cb, v.stripe.clone()))
        .collect();
    let sel = select_on_board_plane(&input, camera)?;
    let mut obs = Vec::with_capacity(views.len());
    let mut poses = Vec::with_capacity(views.len());
    for (((v, cb), keep), off) in views.iter().zip(&sel.keep).zip(&sel.off_plane) {
        let stripe = kept(&v.stripe, keep);
        if let Some(s) = status.iter_mut().find(|s| s.view == v.view) {
            s.stripe_off_plane = *off;
        }
        // The widths follow their points (a shape of another length is dropped).
        let stripe_shape = v
            .stripe_shape
            .as_ref()
            .filter(|sh| sh.width_px.len() == keep.len() && sh.saturated.len() == keep.len())
            .map(|sh| sh.subset(keep));
        obs.push(ViewObs {
            stripe,
            stripe_shape,
            ..(*v).clone()
        });
        poses.push(*cb);
    }
    Ok((obs, poses))
}

/// Selects, per view (`T_cam_board` and stripe points `(u, v)` px), the stripe points
/// on the plane of that view's board, by their consistency with one laser plane over all
/// views (see the module docs).
///
/// Errors: [`Error::InvalidInput`] for a non-finite point or pose;
/// [`Error::Degenerate`] when the points on the board plane do not come from at least 2
/// views with non-parallel board planes (and some view has stripe points at all).
pub fn select_on_board_plane(
    views: &[(Iso3, Vec<[f64; 2]>)],
    camera: &Camera,
) -> Result<StripeSelection> {
    let total: usize = views.iter().map(|(_, s)| s.len()).sum();
    if total == 0 {
        return Ok(StripeSelection::all(views));
    }
    let f = 0.5 * (camera.fu + camera.fv);
    // 1. Back-projection; `vis[k]` = input view of the k-th view with points.
    let mut pts: Vec<Pt> = Vec::with_capacity(total);
    let mut vis: Vec<usize> = Vec::new();
    let mut normals: Vec<Vector3<f64>> = Vec::new();
    for (vi, (cb, uvs)) in views.iter().enumerate() {
        if !cb.to_homogeneous().iter().all(|x| x.is_finite()) {
            return Err(Error::InvalidInput(format!(
                "stripe selection: view {vi}: T_cam_board is not finite"
            )));
        }
        let k = vis.len();
        let before = pts.len();
        for (i, uv) in uvs.iter().enumerate() {
            if !(uv[0].is_finite() && uv[1].is_finite()) {
                return Err(Error::InvalidInput(format!(
                    "stripe selection: view {vi}: stripe point {uv:?} is not finite"
                )));
            }
            if let Ok(p) = backproject_to_board(camera, cb, uv) {
                if p.z > 0.0 {
                    pts.push(Pt {
                        p,
                        px_per_mm: f / p.z,
                        view: k,
                        index: i,
                    });
                }
            }
        }
        if pts.len() > before {
            vis.push(vi);
            normals.push(cb.rotation * Vector3::z());
        }
    }
    let Some(c) = consensus(&pts, &normals, vis.len())? else {
        return Err(not_enough(views, None));
    };
    let (plane, sigma_px, threshold_px) = (c.plane, c.sigma, c.thr);
    // 6. Keep the points on their view's line, of views within the offsets' threshold.
    let mut keep: Vec<Vec<bool>> = views.iter().map(|(_, s)| vec![false; s.len()]).collect();
    let sines = sines(&plane, &normals);
    for q in &pts {
        if c.keeps(q, sines[q.view]) {
            keep[vis[q.view]][q.index] = true;
        }
    }
    let off_plane: Vec<usize> = keep
        .iter()
        .map(|k| k.iter().filter(|x| !**x).count())
        .collect();
    check_views(views, &keep)?;
    Ok(StripeSelection {
        keep,
        off_plane,
        plane: Some(plane),
        sigma_px,
        threshold_px,
    })
}

/// The error when the views on the board plane cannot fix the laser plane;
/// `selected`: the views that kept points and the points rejected, when a consensus
/// was found.
fn not_enough(views: &[(Iso3, Vec<[f64; 2]>)], selected: Option<(usize, usize)>) -> Error {
    let with = views
        .iter()
        .filter(|(_, s)| s.len() >= MIN_POINTS_PER_VIEW)
        .count();
    let kept = match selected {
        Some((usable, rejected)) => format!(
            ", {usable} of them with points on their board plane ({rejected} points off \
             it rejected)"
        ),
        None => String::new(),
    };
    Error::Degenerate(format!(
        "laser plane: needs stripe points on the board plane in at least 2 views whose \
         board planes are not parallel (at least {MIN_BOARD_ANGLE_DEG} deg apart), each \
         with at least {MIN_POINTS_PER_VIEW}: {with} views have stripe points{kept}; add \
         views with the laser on the board at other tilts"
    ))
}

/// Errors unless the kept points come from 2 views with non-parallel board planes.
fn check_views(views: &[(Iso3, Vec<[f64; 2]>)], keep: &[Vec<bool>]) -> Result<()> {
    let used: Vec<Vector3<f64>> = views
        .iter()
        .zip(keep)
        .filter(|(_, k)| k.iter().filter(|x| **x).count() >= MIN_POINTS_PER_VIEW)
        .map(|((cb, _), _)| cb.rotation * Vector3::z())
        .collect();
    let mut widest = 0.0_f64;
    for (i, a) in used.iter().enumerate() {
        for b in &used[i + 1..] {
            widest = widest.max(a.cross(b).norm().min(1.0).asin());
        }
    }
    if used.len() >= 2 && widest.to_degrees() >= MIN_BOARD_ANGLE_DEG {
        return Ok(());
    }
    let rejected = keep.iter().flatten().filter(|x| !**x).count();
    Err(not_enough(views, Some((used.len(), rejected))))
}

/// Sine of the angle between `plane` and each view's board plane (floored).
fn sines(plane: &Plane, normals: &[Vector3<f64>]) -> Vec<f64> {
    normals
        .iter()
        .map(|n| plane.normal.cross(n).norm().max(MIN_SINE))
        .collect()
}

/// A point's residual against `plane`, px (module docs, step 2).
#[inline]
fn residual(plane: &Plane, q: &Pt, sine: f64) -> f64 {
    signed_residual(plane, q, sine).abs()
}

/// [`residual`] with its sign.
#[inline]
fn signed_residual(plane: &Plane, q: &Pt, sine: f64) -> f64 {
    plane.signed_distance(&q.p) / sine * q.px_per_mm
}

/// A view's offset from the consensus plane, px: a line along its stripe, `a + b t`
/// with `t` the point's position along the view's line (mm from the view's centroid):
/// a board pose off by a small rotation tilts the residuals along the line, off by a
/// translation shifts them.
#[derive(Debug, Clone, Copy)]
struct Offset {
    a: f64,
    b: f64,
    centroid: Vector3<f64>,
    dir: Vector3<f64>,
}

impl Offset {
    #[inline]
    fn at(&self, p: &Vector3<f64>) -> f64 {
        self.a + self.b * self.dir.dot(&(p - self.centroid))
    }
}

/// The consensus's verdict: the plane, the points' scatter about their view's offset
/// line and its threshold (px), each view's offset from the plane (`None`: no point of
/// the view near it) and the offsets' threshold (px, at the views' centroids).
struct Consensus {
    plane: Plane,
    sigma: f64,
    thr: f64,
    offsets: Vec<Option<Offset>>,
    offset_thr: f64,
}

impl Consensus {
    /// Whether point `q` is on its view's board plane.
    fn keeps(&self, q: &Pt, sine: f64) -> bool {
        self.offsets[q.view].is_some_and(|o| {
            o.a.abs() <= self.offset_thr
                && (signed_residual(&self.plane, q, sine) - o.at(&q.p)).abs() <= self.thr
        })
    }
}

/// Each view's offset line from `plane` (see [`Offset`]): a least-squares line through
/// the signed residuals of its points within `window` px of the plane, refitted twice
/// to those within 3 robust sigmas of it (a depth step's points drop out); `None` for
/// a view with fewer than 3 points there.
fn view_offsets(
    pts: &[Pt],
    plane: &Plane,
    sines: &[f64],
    nviews: usize,
    window: f64,
) -> Vec<Option<Offset>> {
    let mut per: Vec<Vec<(Vector3<f64>, f64)>> = vec![Vec::new(); nviews];
    for q in pts {
        let r = signed_residual(plane, q, sines[q.view]);
        if r.abs() <= window {
            per[q.view].push((q.p, r));
        }
    }
    per.into_iter().map(|v| offset_line(&v)).collect()
}

/// [`view_offsets`] of one view's `(point, residual)`.
fn offset_line(v: &[(Vector3<f64>, f64)]) -> Option<Offset> {
    if v.len() < 3 {
        return None;
    }
    let pa = tls::principal_axes(v.iter().map(|(p, _)| p)).ok()?;
    let dir = pa.axes.column(0).into_owned();
    let c = pa.centroid;
    let mut o = Offset {
        a: 0.0,
        b: 0.0,
        centroid: c,
        dir,
    };
    let mut tol = f64::INFINITY;
    for _ in 0..3 {
        let (mut n, mut st, mut sr, mut stt, mut str_) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (p, r) in v {
            if (r - o.at(p)).abs() > tol {
                continue;
            }
            let t = dir.dot(&(p - c));
            n += 1.0;
            st += t;
            sr += r;
            stt += t * t;
            str_ += t * r;
        }
        if n < 3.0 {
            break;
        }
        let det = n * stt - st * st;
        let (a, b) = if det > 1e-12 * n * stt.max(1e-300) {
            ((sr * stt - st * str_) / det, (n * str_ - st * sr) / det)
        } else {
            (sr / n, 0.0)
        };
        o.a = a;
        o.b = b;
        let mut dev: Vec<f64> = v.iter().map(|(p, r)| (r - o.at(p)).abs()).collect();
        tol = 3.0 * 1.4826 * median(&mut dev).unwrap_or(0.0) + 1e-12;
    }
    Some(o)
}

/// The noise scale (px) from the chords within each view (module docs, step 3); `None`
/// when no view has enough points.
fn local_sigma(pts: &[Pt], nviews: usize) -> Option<f64> {
    let k = CHORD_STEP;
    let mut d: Vec<f64> = Vec::new();
    for v in 0..nviews {
        let vp: Vec<&Pt> = pts.iter().filter(|q| q.view == v).collect();
        if vp.len() < 2 * k + 1 {
            continue;
        }
        let Ok(pa) = tls::principal_axes(vp.iter().map(|q| &q.p)) else {
            continue;
        };
        let dir = pa.axes.column(0).into_owned();
        let mut sorted = vp;
        sorted.sort_by(|a, b| dir.dot(&a.p).total_cmp(&dir.dot(&b.p)));
        for i in k..sorted.len() - k {
            let (a, q, b) = (sorted[i - k], sorted[i], sorted[i + k]);
            let chord = b.p - a.p;
            let len = chord.norm();
            if len > 0.0 {
                d.push((q.p - a.p).cross(&chord).norm() / len * q.px_per_mm);
            }
        }
    }
    median(&mut d).map(|m| m / (0.6745 * 1.5f64.sqrt()))
}

/// The consensus plane, the robust sigma and the threshold (px) and the views' offsets
/// (module docs, steps 4 and 5); `None` when fewer than 2 views have points.
fn consensus(pts: &[Pt], normals: &[Vector3<f64>], nviews: usize) -> Result<Option<Consensus>> {
    let per_view: Vec<Vec<usize>> = (0..nviews)
        .map(|v| (0..pts.len()).filter(|&i| pts[i].view == v).collect())
        .collect();
    let pairs: Vec<usize> = (0..nviews).filter(|&v| per_view[v].len() >= 2).collect();
    if nviews < 2 || pairs.is_empty() {
        return Ok(None);
    }
    let sigma0 = local_sigma(pts, nviews).unwrap_or(0.0);
    let t0 = (THRESHOLD_SIGMAS * sigma0).max(FLOOR_PX);
    // Candidates are scored with the views' own offsets in mind: a view's board pose is
    // as good as the camera stage's fit, which on a real camera is off by a pixel or
    // two, not by the stripe's noise.
    let t_score = t0.max(LOOSE_PX);
    // Points scored: every view's points evenly thinned to the budget.
    let stride = pts.len().div_ceil(MAX_SCORED_POINTS).max(1);
    let scored: Vec<&Pt> = pts.iter().step_by(stride).collect();
    let mut depths: Vec<f64> = pts.iter().map(|q| q.p.norm()).collect();
    let scale = median(&mut depths).unwrap_or(1.0);
    let mut rng = SplitMix64(0x5717_e5e1);
    let mut best: Option<(f64, Plane)> = None;
    for _ in 0..RANSAC_ITERATIONS {
        let a = pairs[rng.below(pairs.len())];
        let mut b = rng.below(nviews - 1);
        if b >= a {
            b += 1;
        }
        let va = &per_view[a];
        let (i, j) = (rng.below(va.len()), rng.below(va.len()));
        if i == j {
            continue;
        }
        let (p1, p2) = (pts[va[i]].p, pts[va[j]].p);
        let p3 = pts[per_view[b][rng.below(per_view[b].len())]].p;
        let n = (p2 - p1).cross(&(p3 - p1));
        if n.norm() <= 1e-9 * scale * scale {
            continue;
        }
        let Ok(plane) = Plane::new(n, n.dot(&p1)) else {
            continue;
        };
        if plane.d < 1e-3 * scale {
            continue; // through the camera centre: not a laser plane seen from it
        }
        let s = sines(&plane, normals);
        let cost: f64 = scored
            .iter()
            .map(|q| {
                residual(&plane, q, s[q.view])
                    .powi(2)
                    .min(t_score * t_score)
            })
            .sum();
        if best.is_none_or(|(c, _)| cost < c) {
            best = Some((cost, plane));
        }
    }
    let Some((_, plane)) = best else {
        return Ok(None);
    };
    Ok(Some(refine(
        pts, normals, nviews, plane, sigma0, t0, t_score,
    )))
}

/// Step 5 of the module docs: each view's offset from the plane, its points' scatter
/// about it, the plane refitted to the points kept, until the points kept stay the same.
fn refine(
    pts: &[Pt],
    normals: &[Vector3<f64>],
    nviews: usize,
    mut plane: Plane,
    sigma0: f64,
    t0: f64,
    window: f64,
) -> Consensus {
    let mut c = Consensus {
        plane,
        sigma: sigma0,
        thr: t0,
        offsets: vec![None; nviews],
        offset_thr: window,
    };
    let mut inliers: Vec<bool> = Vec::new();
    for _ in 0..MAX_REFINEMENTS {
        let s = sines(&plane, normals);
        c.plane = plane;
        c.offsets = view_offsets(pts, &plane, &s, nviews, c.offset_thr.max(c.thr));
        // the offsets' own scatter sets their threshold (a view far off the others is
        // a view whose board pose, or line, is not the others')
        let mut dev: Vec<f64> = c.offsets.iter().flatten().map(|o| o.a.abs()).collect();
        let spread = 1.4826 * median(&mut dev).unwrap_or(0.0);
        c.offset_thr = (THRESHOLD_SIGMAS * spread).max(c.thr).max(LOOSE_PX);
        let now: Vec<bool> = pts.iter().map(|q| c.keeps(q, s[q.view])).collect();
        if now == inliers {
            break;
        }
        inliers = now;
        let used: Vec<&Vector3<f64>> = pts
            .iter()
            .zip(&inliers)
            .filter(|(_, k)| **k)
            .map(|(q, _)| &q.p)
            .collect();
        let mut in_views = pts
            .iter()
            .zip(&inliers)
            .filter(|(_, k)| **k)
            .map(|(q, _)| q.view);
        let first = in_views.next();
        if used.len() < 3 || in_views.all(|v| Some(v) == first) {
            break; // one view's line: the candidate plane stays
        }
        let Ok(pa) = tls::principal_axes(used.iter().copied()) else {
            break;
        };
        let n = pa.axes.column(2).into_owned();
        let Ok(p) = Plane::new(n, n.dot(&pa.centroid)) else {
            break;
        };
        plane = p;
        // the points' scatter about their own view's offset
        let s = sines(&plane, normals);
        let offsets = view_offsets(pts, &plane, &s, nviews, c.offset_thr.max(c.thr));
        let mut r: Vec<f64> = pts
            .iter()
            .zip(&inliers)
            .filter(|(_, k)| **k)
            .filter_map(|(q, _)| {
                offsets[q.view].map(|o| (signed_residual(&plane, q, s[q.view]) - o.at(&q.p)).abs())
            })
            .collect();
        c.sigma = 1.4826 * median(&mut r).unwrap_or(0.0);
        c.thr = (THRESHOLD_SIGMAS * c.sigma).max(FLOOR_PX);
    }
    c
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::laser_plane::stripe_line_in_view;
    use crate::model::camera::DistortionModel;
    use crate::model::geometry::iso_from_rotvec;

    fn camera() -> Camera {
        Camera::new(
            768,
            576,
            crate::model::camera::Intrinsics {
                fu: 1270.0,
                fv: 1320.0,
                u0: 384.0,
                v0: 288.0,
            },
            DistortionModel::Radial1,
            [0.05, 0.0, 0.0, 0.0, 0.0],
        )
        .unwrap()
    }

    /// Six views of a board with the laser on it; in every view a stretch of the stripe
    /// lies on a surface 3 mm behind the board (a parallel plane: a depth step), and a
    /// few points anywhere in the image (reflections). Points on the board get 0.05 px of
    /// noise.
    #[test]
    fn keeps_the_board_plane_and_rejects_a_step_and_outliers() {
        let cam = camera();
        let laser = Plane::new(Vector3::new(0.629, -0.0492, 0.7759), 79.87).unwrap();
        let mut rng = SplitMix64(3);
        let mut views = Vec::new();
        let mut truth_off = Vec::new();
        for k in 0..6 {
            let a = 0.25 * (k as f64 - 2.5);
            let cb = iso_from_rotvec(
                &Vector3::new(3.1 + 0.1 * a, 0.3 * a, 0.2 * a.sin()),
                &Vector3::new(-20.0 + 3.0 * a, -15.0, 105.0 + 4.0 * a),
            );
            let mut uvs = Vec::new();
            let mut off = 0usize;
            // on the board
            let l = stripe_line_in_view(&laser, &cb, &cam).unwrap();
            for s in -60..=20 {
                let p = l.point_cam + l.direction_cam * (0.4 * s as f64);
                let uv = cam.project(&p).unwrap();
                if cam.contains(&uv, 0.0) {
                    uvs.push([uv.x + 0.05 * rng.normal(), uv.y + 0.05 * rng.normal()]);
                }
            }
            // beyond the sheet: the laser on a parallel plane 3 mm farther
            let behind = iso_from_rotvec(&Vector3::zeros(), &Vector3::new(0.0, 0.0, 3.0));
            let lt = stripe_line_in_view(&laser, &(cb * behind), &cam).unwrap();
            for s in 21..=50 {
                let p = lt.point_cam + lt.direction_cam * (0.4 * s as f64);
                let uv = cam.project(&p).unwrap();
                if cam.contains(&uv, 0.0) {
                    uvs.push([uv.x, uv.y]);
                    off += 1;
                }
            }
            // random outliers
            for _ in 0..5 {
                uvs.push([768.0 * rng.uniform(), 576.0 * rng.uniform()]);
                off += 1;
            }
            views.push((cb, uvs));
            truth_off.push(off);
        }
        let sel = select_on_board_plane(&views, &cam).unwrap();
        let plane = sel.plane.unwrap();
        assert!(plane.normal.angle(&laser.normal) < 1e-3, "{plane:?}");
        assert!((plane.d - laser.d).abs() < 0.05, "{plane:?}");
        assert!(
            sel.sigma_px > 0.02 && sel.sigma_px < 0.1,
            "{}",
            sel.sigma_px
        );
        assert_eq!(
            sel.threshold_px,
            (THRESHOLD_SIGMAS * sel.sigma_px).max(FLOOR_PX)
        );
        for (k, (_, uvs)) in views.iter().enumerate() {
            let n_on = uvs.len() - truth_off[k];
            // every board point kept, every step point rejected; a random outlier may
            // happen to fall on the stripe line
            let kept_on = sel.keep[k][..n_on].iter().filter(|x| **x).count();
            assert_eq!(kept_on, n_on, "view {k}");
            let step = n_on..uvs.len() - 5;
            assert!(sel.keep[k][step].iter().all(|x| !*x), "view {k}");
            assert!(sel.off_plane[k] >= truth_off[k] - 1, "view {k}");
        }
    }

    #[test]
    fn exact_points_are_all_kept_and_one_view_is_refused() {
        let cam = camera();
        let laser = Plane::new(Vector3::new(0.6, 0.05, 0.8), 80.0).unwrap();
        let poses = [
            iso_from_rotvec(
                &Vector3::new(3.4, 0.1, 0.0),
                &Vector3::new(-20.0, -15.0, 100.0),
            ),
            iso_from_rotvec(
                &Vector3::new(2.9, 0.4, 0.2),
                &Vector3::new(-20.0, -15.0, 110.0),
            ),
        ];
        let views: Vec<(Iso3, Vec<[f64; 2]>)> = poses
            .iter()
            .map(|cb| {
                let l = stripe_line_in_view(&laser, cb, &cam).unwrap();
                let pts = (-10..=10)
                    .map(|s| {
                        let uv = cam
                            .project(&(l.point_cam + l.direction_cam * s as f64))
                            .unwrap();
                        [uv.x, uv.y]
                    })
                    .collect();
                (*cb, pts)
            })
            .collect();
        let sel = select_on_board_plane(&views, &cam).unwrap();
        assert_eq!(sel.off_plane, [0, 0]);
        assert_eq!(sel.threshold_px, FLOOR_PX);
        // one view only (the other without a laser image): a typed error
        let one = vec![views[0].clone(), (views[1].0, vec![])];
        let e = select_on_board_plane(&one, &cam).unwrap_err();
        assert!(matches!(e, Error::Degenerate(_)), "{e}");
        assert!(e.to_string().contains("at least 2 views"), "{e}");
        // two views with the same board orientation: parallel board planes
        let shifted = poses[0] * iso_from_rotvec(&Vector3::zeros(), &Vector3::new(0.0, 0.0, -8.0));
        let l = stripe_line_in_view(&laser, &shifted, &cam).unwrap();
        let pts = (-10..=10)
            .map(|s| {
                let uv = cam
                    .project(&(l.point_cam + l.direction_cam * s as f64))
                    .unwrap();
                [uv.x, uv.y]
            })
            .collect();
        let par = vec![views[0].clone(), (shifted, pts)];
        let e = select_on_board_plane(&par, &cam).unwrap_err();
        assert!(e.to_string().contains("not parallel"), "{e}");
        // no stripe at all: nothing to select, no error
        let none = vec![(poses[0], vec![]), (poses[1], vec![])];
        let sel = select_on_board_plane(&none, &cam).unwrap();
        assert_eq!(sel.off_plane, [0, 0]);
        assert!(sel.plane.is_none());
    }
}
