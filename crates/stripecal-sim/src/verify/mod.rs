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
//!
//! This file draws the artefacts and renders the frames; `config.rs` holds the knobs,
//! `placements.rs` the positions and `scans.rs` the sweeps' poses and their checks.

use nalgebra::{Point3, Rotation3, Unit, UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use stripecal::model::geometry::{iso_from_parts, Iso3, Plane};
use stripecal::model::kinematics::IkOptions;
use stripecal::model::{Sphere, Truth};

use crate::dataset::{Twin, ViewRender};

mod config;
mod placements;
mod scans;

use crate::imaging::{form_image, Exposure};
use crate::scene::{FreePlate, World};
use crate::truth::stripe_truth;
use crate::SimError;
pub use config::{MpeCfg, UncertaintyCfg, VerifyCfg};
pub use placements::{BarPlacement, PlatePlacement, BAR_PLACEMENTS, PLATE_PLACEMENTS};

/// The random stream of the artefacts' deviations and certificate errors.
pub const VERIFY_STREAM: u64 = 0x7665_7269_6679;
/// First noise stream of the verification frames (scan `i`, frame `k`:
/// `VERIFY_FRAME_STREAM + 100_000 i + k`).
const VERIFY_FRAME_STREAM: u64 = 3_000_000;
/// Depth of the reference point along the home pose's optical axis, mm.
const REFERENCE_DEPTH_MM: f64 = 105.0;

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
