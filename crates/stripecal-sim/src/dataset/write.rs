//! Writing a dataset: the calibration and scan folders of spec/DATASET.md, rendered
//! view by view, each folder staged under a temporary name and renamed when complete.

use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use super::*;

/// What a written dataset contains.
#[derive(Debug, Clone)]
pub struct DatasetSummary {
    pub calib_dir: PathBuf,
    pub scan_dir: Option<PathBuf>,
    pub views: Vec<PoseInfo>,
    /// Per view: target points imaged (circles fully visible, corners inside the
    /// image), stripe truth points on the board.
    pub view_circles: Vec<usize>,
    pub view_stripe_points: Vec<usize>,
    pub scan_frames: usize,
    pub scan_sphere_points: usize,
    /// The bare-table scan folder (`scan.table`), and its frames.
    pub table_dir: Option<PathBuf>,
    pub table_frames: usize,
    /// The verification folder (`verify.enabled`), and its frames over every scan.
    pub verify_dir: Option<PathBuf>,
    pub verify_frames: usize,
    pub direction: StripeDirection,
    /// The profiler mode's counts (`profiler.enabled`), `None` otherwise.
    pub profiler: Option<crate::profiler_write::ProfilerSummary>,
}

/// One sweep to write as a scan folder: the folder's name, the sweep's poses (encoder
/// readings), the truth.json it starts from and how frame `k` at pose `q` is rendered.
struct Sweep<'a, R> {
    name: &'a str,
    qs: &'a [Vec<f64>],
    truth: Truth,
    render: R,
}

impl Twin {
    /// Renders and writes `out/calib` (and `out/scan` when scans are enabled,
    /// `out/scan_table` with `scan.table`, `out/verify` with `verify.enabled`).
    /// Each folder is written under a temporary name and renamed when complete.
    /// `progress(stage, done, total)` is called on the calling thread.
    pub fn write(
        &self,
        out: &Path,
        progress: &mut dyn FnMut(&str, usize, usize),
    ) -> Result<DatasetSummary, SimError> {
        if self.cfg.profiler.enabled {
            // the profile dataset instead ([`crate::profiler`])
            return self.write_profiler(out, progress);
        }
        if self.cfg.bench.enabled {
            // the bench dataset instead ([`crate::bench`])
            return self.write_bench(out, progress);
        }
        std::fs::create_dir_all(out).map_err(|e| stripecal::Error::io(out, e))?;
        let poses = self.calibration_poses()?;
        let rig = self.rig()?;
        let pose_columns = self.cfg.pose_columns_model()?.unwrap_or_default();
        let (calib_dir, view_circles, view_stripe) =
            self.write_calibration(out, &poses, &rig, &pose_columns, progress)?;
        // --- scan
        let mut scan_dir = None;
        let mut frames_n = 0;
        let mut sphere_pts = 0;
        if self.sphere.is_some() {
            let qs = self.scan_poses()?;
            let sweep = Sweep {
                name: "scan",
                qs: &qs,
                truth: self.truth(true),
                render: |q: &[f64], k| self.render_scan_frame(q, k),
            };
            let (dir, pts) = self.write_sweep(out, sweep, &rig, &pose_columns, progress)?;
            frames_n = qs.len();
            sphere_pts = pts;
            scan_dir = Some(dir);
        }
        // --- the bare table
        let mut table_dir = None;
        let mut table_frames = 0;
        if self.cfg.scan.table {
            let qs = self.table_scan_poses()?;
            let sweep = Sweep {
                name: "scan_table",
                qs: &qs,
                truth: self.truth(true),
                render: |q: &[f64], k| self.render_table_frame(q, k),
            };
            let (dir, _) = self.write_sweep(out, sweep, &rig, &pose_columns, progress)?;
            table_frames = qs.len();
            table_dir = Some(dir);
        }
        // --- verification artefacts
        let mut verify_dir = None;
        let mut verify_frames = 0;
        if self.cfg.verify.enabled {
            let (dir, n) = self.write_verify(out, &rig, &pose_columns, progress)?;
            verify_dir = Some(dir);
            verify_frames = n;
        }
        Ok(DatasetSummary {
            calib_dir,
            scan_dir,
            views: poses,
            view_circles,
            view_stripe_points: view_stripe,
            scan_frames: frames_n,
            scan_sphere_points: sphere_pts,
            table_dir,
            table_frames,
            verify_dir,
            verify_frames,
            direction: self.direction,
            profiler: None,
        })
    }

