//! A scan of the bare table (`scan.table`): a straight sweep like the ball scan's, at
//! the home pose's orientation, over a patch of table `scan.table_offset_mm` from the
//! board centre (away from the board and the ball), so every stripe point lies on the
//! table and the robot is somewhere else in its workspace than for the calibration
//! views. Written to `scan_table/` in the format of `scan/`; its truth is the table
//! plane of truth.json ([`crate::surface`]).

use nalgebra::{Point3, Vector3};

use crate::dataset::{Twin, ViewRender};
use crate::imaging::{form_image, Exposure};
use crate::truth::stripe_truth;
use crate::SimError;

/// Default `scan.table_offset_mm`: 120 mm from the board centre along the board's -y,
/// the side opposite the presets' ball (at +90 mm).
pub const DEFAULT_TABLE_OFFSET_MM: [f64; 2] = [0.0, -120.0];

/// First noise stream of the table frames (the ball scan's start at 1_000_000).
const TABLE_FRAME_STREAM: u64 = 2_000_000;

impl Twin {
    /// Encoder readings of the table sweep (empty unless `scan.table`): the sweep of the
    /// ball scan's length (the ball's diameter plus margins, at most `scan.max_frames`
    /// frames) with the table at the middle of `working_range_mm` along the optical axis.
    pub fn table_scan_poses(&self) -> Result<Vec<Vec<f64>>, SimError> {
        let sc = &self.cfg.scan;
        if !sc.table {
            return Ok(vec![]);
        }
        let home = &self.cfg.poses.home_q_deg;
        let rot = self.base_cam(home)?.rotation;
        let up = self.base_board.rotation * -Vector3::z();
        let ctr = crate::target::points_center(&self.board);
        let point = (self.base_board
            * Point3::new(
                ctr.x + sc.table_offset_mm[0],
                ctr.y + sc.table_offset_mm[1],
                self.cfg.board.plate_thickness_mm,
            ))
        .coords;
        let (sweep, rate) = self.table_sweep(&rot, &up)?;
        let depth = 0.5 * (self.cfg.working_range_mm[0] + self.cfg.working_range_mm[1]);
        let origin = crate::poses::scan_origin(
            &rot,
            &self.laser_plane.normal,
            self.laser_plane.d,
            &point,
            &point,
            depth,
            &sweep,
        )
        .ok_or_else(|| SimError::Poses("cannot place the table sweep".into()))?;
        self.sweep_poses(&origin, &sweep, &rot, rate, "table scan")
    }

    /// Renders table scan frame `index` at `q_deg` (stripe image only) with its truth;
    /// the world of the ball scan, the noise of its own streams.
    pub fn render_table_frame(&self, q_deg: &[f64], index: usize) -> Result<ViewRender, SimError> {
        let (lin, scene) = self.render_linear(q_deg, true)?;
        let img = form_image(
            &lin,
            &self.camera,
            &self.cfg.imaging,
            Exposure::Laser,
            self.cfg.seed,
            TABLE_FRAME_STREAM + index as u64,
        );
        Ok(ViewRender {
            board_image: None,
            board_rgb: None,
            laser_rgb: None,
            laser_image: Some(img),
            circles: vec![],
            stripe: stripe_truth(&scene, &self.camera, self.direction),
            base_cam: self.base_cam(q_deg)?,
        })
    }

    /// The exact stripe points (base frame) of a scan frame at `q_deg` in the scan's
    /// world (the ball if scans are on, the plate, the table), with each point's surface
    /// (`"table"`, `"sphere"`, `"board"`...): the laser sheet meeting the true surfaces
    /// where the camera sees it, without rendering.
    pub fn exact_scan_points(
        &self,
        q_deg: &[f64],
    ) -> Result<Vec<(Vector3<f64>, &'static str)>, SimError> {
        let scene = self.scene(q_deg, true)?;
        let base_cam = self.base_cam(q_deg)?;
        Ok(stripe_truth(&scene, &self.camera, self.direction)
            .into_iter()
            .map(|p| {
                (
                    (base_cam * Point3::from(Vector3::from(p.p_cam))).coords,
                    p.surface,
                )
            })
            .collect())
    }
}
