//! Rendering and writing the bench dataset ([`crate::bench`]) and, with
//! `bench.scan.enabled`, the fixed-sensor scan `OUT/scan` ([`crate::bench_scan`]):
//! `OUT/calib` with
//! rig.json (no robot), views.csv (header `board_image,laser_image`), images/ and
//! truth.json (the true camera and laser plane, no `hand_cam`, `base_board` or robot;
//! per image the true `cam_board`, `sag_mm`, the bend, the floor, the imaged target
//! points and the stripe), staged and renamed when complete.

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use stripecal::io;
use stripecal::model::image::{AnyGray, AnyRgb};

use crate::bench::BenchView;
use crate::config::pose_cfg;
use crate::imaging::{form_image, Exposure};
use crate::poses::PoseInfo;
use crate::truth::{stripe_truth, target_truth, PointTruth, StripePointTruth};
use crate::{DatasetSummary, SimError, Twin};

/// One rendered bench view.
pub struct BenchRender {
    pub board_image: AnyGray,
    pub laser_image: AnyGray,
    /// With `imaging.colour`: the RGB images (`board_image`, `laser_image` their BT.601
    /// gray).
    pub board_rgb: Option<AnyRgb>,
    pub laser_rgb: Option<AnyRgb>,
    /// Imaged target points ([`target_truth`], on the bent sheet for a bent view).
    pub circles: Vec<PointTruth>,
    /// The true stripe centre line (board and floor; the backdrop is dropped).
    pub stripe: Vec<StripePointTruth>,
}

impl Twin {
    /// Renders bench view `index`: the board image (laser off) and the laser image.
    pub fn render_bench_view(&self, v: &BenchView, index: usize) -> Result<BenchRender, SimError> {
        let r = self.renderer()?;
        let im = &self.cfg.imaging;
        let seed = self.cfg.seed;
        let scene = self.bench_scene(v, true);
        let lin = r.render(&scene);
        let s = 3 * index as u64;
        let (board_image, board_rgb, laser_image, laser_rgb) = if im.colour {
            // Each channel rendered with its own reflectances where they differ from the
            // gray ones (as the robot views, [`Twin::render_view`]).
            let board_cam = v.cam_board.inverse();
            let base = self.bench_world(&board_cam, v.floor);
            let rgb = self.channel_renders(&base, lin, |w| {
                let sc = w.image_scene(&board_cam, self.laser());
                match v.bow {
                    Some(b) => sc.with_bow(b),
                    None => sc,
                }
            })?;
            let (bg, bc) = self.expose(&rgb[0], Some(&rgb), Exposure::Board, s)?;
            let (lg, lc) = self.expose(&rgb[0], Some(&rgb), Exposure::Laser, s + 1)?;
            (bg, bc, lg, lc)
        } else {
            (
                form_image(&lin, &self.camera, im, Exposure::Board, seed, s),
                None,
                form_image(&lin, &self.camera, im, Exposure::Laser, seed, s + 1),
                None,
            )
        };
        let stripe = stripe_truth(&scene, &self.camera, self.direction)
            .into_iter()
            .filter(|p| p.surface != "table")
            .collect();
        Ok(BenchRender {
            board_image,
            laser_image,
            board_rgb,
            laser_rgb,
            circles: target_truth(&scene, &self.camera, 0.0),
            stripe,
        })
    }

