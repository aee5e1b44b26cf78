//! Issue 41, item 5: the leave-one-view-out's folds as one Gauss-Newton step from the
//! full solution against the adjustment run again without each view (DECISIONS 3: the
//! held-out figures agree within 5 %), both with the full solution's variance
//! components held, on the bench (the twin's noisy observations without their robot
//! poses) and on a robot with robot-pose noise: every view's board and stripe figures
//! and the medians. The one step is the pipeline's default on the bench; on a robot the
//! one step alone is not within 5 % on the real set etna_calib4, and the pipeline
//! certifies each fold by a second, relinearised step (refitting the views whose figures
//! it moves by more than 1 %; a view whose pull on the others is small keeps its one
//! step): those certified folds are compared with the refits too.
//!
//! `cargo test -p stripecal --test it calib_loo_step:: -- --nocapture` prints the figures.

use crate::common::realdata;
use stripecal::calib::{CircleObs, ViewObs};
use stripecal::model::geometry::iso_from_rotvec;
use stripecal::model::Dataset;
use stripecal::model::{LeaveOneOut, Rig};
use stripecal::pipeline::{
    calibrate_observations, leave_one_out_refits, leave_one_out_with, observe_dataset,
    CalibrateOptions, CalibrationReport, FoldMethod,
};
use stripecal_sim::rng::Rng;
use stripecal_sim::{noisy_observations, SimConfig, Twin};

/// DECISIONS 3's tolerance: the one-step folds' held-out figures within 5 % of the
/// refits'.
const TOLERANCE: f64 = 0.05;

/// `count` views of the hp3-paper twin: its rig and its observations with 0.03 / 0.05 px
/// image noise and robot poses off by 0.02 deg and 0.05 mm (one sigma per component).
fn noisy_twin(count: usize) -> (Rig, Vec<ViewObs>) {
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"poses": {"count": count}}))
        .unwrap();
    let t = Twin::new(cfg).unwrap();
    let rig: Rig = t.rig().unwrap();
    let exact = t.exact_observations().unwrap();
    let mut rng = Rng::new(17, 3);
    let mut views = noisy_observations(&exact, 0.03, 0.05, &mut Rng::new(19, 11));
    for v in &mut views {
        let mut g = |s: f64| s * rng.normal();
        let w = [0.02f64, 0.02, 0.02].map(|s| g(s.to_radians()));
        let d = [0.05, 0.05, 0.05].map(&mut g);
        let e = iso_from_rotvec(&w.into(), &d.into());
        v.base_hand = v.base_hand.map(|a| a * e);
    }
    (rig, views)
}

/// The views as the adjustment of `rep` used them (its circles with their labels, its
/// stripe points on the board), with their robot poses from `views`.
fn used_views(rep: &CalibrationReport, views: &[ViewObs]) -> Vec<ViewObs> {
    let adj = &rep.adjustment;
    let mut ids: Vec<usize> = adj.circle_residuals.iter().map(|c| c.0).collect();
    ids.dedup();
    ids.iter()
        .map(|&id| {
            let src = views.iter().find(|v| v.view == id).unwrap();
            ViewObs {
                view: id,
                circles: adj
                    .circle_residuals
                    .iter()
                    .filter(|c| c.0 == id)
                    .map(|c| CircleObs {
                        row: c.1,
                        col: c.2,
                        u: c.3,
                        v: c.4,
                    })
                    .collect(),
                stripe: adj
                    .stripe_residuals
                    .iter()
                    .filter(|s| s.0 == id)
                    .map(|s| [s.1, s.2])
                    .collect(),
                reading: src.reading.clone(),
                base_hand: src.base_hand,
                alternatives: Vec::new(),
                stripe_shape: None,
            }
        })
        .collect()
}

/// The largest relative difference of the one-step figures from the refits', per view
/// and of the medians; asserted within [`TOLERANCE`].
fn assert_agree(what: &str, step: &LeaveOneOut, refit: &LeaveOneOut) {
    assert_eq!(step.views.len(), refit.views.len());
    let rel = |a: f64, b: f64| (a - b).abs() / b.abs();
    let mut worst = 0.0f64;
    let mut failed = Vec::new();
    let mut check = |name: &str, a: f64, b: f64| {
        let r = rel(a, b);
        worst = worst.max(r);
        println!("{what}: {name}: one step {a:.6e}, refit {b:.6e}, relative {r:.2e}");
        if r > TOLERANCE {
            failed.push(format!("{name}: one step {a} against the refit's {b}"));
        }
    };
    for (s, r) in step.views.iter().zip(&refit.views) {
        assert_eq!(s.view, r.view);
        assert_eq!(s.stripe_points, r.stripe_points);
        check(
            &format!("view {} px", s.view),
            s.board_rms_px,
            r.board_rms_px,
        );
        check(
            &format!("view {} mm", s.view),
            s.board_rms_mm,
            r.board_rms_mm,
        );
        if let (Some(a), Some(b)) = (s.stripe_rms_mm, r.stripe_rms_mm) {
            check(&format!("view {} stripe mm", s.view), a, b);
        }
        assert_eq!(s.disagrees, r.disagrees, "{what}: view {}", s.view);
    }
    check(
        "median px",
        step.median_board_rms_px,
        refit.median_board_rms_px,
    );
    check(
        "median mm",
        step.median_board_rms_mm,
        refit.median_board_rms_mm,
    );
    let (a, b) = (
        step.laser_board.as_ref().unwrap(),
        refit.laser_board.as_ref().unwrap(),
    );
    check("laser->board median", a.median_mm, b.median_mm);
    check("laser->board p95", a.p95_mm, b.p95_mm);
    assert!(failed.is_empty(), "{what}: beyond {TOLERANCE}: {failed:#?}");
    println!(
        "{what}: worst relative difference {worst:.2e}; median board {:.4} / {:.4} px, \
         laser->board median {:.5} / {:.5} mm (one step / refit)",
        step.median_board_rms_px, refit.median_board_rms_px, a.median_mm, b.median_mm
    );
}

