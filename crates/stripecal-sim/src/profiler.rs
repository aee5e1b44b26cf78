//! The profiler mode of the twin (issue 18): a calibrated line PROFILER on the robot's
//! flange measures a reference sphere; the twin renders profile datasets and a scan with
//! known truth (spec/DATASET.md, "A profile dataset (a calibrated line profiler)").
//!
//! ## The profiler
//!
//! The sensor frame `sensor`: x along the laser line, z along the measuring range,
//! y = z x x; the laser plane is `y = 0`. A profile holds `n = round(line_length_mm /
//! spacing_mm)` samples at `x_k = (k - (n - 1) / 2) * spacing_mm` (centred on 0). Each
//! sample is a ray `(x_k, 0, 0) + t (0, 0, 1)`, t > 0 (a parallel-ray model of the
//! measuring range): its value is the sensor z of the FIRST surface hit (the sphere
//! occludes its stand and the table). A hit outside `[z_min_mm, z_max_mm]`, or none, is
//! a gap. Every point of a profile lies in `y = 0` exactly, so a point maps to the base
//! frame as `p_base = T_base_hand(q) * T_hand_sensor * (x, 0, z)`.
//!
//! ## The world (base frame)
//!
//! - The sphere: centre `sphere_center_mm`, diameter `sphere_diameter_mm`.
//! - Its stand: a vertical (base z) cylinder of `stand_diameter_mm` (0: none) under the
//!   centre, from the table up to the centre's height (its part inside the ball is never
//!   seen).
//! - The table: the plane `z = sphere_center_mm.z - stand_height_mm`, normal +z.
//!
//! ## Imperfections (per valid sample, drawn in a fixed order from a stream per profile)
//!
//! - Gaussian noise of `noise_z_mm` on z;
//! - dropouts: with probability `gap_fraction` the point is reported as a gap;
//! - spikes: with probability `spike_fraction` (on the points not dropped) z moves by a
//!   uniform magnitude in `[spike_min_mm, spike_max_mm]` with a random sign.
//!
//! Gaps are written in turn as an empty z, `nan` and the rig's `invalid_z` sentinel
//! (`-inf` instead when `invalid_z` is `null`), so readers meet every kind of gap.
//! With `intensity` a third column holds `round(255 |cos(incidence)|)` (0 for gaps).
//!
//! Poses: [`crate::profiler_poses`]; files: [`crate::profiler_write`].

use nalgebra::{Point3, Vector3};
use serde::{Deserialize, Serialize};

use stripecal::model::geometry::Iso3;

use crate::config::PoseCfg;
use crate::rng::Rng;
use crate::SimError;

/// What rig.json declares as the sphere's diameter (`diameter_declared`): `true` the
/// true diameter, `false` `null` (the calibration estimates it), a number that number
/// (e.g. a wrong one, for failure tests).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum DeclaredDiameter {
    Flag(bool),
    Value(f64),
}

