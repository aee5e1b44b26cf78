//! A fixed-sensor scan (issue 17): a ball carried under the fixed sensor in steps, as
//! on a conveyor, written as the contract's scan without pose columns (`scan.csv` with
//! the header `image` alone) to `OUT/scan` by [`Twin::write`] in bench mode with
//! `bench.scan.enabled`.
//!
//! The camera frame is the world. The ball (diameter `sphere_diameter_mm`) moves along
//! the conveyor direction `m`: the laser plane's normal with its optical-axis part
//! removed (so the plane sweeps the ball while its depth stays put), in `step_mm` steps,
//! centred where the laser plane meets the line at depth `center_depth_mm` (default:
//! the ball's near cap at the middle of the working range) in the plane y = 0, long
//! enough for the plane to cross the whole ball plus `margin_mm` each side (at most
//! `max_frames` frames, 0: no cap). Nothing else is in the scene (the belt is beyond
//! the depth of view: rays that miss the ball see black). truth.json (in the camera
//! frame): the camera, the laser plane, `sphere` (the ball at frame 0), `conveyor`
//! (`direction`, `step_mm`) and per image `sphere_center_mm` and the stripe truth.

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};
use serde_json::{json, Value};

use stripecal::io;
use stripecal::model::geometry::Iso3;

use crate::imaging::{form_image, Exposure};
use crate::scene::World;
use crate::truth::stripe_truth;
use crate::{SimError, Twin};

/// The noise streams of the scan frames start here.
const FRAME_STREAM: u64 = 2_000_000;

/// Knobs of the fixed-sensor scan (module docs).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct BenchScanCfg {
    pub enabled: bool,
    pub sphere_diameter_mm: f64,
    /// Depth of the ball's centre, mm; `None`: its near cap at the middle of the
    /// working range.
    pub center_depth_mm: Option<f64>,
    pub step_mm: f64,
    pub margin_mm: f64,
    pub max_frames: usize,
}

impl Default for BenchScanCfg {
    fn default() -> Self {
        BenchScanCfg {
            enabled: false,
            sphere_diameter_mm: 25.4,
            center_depth_mm: None,
            step_mm: 0.5,
            margin_mm: 2.0,
            max_frames: 0,
        }
    }
}

impl BenchScanCfg {
    /// Checks the knobs; errors name them.
    pub fn validate(&self) -> Result<(), SimError> {
        let ok = self.sphere_diameter_mm > 0.0
            && self.sphere_diameter_mm.is_finite()
            && self.step_mm > 0.0
            && self.margin_mm >= 0.0
            && self
                .center_depth_mm
                .is_none_or(|z| z.is_finite() && z > 0.0);
        if !ok {
            return Err(SimError::Config(
                "bench.scan: sphere_diameter_mm, step_mm > 0, margin_mm >= 0 and a positive \
                 center_depth_mm expected"
                    .into(),
            ));
        }
        Ok(())
    }
}

impl Twin {
    /// The conveyor scan: the ball's centre (camera frame) per frame, and the conveyor
    /// direction.
    pub fn bench_scan_centers(&self) -> Result<(Vec<Vector3<f64>>, Vector3<f64>), SimError> {
        let sc = &self.cfg.bench.scan;
        sc.validate()?;
        let r = 0.5 * sc.sphere_diameter_mm;
        let [a, b] = self.cfg.working_range_mm;
        let depth = sc.center_depth_mm.unwrap_or(0.5 * (a + b) + r);
        let n = self.laser_plane.normal;
        let m = Vector3::new(n.x, n.y, 0.0);
        if m.norm() < 1e-6 {
            return Err(SimError::Config(
                "bench.scan: the laser plane is perpendicular to the optical axis: no \
                 conveyor direction"
                    .into(),
            ));
        }
        let m = m.normalize();
        let rate = n.dot(&m);
        // the middle: on the laser plane at the given depth, in the plane y = 0 (or x = 0)
        let off = self.laser_plane.d - n.z * depth;
        let mid = if n.x.abs() >= n.y.abs() {
            Vector3::new(off / n.x, 0.0, depth)
        } else {
            Vector3::new(0.0, off / n.y, depth)
        };
        let half = (r + sc.margin_mm) / rate.abs();
        let mut count = (2.0 * half / sc.step_mm).floor() as usize + 1;
        if sc.max_frames > 0 {
            count = count.min(sc.max_frames);
        }
        let start = -0.5 * (count - 1) as f64 * sc.step_mm;
        Ok((
            (0..count)
                .map(|k| mid + m * (start + k as f64 * sc.step_mm))
                .collect(),
            m,
        ))
    }