    /// Writes `out/calib` (rendered view by view, staged and renamed when complete);
    /// returns the folder and per view the target points imaged and the stripe truth
    /// points on the board.
    fn write_calibration(
        &self,
        out: &Path,
        poses: &[PoseInfo],
        rig: &Rig,
        pose_columns: &io::PoseColumns,
        progress: &mut dyn FnMut(&str, usize, usize),
    ) -> Result<(PathBuf, Vec<usize>, Vec<usize>), SimError> {
        let calib_dir = out.join("calib");
        let tmp = staging_dir(out, "calib")?;
        let mut views = Vec::new();
        let mut per_image = Vec::new();
        let mut view_circles = Vec::new();
        let mut view_stripe = Vec::new();
        for (i, pose) in poses.iter().enumerate() {
            progress("calibration views", i, poses.len());
            let r = self.render_view(&pose.q_deg, i)?;
            let board_name = format!("images/view_{i:03}_board.png");
            let laser_name = if self.cfg.imaging.single_image {
                board_name.clone()
            } else {
                format!("images/view_{i:03}_laser.png")
            };
            match (&r.board_rgb, &r.board_image) {
                (Some(c), _) => io::save_rgb_png(tmp.join(&board_name), c)?,
                (None, Some(b)) => io::save_gray_png(tmp.join(&board_name), b)?,
                (None, None) => {}
            }
            match (&r.laser_rgb, &r.laser_image) {
                (Some(c), _) => io::save_rgb_png(tmp.join(&laser_name), c)?,
                (None, Some(l)) => io::save_gray_png(tmp.join(&laser_name), l)?,
                (None, None) => {}
            }
            views.push(View {
                line: i + 2,
                board_image: board_name.clone().into(),
                laser_image: Some(laser_name.clone().into()),
                reading: self.reading(&self.reported_q(i, &pose.q_deg))?,
            });
            view_circles.push(r.circles.len());
            view_stripe.push(r.stripe.iter().filter(|p| p.surface == "board").count());
            let mut entry = json!({
                "board_image": board_name,
                "laser_image": laser_name,
                "q_deg": pose.q_deg,
                "standoff_mm": pose.standoff_mm,
                "tilt_deg": pose.tilt_deg,
                "base_cam": pose_cfg(&r.base_cam),
                "circles": r.circles,
                "stripe": stripe_json(&r.stripe, self.direction, false),
            });
            if self.cfg.poses.reading_noise_deg > 0.0 {
                entry["q_reading_deg"] = json!(self.reported_q(i, &pose.q_deg));
            }
            per_image.push(entry);
        }
        progress("calibration views", poses.len(), poses.len());
        io::write_rig(tmp.join("rig.json"), rig)?;
        io::write_views_csv_with(tmp.join("views.csv"), &views, pose_columns)?;
        let mut truth = self.truth(false);
        truth.extra.insert("images".into(), Value::Array(per_image));
        io::write_truth(tmp.join("truth.json"), &truth)?;
        replace_dir(&tmp, &calib_dir)?;
        Ok((calib_dir, view_circles, view_stripe))
    }

    /// Writes `out/verify`: one scan folder per position of [`Twin::verify_scans`]
    /// (`bar_1`.., `plate_1`..), `artefacts.json` (the certificate) and `verify.csv`
    /// (header `scan,artefact`: each folder and the artefacts.json name it measures);
    /// returns the folder and the frames written.
    fn write_verify(
        &self,
        out: &Path,
        rig: &Rig,
        pose_columns: &io::PoseColumns,
        progress: &mut dyn FnMut(&str, usize, usize),
    ) -> Result<(PathBuf, usize), SimError> {
        let scans = self.verify_scans()?;
        let dir = out.join("verify");
        let tmp = out.join(format!(".verify.partial-{}", std::process::id()));
        if tmp.exists() {
            std::fs::remove_dir_all(&tmp).map_err(|e| stripecal::Error::io(&tmp, e))?;
        }
        std::fs::create_dir_all(&tmp).map_err(|e| stripecal::Error::io(&tmp, e))?;
        let mut frames = 0;
        let mut manifest = String::from("scan,artefact\n");
        for (i, scan) in scans.iter().enumerate() {
            let sweep = Sweep {
                name: &scan.name,
                qs: &scan.poses,
                truth: self.verify_truth(scan),
                render: |q: &[f64], k| self.render_verify_frame(scan, i, q, k),
            };
            self.write_sweep(&tmp, sweep, rig, pose_columns, progress)?;
            frames += scan.poses.len();
            manifest.push_str(&format!("{},{}\n", scan.name, scan.artefact));
        }
        let art = self.verify_artefacts();
        let path = tmp.join("artefacts.json");
        let text = serde_json::to_string_pretty(&art.certificate)
            .map_err(|e| SimError::Render(e.to_string()))?;
        std::fs::write(&path, text + "\n").map_err(|e| stripecal::Error::io(&path, e))?;
        let path = tmp.join("verify.csv");
        std::fs::write(&path, manifest).map_err(|e| stripecal::Error::io(&path, e))?;
        replace_dir(&tmp, &dir)?;
        Ok((dir, frames))
    }

