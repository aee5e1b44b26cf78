//! Triangulation: a stripe pixel -> its undistorted viewing ray -> the laser plane ->
//! the robot base frame, with the grazing / behind-the-camera / undistortion drops
//! counted (steps 1-4 and "Dropped points" of the [`crate::reconstruct`] docs).

use nalgebra::{Matrix3, Vector3};

use crate::error::{Error, Result};
#[cfg(test)]
use crate::model::camera::Intrinsics;
use crate::model::camera::{Camera, UndistortTrack};
use crate::model::geometry::{Iso3, Plane};
use crate::model::Calibration;

use super::DEFAULT_MIN_RAY_PLANE_ANGLE_DEG;

/// Why points were dropped.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct DropCounts {
    /// Rays meeting the laser plane below the angle threshold or behind the camera.
    pub grazing: usize,
    /// Pixels where the undistortion failed (outside the distortion's valid zone).
    pub undistort: usize,
    /// Stripe points with a flag in `drop_flags`.
    pub flagged: usize,
}

impl DropCounts {
    /// Adds another count.
    pub fn add(&mut self, o: &DropCounts) {
        self.grazing += o.grazing;
        self.undistort += o.undistort;
        self.flagged += o.flagged;
    }

    /// All dropped points.
    pub fn total(&self) -> usize {
        self.grazing + self.undistort + self.flagged
    }
}

/// Triangulation of stripe pixels with a fixed calibration (camera, laser plane,
/// `T_hand_cam`). Cheap to copy; shares nothing.
#[derive(Debug, Clone)]
pub struct Triangulator {
    camera: Camera,
    /// Laser plane normal and offset (camera frame, mm).
    n: Vector3<f64>,
    d_mm: f64,
    hand_cam: Iso3,
    /// `sin(min angle)`.
    min_sin: f64,
    /// `1 / fu`, `1 / fv`.
    inv_fu: f64,
    inv_fv: f64,
}

impl Triangulator {
    /// A triangulator; checks the camera, the plane (`|n| = 1`, `d > 0`, finite) and the
    /// angle threshold (degrees, in `[0, 90)`).
    pub fn new(
        camera: &Camera,
        laser_plane: &Plane,
        hand_cam: &Iso3,
        min_ray_plane_angle_deg: f64,
    ) -> Result<Triangulator> {
        camera.validate()?;
        let n = laser_plane.normal;
        if !(n.iter().all(|x| x.is_finite())
            && (n.norm() - 1.0).abs() < 1e-6
            && laser_plane.d.is_finite()
            && laser_plane.d > 0.0)
        {
            return Err(Error::InvalidInput(format!(
                "laser plane normal {:?} / d_mm {} must be a unit normal with d > 0",
                n.as_slice(),
                laser_plane.d
            )));
        }
        let a = min_ray_plane_angle_deg;
        if !(a.is_finite() && (0.0..90.0).contains(&a)) {
            return Err(Error::InvalidInput(format!(
                "min_ray_plane_angle_deg = {a} must be in [0, 90)"
            )));
        }
        let t = hand_cam.translation.vector;
        if !(t.iter().all(|x| x.is_finite())
            && hand_cam.rotation.coords.iter().all(|x| x.is_finite()))
        {
            return Err(Error::InvalidInput("hand_cam is not finite".into()));
        }
        Ok(Triangulator {
            camera: camera.clone(),
            n: n / n.norm(),
            d_mm: laser_plane.d,
            hand_cam: *hand_cam,
            min_sin: a.to_radians().sin(),
            inv_fu: 1.0 / camera.fu,
            inv_fv: 1.0 / camera.fv,
        })
    }

    /// From a calibration; an error when it has no laser plane.
    pub fn from_calibration(c: &Calibration, min_ray_plane_angle_deg: f64) -> Result<Self> {
        Self::new(
            &c.camera,
            laser_plane_of(c)?,
            &c.hand_cam,
            min_ray_plane_angle_deg,
        )
    }

    /// `T_hand_cam`.
    pub fn hand_cam(&self) -> &Iso3 {
        &self.hand_cam
    }

    /// The camera.
    pub fn camera(&self) -> &Camera {
        &self.camera
    }

    /// `T_base_cam = T_base_hand * T_hand_cam` as a rotation matrix and translation (mm).
    #[inline]
    fn base_cam(&self, base_hand: &Iso3) -> (Matrix3<f64>, Vector3<f64>) {
        let t = base_hand * self.hand_cam;
        (
            t.rotation.to_rotation_matrix().into_inner(),
            t.translation.vector,
        )
    }

