//! The curved-surface stripe bias (issue 15): the twin's ball scan reconstructed with the
//! TRUE calibration measures the ball ~+0.005 mm too large; the model-based correction
//! (`stripecal::reconstruct::correct_sphere_bias`) brings it within 0.002 mm, and the
//! sheet thickness it estimates from the stripe widths is the twin's.

use stripecal::model::image::AnyView;
use stripecal::model::RobotReading;
use stripecal::reconstruct::{
    correct_sphere_bias, reconstruct_frames, ReconstructOptions, SphereBiasCorrection,
    StripeBiasOptions,
};
use stripecal::Iso3;
use stripecal_sim::{SimConfig, Twin};

/// One scan's figures.
struct Run {
    truth_diameter: f64,
    sheet_sigma_true: f64,
    frames: usize,
    /// The uncorrected fit's errors (diameter, centre vector).
    d0: f64,
    c0: nalgebra::Vector3<f64>,
    corr: SphereBiasCorrection,
    secs: f64,
}

impl Run {
    fn d1(&self) -> f64 {
        self.corr.fit.diameter_mm - self.truth_diameter
    }

    fn report(&self, label: &str) {
        let c = &self.corr;
        let s = &c.sheet;
        eprintln!(
            "{label}: {} frames, {} points ({} modelled); diameter error {:+.4} -> {:+.4} mm \
             (change {:+.4}, systematic {:.4} [emitter {:.4}, sigmas {:.4}, neglected {:.4}]); \
             centre error {:.4} -> {:.4} mm (change {:.4}, systematic [{:.4} {:.4} {:.4}]); \
             sheet sigma {:.4} +- {:.4} mm (linear {:.4}, truth {:.4}), psf {:.3} +- {:.3} px, \
             width rms {:.3} px over {} points, g {:.1}..{:.1} px/mm; emitter {:?} (est {:?}); {} rounds, {:.2} s",
            self.frames,
            c.modelled.len(),
            c.modelled.iter().filter(|&&m| m).count(),
            self.d0,
            self.d1(),
            c.diameter_change_mm,
            c.diameter_systematic_mm,
            c.diameter_systematic_parts_mm[0],
            c.diameter_systematic_parts_mm[1],
            c.diameter_systematic_parts_mm[2],
            self.c0.norm(),
            (c.fit.center_mm - (c.uncorrected.center_mm - self.c0)).norm(),
            c.center_change_mm.norm(),
            c.center_systematic_mm.x,
            c.center_systematic_mm.y,
            c.center_systematic_mm.z,
            s.sheet_sigma_mm,
            s.sheet_sigma_sd_mm,
            s.sheet_sigma_linear_mm,
            self.sheet_sigma_true,
            s.psf_sigma_px,
            s.psf_sigma_sd_px,
            s.width_rms_px,
            s.points,
            s.g_range[0],
            s.g_range[1],
            c.emitter_cam_mm.as_slice(),
            c.emitter_estimate.map(|e| (e.sd_mm, e.rms_log, e.points)),
            c.rounds,
            self.secs
        );
    }
}

/// Renders every `every`-th frame of the ball scan of `preset` with `overrides`,
/// reconstructs it with the true calibration, fits the sphere and corrects it (sheet
/// sigma, PSF sigma and emitter estimated; studies/stripe_bias runs the same scans with
/// the twin's true ones).
fn run(preset: &str, overrides: serde_json::Value, every: usize) -> Run {
    let cfg = SimConfig::preset(preset)
        .unwrap()
        .with_overrides(&overrides)
        .unwrap();
    let tw = Twin::new(cfg).unwrap();
    let qs: Vec<Vec<f64>> = tw
        .scan_poses()
        .unwrap()
        .into_iter()
        .step_by(every)
        .collect();
    let renders: Vec<_> = qs
        .iter()
        .enumerate()
        .map(|(k, q)| tw.render_scan_frame(q, k).unwrap())
        .collect();
    let imgs: Vec<_> = renders
        .iter()
        .map(|r| r.laser_image.clone().unwrap())
        .collect();
    let views: Vec<AnyView<'_>> = imgs.iter().map(|i| i.view().unwrap()).collect();
    let readings: Vec<RobotReading> = qs.iter().map(|q| RobotReading::Joints(q.clone())).collect();
    let calib = tw.true_calibration();
    let opts = ReconstructOptions::default();
    let sp = reconstruct_frames(&calib, &views, &readings, &opts).unwrap();
    let base_cam: Vec<Iso3> = qs.iter().map(|q| tw.base_cam(q).unwrap()).collect();
    let sphere = tw.sphere.unwrap();
    let t0 = std::time::Instant::now();
    let corr = correct_sphere_bias(
        &sp,
        &base_cam,
        &calib.camera,
        calib.laser_plane.as_ref().unwrap(),
        &StripeBiasOptions {
            stripe: opts.stripe.clone(),
            ..Default::default()
        },
    )
    .unwrap();
    let secs = t0.elapsed().as_secs_f64();
    eprintln!("true emitter {:?}", tw.emitter.as_slice());
    Run {
        truth_diameter: sphere.diameter_mm,
        sheet_sigma_true: tw.cfg.imaging.laser_sigma_mm,
        frames: qs.len(),
        d0: corr.uncorrected.diameter_mm - sphere.diameter_mm,
        c0: corr.uncorrected.center_mm - sphere.center_mm,
        corr,
        secs,
    }
}

