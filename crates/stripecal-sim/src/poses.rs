//! Robot poses of the twin: calibration views around a home pose and straight-line
//! scan sweeps, solved by inverse kinematics on the TRUE robot (the readings are what
//! its encoders would report).

use nalgebra::{Matrix3, Point3, Rotation3, Unit, UnitQuaternion, Vector3};

use stripecal::model::geometry::Iso3;
use stripecal::model::kinematics::IkOptions;
use stripecal::{Camera, Robot};

use crate::rng::Rng;
use crate::scene::ImageScene;
use crate::target;
use crate::SimError;

/// Facts about one calibration pose.
#[derive(Debug, Clone, PartialEq)]
pub struct PoseInfo {
    /// Encoder readings, degrees.
    pub q_deg: Vec<f64>,
    /// Distance from the camera centre to the board plane along the optical axis, mm.
    pub standoff_mm: f64,
    /// Angle between the optical axis and the board normal, degrees.
    pub tilt_deg: f64,
    /// Length of the stripe's chord across the circle grid, mm.
    pub stripe_chord_mm: f64,
}

/// Everything pose sampling needs.
pub struct PoseProblem<'a> {
    pub robot: &'a Robot,
    pub camera: &'a Camera,
    pub hand_cam: &'a Iso3,
    pub base_board: &'a Iso3,
    pub home_q: &'a [f64],
    pub standoff: [f64; 2],
    pub max_tilt_deg: f64,
    pub max_roll_deg: f64,
    pub max_joint_delta_deg: f64,
    pub margin_px: f64,
    pub max_laser_incidence_deg: f64,
    /// The stripe beside the pattern instead of across it (see [`StripeLayout`]).
    pub stripe_beside_pattern: bool,
    /// Builds the camera-frame scene for `T_base_cam` (for visibility checks).
    pub scene: &'a (dyn Fn(&Iso3) -> ImageScene + Sync),
}

