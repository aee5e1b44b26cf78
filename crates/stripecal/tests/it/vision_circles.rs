//! Circle-grid detection (issue 3) against the twin's exact truth: accuracy of both
//! centre methods on the paper rig, robustness over 200 random views (any in-plane
//! rotation, tilts to 45 deg, 0.7x..1.5x the stand-off, up to 30 % of the board outside
//! the image), single-image views with the stripe across the board, light circles.
//!
//! Printed figures (`STRIPECAL_TARGET_VIEWS=100 cargo test -p stripecal --test
//! vision_circles -- --nocapture`: the acceptance's 200 random views) are the ones quoted
//! in BENCHMARKS.md ("Vision: circles"). Without the variable the random-view test runs
//! the first 80 of the same 200 (the full count took about 90 s of the CI's 30 minutes).

use crate::common;

use common::Stats;
use rayon::prelude::*;

use stripecal::model::image::AnyGray;
use stripecal::vision::circles::{detect_circles, CentreMethod, CircleGrid, CircleOptions};
use stripecal::Error;
use stripecal_sim::truth::CircleTruth;
use stripecal_sim::views::RandomViews;
use stripecal_sim::{SimConfig, Twin};

fn cfg(overrides: serde_json::Value) -> SimConfig {
    SimConfig::hp3_paper().with_overrides(&overrides).unwrap()
}

fn detect(
    img: &AnyGray,
    twin_board: &stripecal::Board,
    method: CentreMethod,
) -> stripecal::Result<CircleGrid> {
    let opts = CircleOptions {
        method,
        ..Default::default()
    };
    detect_circles(img.view()?, twin_board, &opts)
}

/// Centre errors of one detection against the truth; `Err` names a misordered or
/// unverifiable circle (a detected index that is not where the truth has it).
fn errors(g: &CircleGrid, truth: &[CircleTruth]) -> Result<Vec<f64>, String> {
    let mut out = Vec::with_capacity(g.circles.len());
    for c in &g.circles {
        let Some(t) = truth.iter().find(|t| t.row == c.row && t.col == c.col) else {
            return Err(format!(
                "circle ({}, {}) at ({:.1}, {:.1}) is not an imaged circle of the truth",
                c.row, c.col, c.u, c.v
            ));
        };
        let e = ((c.u - t.u).powi(2) + (c.v - t.v).powi(2)).sqrt();
        if e > 1.0 {
            return Err(format!(
                "circle ({}, {}) at ({:.2}, {:.2}), truth ({:.2}, {:.2}): misordered or wrong",
                c.row, c.col, c.u, c.v, t.u, t.v
            ));
        }
        out.push(e);
    }
    Ok(out)
}

/// Board images of the twin's calibration poses for several seeds.
fn paper_views(
    over: serde_json::Value,
    seeds: &[u64],
) -> Vec<(stripecal::Board, AnyGray, Vec<CircleTruth>)> {
    let mut out = Vec::new();
    for &seed in seeds {
        let mut o = over.clone();
        o["seed"] = serde_json::json!(seed);
        let twin = Twin::new(cfg(o)).unwrap();
        for (i, p) in twin.calibration_poses().unwrap().iter().enumerate() {
            let r = twin.render_view(&p.q_deg, i).unwrap();
            out.push((twin.board.clone(), r.board_image.unwrap(), r.circles));
        }
    }
    out
}

fn measure(
    views: &[(stripecal::Board, AnyGray, Vec<CircleTruth>)],
    method: CentreMethod,
) -> (Stats, usize, f64) {
    let mut st = Stats::default();
    let mut dropped = 0;
    let mut qsum = 0.0;
    for (k, (board, img, truth)) in views.iter().enumerate() {
        let g = detect(img, board, method).unwrap_or_else(|e| panic!("view {k}: {e}"));
        let e = errors(&g, truth).unwrap_or_else(|e| panic!("view {k}: {e}"));
        dropped += g.dropped.len();
        qsum += g.circles.iter().map(|c| c.quality_px).sum::<f64>();
        st.add(&e);
    }
    let q = qsum / st.n.max(1) as f64;
    (st, dropped, q)
}

