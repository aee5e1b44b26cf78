//! Phase 4 of a plan: a point on the laser plane at the stand-off, triangulated from its
//! pixel, with the parameters' covariance propagated through the triangulation (the
//! implicit-function Jacobian of `project(P) = uv, n . P = d`) into the camera, base and
//! board frames.

use nalgebra::{Matrix3, Vector2, Vector3};

use super::{Nominal, PointSigma};
use crate::calib::joint::camera_name;
use crate::error::{Error, Result};
use crate::model::camera::Camera;
use crate::model::geometry::{iso_from_rotvec, iso_to_rotvec, Iso3, Plane};
use crate::model::NamedCovariance;

/// The point where the pixel `uv`'s ray meets the plane `n . P = d` (`n` need not be
/// unit length: the derivatives w.r.t. its components are taken that way).
pub(crate) fn triangulate_raw(
    cam: &Camera,
    n: &Vector3<f64>,
    d: f64,
    uv: &Vector2<f64>,
) -> Result<Vector3<f64>> {
    let ray = cam.unproject(uv)?;
    let den = n.dot(&ray);
    if den.abs() < 1e-12 {
        return Err(Error::Degenerate(
            "the ray is parallel to the laser plane".into(),
        ));
    }
    Ok(ray * (d / den))
}

/// The point triangulated from `uv` on `plane` (camera frame) and in the base frame
/// through `a x` (`T_base_hand T_hand_cam`), with the derivatives of both w.r.t. the
/// numbers of calibration.json they depend on: `(name, d P_cam, d P_base)`. Camera and
/// plane: the implicit-function Jacobian of `project(P) = uv, n . P = d`; `X`'s rotation
/// vector: central differences (step 1e-6 rad); its translation: `R_A`.
#[allow(clippy::type_complexity)]
pub(crate) fn point_jacobian(
    cam: &Camera,
    plane: &Plane,
    x: &Iso3,
    a: &Iso3,
    uv: &Vector2<f64>,
) -> Result<(
    Vector3<f64>,
    Vector3<f64>,
    Vec<(String, Vector3<f64>, Vector3<f64>)>,
)> {
    let p = triangulate_raw(cam, &plane.normal, plane.d, uv)?;
    let (_, jp, jc) = cam.project_with_jacobians(&p)?;
    let m = Matrix3::from_rows(&[
        jp.row(0).into_owned(),
        jp.row(1).into_owned(),
        plane.normal.transpose(),
    ]);
    let mi = m
        .try_inverse()
        .ok_or_else(|| Error::Degenerate("the viewing ray is tangent to the laser plane".into()))?;
    let ra = a.rotation.to_rotation_matrix().into_inner();
    let rx = x.rotation.to_rotation_matrix().into_inner();
    let to_base = ra * rx;
    let mut out = Vec::new();
    for i in 0..9 {
        let dp = mi * Vector3::new(-jc[(0, i)], -jc[(1, i)], 0.0);
        out.push((camera_name(i), dp, to_base * dp));
    }
    for k in 0..3 {
        let dp = mi * Vector3::new(0.0, 0.0, -p[k]);
        out.push((format!("laser_plane.normal[{k}]"), dp, to_base * dp));
    }
    let dp = mi * Vector3::new(0.0, 0.0, 1.0);
    out.push(("laser_plane.d_mm".into(), dp, to_base * dp));
    let (rv, tv) = iso_to_rotvec(x);
    let h = 1e-6;
    for k in 0..3 {
        let mut e = Vector3::zeros();
        e[k] = h;
        let xp = iso_from_rotvec(&(rv + e), &tv);
        let xm = iso_from_rotvec(&(rv - e), &tv);
        let db = ra * (xp.rotation * p - xm.rotation * p) / (2.0 * h);
        out.push((
            format!("hand_cam.rotation_vector[{k}]"),
            Vector3::zeros(),
            db,
        ));
    }
    for k in 0..3 {
        out.push((
            format!("hand_cam.translation_mm[{k}]"),
            Vector3::zeros(),
            ra.column(k).into_owned(),
        ));
    }
    let pb = a * (x * nalgebra::Point3::from(p));
    Ok((p, pb.coords, out))
}