impl PoseProblem<'_> {
    /// Checks a pose (encoder readings) against every constraint; the facts if it passes.
    pub fn check(&self, q: &[f64]) -> Result<PoseInfo, String> {
        let board = {
            let s = (self.scene)(&Iso3::identity());
            s.board().clone()
        };
        for (i, (a, b)) in q.iter().zip(self.home_q).enumerate() {
            if (a - b).abs() > self.max_joint_delta_deg {
                return Err(format!("joint {} moves {:.1} deg from home", i + 1, a - b));
            }
        }
        let base_cam = self.robot.forward(q).map_err(|e| e.to_string())? * self.hand_cam;
        let scene = (self.scene)(&base_cam);
        let (pn, pd) = scene.plate_plane();
        // plate plane n.p = d, optical axis p = s z: s = d / n_z
        if pn.z <= 1e-9 {
            return Err("board seen from behind".into());
        }
        let standoff = pd / pn.z;
        let tilt = pn.z.clamp(-1.0, 1.0).acos().to_degrees();
        if standoff < self.standoff[0] - 1e-9 || standoff > self.standoff[1] + 1e-9 {
            return Err(format!("stand-off {standoff:.1} mm out of range"));
        }
        if tilt > self.max_tilt_deg + 1e-9 {
            return Err(format!("tilt {tilt:.1} deg too large"));
        }
        // The whole printed pattern inside the image margin: every circle's outline
        // (circle grids; 32 points each), the outer squares' outline (chessboards).
        if board.kind.is_circles() {
            let circles = target::points_inside_quick(&scene, self.camera, self.margin_px, 32);
            if circles < board.len() {
                return Err(format!(
                    "only {circles} of {} circles inside the image margin",
                    board.len()
                ));
            }
        } else if !target::pattern_inside(&scene, self.camera, self.margin_px, 32) {
            return Err("the chessboard's squares are not all inside the image margin".into());
        }
        let (chord, mut mid) = stripe_chord(&scene);
        let [x0, x1, y0, y1] = target::points_bbox(&board);
        let need = 0.5 * (x1 - x0).min(y1 - y0);
        if self.stripe_beside_pattern {
            let l = stripe_layout(&scene, self.camera);
            if l.sheet_mm < need || l.sheet_mm < 2.0 * l.pattern_mm || l.sheet_mm < l.table_mm {
                return Err(format!(
                    "stripe beside the pattern over {:.1} mm only ({:.1} mm on the pattern, \
                     {:.1} mm on the table)",
                    l.sheet_mm, l.pattern_mm, l.table_mm
                ));
            }
            if l.table_mm < 2.0 * board.pitch_mm {
                return Err(format!(
                    "stripe on the table beyond the plate over {:.1} mm only",
                    l.table_mm
                ));
            }
            mid = l.sheet_mid;
        } else if chord < need {
            return Err(format!("stripe crosses the grid over {chord:.1} mm only"));
        }
        // incidence of the laser at the chord's middle
        let p = (scene.cam_board * Point3::new(mid.0, mid.1, 0.0)).coords;
        let to_e = (scene.laser.emitter - p).normalize();
        let inc = (-pn).dot(&to_e).clamp(-1.0, 1.0).acos().to_degrees();
        if inc > self.max_laser_incidence_deg {
            return Err(format!(
                "laser incidence {inc:.1} deg on the board is too grazing"
            ));
        }
        Ok(PoseInfo {
            q_deg: q.to_vec(),
            standoff_mm: standoff,
            tilt_deg: tilt,
            stripe_chord_mm: chord,
        })
    }

    /// Samples `count` poses, deterministic by `seed`, spread in orientation.
    pub fn sample(&self, count: usize, seed: u64) -> Result<Vec<PoseInfo>, SimError> {
        let (pool, last_reason, max_attempts) = self.local_candidates(count, seed);
        if pool.len() < count {
            return Err(SimError::Poses(format!(
                "found {} valid poses of the {count} requested after {max_attempts} attempts (last rejection: \
                 {last_reason}); widen poses.standoff_mm / max_tilt_deg or reduce margin_px",
                pool.len()
            )));
        }
        self.select_local(&pool, count)
    }

    /// The local sampler's candidates for `count` poses and `seed` (feasible poses with
    /// their flange rotations), the last rejection and the attempts made.
    #[allow(clippy::type_complexity)]
    pub(crate) fn local_candidates(
        &self,
        count: usize,
        seed: u64,
    ) -> (Vec<(PoseInfo, UnitQuaternion<f64>)>, String, usize) {
        let scene0 = (self.scene)(&Iso3::identity());
        let board = scene0.board().clone();
        let center = target::points_center(&board);
        let want = (count * 8).max(count + 8);
        let mut rng = Rng::new(seed, 0x905e5);
        let mut pool: Vec<(PoseInfo, UnitQuaternion<f64>)> = Vec::new();
        let mut last_reason = String::new();
        let max_attempts = 4000 + 400 * count;
        for _ in 0..max_attempts {
            if pool.len() >= want {
                break;
            }
            let tilt = self.max_tilt_deg.to_radians() * rng.uniform().sqrt();
            let az = rng.range(0.0, std::f64::consts::TAU);
            let roll = rng.range(-1.0, 1.0) * self.max_roll_deg.to_radians();
            let s = rng.range(self.standoff[0], self.standoff[1]);
            // Across the pattern: near its centre; beside it: anywhere over the plate.
            let spread = if self.stripe_beside_pattern {
                let [x0, x1, y0, y1] = scene0.plate_extent();
                Vector3::new(0.5 * (x1 - x0), 0.5 * (y1 - y0), 0.0)
            } else {
                Vector3::new(1.0, 1.0, 0.0) * board.pitch_mm * 0.5
            };
            let look = center
                + Vector3::new(rng.range(-1.0, 1.0), rng.range(-1.0, 1.0), 0.0)
                    .component_mul(&spread);
            match self.try_pose(&look, tilt, az, roll, s, self.home_q) {
                Ok(found) => pool.push(found),
                Err(e) => last_reason = e,
            }
        }
        (pool, last_reason, max_attempts)
    }

    /// The pose whose camera looks at `look` (board frame) from stand-off `s` along an
    /// axis tilted by `tilt` (rad) from the board normal towards azimuth `az`, rolled by
    /// `roll` about it: its readings by inverse kinematics from `start` and its facts, or
    /// why it is refused.
    pub(crate) fn try_pose(
        &self,
        look: &Vector3<f64>,
        tilt: f64,
        az: f64,
        roll: f64,
        s: f64,
        start: &[f64],
    ) -> Result<(PoseInfo, UnitQuaternion<f64>), String> {
        let axis = Unit::new_normalize(Vector3::new(az.cos(), az.sin(), 0.0));
        let z = Rotation3::from_axis_angle(&axis, tilt) * Vector3::z();
        let x0 = Vector3::x() - z * z.x;
        let x0 = Rotation3::from_axis_angle(&Unit::new_normalize(z), roll) * x0.normalize();
        let y0 = z.cross(&x0);
        let r = Matrix3::from_columns(&[x0, y0, z]);
        // distance along the axis to the board plane (z_board = 0) is s: position
        let board_cam = stripecal::model::geometry::iso_from_parts(&r, &(look - z * s));
        let base_hand = self.base_board * board_cam * self.hand_cam.inverse();
        let q = self
            .robot
            .inverse(&base_hand, start, &IkOptions::default())
            .map_err(|e| e.to_string())?;
        let info = self.check(&q)?;
        let rot = self.robot.forward_unchecked(&q).rotation;
        Ok((info, rot))
    }

    /// The local sampler's choice of `count` of `pool`.
    fn select_local(
        &self,
        pool: &[(PoseInfo, UnitQuaternion<f64>)],
        count: usize,
    ) -> Result<Vec<PoseInfo>, SimError> {
        // Farthest-point selection in orientation: diverse rotation axes for hand-eye.
        let mut chosen: Vec<usize> = vec![0];
        while chosen.len() < count {
            let mut best = (0usize, -1.0f64);
            for (i, (_, qi)) in pool.iter().enumerate() {
                if chosen.contains(&i) {
                    continue;
                }
                let dmin = chosen
                    .iter()
                    .map(|&j| qi.angle_to(&pool[j].1))
                    .fold(f64::INFINITY, f64::min);
                if dmin > best.1 {
                    best = (i, dmin);
                }
            }
            chosen.push(best.0);
        }
        let rots: Vec<UnitQuaternion<f64>> = chosen.iter().map(|&i| pool[i].1).collect();
        if count >= 3 {
            let spread = axis_spread(&rots);
            if spread < 0.05 {
                return Err(SimError::Poses(format!(
                    "the sampled poses rotate about nearly parallel axes (axis spread {spread:.3}); \
                     increase poses.max_tilt_deg or max_roll_deg"
                )));
            }
        }
        Ok(chosen.into_iter().map(|i| pool[i].0.clone()).collect())
    }
}