    /// The laser-plane point of one pixel in the camera frame (mm), updating the Newton
    /// start `track` (the previous point's solution; [`Camera::undistort_tracked`]).
    #[inline]
    fn point_cam(
        &self,
        u: f64,
        v: f64,
        track: &mut UndistortTrack,
    ) -> std::result::Result<Vector3<f64>, DropReason> {
        let c = &self.camera;
        let xd = (u - c.u0) * self.inv_fu;
        let yd = (v - c.v0) * self.inv_fv;
        let (xn, yn) = c
            .undistort_tracked(xd, yd, track)
            .ok_or(DropReason::Undistort)?;
        let r = Vector3::new(xn, yn, 1.0);
        let den = self.n.dot(&r);
        // |n . r| / |r| >= sin(angle), and the plane in front (den > 0 since d > 0).
        if !(den > 0.0 && den * den >= self.min_sin * self.min_sin * r.norm_squared()) {
            return Err(DropReason::Grazing);
        }
        Ok(r * (self.d_mm / den))
    }

    /// The laser-plane point of pixel `(u, v)` in the camera frame (mm), or `None` when
    /// it is dropped (grazing ray, plane behind the camera, undistortion failure).
    pub fn point_cam_mm(&self, u: f64, v: f64) -> Option<Vector3<f64>> {
        self.point_cam(u, v, &mut UndistortTrack::new(&self.camera))
            .ok()
    }

    /// Triangulates pixels `uv_px` of one frame taken at `T_base_hand`: the kept points
    /// (base frame, mm) are appended to `out_mm` and their indices into `uv_px` to
    /// `index`. Returns why the others were dropped. Allocates nothing when the vectors
    /// have room. A point that is not finite (a non-finite or huge `T_base_hand`, which
    /// the callers check) is not kept: it is counted as grazing (its ray meets the
    /// plane at no finite place).
    pub fn triangulate_into(
        &self,
        base_hand: &Iso3,
        uv_px: &[[f64; 2]],
        out_mm: &mut Vec<[f64; 3]>,
        index: &mut Vec<u32>,
    ) -> DropCounts {
        let mut drops = DropCounts::default();
        let (r, t) = self.base_cam(base_hand);
        let mut track = UndistortTrack::new(&self.camera);
        for (i, &[u, v]) in uv_px.iter().enumerate() {
            match self.point_cam(u, v, &mut track) {
                Ok(p) => {
                    let b = r * p + t;
                    if b.iter().all(|x| x.is_finite()) {
                        out_mm.push([b.x, b.y, b.z]);
                        index.push(i as u32);
                    } else {
                        drops.grazing += 1;
                    }
                }
                Err(DropReason::Grazing) => drops.grazing += 1,
                Err(DropReason::Undistort) => drops.undistort += 1,
            }
        }
        drops
    }
}

/// Why one pixel gave no point.
#[derive(Debug, Clone, Copy)]
enum DropReason {
    Grazing,
    Undistort,
}

/// Triangulates pixels of one frame: `(points_mm, index)` of the kept points (base
/// frame) and their indices into `uv_px`. Convenience over [`Triangulator`].
pub fn triangulate(
    calibration: &Calibration,
    base_hand: &Iso3,
    uv_px: &[[f64; 2]],
) -> Result<(Vec<[f64; 3]>, Vec<u32>)> {
    let tri = Triangulator::from_calibration(calibration, DEFAULT_MIN_RAY_PLANE_ANGLE_DEG)?;
    check_pose(base_hand)?;
    let mut pts = Vec::with_capacity(uv_px.len());
    let mut idx = Vec::with_capacity(uv_px.len());
    tri.triangulate_into(base_hand, uv_px, &mut pts, &mut idx);
    Ok((pts, idx))
}

pub(super) fn check_pose(t: &Iso3) -> Result<()> {
    if t.translation.vector.iter().all(|x| x.is_finite())
        && t.rotation.coords.iter().all(|x| x.is_finite())
    {
        Ok(())
    } else {
        Err(Error::InvalidInput("T_base_hand is not finite".into()))
    }
}

/// The calibration's laser plane; an error saying why when it has none.
pub fn laser_plane_of(c: &Calibration) -> Result<&Plane> {
    c.laser_plane.as_ref().ok_or_else(|| {
        Error::InvalidInput(
            "the calibration has no laser plane (\"laser_plane\": null: it was made from views \
             without laser images), so it cannot triangulate stripe points; add the plane from \
             laser views with `stripecal calibrate --laser-only --from CALIBRATION.json DATASET`"
                .into(),
        )
    })
}

#[cfg(test)]
pub(super) mod tests {
    use super::*;
    use crate::model::camera::DistortionModel;
    use crate::model::geometry::iso_from_rotvec;

    /// The paper's camera with distortion `k`.
    pub(in crate::reconstruct) fn camera(k: [f64; 5]) -> Camera {
        Camera::new(
            768,
            576,
            Intrinsics {
                fu: 1271.65,
                fv: 1322.52,
                u0: 346.14,
                v0: 262.6,
            },
            DistortionModel::OpenCv5,
            k,
        )
        .unwrap()
    }

