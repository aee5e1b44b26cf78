//! The verification scans' sweeps: each position's scan frame, the artefact placed in
//! it, the sweep's poses by inverse kinematics on the true robot, and the check that
//! the stripe sees the artefact.

use super::*;

impl Twin {
    /// The scan frame of a position: `(rotation, a, s, w, reference point)` with the
    /// camera at the home orientation turned by `yaw_deg` about the table's normal.
    fn verify_frame(&self, yaw_deg: f64) -> Result<ScanAxes, SimError> {
        let home = self.base_cam(&self.cfg.poses.home_q_deg)?;
        let up = self.base_board.rotation * -Vector3::z();
        let turn = UnitQuaternion::from_axis_angle(&Unit::new_normalize(up), yaw_deg.to_radians());
        let rot = turn * home.rotation;
        let a = rot * Vector3::z();
        let n = rot * self.laser_plane.normal;
        let s = n - a * n.dot(&a);
        if s.norm() < 1e-6 {
            return Err(SimError::Poses(
                "the laser plane is perpendicular to the optical axis: no sweep".into(),
            ));
        }
        let s = s.normalize();
        let reference = home.translation.vector + home.rotation * Vector3::z() * REFERENCE_DEPTH_MM;
        Ok(ScanAxes {
            rot,
            a,
            s,
            w: a.cross(&s),
            n,
            reference,
        })
    }

    /// The verification scans the configuration asks for (`verify.bar_positions` bars,
    /// then `verify.plate_positions` plates), whether `verify.enabled` or not; an error
    /// names a position the robot cannot sweep or whose stripe misses the artefact.
    pub fn verify_scans(&self) -> Result<Vec<VerifyScan>, SimError> {
        let v = &self.cfg.verify;
        let art = self.verify_artefacts();
        let mut out = Vec::new();
        for (i, p) in BAR_PLACEMENTS.iter().take(v.bar_positions).enumerate() {
            let ax = self.verify_frame(p.yaw_deg)?;
            let (t, k) = (p.tilt_deg.to_radians(), p.skew_deg.to_radians());
            let b = (ax.s * k.cos() + ax.w * k.sin()) * t.cos() + ax.a * t.sin();
            let mid = ax.reference + Vector3::from(p.offset_mm);
            let half = 0.5 * art.length_mm;
            let spheres = vec![
                Sphere {
                    center_mm: mid - b * half,
                    diameter_mm: art.diameters_mm[0],
                },
                Sphere {
                    center_mm: mid + b * half,
                    diameter_mm: art.diameters_mm[1],
                },
            ];
            let pts: Vec<(Vector3<f64>, f64)> = spheres
                .iter()
                .map(|s| (s.center_mm, 0.5 * s.diameter_mm))
                .collect();
            // the laser plane's travel: both spheres and the margins
            let travel: Vec<(Vector3<f64>, f64)> =
                pts.iter().map(|&(c, r)| (c, r + v.margin_mm)).collect();
            let world = World {
                table: false,
                spheres: pts.clone(),
                free_plate: None,
                ..self.calib_world.clone()
            };
            let name = format!("bar_{}", i + 1);
            let (poses, base_cam_mid) = self.verify_sweep(&ax, &mid, p.depth_mm, &travel, &name)?;
            let scan = VerifyScan {
                name,
                artefact: "bar".into(),
                poses,
                spheres,
                plane: None,
                depth_mm: p.depth_mm,
                base_cam_mid,
                world,
            };
            self.check_verify_scan(&scan)?;
            out.push(scan);
        }
        for (i, p) in PLATE_PLACEMENTS.iter().take(v.plate_positions).enumerate() {
            let ax = self.verify_frame(p.yaw_deg)?;
            // plate axes (s, -w, -a) turned about w, then about s
            let r0 = nalgebra::Matrix3::from_columns(&[ax.s, -ax.w, -ax.a]);
            let turn =
                Rotation3::from_axis_angle(&Unit::new_normalize(ax.w), p.tilt_w_deg.to_radians())
                    * Rotation3::from_axis_angle(
                        &Unit::new_normalize(ax.s),
                        p.tilt_s_deg.to_radians(),
                    );
            let r = turn.matrix() * r0;
            let mid = ax.reference + Vector3::from(p.offset_mm);
            let base_plate = iso_from_parts(&r, &mid);
            let normal = r.column(2).into_owned();
            let plane = Plane::new(normal, normal.dot(&mid))
                .map_err(|e| SimError::Poses(format!("plate plane: {e}")))?;
            let half = [0.5 * v.plate_size_mm[0], 0.5 * v.plate_size_mm[1]];
            // the laser plane's travel: `plate_inset_mm` inside both edges across the sweep
            // wherever the stripe can be seen along the plate (up to 0.6 x the image
            // height at the far end of the working range from the middle)
            let (ex, ey) = (r.column(0).into_owned(), r.column(1).into_owned());
            let seen =
                0.6 * self.camera.height as f64 / self.camera.fv * self.cfg.working_range_mm[1];
            let hy = half[1].min(seen);
            let edges: Vec<(Vector3<f64>, f64)> = [-hy, hy]
                .iter()
                .flat_map(|&y| {
                    [-1.0, 1.0].map(|x| (mid + ex * (x * half[0]) + ey * y, -v.plate_inset_mm))
                })
                .collect();
            let world = World {
                table: false,
                spheres: vec![],
                free_plate: Some(FreePlate {
                    base_plate,
                    half_size_mm: half,
                    reflectance: v.plate_reflectance,
                }),
                ..self.calib_world.clone()
            };
            let name = format!("plate_{}", i + 1);
            let (poses, base_cam_mid) = self.verify_sweep(&ax, &mid, p.depth_mm, &edges, &name)?;
            let scan = VerifyScan {
                name,
                artefact: "plate".into(),
                poses,
                spheres: vec![],
                plane: Some(plane),
                depth_mm: p.depth_mm,
                base_cam_mid,
                world,
            };
            self.check_verify_scan(&scan)?;
            out.push(scan);
        }
        Ok(out)
    }