    /// Writes `out/scan`: the conveyor scan (module docs); returns the folder and its
    /// frames.
    pub fn write_bench_scan(
        &self,
        out: &std::path::Path,
        progress: &mut dyn FnMut(&str, usize, usize),
    ) -> Result<(std::path::PathBuf, usize, usize), SimError> {
        let sc = &self.cfg.bench.scan;
        let (centers, m) = self.bench_scan_centers()?;
        let r = 0.5 * sc.sphere_diameter_mm;
        let dir = out.join("scan");
        let tmp = out.join(format!(".scan.partial-{}", std::process::id()));
        if tmp.exists() {
            std::fs::remove_dir_all(&tmp).map_err(|e| stripecal::Error::io(&tmp, e))?;
        }
        let img_dir = tmp.join("images");
        std::fs::create_dir_all(&img_dir).map_err(|e| stripecal::Error::io(&img_dir, e))?;
        let renderer = self.renderer()?;
        let mut csv = String::from("image\n");
        let mut per_image = Vec::new();
        let mut on_sphere = 0;
        for (k, c) in centers.iter().enumerate() {
            progress("bench scan frames", k, centers.len());
            let world = World {
                table: false,
                spheres: vec![(*c, r)],
                free_plate: None,
                ..self.calib_world.clone()
            };
            let scene = world.image_scene(&Iso3::identity(), self.laser());
            let lin = renderer.render(&scene);
            let img = form_image(
                &lin,
                &self.camera,
                &self.cfg.imaging,
                Exposure::Laser,
                self.cfg.seed,
                FRAME_STREAM + k as u64,
            );
            let name = format!("images/scan_{k:04}.png");
            io::save_gray_png(tmp.join(&name), &img)?;
            csv.push_str(&name);
            csv.push('\n');
            let stripe = stripe_truth(&scene, &self.camera, self.direction);
            on_sphere += stripe.len();
            per_image.push(json!({
                "image": name,
                "sphere_center_mm": [c.x, c.y, c.z],
                "stripe": {"direction": self.direction.name(), "points": stripe},
            }));
        }
        progress("bench scan frames", centers.len(), centers.len());
        let mut rig = self.rig()?;
        rig.robot = None;
        io::write_rig(tmp.join("rig.json"), &rig)?;
        let path = tmp.join("scan.csv");
        std::fs::write(&path, csv).map_err(|e| stripecal::Error::io(&path, e))?;
        let mut truth = self.truth(false);
        truth.robot = None;
        let mut v: Value = serde_json::from_str(&io::truth_to_json(&truth))
            .map_err(|e| SimError::Render(format!("truth.json: {e}")))?;
        if let Some(o) = v.as_object_mut() {
            for key in ["hand_cam", "base_board", "robot", "table", "plate"] {
                o.remove(key);
            }
            o.insert("bench".into(), Value::Bool(true));
            o.insert("frame".into(), json!("cam"));
            o.insert(
                "sphere".into(),
                json!({"center_mm": [centers[0].x, centers[0].y, centers[0].z],
                       "diameter_mm": sc.sphere_diameter_mm}),
            );
            o.insert(
                "conveyor".into(),
                json!({"direction": [m.x, m.y, m.z], "step_mm": sc.step_mm}),
            );
            o.insert("images".into(), Value::Array(per_image));
        }
        let text = serde_json::to_string_pretty(&v).map_err(|e| SimError::Render(e.to_string()))?;
        io::write_atomic(tmp.join("truth.json"), (text + "\n").as_bytes())?;
        if dir.exists() {
            std::fs::remove_dir_all(&dir).map_err(|e| stripecal::Error::io(&dir, e))?;
        }
        std::fs::rename(&tmp, &dir).map_err(|e| stripecal::Error::io(&dir, e))?;
        Ok((dir, centers.len(), on_sphere))
    }
}