/// Acceptance 1: noise 1 gray level, PSF 0.7 px, paper rig: RMS <= 0.015 px, max <=
/// 0.05 px with the default method; both methods are measured and printed.
#[test]
fn centres_match_truth_on_the_paper_rig() {
    let views = paper_views(serde_json::json!({}), &[0, 1, 2]);
    for method in [CentreMethod::Gravity, CentreMethod::Ellipse] {
        let (st, dropped, q) = measure(&views, method);
        eprintln!(
            "paper rig, {} views, {:>8}: {} circles, RMS {:.4} px, max {:.4} px, mean quality {:.4} px, {dropped} dropped",
            views.len(),
            method.name(),
            st.n,
            st.rms(),
            st.max,
            q
        );
        assert_eq!(st.n, 88 * views.len(), "{method:?}: every circle found");
        if method == CentreMethod::default() {
            assert!(st.rms() <= 0.015, "RMS {} px", st.rms());
            assert!(st.max <= 0.05, "max {} px", st.max);
        }
    }
}

/// View index, centre errors or the failure, circles found, all markers in the image.
type ViewResult = (usize, Result<Vec<f64>, String>, usize, bool);

/// Acceptance 2: 200 random views (`STRIPECAL_TARGET_VIEWS=100`: twice that many; 80 by
/// default), in-plane rotation over 360 deg, tilt up to 45 deg, stand-off 0.7x..1.5x the
/// nominal, up to 30 % of the board's circles outside the image. Zero misordered grids;
/// every failure is a typed `Error::Detection`.
#[test]
fn random_views_are_never_misordered() {
    let twin = Twin::new(cfg(serde_json::json!({"seed": 42}))).unwrap();
    let board = twin.board.clone();
    // Sample the poses with their truth first (the library's generator: its defaults
    // are this test's views), then render board images (no laser) and detect in
    // parallel. The sampler draws in order, so a count of 80 renders the first 80 of
    // the acceptance's 200.
    let views = RandomViews {
        count: 2 * common::target_views(),
        ..RandomViews::default()
    }
    .sample(&twin)
    .unwrap();
    let start = std::time::Instant::now();
    let results: Vec<ViewResult> = views
        .par_iter()
        .enumerate()
        .map(|(k, view)| {
            let truth = &view.truth;
            let img = view.render(&twin, k as u64).unwrap();
            let markers_in = board
                .markers
                .iter()
                .all(|m| truth.iter().any(|t| t.row == m[0] && t.col == m[1]));
            match detect(&img, &board, CentreMethod::default()) {
                Ok(g) => (k, errors(&g, truth), g.circles.len(), markers_in),
                Err(Error::Detection(m)) => (k, Err(format!("detection: {m}")), 0, markers_in),
                Err(e) => panic!("view {k}: untyped failure {e}"),
            }
        })
        .collect();
    let elapsed = start.elapsed().as_secs_f64();
    let mut st = Stats::default();
    let (mut ok, mut failed, mut failed_markers_in) = (0, 0, 0);
    let mut found = 0;
    let mut visible = 0;
    for (k, r, n, markers_in) in &results {
        let v = &views[*k];
        let (truth, tilt, roll, scale) = (&v.truth, v.tilt_deg, v.roll_deg, v.standoff_scale);
        match r {
            Ok(e) => {
                ok += 1;
                found += n;
                visible += truth.len();
                st.add(e);
            }
            Err(m) if m.starts_with("detection: ") => {
                failed += 1;
                if *markers_in {
                    failed_markers_in += 1;
                }
                eprintln!(
                    "view {k} (tilt {tilt:.0}, roll {roll:.0}, scale {scale:.2}, {} visible, markers in: {markers_in}): {m}",
                    truth.len()
                );
            }
            Err(m) => panic!(
                "view {k} (tilt {tilt:.0}, roll {roll:.0}, scale {scale:.2}): MISORDERED: {m}"
            ),
        }
    }
    eprintln!(
        "{} random views in {elapsed:.1} s: {ok} detected ({found} of {visible} fully visible circles, \
         RMS {:.4} px, max {:.4} px), {failed} typed detection errors ({failed_markers_in} with all \
         markers in the image)",
        views.len(),
        st.rms(),
        st.max
    );
    assert_eq!(ok + failed, views.len());
    // Views that show every marker must (nearly) all be detected: at most 2 % of them.
    assert!(
        failed_markers_in * 50 <= views.len(),
        "{failed_markers_in} failures with all markers visible of {} views",
        views.len()
    );
}