/// The profiler mode's knobs (module docs; the poses' in [`crate::profiler_poses`]).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct ProfilerCfg {
    pub enabled: bool,
    /// Length of the laser line covered by the samples, mm.
    pub line_length_mm: f64,
    /// Distance between samples along x, mm.
    pub spacing_mm: f64,
    /// The measuring range along sensor z, mm: hits outside are gaps.
    pub z_min_mm: f64,
    pub z_max_mm: f64,
    /// One-sigma of the Gaussian noise on z, mm.
    pub noise_z_mm: f64,
    /// Probability of a random dropout per valid point.
    pub gap_fraction: f64,
    /// Probability of a spike per point not dropped.
    pub spike_fraction: f64,
    /// Range of a spike's magnitude, mm (random sign).
    pub spike_min_mm: f64,
    pub spike_max_mm: f64,
    /// The vendor's "no point" sentinel written to rig.json and used for some gaps;
    /// `null`: none.
    pub invalid_z: Option<f64>,
    /// Write a third column `intensity` in the profile files.
    pub intensity: bool,
    pub sphere_diameter_mm: f64,
    /// The sphere's centre in the base frame, mm.
    pub sphere_center_mm: [f64; 3],
    /// Height of the sphere's centre above the table, mm.
    pub stand_height_mm: f64,
    /// Diameter of the stand (a vertical cylinder under the sphere), mm; 0: no stand.
    pub stand_diameter_mm: f64,
    /// rig.json `artefact.diameter_mm`: `true` (the true one), `false` (`null`) or a
    /// number.
    pub diameter_declared: DeclaredDiameter,
    /// The true `T_hand_sensor` (truth.json `hand_cam`).
    pub hand_sensor: PoseCfg,
    /// Number of calibration views (at most [`MAX_VIEWS`]).
    pub views: usize,
    /// Range of the sphere centre's sensor z over the views, mm.
    pub standoff_min_mm: f64,
    pub standoff_max_mm: f64,
    /// The sphere centre's sensor x is uniform in `+-place_max_mm`.
    pub place_max_mm: f64,
    /// The sphere centre's sensor y (the laser plane's offset from the centre):
    /// `|y|` uniform in `[offset_min_frac, offset_max_frac] * R`, the sign alternating.
    pub offset_min_frac: f64,
    pub offset_max_frac: f64,
    /// Tilt of the sensor's z from the nominal (home) direction, uniform in this range,
    /// about a horizontal axis of uniform azimuth, degrees.
    pub tilt_min_deg: f64,
    pub tilt_max_deg: f64,
    /// Rotation about the sensor's own z, uniform in `+-spin_max_deg`.
    pub spin_max_deg: f64,
    /// `none`, `same_standoff`, `same_place` or `same_offset`: that coordinate of the
    /// sphere centre in the sensor frame is the same in every view.
    pub degenerate: String,
    /// With `degenerate`: the coordinate varies uniformly over this range (mm) around its
    /// constant instead (0: exactly constant).
    pub near_degenerate_mm: f64,
    /// Largest joint excursion from `poses.home_q_deg`, degrees (poses beyond are
    /// rejected).
    pub max_joint_delta_deg: f64,
    /// views.csv / scan.csv columns: `joints` (q1..qN) or `flange` (the flange pose the
    /// controller reports: the NOMINAL robot's forward kinematics of the readings).
    pub poses: String,
    /// The pose columns with `poses = "flange"`: a shorthand or a header
    /// (`stripecal::io::PoseColumns::from_spec`).
    pub pose_columns: String,
    /// Scan frames (0: no scan) and their spacing along the laser plane's normal, mm.
    pub scan_frames: usize,
    pub scan_step_mm: f64,
}

/// The most calibration views a profiler twin renders.
pub const MAX_VIEWS: usize = 200;

/// The most scan frames a profiler twin renders.
pub const MAX_SCAN_FRAMES: usize = 10_000;

/// The degenerate modes of `profiler.degenerate`.
pub const DEGENERATE_MODES: [&str; 4] = ["none", "same_standoff", "same_place", "same_offset"];

impl Default for ProfilerCfg {
    fn default() -> Self {
        ProfilerCfg {
            enabled: false,
            line_length_mm: 90.0,
            spacing_mm: 0.03,
            z_min_mm: 150.0,
            z_max_mm: 350.0,
            noise_z_mm: 0.01,
            gap_fraction: 0.02,
            spike_fraction: 0.01,
            spike_min_mm: 0.5,
            spike_max_mm: 3.0,
            invalid_z: Some(-99999.9999),
            intensity: true,
            sphere_diameter_mm: 80.0,
            sphere_center_mm: [480.0, 0.0, 40.0],
            stand_height_mm: 60.0,
            stand_diameter_mm: 20.0,
            diameter_declared: DeclaredDiameter::Flag(true),
            hand_sensor: PoseCfg {
                rotation_vector: [0.04, -0.06, 0.5],
                translation_mm: [12.0, -8.0, 100.0],
            },
            views: 15,
            standoff_min_mm: 200.0,
            standoff_max_mm: 250.0,
            place_max_mm: 15.0,
            offset_min_frac: 0.1,
            offset_max_frac: 0.75,
            tilt_min_deg: 10.0,
            tilt_max_deg: 30.0,
            spin_max_deg: 30.0,
            degenerate: "none".into(),
            near_degenerate_mm: 0.0,
            max_joint_delta_deg: 150.0,
            poses: "joints".into(),
            pose_columns: "quaternion".into(),
            scan_frames: 60,
            scan_step_mm: 1.0,
        }
    }
}