    /// The sweep of one position: the camera at `ax.rot` with the laser plane through
    /// `mid` at `depth` along the optical axis in the sweep's middle, travelling along
    /// `ax.s` from the first to the last moment the plane is within `reach` of a point
    /// `(point, reach)` of `extent`; or with every reach negative, while the plane
    /// stays `-reach` inside each consecutive pair of points (the plate's two edges
    /// across the sweep); `(readings, T_base_cam at the middle)`.
    fn verify_sweep(
        &self,
        ax: &ScanAxes,
        mid: &Vector3<f64>,
        depth: f64,
        extent: &[(Vector3<f64>, f64)],
        what: &str,
    ) -> Result<(Vec<Vec<f64>>, Iso3), SimError> {
        let step = self.cfg.verify.step_mm;
        let origin = crate::poses::scan_origin(
            &ax.rot,
            &self.laser_plane.normal,
            self.laser_plane.d,
            mid,
            mid,
            depth,
            &ax.s,
        )
        .ok_or_else(|| SimError::Poses(format!("{what}: cannot place the sweep")))?;
        let rate = ax.n.dot(&ax.s);
        // the plane passes through x at travel t = (n . (x - o) - d) / rate
        let tc = |c: &Vector3<f64>| (ax.n.dot(&(c - origin)) - self.laser_plane.d) / rate;
        let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
        let n = if extent.iter().all(|e| e.1 < 0.0) {
            // inside: each pair of points bounds the travel, the plane `-reach` within
            (lo, hi) = (f64::NEG_INFINITY, f64::INFINITY);
            for pair in extent.chunks(2) {
                let (a, b) = (tc(&pair[0].0), tc(&pair[pair.len() - 1].0));
                let dt = -pair[0].1 / rate.abs();
                lo = lo.max(a.min(b) + dt);
                hi = hi.min(a.max(b) - dt);
            }
            if hi < lo {
                return Err(SimError::Poses(format!(
                    "{what}: no travel inside the plate's edges"
                )));
            }
            ((hi - lo) / step).floor() as usize + 1
        } else {
            // across: the plane crosses every point's reach
            for (c, reach) in extent {
                let dt = reach / rate.abs();
                lo = lo.min(tc(c) - dt);
                hi = hi.max(tc(c) + dt);
            }
            ((hi - lo) / step).ceil() as usize + 1
        };
        let start = 0.5 * (lo + hi) - 0.5 * (n - 1) as f64 * step;
        let x_inv = self.hand_cam.inverse();
        let cam_at = |t: f64| Iso3::from_parts((origin + ax.s * t).into(), ax.rot);
        let ik = |cam: &Iso3, q0: &[f64], k: usize| {
            self.robot_true
                .inverse(&(cam * x_inv), q0, &IkOptions::default())
                .map_err(|e| {
                    SimError::Poses(format!(
                        "verify {what} frame {k}: the robot cannot reach the sweep: {e}"
                    ))
                })
        };
        let mid_cam = cam_at(0.5 * (lo + hi));
        let q_mid = ik(&mid_cam, &self.cfg.poses.home_q_deg, n / 2)?;
        let mut q = ik(&cam_at(start), &q_mid, 0)?;
        let mut out = Vec::with_capacity(n);
        for k in 0..n {
            let t = start + k as f64 * step;
            q = ik(&cam_at(t), &q, k)?;
            out.push(q.clone());
        }
        Ok((out, mid_cam))
    }

