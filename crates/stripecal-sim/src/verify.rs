//! Verification artefacts (`verify.*`, issue 15): scans of a ball bar in up to 7
//! positions and of a flat plate in up to 3, in the spirit of VDI/VDE 2634-2, with
//! their certificate (`artefacts.json`, spec/DATASET.md "Verification artefacts") and
//! truth.
//!
//! - The ball bar: two spheres of `sphere_diameter_mm` whose centres are
//!   `bar_length_mm` apart; the plate: a rectangle of `plate_size_mm`. The TRUE sizes
//!   are the nominal ones plus a seeded manufacturing deviation (diameters within
//!   +-0.003 mm, the length within +-0.01 mm); the spheres are perfectly round and the
//!   plate perfectly flat (true form and flatness 0).
//! - The certificate (artefacts.json) gives the true values plus a seeded "calibration
//!   of the artefact" error: Gaussian with one-sigma half the expanded uncertainty it
//!   states (`uncertainty_k2_mm`), clipped to that uncertainty (form and flatness: the
//!   absolute value of such a draw, as a certificate never states a negative form);
//!   `certificate_exact` makes it equal the truth.
//! - The artefacts float: the bar's supports and the table are beyond the sensor's
//!   depth of view (not rendered, rays that miss the artefact see black), so each image
//!   row holds one stripe, on the artefact.
//! - Each scan is a straight sweep at a fixed camera orientation along the laser
//!   plane's normal projected perpendicular to the optical axis (the stand-off stays
//!   constant while sweeping), long enough for the laser plane to cross both spheres
//!   plus `margin_mm`, in `step_mm` steps; inverse kinematics on the TRUE robot, from
//!   the home pose at the sweep's middle. The plate is larger than what the sensor sees
//!   of it (its stripe fills every image row) and its sweep stays `plate_inset_mm`
//!   inside its edges across the sweep: no stripe ends on or straddles an edge.
//! - Positions ([`BAR_PLACEMENTS`], [`PLATE_PLACEMENTS`]) are given in the scan frame of
//!   the camera (`s` the sweep, `w = a x s` along the stripe, `a` the optical axis) at
//!   the home orientation turned by `yaw_deg` about the table's normal, with the
//!   artefact's middle at `offset_mm` (base frame) from the point 105 mm along the home
//!   pose's optical axis and `depth_mm` along the optical axis from the camera.

use nalgebra::{Point3, Rotation3, Unit, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use stripecal::model::geometry::{iso_from_parts, Iso3, Plane};
use stripecal::model::kinematics::IkOptions;
use stripecal::model::{Sphere, Truth};

use crate::dataset::{Twin, ViewRender};
use crate::imaging::{form_image, Exposure};
use crate::scene::{FreePlate, World};
use crate::truth::stripe_truth;
use crate::SimError;

/// The random stream of the artefacts' deviations and certificate errors.
pub const VERIFY_STREAM: u64 = 0x7665_7269_6679;
/// First noise stream of the verification frames (scan `i`, frame `k`:
/// `VERIFY_FRAME_STREAM + 100_000 i + k`).
const VERIFY_FRAME_STREAM: u64 = 3_000_000;
/// Depth of the reference point along the home pose's optical axis, mm.
const REFERENCE_DEPTH_MM: f64 = 105.0;

/// Expanded (k = 2) uncertainties of the certificate, mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct UncertaintyCfg {
    pub diameter: f64,
    pub form: f64,
    pub length: f64,
    pub flatness: f64,
}

impl Default for UncertaintyCfg {
    fn default() -> Self {
        UncertaintyCfg {
            diameter: 0.001,
            form: 0.0005,
            length: 0.002,
            flatness: 0.001,
        }
    }
}

/// Maximum permissible errors the acceptance test applies, mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MpeCfg {
    pub probing_form: f64,
    pub probing_size: f64,
    pub sphere_spacing: f64,
    pub flatness: f64,
}

impl Default for MpeCfg {
    fn default() -> Self {
        MpeCfg {
            probing_form: 0.05,
            probing_size: 0.03,
            sphere_spacing: 0.08,
            flatness: 0.05,
        }
    }
}