    /// Writes the sweep `qs` as the scan folder `out/name` (rig.json, scan.csv,
    /// images/, `truth` with the per-image stripe truth added); returns the folder and
    /// the stripe points on spheres.
    fn write_sweep(
        &self,
        out: &Path,
        sweep: Sweep<impl Fn(&[f64], usize) -> Result<ViewRender, SimError>>,
        rig: &Rig,
        pose_columns: &io::PoseColumns,
        progress: &mut dyn FnMut(&str, usize, usize),
    ) -> Result<(PathBuf, usize), SimError> {
        let Sweep {
            name,
            qs,
            mut truth,
            render,
        } = sweep;
        let verify_stage;
        let stage = match name {
            "scan" => "scan frames",
            "scan_table" => "table scan frames",
            _ => {
                verify_stage = format!("verify {name} frames");
                verify_stage.as_str()
            }
        };
        let dir = out.join(name);
        let tmp = staging_dir(out, name)?;
        let mut frames = Vec::new();
        let mut per_image = Vec::new();
        let mut sphere_pts = 0;
        for (k, q) in qs.iter().enumerate() {
            progress(stage, k, qs.len());
            let r = render(q, k)?;
            let img_name = format!("images/scan_{k:04}.png");
            match (&r.laser_rgb, &r.laser_image) {
                (Some(c), _) => io::save_rgb_png(tmp.join(&img_name), c)?,
                (None, Some(img)) => io::save_gray_png(tmp.join(&img_name), img)?,
                (None, None) => {}
            }
            sphere_pts += r.stripe.iter().filter(|p| p.surface == "sphere").count();
            frames.push(ScanFrame {
                line: k + 2,
                image: img_name.clone().into(),
                reading: self.reading(q)?,
            });
            per_image.push(
                json!({"image": img_name, "stripe": stripe_json(&r.stripe, self.direction, true)}),
            );
        }
        progress(stage, qs.len(), qs.len());
        io::write_rig(tmp.join("rig.json"), rig)?;
        io::write_scan_csv_with(tmp.join("scan.csv"), &frames, pose_columns)?;
        truth.extra.insert("images".into(), Value::Array(per_image));
        io::write_truth(tmp.join("truth.json"), &truth)?;
        replace_dir(&tmp, &dir)?;
        Ok((dir, sphere_pts))
    }
}

/// Stripe truth as JSON. `compact` (scans): `[u, v, surface, incidence_deg, view_deg,
/// edge_mm]` rows; otherwise one object per point.
fn stripe_json(pts: &[StripePointTruth], dir: StripeDirection, compact: bool) -> Value {
    let r9 = |x: f64| (x * 1e9).round() / 1e9;
    let r3 = |x: f64| (x * 1e3).round() / 1e3;
    if compact {
        let rows: Vec<Value> = pts
            .iter()
            .map(|p| {
                json!([
                    r9(p.u),
                    r9(p.v),
                    p.surface,
                    r3(p.incidence_deg),
                    r3(p.view_deg),
                    r3(p.edge_mm)
                ])
            })
            .collect();
        json!({"direction": dir.name(), "columns": ["u", "v", "surface", "incidence_deg", "view_deg", "edge_mm"], "points": rows})
    } else {
        json!({"direction": dir.name(), "points": pts})
    }
}

/// An empty staging folder `out/.name.partial-<pid>` with an empty `images` sub-folder.
fn staging_dir(out: &Path, name: &str) -> Result<PathBuf, SimError> {
    let tmp = out.join(format!(".{name}.partial-{}", std::process::id()));
    if tmp.exists() {
        std::fs::remove_dir_all(&tmp).map_err(|e| stripecal::Error::io(&tmp, e))?;
    }
    let img_dir = tmp.join("images");
    std::fs::create_dir_all(&img_dir).map_err(|e| stripecal::Error::io(&img_dir, e))?;
    Ok(tmp)
}

fn replace_dir(tmp: &Path, target: &Path) -> Result<(), SimError> {
    if target.exists() {
        std::fs::remove_dir_all(target).map_err(|e| stripecal::Error::io(target, e))?;
    }
    std::fs::rename(tmp, target).map_err(|e| stripecal::Error::io(target, e))?;
    Ok(())
}
