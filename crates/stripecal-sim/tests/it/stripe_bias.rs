//! The curved-surface stripe bias (issue 15): the twin's ball scan reconstructed with the
//! TRUE calibration measures the ball ~+0.005 mm too large; the model-based correction
//! (`stripecal::reconstruct::correct_sphere_bias`) brings it within 0.002 mm, and the
//! sheet thickness it estimates from the stripe widths is the twin's.

use nalgebra::{Matrix4, Point3, Vector3, Vector4};
use stripecal::model::image::AnyView;
use stripecal::model::RobotReading;
use stripecal::reconstruct::Triangulator;
use stripecal::reconstruct::{
    correct_sphere_bias, fit_sphere, reconstruct_frames, FitOptions, NoiseShift,
    ReconstructOptions, ScanPoints, SphereBiasCorrection, StripeBiasOptions,
};
use stripecal::Iso3;
use stripecal_sim::truth::StripePointTruth;
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
/// reconstructs it with the true calibration, fits the sphere and corrects it (with the
/// twin's true sheet sigma, PSF sigma and emitter when `STRIPE_BIAS_TRUE_MODEL` is set:
/// what remains then is the model's, not its estimates').
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
    let first = fit_sphere(&sp.points_mm, &FitOptions::default()).unwrap();
    let keep: Vec<usize> = (0..sp.len()).filter(|&i| first.inlier[i]).collect();
    let inl = sp.subset(&keep);
    let base_cam: Vec<Iso3> = qs.iter().map(|q| tw.base_cam(q).unwrap()).collect();
    let sphere = tw.sphere.unwrap();
    let t0 = std::time::Instant::now();
    let known = std::env::var("STRIPE_BIAS_TRUE_MODEL").is_ok();
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
    eprintln!("true emitter {:?}", tw.emitter.as_slice());
    if std::env::var("STRIPE_BIAS_DIAG").is_ok() {
        diagnose(&tw, &renders, &inl, &base_cam, &calib, &opts);
    }
    if std::env::var("STRIPE_BIAS_LEVER").is_ok() {
        lever(&tw, &renders, &sp, &corr.used, &base_cam, &calib, &opts);
    }
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

/// The model's predicted bias per point (px) with the true sphere and sigmas, and the
/// emitter given (`None`: the model's default, `n d`).
fn true_bias_px(
    tw: &Twin,
    sp: &ScanPoints,
    base_cam: &[Iso3],
    calib: &stripecal::model::Calibration,
    opts: &ReconstructOptions,
    emitter_cam_mm: Option<[f64; 3]>,
) -> Vec<Option<f64>> {
    let sphere = tw.sphere.unwrap();
    stripecal::reconstruct::predicted_bias_px(
        sp,
        base_cam,
        &calib.camera,
        calib.laser_plane.as_ref().unwrap(),
        (&sphere.center_mm, 0.5 * sphere.diameter_mm),
        tw.cfg.imaging.laser_sigma_mm,
        tw.cfg.imaging.psf_sigma_px,
        &StripeBiasOptions {
            stripe: opts.stripe.clone(),
            emitter_cam_mm,
            ..Default::default()
        },
    )
    .unwrap()
}

/// The twin's true sphere stripe point on point `i`'s scan line (its frame's row).
fn sphere_truth<'r>(
    renders: &'r [stripecal_sim::ViewRender],
    sp: &ScanPoints,
    i: usize,
) -> Option<&'r StripePointTruth> {
    renders[sp.frame[i] as usize]
        .stripe
        .iter()
        .find(|s| s.surface == "sphere" && (s.v - sp.v_px[i]).abs() < 1e-6)
}

/// The 10-degree bin of an angle (the last one holds 90 deg and beyond).
fn bin_of(deg: f64) -> usize {
    ((deg / 10.0) as usize).min(9)
}