/// The `verify` knobs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VerifyCfg {
    /// Write `verify/` (default false).
    pub enabled: bool,
    /// Nominal centre distance of the ball bar's spheres, mm.
    pub bar_length_mm: f64,
    /// Nominal diameter of both spheres, mm.
    pub sphere_diameter_mm: f64,
    /// Ball bar positions, the first N of [`BAR_PLACEMENTS`] (0..=7).
    pub bar_positions: usize,
    /// Plate positions, the first N of [`PLATE_PLACEMENTS`] (0..=3).
    pub plate_positions: usize,
    /// The plate's sides: along the sweep, along the stripe, mm. Along the stripe it is
    /// longer than the stripe seen in the image (~45 mm at 105 mm): the stripe fills the
    /// image's rows, it never ends on the plate.
    pub plate_size_mm: [f64; 2],
    /// The plate sweep stays this far inside the plate's edges across the sweep (the
    /// laser plane never reaches an edge: every stripe lies inside the plate), mm.
    pub plate_inset_mm: f64,
    pub plate_reflectance: f64,
    /// Sensor translation between frames, mm.
    pub step_mm: f64,
    /// Extra travel of the laser plane before and after the artefact, mm.
    pub margin_mm: f64,
    /// The certificate equals the truth (no calibration error of the artefacts).
    pub certificate_exact: bool,
    pub uncertainty_k2_mm: UncertaintyCfg,
    pub mpe_mm: MpeCfg,
}

impl Default for VerifyCfg {
    fn default() -> Self {
        VerifyCfg {
            enabled: false,
            bar_length_mm: 100.0,
            sphere_diameter_mm: 25.4,
            bar_positions: BAR_PLACEMENTS.len(),
            plate_positions: PLATE_PLACEMENTS.len(),
            plate_size_mm: [80.0, 70.0],
            plate_inset_mm: 5.0,
            plate_reflectance: 0.6,
            step_mm: 0.5,
            margin_mm: 2.0,
            certificate_exact: false,
            uncertainty_k2_mm: UncertaintyCfg::default(),
            mpe_mm: MpeCfg::default(),
        }
    }
}

impl VerifyCfg {
    /// Checks every value; the message names the knob.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |k: &str, m: String| Err(SimError::Config(format!("verify.{k}: {m}")));
        let pos = |v: f64| v.is_finite() && v > 0.0;
        for (k, v) in [
            ("bar_length_mm", self.bar_length_mm),
            ("sphere_diameter_mm", self.sphere_diameter_mm),
            ("plate_size_mm[0]", self.plate_size_mm[0]),
            ("plate_size_mm[1]", self.plate_size_mm[1]),
            ("plate_reflectance", self.plate_reflectance),
            ("step_mm", self.step_mm),
        ] {
            if !pos(v) {
                return bad(k, format!("{v} must be finite and > 0"));
            }
        }
        if !(self.margin_mm.is_finite() && self.margin_mm >= 0.0) {
            return bad("margin_mm", format!("{} must be >= 0", self.margin_mm));
        }
        let i = self.plate_inset_mm;
        if !(i.is_finite() && i >= 0.0 && 2.0 * i < self.plate_size_mm[0] - self.step_mm) {
            return bad(
                "plate_inset_mm",
                format!(
                    "{i} must be >= 0 and leave more than one step of the plate to sweep \
                     (plate_size_mm[0] {})",
                    self.plate_size_mm[0]
                ),
            );
        }
        if self.sphere_diameter_mm >= 0.9 * self.bar_length_mm {
            return bad(
                "sphere_diameter_mm",
                format!(
                    "{} mm: the spheres must not touch (bar_length_mm {})",
                    self.sphere_diameter_mm, self.bar_length_mm
                ),
            );
        }
        if self.bar_positions > BAR_PLACEMENTS.len() {
            return bad(
                "bar_positions",
                format!("{} (at most {})", self.bar_positions, BAR_PLACEMENTS.len()),
            );
        }
        if self.plate_positions > PLATE_PLACEMENTS.len() {
            return bad(
                "plate_positions",
                format!(
                    "{} (at most {})",
                    self.plate_positions,
                    PLATE_PLACEMENTS.len()
                ),
            );
        }
        let u = &self.uncertainty_k2_mm;
        let m = &self.mpe_mm;
        for (k, v) in [
            ("uncertainty_k2_mm.diameter", u.diameter),
            ("uncertainty_k2_mm.form", u.form),
            ("uncertainty_k2_mm.length", u.length),
            ("uncertainty_k2_mm.flatness", u.flatness),
            ("mpe_mm.probing_form", m.probing_form),
            ("mpe_mm.probing_size", m.probing_size),
            ("mpe_mm.sphere_spacing", m.sphere_spacing),
            ("mpe_mm.flatness", m.flatness),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(k, format!("{v} must be finite and >= 0"));
            }
        }
        Ok(())
    }
}

