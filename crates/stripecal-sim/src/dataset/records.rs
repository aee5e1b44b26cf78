//! The twin's records: rig.json's rig, truth.json's true parameters, the exact
//! observations and the true calibration, and observations with noise added.

use super::*;

impl Twin {
    /// The rig description written to rig.json (nominal robot).
    pub fn rig(&self) -> Result<Rig, SimError> {
        Ok(Rig {
            width: self.camera.width,
            height: self.camera.height,
            distortion_model: DistortionModel::from_name(&self.cfg.camera.distortion_model)?,
            board: self.board.clone(),
            robot: Some(self.robot_nominal.clone()),
            stripe_direction: StripeDirection::from_name(&self.cfg.stripe_direction)?,
            stripe_channel: self.cfg.stripe_channel_model()?,
        })
    }

    /// The true parameters as a Truth (no per-image keys).
    pub fn truth(&self, with_sphere: bool) -> Truth {
        let mut extra = serde_json::Map::new();
        extra.insert(
            "laser_emitter_mm".into(),
            json!([self.emitter.x, self.emitter.y, self.emitter.z]),
        );
        extra.insert("stripe_direction".into(), json!(self.direction.name()));
        extra.insert("table".into(), self.table_plane().to_json());
        extra.insert("plate".into(), self.plate_json());
        let mut cfg = serde_json::to_value(&self.cfg).unwrap_or(Value::Null);
        if !self.cfg.verify.enabled {
            // off: truth.json as before the knobs existed
            if let Some(m) = cfg.as_object_mut() {
                m.remove("verify");
            }
        }
        if !self.cfg.bench.enabled {
            // off: truth.json as before the bench mode existed
            if let Some(m) = cfg.as_object_mut() {
                m.remove("bench");
            }
        }
        if !self.cfg.profiler.enabled {
            // off: truth.json as before the profiler mode existed
            if let Some(m) = cfg.as_object_mut() {
                m.remove("profiler");
            }
        }
        if self.cfg.imaging.reflection_ratio == 0.0 {
            // no reflection: truth.json as before the knob existed
            if let Some(im) = cfg
                .as_object_mut()
                .and_then(|m| m.get_mut("imaging"))
                .and_then(|v| v.as_object_mut())
            {
                for k in crate::config::ImagingCfg::REFLECTION_KNOBS {
                    im.remove(k);
                }
            }
        }
        if !self.cfg.imaging.colour && self.cfg.stripe_channel.is_none() {
            // gray: truth.json as before the colour knobs existed
            if let Some(m) = cfg.as_object_mut() {
                m.remove("stripe_channel");
                if let Some(im) = m.get_mut("imaging").and_then(|v| v.as_object_mut()) {
                    for k in crate::config::ImagingCfg::COLOUR_KNOBS {
                        im.remove(k);
                    }
                }
            }
        }
        extra.insert("sim_config".into(), cfg);
        Truth {
            camera: self.camera.clone(),
            laser_plane: self.laser_plane,
            hand_cam: self.hand_cam,
            base_board: self.base_board,
            robot: Some(self.robot_true.clone()),
            sphere: if with_sphere { self.sphere } else { None },
            working_range_mm: Some(self.cfg.working_range_mm),
            extra,
        }
    }

    /// The exact observations of the calibration poses, as a detector would report them
    /// with no error: imaged-circle centres (area centroids of the projected outlines),
    /// stripe points on the board, and `T_base_hand` of the TRUE robot at the reported
    /// readings ([`Self::reported_q`]: the true ones unless `poses.reading_noise_deg`).
    /// For tests and benchmarks of the calibration from points.
    pub fn exact_observations(&self) -> Result<Vec<stripecal::calib::ViewObs>, SimError> {
        use stripecal::calib::{CircleObs, ViewObs};
        let mut out = Vec::new();
        for (i, p) in self.calibration_poses()?.iter().enumerate() {
            let scene = self.scene(&p.q_deg, false)?;
            let circles = target_truth(&scene, &self.camera, 0.0)
                .iter()
                .map(|c| CircleObs {
                    row: c.row,
                    col: c.col,
                    u: c.u,
                    v: c.v,
                })
                .collect();
            let stripe = stripe_truth(&scene, &self.camera, self.direction)
                .into_iter()
                .filter(|s| s.surface == "board")
                .map(|s| [s.u, s.v])
                .collect();
            out.push(ViewObs {
                view: i,
                circles,
                stripe,
                reading: Some(RobotReading::Joints(self.reported_q(i, &p.q_deg))),
                base_hand: Some(self.robot_true.forward(&self.reported_q(i, &p.q_deg))?),
                alternatives: Vec::new(),
                stripe_shape: None,
            });
        }
        Ok(out)
    }

    /// A calibration holding the TRUE parameters (for tests that reconstruct with truth).
    pub fn true_calibration(&self) -> Calibration {
        Calibration {
            camera: self.camera.clone(),
            laser_plane: Some(self.laser_plane),
            mount: stripecal::model::Mount::Robot,
            hand_cam: self.hand_cam,
            base_board: self.base_board,
            robot: Some(self.robot_true.clone()),
            quality: Default::default(),
            uncertainty: Default::default(),
            covariance: None,
            records: Default::default(),
            extra: Default::default(),
        }
    }
}

/// `views` with Gaussian noise of `circle_px` added to each circle-centre coordinate and
/// `stripe_px` to each stripe-point coordinate, drawn from `rng` view by view (circles,
/// then stripe points; a zero sigma draws nothing). For tests and benchmarks of the
/// calibration from points (with [`Twin::exact_observations`]).
pub fn noisy_observations(
    views: &[stripecal::calib::ViewObs],
    circle_px: f64,
    stripe_px: f64,
    rng: &mut crate::rng::Rng,
) -> Vec<stripecal::calib::ViewObs> {
    use stripecal::calib::{CircleObs, ViewObs};
    views
        .iter()
        .map(|v| {
            let circles = if circle_px == 0.0 {
                v.circles.clone()
            } else {
                v.circles
                    .iter()
                    .map(|c| CircleObs {
                        u: c.u + circle_px * rng.normal(),
                        v: c.v + circle_px * rng.normal(),
                        ..*c
                    })
                    .collect()
            };
            let stripe = if stripe_px == 0.0 {
                v.stripe.clone()
            } else {
                v.stripe
                    .iter()
                    .map(|p| {
                        [
                            p[0] + stripe_px * rng.normal(),
                            p[1] + stripe_px * rng.normal(),
                        ]
                    })
                    .collect()
            };
            ViewObs {
                circles,
                stripe,
                ..v.clone()
            }
        })
        .collect()
}