#[test]
fn one_step_folds_agree_with_the_refits_on_a_robot() {
    let (rig, views) = noisy_twin(12);
    let opts = CalibrateOptions::default();
    let rep = calibrate_observations(&views, &rig, &opts).unwrap();
    let used = used_views(&rep, &views);
    assert_eq!(used.len(), views.len());
    let step = leave_one_out_with(&used, &rig, &opts, &rep.adjustment, FoldMethod::OneStep)
        .unwrap()
        .unwrap();
    let refit = leave_one_out_with(&used, &rig, &opts, &rep.adjustment, FoldMethod::Refit)
        .unwrap()
        .unwrap();
    assert_agree("robot", &step, &refit);
}

#[test]
fn one_step_folds_agree_with_the_refits_on_the_bench() {
    let (rig, mut views) = noisy_twin(12);
    for v in &mut views {
        v.base_hand = None;
        v.reading = None;
    }
    let opts = CalibrateOptions::default();
    let rep = calibrate_observations(&views, &rig, &opts).unwrap();
    assert!(!rep.adjustment.board_poses.is_empty());
    let used = used_views(&rep, &views);
    let step = leave_one_out_with(&used, &rig, &opts, &rep.adjustment, FoldMethod::OneStep)
        .unwrap()
        .unwrap();
    let refit = leave_one_out_with(&used, &rig, &opts, &rep.adjustment, FoldMethod::Refit)
        .unwrap()
        .unwrap();
    let own = rep.leave_one_out.as_ref().unwrap();
    assert!((own.median_board_rms_px - step.median_board_rms_px).abs() < 1e-9);
    assert_agree("bench", &step, &refit);
}

#[test]
fn certified_folds_agree_with_the_refits_on_a_robot() {
    let (rig, views) = noisy_twin(12);
    let opts = CalibrateOptions::default();
    let rep = calibrate_observations(&views, &rig, &opts).unwrap();
    let used = used_views(&rep, &views);
    let (cert, solved) =
        leave_one_out_refits(&used, &rig, &opts, &rep.adjustment, FoldMethod::Certified)
            .unwrap()
            .unwrap();
    let refit = leave_one_out_with(&used, &rig, &opts, &rep.adjustment, FoldMethod::Refit)
        .unwrap()
        .unwrap();
    println!("certified: {solved:?}");
    assert!(solved.refitted.len() < used.len());
    // A twin's views pull the others' solution by about a chi-square of the global
    // columns over the views (below 1.5 here): some folds stand on their one step, and
    // their figures are held to the refits' below like the others'.
    assert!(!solved.one_step.is_empty(), "{solved:?}");
    // The pipeline's own figure on a robot is the certified folds'.
    let own = rep.leave_one_out.as_ref().unwrap();
    assert!((own.median_board_rms_px - cert.median_board_rms_px).abs() < 1e-9);
    assert_agree("robot, certified", &cert, &refit);
}

/// The real set where the one step alone was 9.7 % off the refits (view 6; 9 views, a
/// laser): the certified folds stand or refit so that every figure is within 5 %.
#[test]
fn certified_folds_agree_with_the_refits_on_etna_calib4() {
    let Some(root) = realdata() else { return };
    let ds = Dataset::load(root.join("etna_calib4")).unwrap();
    let opts = CalibrateOptions::default();
    let (views, _) = observe_dataset(&ds, &opts).unwrap();
    let rep = calibrate_observations(&views, &ds.rig, &opts).unwrap();
    let used = used_views(&rep, &views);
    let (cert, solved) = leave_one_out_refits(
        &used,
        &ds.rig,
        &opts,
        &rep.adjustment,
        FoldMethod::Certified,
    )
    .unwrap()
    .unwrap();
    let refit = leave_one_out_with(&used, &ds.rig, &opts, &rep.adjustment, FoldMethod::Refit)
        .unwrap()
        .unwrap();
    println!("etna_calib4 certified: {solved:?} of {} views", used.len());
    // The real set's views pull hard (39-274): no fold may skip its second step here,
    // where the one step alone was 9.7 % off.
    assert!(solved.one_step.is_empty(), "{solved:?}");
    assert_agree("etna_calib4, certified", &cert, &refit);
}