/// Where a ball bar stands (see the module docs for the frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct BarPlacement {
    /// Turn of the camera (and the bar) about the table's normal from the home
    /// orientation, deg.
    pub yaw_deg: f64,
    /// The bar's angle out of the plane perpendicular to the optical axis (positive:
    /// sphere B farther), deg.
    pub tilt_deg: f64,
    /// The bar's angle from the sweep towards the stripe (diagonal in the image), deg.
    pub skew_deg: f64,
    /// The bar's middle from the reference point, base frame, mm.
    pub offset_mm: [f64; 3],
    /// Depth of the bar's middle (the centres' mean) along the optical axis, mm.
    pub depth_mm: f64,
}

/// Where the plate stands (see the module docs for the frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlatePlacement {
    pub yaw_deg: f64,
    /// Turn of the plate about the stripe's direction `w` (depth changes along the
    /// sweep), deg.
    pub tilt_w_deg: f64,
    /// Turn of the plate about the sweep `s` (depth changes along the stripe), deg.
    pub tilt_s_deg: f64,
    pub offset_mm: [f64; 3],
    /// Depth of the plate's centre along the optical axis, mm.
    pub depth_mm: f64,
}

/// The ball bar's positions: along the sweep, across it (turned 90 deg), the two
/// diagonals, tilted in depth both ways, and diagonal in the image at a far stand-off;
/// the bar's middle moved +-40 mm across and +-20 mm up and down the working volume,
/// stand-offs 98..118 mm.
pub const BAR_PLACEMENTS: [BarPlacement; 7] = [
    BarPlacement {
        yaw_deg: 0.0,
        tilt_deg: 0.0,
        skew_deg: 0.0,
        offset_mm: [0.0, 0.0, 0.0],
        depth_mm: 105.0,
    },
    BarPlacement {
        yaw_deg: 90.0,
        tilt_deg: 0.0,
        skew_deg: 0.0,
        offset_mm: [0.0, 40.0, 0.0],
        depth_mm: 105.0,
    },
    BarPlacement {
        yaw_deg: 45.0,
        tilt_deg: 0.0,
        skew_deg: 0.0,
        offset_mm: [40.0, 0.0, 10.0],
        depth_mm: 98.0,
    },
    BarPlacement {
        yaw_deg: -45.0,
        tilt_deg: 0.0,
        skew_deg: 0.0,
        offset_mm: [-40.0, 0.0, -10.0],
        depth_mm: 118.0,
    },
    BarPlacement {
        yaw_deg: 0.0,
        tilt_deg: 12.0,
        skew_deg: 0.0,
        offset_mm: [0.0, -40.0, 20.0],
        depth_mm: 108.0,
    },
    BarPlacement {
        yaw_deg: 90.0,
        tilt_deg: -12.0,
        skew_deg: 0.0,
        offset_mm: [-30.0, -30.0, -20.0],
        depth_mm: 108.0,
    },
    BarPlacement {
        yaw_deg: 135.0,
        tilt_deg: 0.0,
        skew_deg: 5.0,
        offset_mm: [30.0, 30.0, -20.0],
        depth_mm: 115.0,
    },
];

