//! The sphere stripe-bias studies' shared parts: a ball scan of the twin reconstructed
//! with the TRUE calibration and corrected ([`run`]), and a point's leverage on the
//! fitted diameter ([`radial_row`], [`DiameterLeverage`]). Formerly in the twin's
//! integration tests (crates/stripecal-sim/tests/it/stripe_bias.rs).

use nalgebra::{Matrix4, Point3, Vector3, Vector4};
use stripecal::model::image::AnyView;
use stripecal::model::RobotReading;
use stripecal::reconstruct::Triangulator;
use stripecal::reconstruct::{
    correct_sphere_bias, reconstruct_frames, ReconstructOptions, SphereBiasCorrection,
    StripeBiasOptions,
};
use stripecal::Iso3;
use stripecal_sim::truth::StripePointTruth;
use stripecal_sim::{SimConfig, Twin};

/// One scan's figures.
pub struct Run {
    pub truth_diameter: f64,
    pub sheet_sigma_true: f64,
    pub frames: usize,
    /// The uncorrected fit's errors (diameter, centre vector).
    pub d0: f64,
    pub c0: nalgebra::Vector3<f64>,
    pub corr: SphereBiasCorrection,
    pub secs: f64,
}

impl Run {
    pub fn d1(&self) -> f64 {
        self.corr.fit.diameter_mm - self.truth_diameter
    }

    pub fn report(&self, label: &str) {
        let c = &self.corr;
        let s = &c.sheet;
        println!(
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
/// reconstructs it with the true calibration, fits the sphere and corrects it (with the
/// twin's true sheet sigma, PSF sigma and emitter when `known`: what remains then is the
/// model's, not its estimates').
pub fn run(preset: &str, overrides: serde_json::Value, every: usize, known: bool) -> Run {
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
            sheet_sigma_mm: known.then_some(tw.cfg.imaging.laser_sigma_mm),
            psf_sigma_px: known.then_some(tw.cfg.imaging.psf_sigma_px),
            emitter_cam_mm: known.then_some([tw.emitter.x, tw.emitter.y, tw.emitter.z]),
            ..Default::default()
        },
    )
    .unwrap();
    let secs = t0.elapsed().as_secs_f64();
    println!("true emitter {:?}", tw.emitter.as_slice());
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

/// The 10-degree bin of an angle (the last one holds 90 deg and beyond).
pub fn bin_of(deg: f64) -> usize {
    ((deg / 10.0) as usize).min(9)
}

/// A point's row of the sphere fit's linearisation: `J = [-n, -1]` (base frame, `n` the
/// true sphere's normal at the true point `t`) and the radial move of the point measured
/// at `u` on `t`'s scan line per pixel along it, mm/px (stripes along columns).
pub fn radial_row(
    tri: &Triangulator,
    base_cam: &Iso3,
    sphere_center_mm: &Vector3<f64>,
    t: &StripePointTruth,
    u: f64,
) -> Option<(Vector4<f64>, f64)> {
    let a = tri.point_cam_mm(u + 0.5, t.v)?;
    let b = tri.point_cam_mm(u - 0.5, t.v)?;
    let c_cam = base_cam.inverse() * Point3::from(*sphere_center_mm);
    let n_cam = (Vector3::from(t.p_cam) - c_cam.coords).normalize();
    let n = base_cam.rotation * n_cam;
    Some((Vector4::new(-n.x, -n.y, -n.z, -1.0), (a - b).dot(&n_cam)))
}

/// The fitted diameter's linear response to radial moves of the points whose rows are
/// `js`: [`Self::gain`] of a row times its radial move (mm) is the diameter's change.
pub struct DiameterLeverage(Matrix4<f64>);

impl DiameterLeverage {
    pub fn new<'a>(js: impl Iterator<Item = &'a Vector4<f64>>) -> Self {
        let nm: Matrix4<f64> = js.map(|j| j * j.transpose()).sum();
        DiameterLeverage(nm.try_inverse().unwrap())
    }

    pub fn gain(&self, j: &Vector4<f64>) -> f64 {
        -2.0 * (self.0 * j)[3]
    }
}