    /// Points on the laser plane, projected, triangulated back: the chain inverts the
    /// projection to rounding (strong opencv5 distortion).
    #[test]
    fn triangulation_inverts_projection() {
        let cam = camera([-0.3, 0.12, 0.001, -0.002, 0.01]);
        let plane = Plane::new(Vector3::new(0.629, -0.0492, 0.7759), 79.87).unwrap();
        let hand_cam = iso_from_rotvec(
            &Vector3::new(-0.3087, 0.2362, 3.0369),
            &Vector3::new(29.19, 5.37, 62.64),
        );
        let base_hand = iso_from_rotvec(
            &Vector3::new(0.1, 3.0, -0.2),
            &Vector3::new(480.0, 10.0, 365.0),
        );
        let tri = Triangulator::new(&cam, &plane, &hand_cam, 2.0).unwrap();
        // Points on the plane: p = n d + a e1 + b e2.
        let e1 = plane.normal.cross(&Vector3::y()).normalize();
        let e2 = plane.normal.cross(&e1);
        let mut uv = Vec::new();
        let mut truth = Vec::new();
        for i in -10..=10 {
            for j in -10..=10 {
                let p = plane.normal * plane.d + e1 * (2.0 * i as f64) + e2 * (2.5 * j as f64);
                let px = cam.project(&p).unwrap();
                uv.push([px.x, px.y]);
                truth.push(base_hand * hand_cam * nalgebra::Point3::from(p));
            }
        }
        let (mut out, mut idx) = (Vec::new(), Vec::new());
        let drops = tri.triangulate_into(&base_hand, &uv, &mut out, &mut idx);
        assert_eq!(drops.total(), 0);
        assert_eq!(out.len(), uv.len());
        for (k, p) in out.iter().enumerate() {
            let t = truth[idx[k] as usize];
            let e = (Vector3::from(*p) - t.coords).norm();
            assert!(e < 1e-9, "point {k}: error {e:.3e} mm");
        }
    }

    /// A plane containing the optical axis direction x = 0 (n = x, d = 50 mm): rays
    /// through pixels left of u0 meet it behind the camera, those near u0 at grazing
    /// angles; both are dropped, not turned into far points.
    #[test]
    fn grazing_and_backward_rays_are_dropped() {
        let cam = camera([0.0; 5]);
        let plane = Plane::new(Vector3::x(), 50.0).unwrap();
        let tri = Triangulator::new(&cam, &plane, &Iso3::identity(), 2.0).unwrap();
        // angle to the plane = atan(xn) for yn = 0: 2 deg at xn = tan(2 deg) = 0.0349.
        let u_at = |deg: f64| cam.u0 + cam.fu * deg.to_radians().tan();
        let uv = [
            [u_at(-10.0), cam.v0], // behind
            [u_at(0.5), cam.v0],   // grazing
            [u_at(1.99), cam.v0],  // grazing
            [u_at(2.01), cam.v0],  // kept
            [u_at(20.0), cam.v0],  // kept
        ];
        let (mut out, mut idx) = (Vec::new(), Vec::new());
        let d = tri.triangulate_into(&Iso3::identity(), &uv, &mut out, &mut idx);
        assert_eq!(idx, vec![3, 4]);
        assert_eq!(d.grazing, 3);
        for p in &out {
            assert!((p[0] - 50.0).abs() < 1e-9);
            assert!(p[2] > 0.0 && p[2] < 50.0 / (2.0f64).to_radians().tan() + 1.0);
        }
    }

    /// The 1D radial undistortion agrees with the camera's 2D Newton over the whole
    /// image of a strongly distorted lens (k1 = -0.25, k2 = 0.12, k3 = 0.01).
    #[test]
    fn radial_undistortion_matches_general() {
        let cam = Camera::new(
            1024,
            768,
            Intrinsics {
                fu: 900.0,
                fv: 900.5,
                u0: 515.3,
                v0: 380.8,
            },
            DistortionModel::OpenCv5,
            [-0.25, 0.12, 0.0, 0.0, 0.01],
        )
        .unwrap();
        assert!(UndistortTrack::new(&cam).is_radial_only());
        let mut scale = 1.0;
        for row in (0..768).step_by(7) {
            for col in (0..1024).step_by(13) {
                let (u, v) = (col as f64 + 0.3, row as f64 - 0.2);
                let s =
                    cam.undistort_radial_scale((u - cam.u0) / cam.fu, (v - cam.v0) / cam.fv, scale);
                let s = s.expect("converges inside the image");
                scale = s;
                let (xd, yd) = ((u - cam.u0) / cam.fu, (v - cam.v0) / cam.fv);
                let (xn, yn) = cam.undistort(xd, yd).unwrap();
                assert!((xd * s - xn).abs() < 1e-13 && (yd * s - yn).abs() < 1e-13);
            }
        }
    }

    #[test]
    fn bad_triangulator_input() {
        let cam = camera([0.0; 5]);
        let plane = Plane::new(Vector3::z(), 100.0).unwrap();
        for a in [-1.0, 90.0, f64::NAN] {
            assert!(matches!(
                Triangulator::new(&cam, &plane, &Iso3::identity(), a),
                Err(Error::InvalidInput(_))
            ));
        }
        let bad = Plane {
            normal: Vector3::new(0.0, 0.0, 2.0),
            d: 100.0,
        };
        assert!(Triangulator::new(&cam, &bad, &Iso3::identity(), 2.0).is_err());
    }
}
