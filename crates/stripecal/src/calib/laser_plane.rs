//! The laser plane from stripe points on the board (the two-stage way: camera and board
//! poses known), and the predicted stripe line of a view for residuals.
//!
//! ## Method
//!
//! Each stripe pixel is unprojected to its viewing ray and intersected with its view's
//! board plane (board z = 0, expressed in the camera frame with `T_cam_board`): 3D points
//! on the laser plane in the camera frame (mm). The plane is the total-least-squares
//! fit (centroid + right singular vector of the smallest singular value of the centred
//! points, faer SVD), then points farther than `max(3.5 sigma, 1e-6 mm)` (sigma = 1.4826
//! MAD of the distances) are trimmed and the plane refitted, up to 3 rounds, never more
//! than 10 % of the points in all. The result follows the spec: `n . p = d`, `|n| = 1`,
//! `d > 0`.
//!
//! ## Degenerate input
//!
//! The points must span a plane, not only a line. A view gives a line; distinct views
//! give distinct lines only if their board planes differ. Parallel stripe lines at
//! different positions do fix the plane (it rests on their separation); the degenerate
//! case is that all points lie on (or near) one 3D line: the fit refuses with
//! [`Error::Degenerate`] when the RMS extent of the points across their common line is
//! below `1e-3` of their extent along it, or below 10 times the fit's RMS residual.
//! Fewer than 2 views with at least 2 usable stripe points, or fewer than 4 points, are
//! refused too. Nearly parallel stripe lines (largest angle between two views' lines
//! below 5 deg) give a warning.

use nalgebra::{Matrix3, Point3, Vector2, Vector3};

use crate::error::{Error, Result};
use crate::model::camera::Camera;
use crate::model::geometry::{Iso3, Plane};
use crate::numerics::tls;

/// Refuse when the points' RMS extent across their common line is below this fraction of
/// their extent along it.
pub const MIN_RELATIVE_SPAN: f64 = 1e-3;
/// Refuse when the points' RMS extent across their common line is below this multiple of
/// the fit's RMS residual.
pub const MIN_SPAN_OVER_RMS: f64 = 10.0;
/// Warn when the largest angle between two views' stripe lines is below this (degrees).
pub const WEAK_LINE_ANGLE_DEG: f64 = 5.0;
/// Fewest stripe points a view needs to count as a stripe view.
pub const MIN_POINTS_PER_VIEW: usize = 2;

/// One-sigma uncertainties of the fitted plane (from the residual scatter; the errors of
/// the board poses are not included).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlaneSigma {
    /// One-sigma of each component of the unit normal.
    pub normal: Vector3<f64>,
    /// One-sigma of `d`, mm.
    pub d_mm: f64,
}

/// The result of [`fit_laser_plane`].
#[derive(Debug, Clone, PartialEq)]
pub struct LaserPlaneFit {
    /// The plane in the camera frame, `n . p = d`, `|n| = 1`, `d > 0`.
    pub plane: Plane,
    /// RMS distance of the inlier points from the plane, mm.
    pub rms_mm: f64,
    /// Per input view: RMS distance of its inlier points from the plane, mm (`None` for
    /// views without usable stripe points).
    pub per_view_rms_mm: Vec<Option<f64>>,
    /// Inlier points used by the final fit.
    pub n_points: usize,
    /// Points trimmed as outliers.
    pub n_outliers: usize,
    /// One-sigma uncertainties.
    pub sigma: PlaneSigma,
    /// Largest angle between the stripe lines of two views, degrees (0 .. 90).
    pub max_line_angle_deg: f64,
    /// RMS extent of the points across their common line direction, mm.
    pub span_across_mm: f64,
    /// Human-readable warnings.
    pub warnings: Vec<String>,
}

/// The board plane (board z = 0) in the camera frame.
pub fn board_plane_in_cam(cam_board: &Iso3) -> Plane {
    let n = cam_board.rotation * Vector3::z();
    Plane {
        normal: n,
        d: n.dot(&cam_board.translation.vector),
    }
}