/// Middle-to-largest eigenvalue ratio of the scatter of relative rotation axes
/// (weighted by angle): near 0 when all relative rotations share one axis, which
/// leaves hand-eye calibration unsolvable.
pub fn axis_spread(rots: &[UnitQuaternion<f64>]) -> f64 {
    let mut m = Matrix3::zeros();
    for i in 0..rots.len() {
        for j in i + 1..rots.len() {
            let rel = rots[i].inverse() * rots[j];
            if let Some((axis, angle)) = rel.axis_angle() {
                let a = axis.into_inner() * angle;
                m += a * a.transpose();
            }
        }
    }
    let mut ev: Vec<f64> = m.symmetric_eigenvalues().iter().copied().collect();
    ev.sort_by(|a, b| b.total_cmp(a));
    if ev[0] <= 0.0 {
        return 0.0;
    }
    ev[1] / ev[0]
}

/// Length of the laser line's chord across the rectangle spanned by the target points
/// (circle centres, inner corners; [`target::points_bbox`]), and the chord's middle
/// (board coordinates).
pub fn stripe_chord(scene: &ImageScene) -> (f64, (f64, f64)) {
    let b = scene.board();
    let t = scene.cam_board;
    // Laser plane in board coordinates.
    let lp = scene.laser.plane.transformed(&t.inverse());
    let (n, d) = (lp.normal, lp.d);
    // Line n.x x + n.y y = d in the board plane z = 0 (the box starts at the origin).
    let [_, w, _, h] = target::points_bbox(b);
    let mut pts: Vec<(f64, f64)> = Vec::new();
    if n.y.abs() > 1e-12 {
        for x in [0.0, w] {
            let y = (d - n.x * x) / n.y;
            if (0.0..=h).contains(&y) {
                pts.push((x, y));
            }
        }
    }
    if n.x.abs() > 1e-12 {
        for y in [0.0, h] {
            let x = (d - n.y * y) / n.x;
            if (0.0..=w).contains(&x) {
                pts.push((x, y));
            }
        }
    }
    let mut best = (0.0, (0.0, 0.0));
    for i in 0..pts.len() {
        for j in i + 1..pts.len() {
            let len = ((pts[i].0 - pts[j].0).powi(2) + (pts[i].1 - pts[j].1).powi(2)).sqrt();
            if len > best.0 {
                best = (
                    len,
                    (0.5 * (pts[i].0 + pts[j].0), 0.5 * (pts[i].1 + pts[j].1)),
                );
            }
        }
    }
    best
}