    /// Writes the bench dataset to `out/calib` (module docs).
    pub fn write_bench(
        &self,
        out: &Path,
        progress: &mut dyn FnMut(&str, usize, usize),
    ) -> Result<DatasetSummary, SimError> {
        std::fs::create_dir_all(out).map_err(|e| stripecal::Error::io(out, e))?;
        let views = self.bench_views()?;
        let calib_dir = out.join("calib");
        let tmp = out.join(format!(".calib.partial-{}", std::process::id()));
        if tmp.exists() {
            std::fs::remove_dir_all(&tmp).map_err(|e| stripecal::Error::io(&tmp, e))?;
        }
        let img_dir = tmp.join("images");
        std::fs::create_dir_all(&img_dir).map_err(|e| stripecal::Error::io(&img_dir, e))?;
        let mut csv = String::from("board_image,laser_image\n");
        let mut per_image = Vec::new();
        let mut infos = Vec::new();
        let mut view_circles = Vec::new();
        let mut view_stripe = Vec::new();
        for (i, v) in views.iter().enumerate() {
            progress("bench views", i, views.len());
            let r = self.render_bench_view(v, i)?;
            let board_name = format!("images/view_{i:03}_board.png");
            let laser_name = format!("images/view_{i:03}_laser.png");
            match &r.board_rgb {
                Some(c) => io::save_rgb_png(tmp.join(&board_name), c)?,
                None => io::save_gray_png(tmp.join(&board_name), &r.board_image)?,
            }
            match &r.laser_rgb {
                Some(c) => io::save_rgb_png(tmp.join(&laser_name), c)?,
                None => io::save_gray_png(tmp.join(&laser_name), &r.laser_image)?,
            }
            csv.push_str(&format!("{board_name},{laser_name}\n"));
            let on_board = r.stripe.iter().filter(|p| p.surface == "board").count();
            view_circles.push(r.circles.len());
            view_stripe.push(on_board);
            infos.push(PoseInfo {
                q_deg: vec![],
                standoff_mm: v.standoff_mm,
                tilt_deg: v.tilt_deg,
                stripe_chord_mm: 0.0,
            });
            per_image.push(json!({
                "board_image": board_name,
                "laser_image": laser_name,
                "cam_board": pose_cfg(&v.cam_board),
                "standoff_mm": v.standoff_mm,
                "tilt_deg": v.tilt_deg,
                "partial": v.partial,
                "sag_mm": v.bow.map_or(0.0, |b| b.sag_mm),
                "bow": v.bow.map(|b| json!({
                    "sag_mm": b.sag_mm,
                    "axis_deg": self.cfg.bench.bow.axis_deg,
                    "across": b.u,
                    "center_mm": b.center,
                    "width_mm": b.width_mm,
                })),
                "floor": v.floor.map(|(n, d)| json!({"normal": [n.x, n.y, n.z], "d_mm": d})),
                "circles": r.circles,
                "stripe": {"direction": self.direction.name(), "points": r.stripe},
            }));
        }
        progress("bench views", views.len(), views.len());
        let mut rig = self.rig()?;
        rig.robot = None;
        io::write_rig(tmp.join("rig.json"), &rig)?;
        let path = tmp.join("views.csv");
        std::fs::write(&path, csv).map_err(|e| stripecal::Error::io(&path, e))?;
        write_bench_truth(&tmp.join("truth.json"), self, Value::Array(per_image))?;
        if calib_dir.exists() {
            std::fs::remove_dir_all(&calib_dir).map_err(|e| stripecal::Error::io(&calib_dir, e))?;
        }
        std::fs::rename(&tmp, &calib_dir).map_err(|e| stripecal::Error::io(&calib_dir, e))?;
        let (scan_dir, scan_frames, scan_sphere_points) = if self.cfg.bench.scan.enabled {
            let (d, n, p) = self.write_bench_scan(out, progress)?;
            (Some(d), n, p)
        } else {
            (None, 0, 0)
        };
        Ok(DatasetSummary {
            calib_dir,
            scan_dir,
            views: infos,
            view_circles,
            view_stripe_points: view_stripe,
            scan_frames,
            scan_sphere_points,
            table_dir: None,
            table_frames: 0,
            verify_dir: None,
            verify_frames: 0,
            direction: self.direction,
            profiler: None,
        })
    }
}

/// truth.json of a bench dataset: the twin's truth without `hand_cam`, `base_board`,
/// `robot`, `table` and `plate` (the robot cell's), with `"bench": true` and `images`.
fn write_bench_truth(path: &PathBuf, twin: &Twin, images: Value) -> Result<(), SimError> {
    let mut truth = twin.truth(false);
    truth.robot = None;
    let text = io::truth_to_json(&truth);
    let mut v: Value =
        serde_json::from_str(&text).map_err(|e| SimError::Render(format!("truth.json: {e}")))?;
    if let Some(m) = v.as_object_mut() {
        for k in ["hand_cam", "base_board", "robot", "table", "plate"] {
            m.remove(k);
        }
        m.insert("bench".into(), Value::Bool(true));
        m.insert("images".into(), images);
    }
    let text = serde_json::to_string_pretty(&v).map_err(|e| SimError::Render(e.to_string()))?;
    io::write_atomic(path, (text + "\n").as_bytes())?;
    Ok(())
}