/// The 3D point (camera frame, mm) where the viewing ray of pixel `uv` meets the board of
/// `cam_board` (`T_cam_board`).
///
/// Errors: [`Error::Degenerate`] when the ray is parallel to the board or meets it behind
/// the camera; errors of [`Camera::unproject`].
pub fn backproject_to_board(
    camera: &Camera,
    cam_board: &Iso3,
    uv: &[f64; 2],
) -> Result<Vector3<f64>> {
    if !(uv[0].is_finite() && uv[1].is_finite()) {
        return Err(Error::InvalidInput(format!(
            "stripe point {uv:?} is not finite"
        )));
    }
    let ray = camera.unproject(&Vector2::new(uv[0], uv[1]))?;
    let plane = board_plane_in_cam(cam_board);
    match plane.intersect_ray(&Vector3::zeros(), &ray) {
        Some(s) if s > 0.0 && s.is_finite() => Ok(ray * s),
        Some(_) => Err(Error::Degenerate(format!(
            "the ray of pixel ({:.2}, {:.2}) meets the board behind the camera",
            uv[0], uv[1]
        ))),
        None => Err(Error::Degenerate(format!(
            "the ray of pixel ({:.2}, {:.2}) is parallel to the board",
            uv[0], uv[1]
        ))),
    }
}

/// Centroid, principal axes (columns, by decreasing singular value) and singular values
/// of points: [`crate::numerics::tls`].
fn principal_axes(pts: &[Vector3<f64>]) -> Result<(Vector3<f64>, Matrix3<f64>, [f64; 3])> {
    let pa =
        tls::principal_axes(pts).map_err(|e| Error::Degenerate(format!("laser plane: {e}")))?;
    Ok((pa.centroid, pa.axes, pa.singular))
}

/// Fits the laser plane to stripe points on the board.
///
/// `views`: per view, `T_cam_board` and the stripe points `(u, v)` px on the board.
/// Views without points are allowed (they report `None` in `per_view_rms_mm`); stripe
/// points whose ray cannot be intersected with the board are skipped with a warning.
///
/// Errors: [`Error::InvalidInput`] for non-finite input, [`Error::Degenerate`] (with the
/// figure) when the points do not determine a plane (see the module docs).
pub fn fit_laser_plane(views: &[(Iso3, Vec<[f64; 2]>)], camera: &Camera) -> Result<LaserPlaneFit> {
    camera.validate()?;
    let mut warnings = Vec::new();
    let BoardPoints {
        pts,
        view_of,
        line_dirs,
    } = board_points(views, camera, &mut warnings)?;
    let max_line_angle_deg = max_line_angle_deg(&line_dirs);
    let (fit, inlier, n_out) = trimmed_fit(&pts)?;
    let (c, axes, s) = fit;
    let n_used = pts.len() - n_out;
    let e1 = axes.column(0).into_owned();
    let e2 = axes.column(1).into_owned();
    let normal = axes.column(2).into_owned();
    let plane = Plane::new(normal, normal.dot(&c))?;
    let rms_mm = s[2] / (n_used as f64).sqrt();
    let along = s[0] / (n_used as f64).sqrt();
    let across = s[1] / (n_used as f64).sqrt();
    if across < MIN_RELATIVE_SPAN * along || across < MIN_SPAN_OVER_RMS * rms_mm {
        return Err(Error::Degenerate(format!(
            "laser plane: the stripe points of all views lie on nearly one 3D line: they \
             span {across:.4} mm (RMS) across it against {along:.2} mm along it and a fit \
             residual of {rms_mm:.4} mm RMS (largest angle between two views' stripe lines \
             {max_line_angle_deg:.2} deg); use board poses at different tilts or stand-offs"
        )));
    }
    if max_line_angle_deg < WEAK_LINE_ANGLE_DEG {
        warnings.push(format!(
            "stripe lines nearly parallel (largest angle {max_line_angle_deg:.2} deg): the \
             plane's tilt rests on their separation ({across:.2} mm RMS)"
        ));
    }
    if n_out > 0 {
        warnings.push(format!("{n_out} stripe points trimmed as outliers"));
    }
    let per_view_rms_mm = per_view_rms(&plane, &pts, &view_of, &inlier, views.len());
    for (vi, r) in per_view_rms_mm.iter().enumerate() {
        if let Some(r) = r {
            if *r > 5.0 * rms_mm && *r > 1e-6 {
                warnings.push(format!(
                    "view {vi}: stripe RMS {r:.4} mm, more than 5 times the overall {rms_mm:.4} mm"
                ));
            }
        }
    }

    // Uncertainty: tilts about the in-plane axes and the offset at the centroid.
    let dof = (n_used as f64 - 3.0).max(1.0);
    let var = s[2] * s[2] / dof;
    let (l1, l2) = ((s[0] * s[0]).max(1e-300), (s[1] * s[1]).max(1e-300));
    let cov_n = e1 * e1.transpose() * (var / l1) + e2 * e2.transpose() * (var / l2);
    let var_d = var / n_used as f64 + var * e1.dot(&c).powi(2) / l1 + var * e2.dot(&c).powi(2) / l2;
    let sigma = PlaneSigma {
        normal: Vector3::new(
            cov_n[(0, 0)].sqrt(),
            cov_n[(1, 1)].sqrt(),
            cov_n[(2, 2)].sqrt(),
        ),
        d_mm: var_d.sqrt(),
    };
    Ok(LaserPlaneFit {
        plane,
        rms_mm,
        per_view_rms_mm,
        n_points: n_used,
        n_outliers: n_out,
        sigma,
        max_line_angle_deg,
        span_across_mm: across,
        warnings,
    })
}