impl ProfilerCfg {
    /// The number of samples of a profile.
    pub fn samples(&self) -> usize {
        (self.line_length_mm / self.spacing_mm).round() as usize
    }

    /// The sphere's radius, mm.
    pub fn radius(&self) -> f64 {
        0.5 * self.sphere_diameter_mm
    }

    /// rig.json's `artefact.diameter_mm`.
    pub fn declared_diameter(&self) -> Option<f64> {
        match self.diameter_declared {
            DeclaredDiameter::Flag(true) => Some(self.sphere_diameter_mm),
            DeclaredDiameter::Flag(false) => None,
            DeclaredDiameter::Value(d) => Some(d),
        }
    }

    /// Whether views.csv carries joint readings (`poses = "joints"`).
    pub fn joints(&self) -> bool {
        self.poses == "joints"
    }

    /// The flange-pose columns (`pose_columns`).
    pub fn pose_columns_model(&self) -> Result<stripecal::io::PoseColumns, SimError> {
        stripecal::io::PoseColumns::from_spec(&[self.pose_columns.as_str()])
            .map_err(|e| SimError::Config(format!("profiler.pose_columns: {e}")))
    }

    /// Checks the knobs; errors name them.
    pub fn validate(&self) -> Result<(), SimError> {
        self.validate_numbers()?;
        self.validate_line()?;
        self.validate_sphere()?;
        self.validate_poses()?;
        self.pose_columns_model()?;
        Ok(())
    }