/// The covariance `G C G^T` of a 3-vector whose derivatives w.r.t. named numbers are
/// `grads` (numbers not in `cov` are held: no contribution).
fn propagate(cov: &NamedCovariance, grads: &[(String, Vector3<f64>)]) -> Matrix3<f64> {
    let idx: Vec<(usize, Vector3<f64>)> = grads
        .iter()
        .filter_map(|(n, g)| cov.index(n).map(|i| (i, *g)))
        .collect();
    let mut c = Matrix3::zeros();
    for (i, gi) in &idx {
        for (j, gj) in &idx {
            c += gi * gj.transpose() * cov.matrix[(*i, *j)];
        }
    }
    c
}

/// The per-axis one-sigmas of a 3-vector covariance and the one-sigma of its norm
/// (the trace's root).
fn sigmas(c: &Matrix3<f64>) -> ([f64; 3], f64) {
    (
        [0, 1, 2].map(|k| c[(k, k)].max(0.0).sqrt()),
        c.trace().max(0.0).sqrt(),
    )
}

/// The base-frame point's derivatives per DH correction, from its flange-frame position.
pub(super) type DhGradients<'a> = dyn Fn(&Vector3<f64>) -> Vec<(String, Vector3<f64>)> + 'a;

/// The point on the laser plane at depth `s` nearest the optical axis, and its sigma
/// (camera frame; base and board frames through `base`'s flange pose).
pub(super) fn point_sigma(
    nominal: &Nominal<'_>,
    pl: &Plane,
    base: Option<(usize, Iso3)>,
    s: f64,
    cov: &NamedCovariance,
    dh: &DhGradients<'_>,
) -> Result<PointSigma> {
    let (cam, x, z) = (nominal.camera, &nominal.hand_cam, &nominal.base_board);
    let n = pl.normal;
    let h2 = n.x * n.x + n.y * n.y;
    if !(s.is_finite() && s > 0.0) {
        return Err(Error::InvalidInput(format!(
            "the stand-off must be positive, got {s}"
        )));
    }
    if h2 < 1e-12 {
        return Err(Error::Degenerate(
            "the laser plane is perpendicular to the optical axis".into(),
        ));
    }
    let k = (pl.d - n.z * s) / h2;
    let p0 = Vector3::new(n.x * k, n.y * k, s);
    let uv = cam.project(&p0)?;
    let a = base.map_or(Iso3::identity(), |b| b.1);
    let (p, pb, grads) = point_jacobian(cam, pl, x, &a, &uv)?;
    let gc: Vec<(String, Vector3<f64>)> = grads.iter().map(|(n, c, _)| (n.clone(), *c)).collect();
    let (sc, nc) = sigmas(&propagate(cov, &gc));
    let (base_mm, sigma_base_mm, sigma_base_norm_mm, gz) = if base.is_some() {
        let mut gb: Vec<(String, Vector3<f64>)> =
            grads.iter().map(|(n, _, b)| (n.clone(), *b)).collect();
        gb.extend(dh(&(x * nalgebra::Point3::from(p)).coords));
        let (sb, nb) = sigmas(&propagate(cov, &gb));
        (
            Some([pb.x, pb.y, pb.z]),
            Some(sb),
            Some(nb),
            Some(board_frame(z, &pb, &gb)),
        )
    } else {
        (None, None, None, None)
    };
    let (board_mm, sigma_board_mm, sigma_board_norm_mm) = match gz {
        Some((pz, g)) => {
            let (s, n) = sigmas(&propagate(cov, &g));
            (Some([pz.x, pz.y, pz.z]), Some(s), Some(n))
        }
        None => (None, None, None),
    };
    Ok(PointSigma {
        standoff_mm: s,
        pixel: [uv.x, uv.y],
        camera_mm: [p.x, p.y, p.z],
        sigma_camera_mm: sc,
        sigma_camera_norm_mm: nc,
        base_pose: base.map(|b| b.0),
        base_mm,
        sigma_base_mm,
        sigma_base_norm_mm,
        board_mm,
        sigma_board_mm,
        sigma_board_norm_mm,
    })
}