/// Centroid, principal axes (columns, by decreasing spread) and singular values.
type AxesFit = (Vector3<f64>, Matrix3<f64>, [f64; 3]);

/// The stripe points of every usable view on the board, camera frame.
struct BoardPoints {
    pts: Vec<Vector3<f64>>,
    /// View index of each point.
    view_of: Vec<usize>,
    /// Direction of each view's stripe line (views with a non-degenerate spread).
    line_dirs: Vec<Vector3<f64>>,
}

/// Back-projects every view's stripe points onto its board (views with fewer than
/// [`MIN_POINTS_PER_VIEW`] points left out); errors on non-finite input or fewer than
/// 2 views or 4 points.
fn board_points(
    views: &[(Iso3, Vec<[f64; 2]>)],
    camera: &Camera,
    warnings: &mut Vec<String>,
) -> Result<BoardPoints> {
    let mut pts: Vec<Vector3<f64>> = Vec::new();
    let mut view_of: Vec<usize> = Vec::new();
    let mut line_dirs: Vec<Vector3<f64>> = Vec::new();
    let mut stripe_views = 0usize;
    for (vi, (cam_board, uvs)) in views.iter().enumerate() {
        let t = cam_board;
        if !(t.translation.vector.iter().all(|v| v.is_finite())
            && t.rotation.coords.iter().all(|v| v.is_finite()))
        {
            return Err(Error::InvalidInput(format!(
                "laser plane: view {vi}: T_cam_board is not finite"
            )));
        }
        let mut vp = Vec::with_capacity(uvs.len());
        let mut skipped = 0usize;
        for uv in uvs {
            if !(uv[0].is_finite() && uv[1].is_finite()) {
                return Err(Error::InvalidInput(format!(
                    "laser plane: view {vi}: stripe point {uv:?} is not finite"
                )));
            }
            match backproject_to_board(camera, cam_board, uv) {
                Ok(p) => vp.push(p),
                Err(_) => skipped += 1,
            }
        }
        if skipped > 0 {
            warnings.push(format!(
                "view {vi}: {skipped} stripe points could not be intersected with the board"
            ));
        }
        if vp.len() >= MIN_POINTS_PER_VIEW {
            stripe_views += 1;
            let (_, axes, s) = principal_axes(&vp)?;
            if s[0] > 0.0 {
                line_dirs.push(axes.column(0).into_owned());
            }
            view_of.extend(std::iter::repeat_n(vi, vp.len()));
            pts.extend(vp);
        }
    }
    if stripe_views < 2 {
        return Err(Error::Degenerate(format!(
            "laser plane: needs stripe points in at least 2 views (each with at least \
             {MIN_POINTS_PER_VIEW}), got {stripe_views}"
        )));
    }
    if pts.len() < 4 {
        return Err(Error::Degenerate(format!(
            "laser plane: needs at least 4 stripe points, got {}",
            pts.len()
        )));
    }
    Ok(BoardPoints {
        pts,
        view_of,
        line_dirs,
    })
}

