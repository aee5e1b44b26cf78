//! Camera calibration (issue 4) against the twin's exact truth: exact recovery from the
//! exact imaged-circle centres (area centroids of the projected outlines), what the
//! bias-free centre model gains over the naive one, Zhang's closed form as a starting
//! point, typed errors.
//!
//! Printed figures (`cargo test -p stripecal --test it calib_camera:: -- --nocapture`)
//! are the ones in docs/results/conic_model.md.

use stripecal::calib::camera::{calibrate_camera, CameraCalibration, CameraOptions};
use stripecal::calib::conic::CentreModel;
use stripecal::calib::ViewObs;
use stripecal::{Camera, DistortionModel, Error, Iso3};
use stripecal_sim::rng::Rng;
use stripecal_sim::{noisy_observations, SimConfig, Twin};

struct Case {
    twin: Twin,
    views: Vec<ViewObs>,
    truth_poses: Vec<Iso3>,
    model: DistortionModel,
}

fn case(name: &'static str, count: usize) -> Case {
    let base = if name == "hp3-wide" {
        SimConfig::hp3_wide()
    } else {
        SimConfig::hp3_paper()
    };
    let cfg = base
        .with_overrides(&serde_json::json!({"poses": {"count": count}}))
        .unwrap();
    let twin = Twin::new(cfg).unwrap();
    let model = twin.camera.model;
    // Camera calibration only: the circles of the exact observations.
    let views: Vec<ViewObs> = twin
        .exact_observations()
        .unwrap()
        .into_iter()
        .map(|v| ViewObs {
            stripe: vec![],
            reading: None,
            base_hand: None,
            ..v
        })
        .collect();
    let truth_poses: Vec<Iso3> = twin
        .calibration_poses()
        .unwrap()
        .iter()
        .map(|p| twin.scene(&p.q_deg, false).unwrap().cam_board)
        .collect();
    Case {
        twin,
        views,
        truth_poses,
        model,
    }
}

fn with_noise(views: &[ViewObs], sigma: f64, seed: u64) -> Vec<ViewObs> {
    noisy_observations(views, sigma, 0.0, &mut Rng::new(seed, 7))
}

fn run(c: &Case, views: &[ViewObs], model: CentreModel) -> CameraCalibration {
    let opts = CameraOptions {
        centre_model: model,
        ..Default::default()
    };
    let cam = &c.twin.camera;
    calibrate_camera(views, &c.twin.board, cam.width, cam.height, c.model, &opts).unwrap()
}

/// Errors: [fu, fv, u0, v0] absolute px, distortion max abs, pose max translation mm,
/// pose max rotation rad.
struct Errs {
    k: [f64; 4],
    dist: f64,
    t_mm: f64,
    r_rad: f64,
}

fn errors(c: &Case, res: &CameraCalibration) -> Errs {
    let t: &Camera = &c.twin.camera;
    let e: &Camera = &res.camera;
    let k = [e.fu - t.fu, e.fv - t.fv, e.u0 - t.u0, e.v0 - t.v0];
    let dist = (0..5)
        .map(|i| (e.distortion[i] - t.distortion[i]).abs())
        .fold(0.0, f64::max);
    let (mut t_mm, mut r_rad) = (0.0f64, 0.0f64);
    for (view, pose) in &res.poses {
        let tp = &c.truth_poses[*view];
        t_mm = t_mm.max((pose.translation.vector - tp.translation.vector).norm());
        r_rad = r_rad.max(pose.rotation.angle_to(&tp.rotation));
    }
    Errs {
        k,
        dist,
        t_mm,
        r_rad,
    }
}

fn row(label: &str, e: &Errs, rms: f64) -> String {
    format!(
        "| {label} | {:+.2e} | {:+.2e} | {:+.2e} | {:+.2e} | {:.1e} | {:.1e} | {:.1e} | {:.1e} |",
        e.k[0], e.k[1], e.k[2], e.k[3], e.dist, e.t_mm, e.r_rad, rms
    )
}

const HEADER: &str = "| case | d fu px | d fv px | d u0 px | d v0 px | max d k | pose mm | pose rad | rms px |\n|---|---|---|---|---|---|---|---|---|";

#[test]
fn exact_centres_recover_the_camera_exactly_with_the_bias_free_model() {
    let mut table = vec![HEADER.to_string()];
    for name in ["hp3-paper", "hp3-wide"] {
        for count in [5, 15] {
            let c = case(name, count);
            for model in [
                CentreModel::Naive,
                CentreModel::Conic,
                CentreModel::ConicExact,
            ] {
                let res = run(&c, &c.views, model);
                let e = errors(&c, &res);
                table.push(row(
                    &format!("{name}, {count} poses, exact centres, {}", model.name()),
                    &e,
                    res.rms_px,
                ));
                if model == CentreModel::ConicExact {
                    let t = &c.twin.camera;
                    let tk = [t.fu, t.fv, t.u0, t.v0];
                    for (i, (err, tv)) in e.k.iter().zip(tk).enumerate() {
                        assert!(
                            err.abs() < 1e-6 * tv,
                            "{name} {count}: param {i} error {err:e}"
                        );
                    }
                    for i in 0..5 {
                        let (a, b) = (res.camera.distortion[i], t.distortion[i]);
                        assert!(
                            (a - b).abs() < 1e-8 || (a - b).abs() < 1e-6 * b.abs(),
                            "{name} {count}: k[{i}] {a:e} vs {b:e}"
                        );
                    }
                    assert!(e.t_mm < 1e-6, "{name} {count}: pose {:e} mm", e.t_mm);
                    assert!(e.r_rad < 1e-8, "{name} {count}: pose {:e} rad", e.r_rad);
                    assert!(res.unobservable.is_empty(), "{:?}", res.unobservable);
                    assert!(res.warnings.is_empty(), "{:?}", res.warnings);
                }
            }
        }
    }
    println!("\nExact imaged centres (twin truth):\n{}", table.join("\n"));
}