    /// The lengths and steps that must be positive, the noise, sizes and angles that
    /// must not be negative.
    fn validate_numbers(&self) -> Result<(), SimError> {
        for (k, v) in [
            ("line_length_mm", self.line_length_mm),
            ("spacing_mm", self.spacing_mm),
            ("sphere_diameter_mm", self.sphere_diameter_mm),
            ("stand_height_mm", self.stand_height_mm),
            ("scan_step_mm", self.scan_step_mm),
        ] {
            if !(v.is_finite() && v > 0.0) {
                return bad(k, format!("{v} must be finite and > 0"));
            }
        }
        for (k, v) in [
            ("noise_z_mm", self.noise_z_mm),
            ("spike_min_mm", self.spike_min_mm),
            ("stand_diameter_mm", self.stand_diameter_mm),
            ("near_degenerate_mm", self.near_degenerate_mm),
            ("place_max_mm", self.place_max_mm),
            ("tilt_min_deg", self.tilt_min_deg),
            ("spin_max_deg", self.spin_max_deg),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(k, format!("{v} must be finite and >= 0"));
            }
        }
        Ok(())
    }

    /// The line's sampling, the measuring range and the faults (gaps, spikes, the
    /// invalid-z marker).
    fn validate_line(&self) -> Result<(), SimError> {
        let n = self.samples();
        if !(2..=1_000_000).contains(&n) {
            return bad(
                "spacing_mm",
                format!("{n} samples over the line (expected 2..=1000000)"),
            );
        }
        if !(self.z_min_mm.is_finite()
            && self.z_max_mm.is_finite()
            && self.z_max_mm > self.z_min_mm)
        {
            return bad(
                "z_min_mm",
                format!("[{}, {}] is not a range", self.z_min_mm, self.z_max_mm),
            );
        }
        for (k, v) in [
            ("gap_fraction", self.gap_fraction),
            ("spike_fraction", self.spike_fraction),
        ] {
            if !(0.0..1.0).contains(&v) {
                return bad(k, format!("{v} outside [0, 1)"));
            }
        }
        if !(self.spike_max_mm.is_finite() && self.spike_max_mm >= self.spike_min_mm) {
            return bad(
                "spike_max_mm",
                format!("{} < spike_min_mm {}", self.spike_max_mm, self.spike_min_mm),
            );
        }
        if let Some(v) = self.invalid_z {
            if !v.is_finite() || (self.z_min_mm..=self.z_max_mm).contains(&v) {
                return bad(
                    "invalid_z",
                    format!("{v} must be finite and outside the measuring range"),
                );
            }
        }
        Ok(())
    }

    /// The sphere, its stand and the declared diameter.
    fn validate_sphere(&self) -> Result<(), SimError> {
        if self.sphere_center_mm.iter().any(|x| !x.is_finite()) {
            return bad("sphere_center_mm", "must be finite".into());
        }
        if 0.5 * self.stand_diameter_mm >= self.radius() {
            return bad(
                "stand_diameter_mm",
                format!(
                    "{} must be below the sphere's diameter",
                    self.stand_diameter_mm
                ),
            );
        }
        if let DeclaredDiameter::Value(d) = self.diameter_declared {
            if !(d.is_finite() && d > 0.0) {
                return bad("diameter_declared", format!("{d} must be > 0"));
            }
        }
        Ok(())
    }

    /// The hand-eye, the views' poses and the scan's frames.
    fn validate_poses(&self) -> Result<(), SimError> {
        let h = &self.hand_sensor;
        if h.rotation_vector
            .iter()
            .chain(&h.translation_mm)
            .any(|x| !x.is_finite())
        {
            return bad("hand_sensor", "must be finite".into());
        }
        if self.views == 0 || self.views > MAX_VIEWS {
            return bad("views", format!("{} outside 1..={MAX_VIEWS}", self.views));
        }
        if !(self.standoff_min_mm.is_finite()
            && self.standoff_max_mm.is_finite()
            && self.standoff_max_mm >= self.standoff_min_mm
            && self.standoff_min_mm > self.radius())
        {
            return bad(
                "standoff_min_mm",
                format!(
                    "[{}, {}] must be a range beyond the sphere's radius",
                    self.standoff_min_mm, self.standoff_max_mm
                ),
            );
        }
        if !(0.0 <= self.offset_min_frac
            && self.offset_min_frac <= self.offset_max_frac
            && self.offset_max_frac < 1.0)
        {
            return bad(
                "offset_min_frac",
                format!(
                    "[{}, {}] must lie in [0, 1)",
                    self.offset_min_frac, self.offset_max_frac
                ),
            );
        }
        if !(self.tilt_max_deg.is_finite()
            && self.tilt_max_deg >= self.tilt_min_deg
            && self.tilt_max_deg < 80.0)
        {
            return bad(
                "tilt_max_deg",
                format!(
                    "[{}, {}] must be a range below 80",
                    self.tilt_min_deg, self.tilt_max_deg
                ),
            );
        }
        if !DEGENERATE_MODES.contains(&self.degenerate.as_str()) {
            return bad(
                "degenerate",
                format!(
                    "{:?} (expected one of {DEGENERATE_MODES:?})",
                    self.degenerate
                ),
            );
        }
        if !(self.max_joint_delta_deg.is_finite() && self.max_joint_delta_deg > 0.0) {
            return bad("max_joint_delta_deg", "must be > 0".into());
        }
        if !matches!(self.poses.as_str(), "joints" | "flange") {
            return bad(
                "poses",
                format!("{:?} (expected \"joints\" or \"flange\")", self.poses),
            );
        }
        if self.scan_frames > MAX_SCAN_FRAMES {
            return bad(
                "scan_frames",
                format!("{} > {MAX_SCAN_FRAMES}", self.scan_frames),
            );
        }
        Ok(())
    }
}

/// The error of a bad knob of the profiler section: its name and what is wrong.
fn bad<T>(k: &str, m: String) -> Result<T, SimError> {
    Err(SimError::Config(format!("profiler.{k}: {m}")))
}

/// What a profile ray hits.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Hit {
    Sphere,
    Stand,
    Table,
}

impl Hit {
    pub fn name(self) -> &'static str {
        match self {
            Hit::Sphere => "sphere",
            Hit::Stand => "stand",
            Hit::Table => "table",
        }
    }
}

/// The measured world of a profiler twin, base frame (module docs).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProfilerScene {
    pub center: Vector3<f64>,
    pub radius: f64,
    /// The table plane `z = table_z`.
    pub table_z: f64,
    /// The stand's radius (0: no stand).
    pub stand_radius: f64,
}

impl ProfilerScene {
    /// The scene of the knobs.
    pub fn of(cfg: &ProfilerCfg) -> ProfilerScene {
        let center = Vector3::from(cfg.sphere_center_mm);
        ProfilerScene {
            center,
            radius: cfg.radius(),
            table_z: center.z - cfg.stand_height_mm,
            stand_radius: 0.5 * cfg.stand_diameter_mm,
        }
    }

