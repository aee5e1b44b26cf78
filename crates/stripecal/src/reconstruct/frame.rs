//! One-frame reconstruction for line software: an image plus joint readings (or a
//! flange pose) in, points appended to a [`ScanPoints`] out, without allocating after the
//! first frame of a given size.

use crate::error::{Error, Result};
use crate::model::geometry::Iso3;
use crate::model::image::AnyView;
use crate::model::kinematics::Robot;
use crate::model::{Calibration, RobotReading, StripeDirection};
use crate::vision::stripe::{StripeExtractor, StripePoint};

use super::triangulate::{check_pose, laser_plane_of};
use super::{at_frame, stripe_direction_from_plane, ReconstructOptions, ScanPoints, Triangulator};

/// One-frame reconstruction for line software (see the module docs). Not `Sync`-shared:
/// use one per thread.
#[derive(Debug, Clone)]
pub struct Reconstructor {
    tri: Triangulator,
    robot: Option<Robot>,
    extractor: StripeExtractor,
    drop_flags: u8,
    stripe: Vec<StripePoint>,
    /// Pixels of the stripe points not dropped by flag, and their stripe indices.
    uv: Vec<[f64; 2]>,
    sel: Vec<u32>,
    /// Indices into `uv` of the triangulated points.
    kept: Vec<u32>,
}

impl Reconstructor {
    /// A reconstructor for a calibration (its robot is used for joint readings).
    pub fn new(calibration: &Calibration, opts: &ReconstructOptions) -> Result<Reconstructor> {
        opts.validate()?;
        let tri = Triangulator::from_calibration(calibration, opts.min_ray_plane_angle_deg)?;
        let mut so = opts.stripe.clone();
        if so.direction == StripeDirection::Auto {
            so.direction =
                stripe_direction_from_plane(&calibration.camera, laser_plane_of(calibration)?);
        }
        if let Some(r) = &calibration.robot {
            r.validate()?;
        }
        Ok(Reconstructor {
            tri,
            robot: calibration.robot.clone(),
            extractor: StripeExtractor::new(so)?,
            drop_flags: opts.drop_flags,
            stripe: Vec::new(),
            uv: Vec::new(),
            sel: Vec::new(),
            kept: Vec::new(),
        })
    }

    /// The stripe direction used.
    pub fn direction(&self) -> StripeDirection {
        self.extractor.options().direction
    }

    /// The triangulator.
    pub fn triangulator(&self) -> &Triangulator {
        &self.tri
    }

    /// `T_base_hand` of a reading (errors name nothing; callers add the frame).
    pub fn base_hand(&self, reading: &RobotReading) -> Result<Iso3> {
        let t = reading.base_hand(self.robot.as_ref())?;
        check_pose(&t)?;
        Ok(t)
    }

    /// Reconstructs one frame taken at encoder readings `q_deg`, appending its points
    /// (tagged `frame`) to `out`. Errors (wrong joint count, NaN readings, an image whose
    /// size is not the calibration's) name the frame and append nothing.
    pub fn frame_joints(
        &mut self,
        img: AnyView<'_>,
        q_deg: &[f64],
        frame: u32,
        out: &mut ScanPoints,
    ) -> Result<usize> {
        let Some(robot) = &self.robot else {
            return Err(at_frame(
                Error::InvalidInput(
                    "joint readings given but the calibration has no robot (DH table)".into(),
                ),
                frame as usize,
                None,
            ));
        };
        let t = robot
            .forward(q_deg)
            .map_err(|e| at_frame(e, frame as usize, None))?;
        self.frame_pose(img, &t, frame, out)
    }

    /// Reconstructs one frame taken at flange pose `T_base_hand`; see
    /// [`Reconstructor::frame_joints`]. Returns the number of points appended.
    pub fn frame_pose(
        &mut self,
        img: AnyView<'_>,
        base_hand: &Iso3,
        frame: u32,
        out: &mut ScanPoints,
    ) -> Result<usize> {
        let cam = self.tri.camera();
        let (w, h) = img.size();
        if w != cam.width as usize || h != cam.height as usize {
            return Err(at_frame(
                Error::InvalidInput(format!(
                    "image is {w} x {h} pixels, the calibrated camera is {} x {}",
                    cam.width, cam.height
                )),
                frame as usize,
                None,
            ));
        }
        check_pose(base_hand).map_err(|e| at_frame(e, frame as usize, None))?;
        self.extractor
            .extract_into(img, &mut self.stripe)
            .map_err(|e| at_frame(e, frame as usize, None))?;
        let Self {
            tri,
            drop_flags,
            stripe,
            uv,
            sel,
            kept,
            ..
        } = self;
        uv.clear();
        sel.clear();
        kept.clear();
        let mut flagged = 0;
        for (i, p) in stripe.iter().enumerate() {
            if p.flags & *drop_flags != 0 {
                flagged += 1;
                continue;
            }
            uv.push([p.u, p.v]);
            sel.push(i as u32);
        }
        let n0 = out.points_mm.len();
        let mut drops = tri.triangulate_into(base_hand, uv, &mut out.points_mm, kept);
        drops.flagged = flagged;
        for &k in kept.iter() {
            let p = &stripe[sel[k as usize] as usize];
            out.frame.push(frame);
            out.u_px.push(p.u);
            out.v_px.push(p.v);
            out.intensity.push(p.peak);
            out.width_px.push(p.width_px);
            out.flags.push(p.flags);
        }
        out.dropped.add(&drops);
        Ok(out.points_mm.len() - n0)
    }

    /// Reconstructs one frame with a [`RobotReading`] (joints or flange pose).
    pub fn frame_reading(
        &mut self,
        img: AnyView<'_>,
        reading: &RobotReading,
        frame: u32,
        out: &mut ScanPoints,
    ) -> Result<usize> {
        match reading {
            RobotReading::Joints(q) => self.frame_joints(img, q, frame, out),
            RobotReading::FlangePose(t) => self.frame_pose(img, t, frame, out),
            // A fixed sensor: the points in the camera frame (`T_base_cam` the identity).
            RobotReading::Fixed => {
                let cam_hand = self.tri.hand_cam().inverse();
                self.frame_pose(img, &cam_hand, frame, out)
            }
        }
    }
}