/// Where the laser line lies in a view: its lengths (mm, along the line) in the image on
/// the printed pattern ([`stripecal::Board::pattern_extent`]), on the plate beside the
/// pattern, and on the table where the camera sees it past the plate's edge (the laser
/// meets the table `plate_thickness_mm` behind the plate plane), and the middle of the
/// part beside the pattern (board mm).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct StripeLayout {
    pub pattern_mm: f64,
    pub sheet_mm: f64,
    pub table_mm: f64,
    pub sheet_mid: (f64, f64),
}

/// The [`StripeLayout`] of a scene, from the laser's lines on the plate and table planes
/// sampled every `1/2000` of three stand-offs (calibration scenes: no sphere).
pub fn stripe_layout(scene: &ImageScene, camera: &Camera) -> StripeLayout {
    let t = scene.cam_board;
    let lp = scene.laser.plane.transformed(&t.inverse());
    let (n, d) = (lp.normal, lp.d);
    let nxy = (n.x * n.x + n.y * n.y).sqrt();
    let mut out = StripeLayout {
        pattern_mm: 0.0,
        sheet_mm: 0.0,
        table_mm: 0.0,
        sheet_mid: (0.0, 0.0),
    };
    if nxy < 1e-9 {
        return out;
    }
    let (pn, pd) = scene.plate_plane();
    let (_, td) = scene.table_plane();
    let depth = td - pd; // the table's z in the board frame
    let dir = (-n.y / nxy, n.x / nxy);
    let half = 3.0 * pd.abs().max(1.0);
    let steps = 2000;
    let ds = 2.0 * half / steps as f64;
    let pat = scene.board().pattern_extent();
    let plate = scene.plate_extent();
    let inside = |e: &[f64; 4], x: f64, y: f64| x >= e[0] && x <= e[1] && y >= e[2] && y <= e[3];
    let (mut s_lo, mut s_hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for (z, table) in [(0.0, false), (depth, true)] {
        // the line n.x x + n.y y = d - n.z z in the plane board z = z
        let c = (d - n.z * z) / nxy;
        let foot = (n.x / nxy * c, n.y / nxy * c);
        for k in 0..=steps {
            let s = -half + k as f64 * ds;
            let (x, y) = (foot.0 + s * dir.0, foot.1 + s * dir.1);
            let p = (t * Point3::new(x, y, z)).coords;
            if p.z <= 0.0 {
                continue;
            }
            let Ok(uv) = camera.project(&p) else {
                continue;
            };
            if !camera.contains(&uv, 0.0) {
                continue;
            }
            if table {
                // seen past the plate: the ray meets the plate plane outside the plate
                let den = pn.dot(&p);
                if den <= 0.0 {
                    continue;
                }
                let (qx, qy) = scene.board_xy(&(p * (pd / den)));
                if !inside(&plate, qx, qy) && scene.lit(crate::scene::SURF_TABLE, &p) {
                    out.table_mm += ds;
                }
            } else if inside(&pat, x, y) {
                out.pattern_mm += ds;
            } else if inside(&plate, x, y) {
                out.sheet_mm += ds;
                s_lo = s_lo.min(s);
                s_hi = s_hi.max(s);
            }
        }
        if !table && s_lo <= s_hi {
            let sm = 0.5 * (s_lo + s_hi);
            out.sheet_mid = (foot.0 + sm * dir.0, foot.1 + sm * dir.1);
        }
    }
    out
}

/// Where `T_base_cam` must be so that the laser plane passes through `point` with the
/// optical axis `depth_mm` from `top` (both base frame), the camera keeping rotation
/// `rot`, and `point` centred across the sweep. Returns the camera origin.
pub fn scan_origin(
    rot: &UnitQuaternion<f64>,
    plane_n_cam: &Vector3<f64>,
    plane_d: f64,
    point: &Vector3<f64>,
    top: &Vector3<f64>,
    depth_mm: f64,
    sweep_dir: &Vector3<f64>,
) -> Option<Vector3<f64>> {
    let a = rot * Vector3::z();
    let n = rot * plane_n_cam;
    let side = a.cross(sweep_dir);
    // a.o = a.top - depth ; n.o = n.point - d ; side.o = side.point
    let m = Matrix3::from_rows(&[a.transpose(), n.transpose(), side.transpose()]);
    let rhs = Vector3::new(
        a.dot(top) - depth_mm,
        n.dot(point) - plane_d,
        side.dot(point),
    );
    m.try_inverse().map(|mi| mi * rhs)
}