#[test]
fn noisy_centres_bias_free_vs_naive() {
    let mut table = vec![HEADER.to_string()];
    for name in ["hp3-paper", "hp3-wide"] {
        let c = case(name, 15);
        let noisy = with_noise(&c.views, 0.02, 3);
        let mut err_k = Vec::new();
        for model in [CentreModel::Naive, CentreModel::ConicExact] {
            let res = run(&c, &noisy, model);
            let e = errors(&c, &res);
            table.push(row(
                &format!("{name}, 15 poses, 0.02 px noise, {}", model.name()),
                &e,
                res.rms_px,
            ));
            println!(
                "{name} {}: reported 1-sigma fu {:.3e} fv {:.3e} u0 {:.3e} v0 {:.3e} px",
                model.name(),
                res.camera_sigma[0],
                res.camera_sigma[1],
                res.camera_sigma[2],
                res.camera_sigma[3]
            );
            if model == CentreModel::ConicExact {
                // errors within 5 sigma of the reported uncertainty
                for i in 0..4 {
                    assert!(
                        e.k[i].abs() < 5.0 * res.camera_sigma[i] + 1e-9,
                        "{name}: param {i} error {:e} sigma {:e}",
                        e.k[i],
                        res.camera_sigma[i]
                    );
                }
                assert!(
                    (res.rms_px - 0.02 * 2f64.sqrt()).abs() < 0.005,
                    "{}",
                    res.rms_px
                );
            }
            err_k.push(e.k.iter().map(|x| x * x).sum::<f64>().sqrt());
        }
        println!(
            "{name}: |d(fu,fv,u0,v0)| naive {:.3e} px, bias-free {:.3e} px",
            err_k[0], err_k[1]
        );
    }
    println!(
        "\nNoisy imaged centres (0.02 px per coordinate):\n{}",
        table.join("\n")
    );
}

#[test]
fn zhang_closed_form_is_near_truth_and_lm_converges() {
    for name in ["hp3-paper", "hp3-wide"] {
        let c = case(name, 5);
        let res = run(&c, &c.views, CentreModel::ConicExact);
        let t = &c.twin.camera;
        let tk = [t.fu, t.fv, t.u0, t.v0];
        let rel: Vec<f64> = (0..4)
            .map(|i| (res.initial_intrinsics[i] - tk[i]).abs() / tk[i])
            .collect();
        println!(
            "{name}: Zhang initial relative errors fu {:.2e} fv {:.2e} u0 {:.2e} v0 {:.2e}; \
             LM iterations {}, stop {:?}",
            rel[0], rel[1], rel[2], rel[3], res.iterations, res.stop_reason
        );
        if name == "hp3-paper" {
            assert!(rel.iter().all(|r| *r < 0.01), "{rel:?}");
        }
        assert!(res.iterations < 50);
    }
}

#[test]
fn typed_errors_and_dropped_views() {
    let c = case("hp3-paper", 5);
    let cam = &c.twin.camera;
    let opts = CameraOptions::default();
    let cal =
        |v: &[ViewObs]| calibrate_camera(v, &c.twin.board, cam.width, cam.height, c.model, &opts);
    // two views
    assert!(matches!(cal(&c.views[..2]), Err(Error::InvalidInput(_))));
    // NaN
    let mut bad = c.views.clone();
    bad[1].circles[3].u = f64::NAN;
    match cal(&bad) {
        Err(Error::InvalidInput(m)) => assert!(m.contains("view 1"), "{m}"),
        other => panic!("{other:?}"),
    }
    // collinear circles in one view (one board row): dropped with a warning; with only
    // three views left that is two usable: error
    let mut col = c.views.clone();
    col[2].circles.retain(|o| o.row == 3);
    let res = cal(&col).unwrap();
    assert_eq!(res.poses.len(), 4);
    assert!(
        res.warnings.iter().any(|w| w.contains("view 2")),
        "{:?}",
        res.warnings
    );
    assert!(matches!(cal(&col[..3]), Err(Error::InvalidInput(_))));
    // too few circles
    let mut few = c.views.clone();
    few[0].circles.truncate(3);
    let res = cal(&few).unwrap();
    assert!(res.warnings.iter().any(|w| w.contains("view 0")));
    // circle outside the grid
    let mut out = c.views.clone();
    out[0].circles[0].row = 99;
    assert!(matches!(cal(&out), Err(Error::InvalidInput(_))));
}