/// Acceptance 6: single-image views (board lit at ambient 0.4 and the stripe on, one
/// image): circles crossed by the stripe are dropped (documented in
/// `stripecal::vision::circles`), the others hold the accuracy figures of acceptance 1
/// within 1.5x (RMS <= 0.0225 px, max <= 0.075 px).
#[test]
fn single_image_views_hold_the_figures() {
    let seeds = [0u64, 1, 2];
    let single = paper_views(
        serde_json::json!({"imaging": {"single_image": true}}),
        &seeds,
    );
    let mut st = Stats::default();
    let mut dropped = 0;
    let mut crossed = 0;
    for (k, (board, img, truth)) in single.iter().enumerate() {
        let g =
            detect(img, board, CentreMethod::default()).unwrap_or_else(|e| panic!("view {k}: {e}"));
        let e = errors(&g, truth).unwrap_or_else(|e| panic!("view {k}: {e}"));
        crossed += g
            .dropped
            .iter()
            .filter(|d| d.reason.contains("stripe"))
            .count();
        dropped += g.dropped.len();
        assert!(e.len() >= 60, "view {k}: only {} circles kept", e.len());
        st.add(&e);
    }
    // The same circles without stripe handling (kept and flagged), for comparison.
    let mut kept = Stats::default();
    for (board, img, truth) in &single {
        let opts = CircleOptions {
            drop_stripe_crossed: false,
            ..Default::default()
        };
        let g = detect_circles(img.view().unwrap(), board, &opts).unwrap();
        for c in g.circles.iter().filter(|c| c.stripe_crossed) {
            if let Some(t) = truth.iter().find(|t| t.row == c.row && t.col == c.col) {
                kept.add(&[((c.u - t.u).powi(2) + (c.v - t.v).powi(2)).sqrt()]);
            }
        }
    }
    eprintln!(
        "single-image views ({} views, ambient 0.4): {} circles, RMS {:.4} px, max {:.4} px; \
         {crossed} crossed by the stripe dropped ({dropped} dropped in all); if kept, the crossed \
         ones have RMS {:.4} px, max {:.4} px",
        single.len(),
        st.n,
        st.rms(),
        st.max,
        kept.rms(),
        kept.max
    );
    assert!(crossed > 0, "the stripe crosses circles in these views");
    assert!(st.rms() <= 1.5 * 0.015, "RMS {} px", st.rms());
    assert!(st.max <= 1.5 * 0.05, "max {} px", st.max);
}

/// Light circles on a dark plate (the board's `dark_circles: false`).
#[test]
fn light_circles_are_detected() {
    let views = paper_views(serde_json::json!({"board": {"dark_circles": false}}), &[3]);
    let (st, dropped, _) = measure(&views, CentreMethod::default());
    eprintln!(
        "light circles, {} views: {} circles, RMS {:.4} px, max {:.4} px, {dropped} dropped",
        views.len(),
        st.n,
        st.rms(),
        st.max
    );
    assert_eq!(st.n, 88 * views.len());
    assert!(st.rms() <= 0.015 && st.max <= 0.05, "{st:?}");
}