    /// Checks that the stripe sees each sphere of a bar (at the frame where the laser
    /// plane is nearest its centre) over at least half the rows its diameter could
    /// cover, or the plate (in the middle frame) over 90% of the rows.
    fn check_verify_scan(&self, scan: &VerifyScan) -> Result<(), SimError> {
        let laser = self.laser();
        let count = |q: &[f64], surface: &str| -> Result<usize, SimError> {
            let sc = scan.world.image_scene(&self.base_cam(q)?, laser);
            Ok(stripe_truth(&sc, &self.camera, self.direction)
                .iter()
                .filter(|p| p.surface == surface)
                .count())
        };
        let fv = self.camera.fv;
        if scan.spheres.is_empty() {
            let q = &scan.poses[scan.poses.len() / 2];
            let got = count(q, "flat_plate")?;
            let want = (self.cfg.verify.plate_size_mm[1] * fv / scan.depth_mm)
                .min(self.camera.height as f64)
                * 0.9;
            if (got as f64) < want {
                return Err(SimError::Poses(format!(
                    "verify {}: the stripe covers {got} rows of the plate in the middle frame \
                     (want >= {want:.0})",
                    scan.name
                )));
            }
            return Ok(());
        }
        for (j, s) in scan.spheres.iter().enumerate() {
            // the frame whose laser plane passes nearest the centre
            let mut best = (0, f64::INFINITY);
            for (k, q) in scan.poses.iter().enumerate() {
                let cam = self.base_cam(q)?;
                let c = (cam.inverse() * Point3::from(s.center_mm)).coords;
                let dist = self.laser_plane.signed_distance(&c).abs();
                if dist < best.1 {
                    best = (k, dist);
                }
            }
            let got = count(&scan.poses[best.0], "sphere")?;
            let want = 0.5 * s.diameter_mm * fv / scan.depth_mm;
            if (got as f64) < want {
                return Err(SimError::Poses(format!(
                    "verify {}: the stripe covers {got} rows of sphere {} at its centre \
                     (want >= {want:.0})",
                    scan.name,
                    ["A", "B"][j]
                )));
            }
        }
        Ok(())
    }
}

/// The scan frame of one position (base frame).
struct ScanAxes {
    rot: UnitQuaternion<f64>,
    /// Optical axis.
    a: Vector3<f64>,
    /// Sweep direction.
    s: Vector3<f64>,
    /// Along the stripe: `a x s`.
    w: Vector3<f64>,
    /// Laser plane normal.
    n: Vector3<f64>,
    reference: Vector3<f64>,
}