/// The plate's positions: facing the sensor, tilted 25 deg about the stripe's
/// direction, tilted 25 deg about the sweep (turned 90 deg).
pub const PLATE_PLACEMENTS: [PlatePlacement; 3] = [
    PlatePlacement {
        yaw_deg: 0.0,
        tilt_w_deg: 0.0,
        tilt_s_deg: 0.0,
        offset_mm: [0.0, 0.0, 0.0],
        depth_mm: 105.0,
    },
    PlatePlacement {
        yaw_deg: 45.0,
        tilt_w_deg: 25.0,
        tilt_s_deg: 0.0,
        offset_mm: [30.0, -30.0, 10.0],
        depth_mm: 108.0,
    },
    PlatePlacement {
        yaw_deg: 90.0,
        tilt_w_deg: 0.0,
        tilt_s_deg: -25.0,
        offset_mm: [-30.0, 30.0, -10.0],
        depth_mm: 108.0,
    },
];

/// The artefacts: true values and the certificate's.
#[derive(Debug, Clone, PartialEq)]
pub struct Artefacts {
    /// True diameters of spheres A and B, mm.
    pub diameters_mm: [f64; 2],
    /// True centre distance, mm.
    pub length_mm: f64,
    /// The certificate: artefacts.json's content.
    pub certificate: Value,
}

/// One verification scan.
#[derive(Debug, Clone)]
pub struct VerifyScan {
    /// `bar_1`..`bar_7`, `plate_1`..`plate_3`: the folder's name.
    pub name: String,
    /// `bar` or `plate`: the artefact's name in artefacts.json.
    pub artefact: String,
    /// Encoder readings of the sweep (true robot).
    pub poses: Vec<Vec<f64>>,
    /// The bar's spheres A and B (base frame, true); empty for the plate.
    pub spheres: Vec<Sphere>,
    /// The plate's plane (base frame, normal towards the sensor); `None` for the bar.
    pub plane: Option<Plane>,
    /// Depth of the artefact's middle along the optical axis, mm.
    pub depth_mm: f64,
    /// `T_base_cam` at the sweep's middle.
    pub base_cam_mid: Iso3,
    world: World,
}

impl Twin {
    /// The artefacts' true values and certificate, drawn from the seed.
    pub fn verify_artefacts(&self) -> Artefacts {
        let v = &self.cfg.verify;
        let u = &v.uncertainty_k2_mm;
        let mut rng = crate::rng::Rng::new(self.cfg.seed, VERIFY_STREAM);
        let da = v.sphere_diameter_mm + rng.range(-0.003, 0.003);
        let db = v.sphere_diameter_mm + rng.range(-0.003, 0.003);
        let len = v.bar_length_mm + rng.range(-0.01, 0.01);
        let exact = v.certificate_exact;
        let mut err = |k2: f64| {
            let e = (0.5 * k2 * rng.normal()).clamp(-k2, k2);
            if exact {
                0.0
            } else {
                e
            }
        };
        let r7 = |x: f64| (x * 1e7).round() / 1e7;
        let (ca, cb, cl) = (
            r7(da + err(u.diameter)),
            r7(db + err(u.diameter)),
            r7(len + err(u.length)),
        );
        let (fa, fb, fl) = (
            r7(err(u.form).abs()),
            r7(err(u.form).abs()),
            r7(err(u.flatness).abs()),
        );
        let m = &v.mpe_mm;
        let certificate = json!({
            "format": "stripecal/artefacts@1",
            "spheres": [
                {"name": "A", "diameter_mm": ca, "form_mm": fa},
                {"name": "B", "diameter_mm": cb, "form_mm": fb},
            ],
            "ball_bars": [{"name": "bar", "spheres": ["A", "B"], "length_mm": cl}],
            "planes": [{"name": "plate", "flatness_mm": fl}],
            "uncertainty_k2_mm": {"diameter": u.diameter, "form": u.form,
                                  "length": u.length, "flatness": u.flatness},
            "mpe_mm": {"probing_form": m.probing_form, "probing_size": m.probing_size,
                       "sphere_spacing": m.sphere_spacing, "flatness": m.flatness},
        });
        Artefacts {
            diameters_mm: [da, db],
            length_mm: len,
            certificate,
        }
    }

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