/// Largest angle between two views' lines (0..90 deg).
fn max_line_angle_deg(line_dirs: &[Vector3<f64>]) -> f64 {
    let mut max_line_angle = 0.0_f64;
    for (i, a) in line_dirs.iter().enumerate() {
        for b in &line_dirs[i + 1..] {
            let c = a.dot(b).abs().min(1.0);
            max_line_angle = max_line_angle.max(c.acos());
        }
    }
    max_line_angle.to_degrees()
}

/// The plane fit (principal axes) with trimming: up to 3 rounds drop the points beyond
/// `3.5 * 1.4826 MAD` of the plane distances, at most a tenth of the points in all.
/// Returns the fit, the inlier flags and the number trimmed.
fn trimmed_fit(pts: &[Vector3<f64>]) -> Result<(AxesFit, Vec<bool>, usize)> {
    let max_trim = pts.len() / 10;
    let mut inlier = vec![true; pts.len()];
    let mut n_out = 0usize;
    let mut fit;
    let mut round = 0;
    loop {
        let used: Vec<Vector3<f64>> = pts
            .iter()
            .zip(&inlier)
            .filter(|(_, &k)| k)
            .map(|(p, _)| *p)
            .collect();
        fit = principal_axes(&used)?;
        if round == 3 {
            break;
        }
        round += 1;
        let (c, axes, _) = fit;
        let nrm = axes.column(2).into_owned();
        let mut dist: Vec<f64> = pts
            .iter()
            .zip(&inlier)
            .filter(|(_, &k)| k)
            .map(|(p, _)| nrm.dot(&(p - c)).abs())
            .collect();
        dist.sort_by(|a, b| a.total_cmp(b));
        let mad = dist[dist.len() / 2];
        let thr = (3.5 * 1.4826 * mad).max(1e-6);
        let mut cand: Vec<(f64, usize)> = pts
            .iter()
            .enumerate()
            .filter(|(i, _)| inlier[*i])
            .map(|(i, p)| (nrm.dot(&(p - c)).abs(), i))
            .filter(|(d, _)| *d > thr)
            .collect();
        if cand.is_empty() || n_out >= max_trim {
            break;
        }
        cand.sort_by(|a, b| b.0.total_cmp(&a.0));
        for &(_, i) in cand.iter().take(max_trim - n_out) {
            inlier[i] = false;
            n_out += 1;
        }
    }
    Ok((fit, inlier, n_out))
}

/// RMS distance from `plane` of each view's inliers (`None`: no inlier).
fn per_view_rms(
    plane: &Plane,
    pts: &[Vector3<f64>],
    view_of: &[usize],
    inlier: &[bool],
    nviews: usize,
) -> Vec<Option<f64>> {
    let mut acc = vec![(0.0_f64, 0usize); nviews];
    for ((p, &vi), &k) in pts.iter().zip(view_of).zip(inlier) {
        if k {
            let d = plane.signed_distance(p);
            acc[vi].0 += d * d;
            acc[vi].1 += 1;
        }
    }
    acc.iter()
        .map(|&(s2, k)| (k > 0).then(|| (s2 / k as f64).sqrt()))
        .collect()
}

/// The predicted stripe of a view: the line where the laser plane meets the board.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StripeLine {
    /// The point of the line closest to the camera centre (camera frame, mm).
    pub point_cam: Vector3<f64>,
    /// Unit direction (camera frame).
    pub direction_cam: Vector3<f64>,
    /// The image of the line in normalised (undistorted) coordinates: `l . (xn, yn, 1) = 0`
    /// with `l0^2 + l1^2 = 1`, so `l . (xn, yn, 1)` is a signed distance in normalised units.
    pub normalized: Vector3<f64>,
    /// The line on the board (board frame, z = 0): a point (mm) ...
    pub point_board: Vector2<f64>,
    /// ... and a unit direction.
    pub direction_board: Vector2<f64>,
}