/// A point's row of the sphere fit's linearisation: `J = [-n, -1]` (base frame, `n` the
/// true sphere's normal at the true point `t`) and the radial move of the point measured
/// at `u` on `t`'s scan line per pixel along it, mm/px (stripes along columns).
fn radial_row(
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
struct DiameterLeverage(Matrix4<f64>);

impl DiameterLeverage {
    fn new<'a>(js: impl Iterator<Item = &'a Vector4<f64>>) -> Self {
        let nm: Matrix4<f64> = js.map(|j| j * j.transpose()).sum();
        DiameterLeverage(nm.try_inverse().unwrap())
    }

    fn gain(&self, j: &Vector4<f64>) -> f64 {
        -2.0 * (self.0 * j)[3]
    }
}

/// Measured minus true stripe centre per point against the model's prediction (true
/// sphere, true sigmas), in bins of the true incidence angle.
fn diagnose(
    tw: &Twin,
    renders: &[stripecal_sim::ViewRender],
    sp: &ScanPoints,
    base_cam: &[Iso3],
    calib: &stripecal::model::Calibration,
    opts: &ReconstructOptions,
) {
    let pred = true_bias_px(tw, sp, base_cam, calib, opts, None);
    let mut bins = vec![(0usize, 0.0f64, 0.0f64, 0.0f64); 10];
    let mut none = 0;
    for (i, pr) in pred.iter().enumerate() {
        let Some(t) = sphere_truth(renders, sp, i) else {
            continue;
        };
        let Some(p) = *pr else {
            none += 1;
            continue;
        };
        let act = sp.u_px[i] - t.u;
        let b = bin_of(t.incidence_deg);
        bins[b].0 += 1;
        bins[b].1 += act;
        bins[b].2 += p;
        bins[b].3 += (act - p) * (act - p);
    }
    for (k, b) in bins.iter().enumerate() {
        if b.0 > 0 {
            let n = b.0 as f64;
            eprintln!(
                "  incidence {:2}-{:2} deg: {:5} points, measured bias {:+.4} px, predicted {:+.4} px, rms diff {:.4}",
                10 * k,
                10 * k + 10,
                b.0,
                b.1 / n,
                b.2 / n,
                (b.3 / n).sqrt()
            );
        }
    }
    eprintln!("  {none} points not modelled");
}