/// hp3-paper, every 3rd frame of the scan: the known bias, corrected within 0.002 mm
/// (0.0005 mm with the points seen at grazing angles left out; with them the full scan
/// keeps +0.0010 mm),
/// the centre within 0.002 mm of the truth, the sheet sigma within 15 %.
#[test]
fn ball_bias_is_corrected_on_the_paper_rig() {
    let r = run("hp3-paper", serde_json::json!({"seed": 1}), 3);
    r.report("hp3-paper seed 1");
    let c = &r.corr;
    assert!(
        (0.003..0.0065).contains(&r.d0),
        "uncorrected diameter error {:+.4} mm: the twin's bias changed",
        r.d0
    );
    assert!(
        r.d1().abs() < 0.0005,
        "corrected diameter error {:+.4} mm",
        r.d1()
    );
    let truth_c = c.uncorrected.center_mm - r.c0;
    let dc = (c.fit.center_mm - truth_c).norm();
    assert!(
        dc < 0.002 + r.c0.norm().min(0.0),
        "corrected centre error {dc:.4} mm"
    );
    let s = c.sheet.sheet_sigma_mm;
    assert!(
        (s / r.sheet_sigma_true - 1.0).abs() < 0.15,
        "sheet sigma {s:.4} mm, truth {}",
        r.sheet_sigma_true
    );
    // The systematic standard uncertainty reported covers what remains.
    assert!(
        c.diameter_systematic_mm > 0.0 && c.diameter_systematic_mm < 0.003,
        "{}",
        c.diameter_systematic_mm
    );
    assert!(r.d1().abs() < 2.0 * c.diameter_systematic_mm);
}

/// The emitter moved 25 mm within the plane (towards the camera's optical axis side):
/// the uncorrected bias doubles (+0.010 mm), assuming the emitter at `n d` would leave
/// +0.0056 mm; estimated from the stripe's brightness it is found within 1 mm and the
/// diameter corrected within 0.002 mm, the centre within 0.001 mm (0.0018 mm when the
/// saturated points were modelled as if unclipped).
#[test]
fn moved_emitter_is_estimated_from_the_brightness() {
    let tw = Twin::new(SimConfig::preset("hp3-paper").unwrap()).unwrap();
    let n = tw.laser_plane.normal;
    let w = n.cross(&(nalgebra::Vector3::y() - n * n.y).normalize());
    let e = tw.emitter + w * 25.0;
    let r = run(
        "hp3-paper",
        serde_json::json!({"seed": 1, "imaging": {"laser_emitter_mm": [e.x, e.y, e.z]}}),
        3,
    );
    r.report("hp3-paper seed 1, emitter moved 25 mm");
    assert!(r.d0 > 0.007, "uncorrected diameter error {:+.4} mm", r.d0);
    assert!(
        r.d1().abs() < 0.002,
        "corrected diameter error {:+.4} mm",
        r.d1()
    );
    // The moved emitter lights the ball brighter: most of its stripe points saturate.
    // Modelled as if unclipped they left ~0.002 mm in the centre; they are left out.
    let c = &r.corr;
    assert!(
        c.saturated > c.uncorrected.points / 2,
        "{} saturated of the uncorrected fit's {} inliers",
        c.saturated,
        c.uncorrected.points
    );
    let truth_c = c.uncorrected.center_mm - r.c0;
    let dc = (c.fit.center_mm - truth_c).norm();
    assert!(dc < 0.001, "corrected centre error {dc:.4} mm");
    let est = r.corr.emitter_estimate.expect("emitter estimated");
    let de = (est.emitter_cam_mm - e).norm();
    assert!(de < 1.0, "emitter estimate off by {de:.2} mm");
}