    /// Renders frame `index` of verification scan `scan` at `q_deg` (stripe image only)
    /// with its truth; the noise of its own streams.
    pub fn render_verify_frame(
        &self,
        scan: &VerifyScan,
        scan_index: usize,
        q_deg: &[f64],
        index: usize,
    ) -> Result<ViewRender, SimError> {
        let base_cam = self.base_cam(q_deg)?;
        let scene = scan.world.image_scene(&base_cam, self.laser());
        let lin = self.renderer()?.render(&scene);
        let img = form_image(
            &lin,
            &self.camera,
            &self.cfg.imaging,
            Exposure::Laser,
            self.cfg.seed,
            VERIFY_FRAME_STREAM + 100_000 * scan_index as u64 + index as u64,
        );
        Ok(ViewRender {
            board_image: None,
            board_rgb: None,
            laser_rgb: None,
            laser_image: Some(img),
            circles: vec![],
            stripe: stripe_truth(&scene, &self.camera, self.direction),
            base_cam,
        })
    }

    /// truth.json of a verification scan: the true calibration (as `scan/truth.json`),
    /// `sphere` = sphere A (bars), `spheres` (bars: A and B with centres and diameters),
    /// `plane` (plates: normal towards the sensor and `d_mm`, base frame), `artefact`,
    /// `placement`; without the board's `table` and `plate` (not in these scenes).
    pub fn verify_truth(&self, scan: &VerifyScan) -> Truth {
        let mut t = self.truth(false);
        t.extra.remove("table");
        t.extra.remove("plate");
        t.sphere = scan.spheres.first().copied();
        t.extra.insert("artefact".into(), json!(scan.artefact));
        if !scan.spheres.is_empty() {
            let sph: Vec<Value> = scan
                .spheres
                .iter()
                .zip(["A", "B"])
                .map(|(s, n)| {
                    json!({"name": n, "center_mm": [s.center_mm.x, s.center_mm.y, s.center_mm.z],
                           "diameter_mm": s.diameter_mm})
                })
                .collect();
            t.extra.insert("spheres".into(), Value::Array(sph));
            let l = (scan.spheres[1].center_mm - scan.spheres[0].center_mm).norm();
            t.extra.insert("length_mm".into(), json!(l));
        }
        if let Some(p) = &scan.plane {
            t.extra.insert(
                "plane".into(),
                json!({"normal": [p.normal.x, p.normal.y, p.normal.z], "d_mm": p.d,
                       "flatness_mm": 0.0}),
            );
        }
        t.extra.insert("depth_mm".into(), json!(scan.depth_mm));
        t
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

#[cfg(test)]
mod tests {
    use crate::SimConfig;

    #[test]
    fn verify_knobs_merge_and_validate() {
        let c = SimConfig::hp3_paper()
            .with_overrides(&serde_json::json!({"verify": {"enabled": true, "step_mm": 3.0}}))
            .unwrap();
        assert!(c.verify.enabled && c.verify.step_mm == 3.0);
        assert_eq!(c.verify.bar_positions, 7);
        for (over, knob) in [
            (
                serde_json::json!({"bar_positions": 8}),
                "verify.bar_positions",
            ),
            (
                serde_json::json!({"plate_positions": 4}),
                "verify.plate_positions",
            ),
            (serde_json::json!({"step_mm": 0.0}), "verify.step_mm"),
            (
                serde_json::json!({"sphere_diameter_mm": 95.0}),
                "verify.sphere_diameter_mm",
            ),
            (
                serde_json::json!({"mpe_mm": {"flatness": -1.0}}),
                "verify.mpe_mm.flatness",
            ),
            (serde_json::json!({"ball": 1}), "verify.ball"),
        ] {
            let e = SimConfig::hp3_paper()
                .with_overrides(&serde_json::json!({ "verify": over }))
                .unwrap_err()
                .to_string();
            assert!(e.contains(knob), "{knob}: {e}");
        }
    }
}