/// The board-frame point `Z^-1 p_b` and its derivatives: the base point's rotated by
/// `R_Z^T`, and `Z`'s own (its rotation vector by central differences, its translation
/// `-R_Z^T e_k`).
fn board_frame(
    z: &Iso3,
    pb: &Vector3<f64>,
    gb: &[(String, Vector3<f64>)],
) -> (Vector3<f64>, Vec<(String, Vector3<f64>)>) {
    let rzt = z.rotation.to_rotation_matrix().into_inner().transpose();
    let at = |zz: &Iso3| (zz.inverse() * nalgebra::Point3::from(*pb)).coords;
    let mut g: Vec<(String, Vector3<f64>)> = gb.iter().map(|(n, v)| (n.clone(), rzt * v)).collect();
    let (rv, tv) = iso_to_rotvec(z);
    let h = 1e-6;
    for k in 0..3 {
        let mut e = Vector3::zeros();
        e[k] = h;
        let d = (at(&iso_from_rotvec(&(rv + e), &tv)) - at(&iso_from_rotvec(&(rv - e), &tv)))
            / (2.0 * h);
        g.push((format!("base_board.rotation_vector[{k}]"), d));
    }
    for k in 0..3 {
        g.push((
            format!("base_board.translation_mm[{k}]"),
            -rzt.column(k).into_owned(),
        ));
    }
    (at(z), g)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::camera::DistortionModel;

    /// The triangulation's Jacobian against central differences of the whole map
    /// (unprojection with undistortion, intersection, `A X`), every named number.
    #[test]
    fn point_jacobian_matches_central_differences() {
        let cam = Camera::new(
            1024,
            768,
            crate::model::camera::Intrinsics {
                fu: 1500.0,
                fv: 1490.0,
                u0: 515.0,
                v0: 380.0,
            },
            DistortionModel::OpenCv5,
            [-0.2, 0.1, 1e-3, -1e-3, 0.02],
        )
        .unwrap();
        let plane = Plane::new(Vector3::new(0.6, -0.05, 0.78), 80.0).unwrap();
        let x = iso_from_rotvec(
            &Vector3::new(-0.3, 0.24, 2.9),
            &Vector3::new(29.0, 5.0, 62.0),
        );
        let a = iso_from_rotvec(
            &Vector3::new(0.1, 3.0, 0.2),
            &Vector3::new(480.0, 20.0, 300.0),
        );
        let uv = Vector2::new(640.0, 300.0);
        let (p, pb, grads) = point_jacobian(&cam, &plane, &x, &a, &uv).unwrap();
        // value: the pixel reprojects, the point is on the plane
        assert!((cam.project(&p).unwrap() - uv).norm() < 1e-8);
        assert!(plane.signed_distance(&p).abs() < 1e-9);
        let eval = |name: &str, h: f64| -> (Vector3<f64>, Vector3<f64>) {
            let mut cp = cam.params();
            let (mut n, mut d) = (plane.normal, plane.d);
            let (mut rv, mut tv) = iso_to_rotvec(&x);
            if let Some(i) = (0..9).find(|&i| camera_name(i) == name) {
                cp[i] += h;
            } else if let Some(k) = (0..3).find(|&k| name == format!("laser_plane.normal[{k}]")) {
                n[k] += h;
            } else if name == "laser_plane.d_mm" {
                d += h;
            } else if let Some(k) =
                (0..3).find(|&k| name == format!("hand_cam.rotation_vector[{k}]"))
            {
                rv[k] += h;
            } else if let Some(k) =
                (0..3).find(|&k| name == format!("hand_cam.translation_mm[{k}]"))
            {
                tv[k] += h;
            } else {
                panic!("{name}");
            }
            let c = cam.with_params(&cp);
            let q = triangulate_raw(&c, &n, d, &uv).unwrap();
            let xx = iso_from_rotvec(&rv, &tv);
            // The base point less the nominal one (the same derivative, no cancellation
            // against the flange's metres).
            let rel = (xx * nalgebra::Point3::from(q)) - (x * nalgebra::Point3::from(p));
            (q, a.rotation * rel)
        };
        let mut worst = 0.0f64;
        for (name, gc, gb) in &grads {
            let h = if name.starts_with("camera.distortion") || name.contains("normal") {
                1e-5
            } else if name.contains("rotation_vector") {
                1e-6
            } else {
                1e-3
            };
            let (cp, bp) = eval(name, h);
            let (cm, bm) = eval(name, -h);
            let (fc, fb) = ((cp - cm) / (2.0 * h), (bp - bm) / (2.0 * h));
            let scale = fc.norm().max(fb.norm()).max(1e-3);
            let err = (fc - gc).norm().max((fb - gb).norm()) / scale;
            println!(
                "{name:32} |dP_cam| {:10.4e} |dP_base| {:10.4e} rel. FD diff {err:.1e}",
                gc.norm(),
                gb.norm()
            );
            assert!(err < 1e-5, "{name}: {gc:?} {gb:?} vs {fc:?} {fb:?}");
            worst = worst.max(err);
        }
        assert_eq!(grads.len(), 19);
        assert!(pb.iter().all(|v| v.is_finite()));
        println!("largest relative FD difference {worst:.1e}");
    }
}