    /// The first surface the ray `o + t d` (t > 0, `d` unit) hits: `(t, what, unit
    /// normal)`.
    pub fn cast(&self, o: &Vector3<f64>, d: &Vector3<f64>) -> Option<(f64, Hit, Vector3<f64>)> {
        let mut best: Option<(f64, Hit, Vector3<f64>)> = None;
        let mut take = |t: f64, h: Hit, n: Vector3<f64>| {
            if t > 0.0 && best.is_none_or(|(b, _, _)| t < b) {
                best = Some((t, h, n));
            }
        };
        // sphere: |o + t d - c|^2 = R^2, the entry point
        let oc = o - self.center;
        let b = d.dot(&oc);
        let disc = b * b - (oc.norm_squared() - self.radius * self.radius);
        if disc >= 0.0 {
            let t = -b - disc.sqrt();
            take(t, Hit::Sphere, (oc + d * t) / self.radius);
        }
        // stand: the vertical cylinder's outside, between the table and the centre
        if self.stand_radius > 0.0 {
            let (ox, oy) = (o.x - self.center.x, o.y - self.center.y);
            let a = d.x * d.x + d.y * d.y;
            if a > 1e-15 {
                let bb = ox * d.x + oy * d.y;
                let c = ox * ox + oy * oy - self.stand_radius * self.stand_radius;
                let disc = bb * bb - a * c;
                if disc >= 0.0 {
                    let t = (-bb - disc.sqrt()) / a;
                    let z = o.z + t * d.z;
                    if z >= self.table_z && z <= self.center.z {
                        let n = Vector3::new(ox + t * d.x, oy + t * d.y, 0.0) / self.stand_radius;
                        take(t, Hit::Stand, n);
                    }
                }
            }
        }
        // table: z = table_z, seen from above
        if d.z.abs() > 1e-15 && o.z > self.table_z {
            take((self.table_z - o.z) / d.z, Hit::Table, Vector3::z());
        }
        best
    }
}

/// One sample of a profile.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ProfileSample {
    pub x_mm: f64,
    /// The true z and surface when a surface is hit within the measuring range.
    pub truth: Option<(f64, Hit)>,
    /// The reported z (`None`: a gap).
    pub z_mm: Option<f64>,
    /// A random dropout (the point was valid but is reported as a gap).
    pub dropout: bool,
    /// The spike added to z, mm (0 for none).
    pub spike_mm: f64,
    /// `round(255 |cos(incidence)|)`, 0 for gaps.
    pub intensity: u8,
}