impl StripeLine {
    /// Signed distance (px) of an image point from the (distorted) image of the line:
    /// the point of the 3D line whose projection is nearest to `uv` is found by a few
    /// Gauss-Newton steps along the line; the sign is that of the cross product of the
    /// line's image direction with the offset.
    pub fn signed_distance_px(&self, camera: &Camera, uv: &[f64; 2]) -> Result<f64> {
        let target = Vector2::new(uv[0], uv[1]);
        // Start: the foot point in normalised coordinates, lifted onto the 3D line.
        let ray = camera.unproject(&target)?;
        // Closest point on the 3D line to the ray (both through known points).
        let (p0, d) = (self.point_cam, self.direction_cam);
        let r = ray.normalize();
        let b = d.dot(&r);
        let den = 1.0 - b * b;
        let mut s = if den > 1e-12 {
            (b * r.dot(&p0) - d.dot(&p0)) / den
        } else {
            0.0
        };
        let mut last = (Vector2::zeros(), Vector2::zeros());
        for _ in 0..8 {
            let p = p0 + d * s;
            let (uvp, jp, _) = camera.project_with_jacobians(&p)?;
            let res = uvp - target;
            let j = jp * d;
            last = (res, j);
            let jj = j.norm_squared();
            if jj < 1e-300 {
                break;
            }
            let step = -j.dot(&res) / jj;
            s += step;
            if (step * j.norm()).abs() < 1e-10 {
                let p = p0 + d * s;
                let (uvp, jp, _) = camera.project_with_jacobians(&p)?;
                last = (uvp - target, jp * d);
                break;
            }
        }
        let (res, j) = last;
        let dist = res.norm();
        let cross = j.x * res.y - j.y * res.x;
        Ok(if cross < 0.0 { -dist } else { dist })
    }
}

/// The predicted stripe line of a view with `T_cam_board`, given the laser plane (camera
/// frame).
///
/// Errors: [`Error::Degenerate`] when the laser plane is parallel to the board or the
/// line passes through the camera centre (its image is a point).
pub fn stripe_line_in_view(
    plane: &Plane,
    cam_board: &Iso3,
    _camera: &Camera,
) -> Result<StripeLine> {
    let board = board_plane_in_cam(cam_board);
    let (n1, d1) = (plane.normal, plane.d);
    let (n2, d2) = (board.normal, board.d);
    let dir = n1.cross(&n2);
    let s = dir.norm();
    if s.is_nan() || s <= 1e-9 {
        return Err(Error::Degenerate(format!(
            "the laser plane is parallel to the board (angle {:.2e} deg)",
            s.asin().to_degrees()
        )));
    }
    let direction_cam = dir / s;
    // Point of both planes closest to the origin.
    let point_cam = (n2.cross(&dir) * d1 + dir.cross(&n1) * d2) / (s * s);
    // Image line: plane through the origin containing the 3D line: normal = p x dir.
    let m = point_cam.cross(&direction_cam);
    let h = (m.x * m.x + m.y * m.y).sqrt();
    if h.is_nan() || h <= 1e-12 || point_cam.norm() < 1e-9 {
        return Err(Error::Degenerate(
            "the stripe line passes through the camera centre or along the optical axis".into(),
        ));
    }
    let normalized = m / h;
    let board_cam = cam_board.inverse();
    let pb = board_cam * Point3::from(point_cam);
    let db = board_cam.rotation * direction_cam;
    let db2 = Vector2::new(db.x, db.y);
    let dn = db2.norm();
    Ok(StripeLine {
        point_cam,
        direction_cam,
        normalized,
        point_board: Vector2::new(pb.x, pb.y),
        direction_board: if dn > 0.0 { db2 / dn } else { db2 },
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::camera::DistortionModel;
    use crate::model::geometry::iso_from_rotvec;

    #[test]
    fn two_point_views_are_enough_and_exact() {
        let cam = Camera::new(
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
        .unwrap();
        let laser = Plane::new(Vector3::new(0.629, -0.0492, 0.7759), 79.87).unwrap();
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
                let pts = [-5.0, 5.0]
                    .iter()
                    .map(|s| {
                        let uv = cam.project(&(l.point_cam + l.direction_cam * *s)).unwrap();
                        [uv.x, uv.y]
                    })
                    .collect();
                (*cb, pts)
            })
            .collect();
        let fit = fit_laser_plane(&views, &cam).unwrap();
        assert!((fit.plane.normal - laser.normal).norm() < 1e-9);
        assert!((fit.plane.d - laser.d).abs() < 1e-9);
    }
}