/// Where a corrected diameter's error comes from: per modelled point its error after the
/// model's correction (measured minus predicted bias minus the true stripe centre, px;
/// true sphere, sigmas and emitter), turned radial (mm) and weighted by its leverage on
/// the fitted diameter (the sphere fit's linear response), summed in bins of the view
/// angle. The sum is the diameter's error to first order (hp3-wide seed 1: +0.132 um
/// against the fit's +0.131 noise-free). Also, per bin, the raw error (measured minus
/// true centre) of the points the model kept and of those it left out, and the true
/// stripe rows with no point (`SELECT` lines): whether noise changes which points are
/// fitted. `STRIPE_BIAS_LEVER=1` in the sweep; stripes along columns (`u` the scan-line
/// coordinate), as on the presets.
#[allow(clippy::too_many_arguments)]
fn lever(
    tw: &Twin,
    renders: &[stripecal_sim::ViewRender],
    sp: &ScanPoints,
    modelled: &[bool],
    base_cam: &[Iso3],
    calib: &stripecal::model::Calibration,
    opts: &ReconstructOptions,
) {
    let sphere = tw.sphere.unwrap();
    let e = tw.emitter;
    let pred = true_bias_px(tw, sp, base_cam, calib, opts, Some([e.x, e.y, e.z]));
    let tri = Triangulator::from_calibration(calib, 1.0).unwrap();
    let truths: Vec<Option<&StripePointTruth>> = (0..sp.len())
        .map(|i| sphere_truth(renders, sp, i))
        .collect();
    // (view deg, J, radial mm per px, error px)
    let mut rows = Vec::new();
    for (i, pr) in pred.iter().enumerate() {
        let (Some(p), true, Some(t)) = (*pr, modelled[i], truths[i]) else {
            continue;
        };
        let f = sp.frame[i] as usize;
        let u = sp.u_px[i];
        if let Some((j, q)) = radial_row(&tri, &base_cam[f], &sphere.center_mm, t, u) {
            rows.push((t.view_deg, j, q, u - p - t.u));
        }
    }
    // Selection: raw errors (measured minus true centre, px) of the points the model
    // kept and of those it left out, and the true stripe rows with no point at all.
    let mut sel = vec![(0usize, 0.0f64, 0usize, 0.0f64, 0usize); 10];
    let mut seen = std::collections::HashSet::new();
    for (i, (&kept, t)) in modelled.iter().zip(&truths).enumerate() {
        let Some(t) = t else {
            continue;
        };
        seen.insert((sp.frame[i] as usize, sp.v_px[i].round() as i64));
        let b = &mut sel[bin_of(t.view_deg)];
        if kept {
            b.0 += 1;
            b.1 += sp.u_px[i] - t.u;
        } else {
            b.2 += 1;
            b.3 += sp.u_px[i] - t.u;
        }
    }
    for (f, r) in renders.iter().enumerate() {
        for t in r.stripe.iter().filter(|s| s.surface == "sphere") {
            if !seen.contains(&(f, t.v.round() as i64)) {
                sel[bin_of(t.view_deg)].4 += 1;
            }
        }
    }
    for (k, b) in sel.iter().enumerate() {
        eprintln!(
            "  SELECT view {:2}-{:2}: kept {:5} raw {:+.5} px | left out {:5} raw {:+.5} px | no point {:5}",
            10 * k,
            10 * k + 10,
            b.0,
            b.1 / b.0.max(1) as f64,
            b.2,
            b.3 / b.2.max(1) as f64,
            b.4
        );
    }
    let lev = DiameterLeverage::new(rows.iter().map(|r| &r.1));
    let mut bins = vec![(0usize, 0.0f64, 0.0f64, 0.0f64); 10];
    let mut total = 0.0;
    for (view, j, q, err) in &rows {
        let g = lev.gain(j);
        let b = &mut bins[bin_of(*view)];
        b.0 += 1;
        b.1 += g * q * err;
        b.2 += err;
        b.3 += g * q;
        total += g * q * err;
    }
    for (k, b) in bins.iter().enumerate() {
        if b.0 > 0 {
            let n = b.0 as f64;
            eprintln!(
                "  view {:2}-{:2} deg: {:5} points, diameter {:+.4} um, mean error {:+.5} px, \
                 leverage sum {:+.4} um/px",
                10 * k,
                10 * k + 10,
                b.0,
                1e3 * b.1,
                b.2 / n,
                1e3 * b.3
            );
        }
    }
    eprintln!(
        "  LEVER total {:+.4} um over {} points",
        1e3 * total,
        rows.len()
    );
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

/// Throwaway sweeps: `STRIPE_BIAS_RUNS='[["hp3-paper", {"seed": 2}, 1], ...]' cargo test
/// --test it stripe_bias::sweep -- --ignored --nocapture` (`STRIPE_BIAS_TRUE_MODEL=1`: the
/// true sigmas and emitter, see [`run`]; `STRIPE_BIAS_LEVER=1`: where the diameter's
/// remainder comes from, see [`lever`]). From the workspace root without `-p`, so that
/// the build shares the workspace's dependency features (crates/workspace-hack).
#[test]
#[ignore]
fn sweep() {
    let runs: Vec<(String, serde_json::Value, usize)> =
        serde_json::from_str(&std::env::var("STRIPE_BIAS_RUNS").unwrap()).unwrap();
    for (preset, over, every) in runs {
        let r = run(&preset, over.clone(), every);
        r.report(&format!("{preset} {over} every {every}"));
        // One line per run for scripts: the errors and changes in mm, full precision.
        let c = &r.corr;
        let truth_c = c.uncorrected.center_mm - r.c0;
        let e1 = c.fit.center_mm - truth_c;
        eprintln!(
            "SWEEP {}",
            serde_json::json!({
                "preset": preset, "overrides": over, "every": every,
                "diameter_error_mm": [r.d0, r.d1()], "diameter_change_mm": c.diameter_change_mm,
                "diameter_systematic_mm": c.diameter_systematic_mm,
                "center_error_mm": [r.c0.as_slice(), e1.as_slice()],
                "center_change_mm": c.center_change_mm.as_slice(),
            })
        );
    }
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

/// The real extractor's mean response to the image noise on the ball's stripe: every
/// `STRIPE_NOISE_EVERY`-th frame (default 4) of the ball scan of `STRIPE_NOISE_PRESET`
/// (default hp3-wide, seed 1) rendered noise-free and `STRIPE_NOISE_DRAWS` times (default
/// 12) with `noise_gray` 2 (the same geometry, other noise), `STRIPE_NOISE_BITS` (8) bits
/// deep (16: the noise-free image is not rounded to the 8-bit levels), with the
/// overrides `STRIPE_NOISE_OVERRIDES` (JSON) on top. Per row the mean noisy centre
/// minus the noise-free one; printed in bins of the true view angle (mean and its
/// standard error over the rows, the share of rows found) and propagated to the fitted
/// diameter (radial, times the row's leverage on a sphere fit of the rows seen at up to
/// 75 deg, as the corrected fit keeps them). `cargo test --test it stripe_bias::
/// noise_response -- --ignored --nocapture`. hp3-wide seed 1, 16 bits: +0.58 um on the
/// diameter (every 2nd frame, 40 draws), +0.33 and +0.36 um (every 4th, 24 and 40
/// draws); the rows' median shift +0.0009 to +0.0023 px in every view bin (`TAILS`
/// lines, with the draws off by more than 0.1 px).
///
/// With `STRIPE_NOISE_MODEL_PAIRS` (antithetic pairs per point, default 0: not run) the
/// model's profiles of the same rows get the same noise
/// (`stripecal::reconstruct::predicted_noise_shift_px`, the true sphere, sigmas and
/// emitter), and the `MODEL` lines compare the two row by row, over the rows the model
/// holds for, as mean, median and 3-MAD trimmed mean. Every 4th frame, 24 draws, 16
/// pairs: the rendered and the modelled medians agree per bin (+0.0009 to +0.0042 px
/// against +0.0015 to +0.0047), and so do the means, which are nil (-0.0014 to +0.0007
/// against -0.0001 to +0.0008 px): over the modelled rows the noise moves the diameter
/// by -0.20 um (rendered, the draws' scatter) and +0.02 um (modelled). The +0.33 um
/// above comes from rows the corrected fit does not keep.
#[test]
#[ignore]
fn noise_response() {
    use stripecal::vision::stripe::extract_stripe;
    let env = |k: &str, d: &str| std::env::var(k).unwrap_or_else(|_| d.to_string());
    let preset = env("STRIPE_NOISE_PRESET", "hp3-wide");
    let every: usize = env("STRIPE_NOISE_EVERY", "4").parse().unwrap();
    let draws: usize = env("STRIPE_NOISE_DRAWS", "12").parse().unwrap();
    let bits: u8 = env("STRIPE_NOISE_BITS", "8").parse().unwrap();
    let extra: serde_json::Value =
        serde_json::from_str(&env("STRIPE_NOISE_OVERRIDES", "{}")).unwrap();
    let twin = |noise: f64| {
        let over =
            serde_json::json!({"seed": 1, "imaging": {"noise_gray": noise, "bit_depth": bits}});
        Twin::new(
            SimConfig::preset(&preset)
                .unwrap()
                .with_overrides(&over)
                .unwrap()
                .with_overrides(&extra)
                .unwrap(),
        )
        .unwrap()
    };
    let (clean, noisy) = (twin(0.0), twin(2.0));
    let calib = clean.true_calibration();
    let tri = Triangulator::from_calibration(&calib, 1.0).unwrap();
    let sphere = clean.sphere.unwrap();
    let mut so = ReconstructOptions::default().stripe;
    so.direction = stripecal::reconstruct::stripe_direction_from_plane(
        &calib.camera,
        calib.laser_plane.as_ref().unwrap(),
    );
    let centres = |img: &stripecal::model::image::AnyGray| -> std::collections::HashMap<i64, f64> {
        extract_stripe(img.view().unwrap(), &so)
            .map(|s| s.points.iter().map(|p| (p.v.round() as i64, p.u)).collect())
            .unwrap_or_default()
    };
    // Per row: view deg, median shift, draws off by more than 0.1 px, draws found.
    let mut tails: Vec<(f64, f64, usize, usize)> = Vec::new();
    // Per row: view deg, J (base frame), radial mm per px, mean shift px, share found.
    let mut rows: Vec<(f64, Vector4<f64>, f64, f64, f64)> = Vec::new();
    let qs: Vec<Vec<f64>> = clean
        .scan_poses()
        .unwrap()
        .into_iter()
        .step_by(every)
        .collect();
    // The model's own noise response on the same rows (STRIPE_NOISE_MODEL_PAIRS
    // antithetic pairs per point; 0: not computed), with the true sphere, sigmas and
    // emitter: (frame, row) -> mean shift px.
    let pairs: usize = env("STRIPE_NOISE_MODEL_PAIRS", "0").parse().unwrap();
    let model_shift: std::collections::HashMap<(u32, i64), NoiseShift> = if pairs > 0 {
        let renders: Vec<_> = qs
            .iter()
            .enumerate()
            .map(|(k, q)| clean.render_scan_frame(q, k).unwrap())
            .collect();
        let views: Vec<AnyView<'_>> = renders
            .iter()
            .map(|r| r.laser_image.as_ref().unwrap().view().unwrap())
            .collect();
        let readings: Vec<RobotReading> =
            qs.iter().map(|q| RobotReading::Joints(q.clone())).collect();
        let ro = ReconstructOptions::default();
        let sp = reconstruct_frames(&calib, &views, &readings, &ro).unwrap();
        let base_cam: Vec<Iso3> = qs.iter().map(|q| clean.base_cam(q).unwrap()).collect();
        let maxv = if bits == 16 { 65535.0 } else { 255.0 };
        let shifts = stripecal::reconstruct::predicted_noise_shift_px(
            &sp,
            &base_cam,
            &calib.camera,
            calib.laser_plane.as_ref().unwrap(),
            (&sphere.center_mm, 0.5 * sphere.diameter_mm),
            clean.cfg.imaging.laser_sigma_mm,
            clean.cfg.imaging.psf_sigma_px,
            &StripeBiasOptions {
                stripe: ro.stripe.clone(),
                emitter_cam_mm: Some([clean.emitter.x, clean.emitter.y, clean.emitter.z]),
                ..Default::default()
            },
            2.0 * maxv / 255.0,
            pairs,
            7,
        )
        .unwrap();
        (0..sp.len())
            .filter_map(|i| shifts[i].map(|m| ((sp.frame[i], sp.v_px[i].round() as i64), m)))
            .collect()
    } else {
        Default::default()
    };
    // Per row with a model response: view deg, J, radial mm per px, rendered, modelled.
    let mut pairs_rows: Vec<(f64, Vector4<f64>, f64, NoiseShift, NoiseShift)> = Vec::new();
    for (k, q) in qs.iter().enumerate() {
        let base_cam = clean.base_cam(q).unwrap();
        let r0 = clean.render_scan_frame(q, k).unwrap();
        let c0 = centres(r0.laser_image.as_ref().unwrap());
        let noisy_c: Vec<_> = (0..draws)
            .map(|j| {
                let r = noisy.render_scan_frame(q, 1000 * (j + 1) + k).unwrap();
                // The two twins differ in their noise only: the same true stripe.
                assert_eq!(
                    r.stripe, r0.stripe,
                    "frame {k}: the twins' geometry differs"
                );
                centres(r.laser_image.as_ref().unwrap())
            })
            .collect();
        for t in r0.stripe.iter().filter(|s| s.surface == "sphere") {
            let row = t.v.round() as i64;
            let Some(&u0) = c0.get(&row) else { continue };
            let found: Vec<f64> = noisy_c
                .iter()
                .filter_map(|m| m.get(&row))
                .map(|u| u - u0)
                .collect();
            if found.len() * 2 < draws {
                continue;
            }
            let Some((j, q)) = radial_row(&tri, &base_cam, &sphere.center_mm, t, u0) else {
                continue;
            };
            let m = found.iter().sum::<f64>() / found.len() as f64;
            let mut sorted = found.clone();
            let rs = NoiseShift::of(&mut sorted).unwrap();
            let med = rs.median;
            let big = found.iter().filter(|d| d.abs() > 0.1).count();
            tails.push((t.view_deg, med, big, found.len()));
            if let Some(&mm) = model_shift.get(&(k as u32, row)) {
                pairs_rows.push((t.view_deg, j, q, rs, mm));
            }
            rows.push((t.view_deg, j, q, m, found.len() as f64 / draws as f64));
        }
    }
    if !pairs_rows.is_empty() {
        let lev = DiameterLeverage::new(pairs_rows.iter().filter(|r| r.0 <= 75.0).map(|r| &r.1));
        type Pick = fn(&NoiseShift) -> f64;
        let picks: [(&str, Pick); 3] = [
            ("mean", |s| s.mean),
            ("median", |s| s.median),
            ("trimmed", |s| s.trimmed),
        ];
        for (name, pick) in picks {
            // per bin: rows, rendered sum, modelled sum, rendered um, modelled um, sd sums
            let mut bins = vec![(0usize, 0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64, 0.0f64); 10];
            for (view, j, q, r, mm) in &pairs_rows {
                let b = &mut bins[bin_of(*view)];
                b.0 += 1;
                b.1 += pick(r);
                b.2 += pick(mm);
                b.5 += r.sd;
                b.6 += mm.sd;
                if *view <= 75.0 {
                    b.3 += lev.gain(j) * q * pick(r) * 1e3;
                    b.4 += lev.gain(j) * q * pick(mm) * 1e3;
                }
            }
            let (mut tr, mut tm) = (0.0, 0.0);
            for (k, b) in bins.iter().enumerate() {
                if b.0 > 0 {
                    let n = b.0 as f64;
                    tr += b.3;
                    tm += b.4;
                    eprintln!(
                        "  MODEL {name} view {:2}-{:2} deg: {:5} rows, rendered {:+.5} px (sd {:.4}), modelled {:+.5} px (sd {:.4}); diameter {:+.4} / {:+.4} um",
                        10 * k,
                        10 * k + 10,
                        b.0,
                        b.1 / n,
                        b.5 / n,
                        b.2 / n,
                        b.6 / n,
                        b.3,
                        b.4
                    );
                }
            }
            eprintln!("  MODEL {name} diameter total: rendered {tr:+.4} um, modelled {tm:+.4} um");
        }
    }
    let lev = DiameterLeverage::new(rows.iter().filter(|r| r.0 <= 75.0).map(|r| &r.1));
    // per bin: rows, sum of shifts, sum of squares, found, diameter (um)
    let mut bins = vec![(0usize, 0.0f64, 0.0f64, 0.0f64, 0.0f64); 10];
    for (view, j, q, m, f) in &rows {
        let b = &mut bins[bin_of(*view)];
        b.0 += 1;
        b.1 += m;
        b.2 += m * m;
        b.3 += f;
        if *view <= 75.0 {
            b.4 += lev.gain(j) * q * m * 1e3;
        }
    }
    let mut total = 0.0;
    for (k, b) in bins.iter().enumerate() {
        if b.0 > 1 {
            let n = b.0 as f64;
            let mean = b.1 / n;
            let se = ((b.2 / n - mean * mean).max(0.0) / (n - 1.0)).sqrt();
            total += b.4;
            eprintln!(
                "  NOISE view {:2}-{:2} deg: {:5} rows, mean shift {:+.5} +- {:.5} px, found {:.3}, diameter {:+.4} um",
                10 * k,
                10 * k + 10,
                b.0,
                mean,
                se,
                b.3 / n,
                b.4
            );
        }
    }
    eprintln!(
        "  NOISE diameter total {total:+.4} um ({} rows)",
        rows.len()
    );
    // The shape of the response: the rows' median shift and the draws off by > 0.1 px.
    let mut tb = vec![(0usize, 0.0f64, 0usize, 0usize); 10];
    for (view, med, big, n) in &tails {
        let b = &mut tb[bin_of(*view)];
        b.0 += 1;
        b.1 += med;
        b.2 += big;
        b.3 += n;
    }
    for (k, b) in tb.iter().enumerate() {
        if b.0 > 0 {
            eprintln!(
                "  TAILS view {:2}-{:2} deg: median shift {:+.5} px, {} of {} draws off by > 0.1 px",
                10 * k,
                10 * k + 10,
                b.1 / b.0 as f64,
                b.2,
                b.3
            );
        }
    }
}

/// The extractor on a SYMMETRIC stripe (a Gaussian of sigma `STRIPE_SYM_SIGMA` px, default
/// 1.2, integrated over each pixel, 16 bits, area 60 000 on a flat 3 000 background, the
/// centre's pixel phase swept over the rows) with noise of 2 gray levels (514 in 16 bits):
/// the mean and median of (found - true) centre over `STRIPE_SYM_DRAWS` noisy images (20),
/// against the noise-free image. Any shift is the extraction's own, not a profile's.
#[test]
#[ignore]
fn noise_on_a_symmetric_stripe() {
    use stripecal::model::image::{AnyView, ImageView};
    use stripecal::numerics::rng::SplitMix64;
    use stripecal::vision::stripe::{extract_stripe, StripeDirection, StripeOptions};
    let env = |k: &str, d: &str| std::env::var(k).unwrap_or_else(|_| d.to_string());
    let sigma: f64 = env("STRIPE_SYM_SIGMA", "1.2").parse().unwrap();
    let draws: usize = env("STRIPE_SYM_DRAWS", "20").parse().unwrap();
    let (w, h) = (128usize, 2000usize);
    let centre = |row: usize| 60.0 + 0.0137 * row as f64;
    let erf = |x: f64| {
        let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
        let y = 1.0
            - (((((1.061_405_429 * t - 1.453_152_027) * t) + 1.421_413_741) * t - 0.284_496_736)
                * t
                + 0.254_829_592)
                * t
                * (-x * x).exp();
        if x < 0.0 {
            -y
        } else {
            y
        }
    };
    let clean: Vec<f64> = (0..w * h)
        .map(|k| {
            let (x, row) = ((k % w) as f64, k / w);
            let s = std::f64::consts::SQRT_2 * sigma;
            let c = centre(row);
            // 60 000 times the Gaussian's share of the pixel (its area 1).
            3000.0 + 60000.0 * 0.5 * (erf((x + 0.5 - c) / s) - erf((x - 0.5 - c) / s))
        })
        .collect();
    let opts = StripeOptions {
        direction: StripeDirection::Cols,
        ..Default::default()
    };
    let errors = |noise: f64, seed: u64| -> Vec<f64> {
        let mut rng = SplitMix64(seed);
        let data: Vec<u16> = clean
            .iter()
            .map(|&v| (v + noise * rng.normal()).round().clamp(0.0, 65535.0) as u16)
            .collect();
        let img = ImageView::from_slice(&data, w, h).unwrap();
        let s = extract_stripe(AnyView::U16(img), &opts).unwrap();
        s.points
            .iter()
            .map(|p| p.u - centre(p.v.round() as usize))
            .collect()
    };
    let e0 = errors(0.0, 1);
    let m0 = e0.iter().sum::<f64>() / e0.len() as f64;
    let mut all = Vec::new();
    for d in 0..draws {
        all.extend(errors(514.0, 100 + d as u64));
    }
    let n = all.len() as f64;
    let mean = all.iter().sum::<f64>() / n;
    let sd = (all.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
    all.sort_by(f64::total_cmp);
    eprintln!(
        "  SYM sigma {sigma} px: noise-free mean error {m0:+.5} px over {} rows; noisy mean \
         {mean:+.5} +- {:.5} px, median {:+.5} px, sd {sd:.4} px over {} points",
        e0.len(),
        sd / n.sqrt(),
        all[all.len() / 2],
        all.len()
    );
}
