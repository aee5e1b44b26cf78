//! The real extractor's mean response to the image noise on the ball's stripe: every
//! `--every`-th frame (default 4) of the ball scan of `--preset` (default hp3-wide,
//! seed 1) rendered noise-free and `--draws` times (default 12) with `noise_gray` 2
//! (the same geometry, other noise), `--bits` (8) bits deep (16: the noise-free image is not
//! rounded to the 8-bit levels), with the overrides `--overrides JSON` on top. Per row
//! the mean noisy centre minus the noise-free one; printed in bins of the true view
//! angle (mean and its standard error over the rows, the share of rows found) and
//! propagated to the fitted diameter (radial, times the row's leverage on a sphere fit
//! of the rows seen at up to 75 deg, as the corrected fit keeps them); `TAILS` lines:
//! the rows' median shift and the draws off by more than 0.1 px. Formerly the ignored
//! test `stripe_bias::noise_response` of the twin's integration tests (its knobs
//! `STRIPE_NOISE_*`), without its `STRIPE_NOISE_MODEL_PAIRS` part (README).

use std::collections::HashMap;

use nalgebra::Vector4;
use stripe_bias_studies::{bin_of, radial_row, DiameterLeverage};
use stripecal::model::image::AnyGray;
use stripecal::reconstruct::{ReconstructOptions, Triangulator};
use stripecal::vision::stripe::extract_stripe;
use stripecal_sim::{SimConfig, Twin};

/// The command line's `--name value` pairs.
struct Args(Vec<String>);

impl Args {
    fn get(&self, name: &str, default: &str) -> String {
        self.0
            .iter()
            .position(|a| a == name)
            .map_or(default.to_string(), |i| self.0[i + 1].clone())
    }
}

/// The middle value of `v` (sorted in place; not empty; the upper one of an even count,
/// as the crate-private `NoiseShift::of` of `reconstruct/fit/stripe_bias/noise.rs` takes it).
fn median(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn main() {
    let args = Args(std::env::args().skip(1).collect());
    let preset = args.get("--preset", "hp3-wide");
    let every: usize = args.get("--every", "4").parse().unwrap();
    let draws: usize = args.get("--draws", "12").parse().unwrap();
    let bits: u8 = args.get("--bits", "8").parse().unwrap();
    let extra: serde_json::Value = serde_json::from_str(&args.get("--overrides", "{}")).unwrap();
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
    let centres = |img: &AnyGray| -> HashMap<i64, f64> {
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
            let med = median(&mut found.clone());
            let big = found.iter().filter(|d| d.abs() > 0.1).count();
            tails.push((t.view_deg, med, big, found.len()));
            rows.push((t.view_deg, j, q, m, found.len() as f64 / draws as f64));
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
            println!(
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
    println!(
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
            println!(
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