/// Renders the profile of a sensor at `base_sensor` (module docs). `rng`: the stream of
/// the noise, dropouts and spikes; `None` renders the noise-free profile (only the
/// measuring range makes gaps).
pub fn render_profile(
    cfg: &ProfilerCfg,
    scene: &ProfilerScene,
    base_sensor: &Iso3,
    mut rng: Option<&mut Rng>,
) -> Vec<ProfileSample> {
    let n = cfg.samples();
    let d = base_sensor.rotation * Vector3::z();
    (0..n)
        .map(|k| {
            let x = (k as f64 - 0.5 * (n - 1) as f64) * cfg.spacing_mm;
            let o = (base_sensor * Point3::new(x, 0.0, 0.0)).coords;
            let hit = scene
                .cast(&o, &d)
                .filter(|(t, _, _)| *t >= cfg.z_min_mm && *t <= cfg.z_max_mm);
            // the same draws for every sample, hit or not (stable streams)
            let draws = rng.as_deref_mut().map(|r| {
                let u: [f64; 4] = std::array::from_fn(|_| r.uniform());
                (u, r.normal())
            });
            let mut s = ProfileSample {
                x_mm: x,
                truth: hit.map(|(t, h, _)| (t, h)),
                z_mm: hit.map(|(t, _, _)| t),
                dropout: false,
                spike_mm: 0.0,
                intensity: hit.map_or(0, |(_, _, nrm)| (255.0 * nrm.dot(&d).abs()).round() as u8),
            };
            if let (Some((t, _, _)), Some((u, g))) = (hit, draws) {
                if u[0] < cfg.gap_fraction {
                    s.dropout = true;
                    s.z_mm = None;
                    s.intensity = 0;
                } else {
                    if u[1] < cfg.spike_fraction {
                        let sign = if u[2] < 0.5 { -1.0 } else { 1.0 };
                        s.spike_mm = sign
                            * (cfg.spike_min_mm + (cfg.spike_max_mm - cfg.spike_min_mm) * u[3]);
                    }
                    s.z_mm = Some(t + cfg.noise_z_mm * g + s.spike_mm);
                }
            }
            s
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;
    use stripecal::model::geometry::iso_from_rotvec;

    fn looking_down(at: Vector3<f64>, height: f64) -> Iso3 {
        // sensor z = -base z: a half turn about base x
        iso_from_rotvec(
            &Vector3::new(std::f64::consts::PI, 0.0, 0.0),
            &(at + Vector3::new(0.0, 0.0, height)),
        )
    }

    #[test]
    fn a_profile_from_above_sees_the_ball_then_the_stand_free_table() {
        let cfg = ProfilerCfg::default();
        let sc = ProfilerScene::of(&cfg);
        let r = sc.radius;
        // the plane 20 mm off the centre: the circle of radius sqrt(R^2 - 400)
        let t = looking_down(sc.center + Vector3::new(0.0, 20.0, 0.0), 220.0);
        let p = render_profile(&cfg, &sc, &t, None);
        assert_eq!(p.len(), 3000);
        assert!((p[0].x_mm + 44.985).abs() < 1e-12 && (p[2999].x_mm - 44.985).abs() < 1e-12);
        let rc = (r * r - 400.0).sqrt();
        for s in &p {
            let (z, h) = s.truth.expect("everything within range from 220 mm");
            match h {
                Hit::Sphere => {
                    assert!(s.x_mm.abs() <= rc + 1e-9);
                    let want = 220.0 - (rc * rc - s.x_mm * s.x_mm).sqrt();
                    assert!((z - want).abs() < 1e-9, "{z} vs {want}");
                }
                Hit::Table => {
                    assert!(s.x_mm.abs() >= rc - 1e-9);
                    assert!((z - (220.0 + cfg.stand_height_mm)).abs() < 1e-9);
                }
                Hit::Stand => panic!("a vertical view never sees the stand's side"),
            }
            assert_eq!(s.z_mm, Some(z));
        }
        // out of the measuring range: a gap
        let far = looking_down(sc.center, 300.0);
        let q = render_profile(&cfg, &sc, &far, None);
        for s in &q {
            if s.x_mm.abs() > r {
                assert_eq!(s.truth, None, "the table at 360 mm is beyond the range");
            } else {
                assert!(matches!(s.truth, Some((_, Hit::Sphere))));
            }
        }
    }

    #[test]
    fn a_tilted_ray_meets_the_stand_first() {
        let cfg = ProfilerCfg::default();
        let sc = ProfilerScene::of(&cfg);
        // a horizontal ray 20 mm below the ball's bottom, towards the stand's axis
        let z = sc.center.z - sc.radius - 5.0;
        let o = Vector3::new(sc.center.x - 100.0, sc.center.y, z);
        let (t, h, n) = sc.cast(&o, &Vector3::x()).unwrap();
        assert_eq!(h, Hit::Stand);
        assert!((t - (100.0 - sc.stand_radius)).abs() < 1e-9);
        assert!((n - -Vector3::x()).norm() < 1e-12);
    }

    #[test]
    fn knobs_are_checked() {
        let mut c = ProfilerCfg::default();
        c.validate().unwrap();
        c.degenerate = "flat".into();
        assert!(c
            .validate()
            .unwrap_err()
            .to_string()
            .contains("profiler.degenerate"));
        let c = ProfilerCfg {
            invalid_z: Some(200.0),
            ..Default::default()
        };
        assert!(c.validate().unwrap_err().to_string().contains("invalid_z"));
        let c = ProfilerCfg {
            offset_max_frac: 1.0,
            ..Default::default()
        };
        assert!(c.validate().is_err());
        let c: ProfilerCfg =
            serde_json::from_value(serde_json::json!({"diameter_declared": 81.0})).unwrap();
        assert_eq!(c.declared_diameter(), Some(81.0));
        let c: ProfilerCfg =
            serde_json::from_value(serde_json::json!({"diameter_declared": false})).unwrap();
        assert_eq!(c.declared_diameter(), None);
    }
}
