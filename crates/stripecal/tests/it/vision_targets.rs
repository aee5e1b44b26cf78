//! Every target kind against the twin's exact truth (issue 10, acceptance 3): accuracy
//! on whole-board views, and 200 random views per kind (any in-plane rotation, tilt up
//! to 45 deg, 100 with the whole board in the image and 100 with up to 30 % of it
//! outside): zero misordered points, the detection rate of whole-board views, partial
//! views' refusals counted by reason.
//!
//! `STRIPECAL_TARGET_VIEWS=100 cargo test -p stripecal --test it vision_targets:: --
//! --nocapture` runs the acceptance's 100 + 100 views of every kind and prints the
//! figures quoted in BENCHMARKS.md ("Vision: targets"). Without it each kind gets
//! [`common::DEFAULT_TARGET_VIEWS`] + as many (the same first views of the same sequence):
//! the full count renders 400 board images per kind and took 100-110 s of the CI's
//! 30 minutes for each of the two slow kinds.

use crate::common;

use common::Stats;
use std::collections::BTreeMap;

use rayon::prelude::*;

use stripecal::model::board::Symmetry;
use stripecal::vision::target::{detect_target, TargetDetection, TargetOptions};
use stripecal::{Board, Error};
use stripecal_sim::truth::PointTruth;
use stripecal_sim::views::{RandomView, RandomViews};
use stripecal_sim::{SimConfig, Twin};

fn twin(preset: &str, over: serde_json::Value) -> Twin {
    let cfg = SimConfig::preset(preset)
        .unwrap()
        .with_overrides(&over)
        .unwrap();
    Twin::new(cfg).unwrap()
}

/// Errors of a detection against the truth: `Ok(errors px)` or `Err` naming a point that
/// is misordered (not where the truth has that index, under the identity or one of the
/// returned alternatives). With alternatives, the labelling the truth agrees with is
/// used.
fn check(board: &Board, d: &TargetDetection, truth: &[PointTruth]) -> Result<Vec<f64>, String> {
    let by_index: BTreeMap<(usize, usize), &PointTruth> =
        truth.iter().map(|t| ((t.row, t.col), t)).collect();
    let mut labellings: Vec<Option<Symmetry>> = vec![None];
    labellings.extend(d.alternatives.iter().map(|s| Some(*s)));
    let mut best: Option<Vec<f64>> = None;
    for lab in labellings {
        let errs: Option<Vec<f64>> = d
            .points
            .iter()
            .map(|p| {
                let (r, c) = match lab {
                    None => (p.row, p.col),
                    Some(s) => s.apply(board, p.row, p.col)?,
                };
                let t = by_index.get(&(r, c))?;
                let e = (p.u - t.u).hypot(p.v - t.v);
                (e < 1.0).then_some(e)
            })
            .collect();
        if let Some(e) = errs {
            best = Some(e);
            break;
        }
    }
    best.ok_or_else(|| {
        let p = d.points.first();
        format!(
            "MISORDERED: no labelling of the {} points ({} alternatives) agrees with the truth; \
             first point ({:?})",
            d.points.len(),
            d.alternatives.len(),
            p.map(|p| (p.row, p.col, p.u, p.v))
        )
    })
}

/// What happened to one view.
enum Outcome {
    Detected(Vec<f64>, usize),
    Refused(String),
}

fn run(twin: &Twin, views: &[RandomView], stream0: u64) -> Vec<Outcome> {
    let board = twin.board.clone();
    views
        .par_iter()
        .enumerate()
        .map(|(k, v)| {
            let img = v.render(twin, stream0 + k as u64).unwrap();
            match detect_target(img.view().unwrap(), &board, &TargetOptions::default()) {
                Ok(d) => match check(&board, &d, &v.truth) {
                    Ok(e) => Outcome::Detected(e, d.alternatives.len()),
                    Err(m) => panic!(
                        "view {k} (tilt {:.0}, roll {:.0}, scale {:.2}): {m}",
                        v.tilt_deg, v.roll_deg, v.standoff_scale
                    ),
                },
                Err(Error::Detection(m)) => Outcome::Refused(m),
                Err(e) => panic!("view {k}: untyped failure {e}"),
            }
        })
        .collect()
}

/// A refusal's reason: the message up to its first colon, with numbers dropped.
fn reason(m: &str) -> String {
    let head = m.split(':').next().unwrap_or(m);
    head.chars()
        .filter(|c| !c.is_ascii_digit())
        .collect::<String>()
        .trim()
        .to_string()
}

/// [`common::target_views`] whole-board and as many partial random views of `twin`'s board: prints
/// the figures and returns the whole-board error statistics; asserts zero misordered
/// (in `run`) and a whole-board detection rate of at least 98 %.
fn random_views(name: &str, twin: &Twin) -> Stats {
    let n = common::target_views();
    let whole = RandomViews {
        count: n,
        seed: 11,
        ..RandomViews::whole_board()
    }
    .sample(twin)
    .unwrap();
    let partial = RandomViews {
        count: n,
        seed: 12,
        ..Default::default()
    }
    .sample(twin)
    .unwrap();
    let mut st = Stats::default();
    let mut alternatives = 0;
    let mut refused_whole: Vec<String> = Vec::new();
    for o in run(twin, &whole, 0) {
        match o {
            Outcome::Detected(e, a) => {
                st.add(&e);
                alternatives += (a > 0) as usize;
            }
            Outcome::Refused(m) => refused_whole.push(m),
        }
    }
    let mut partial_ok = 0;
    let mut partial_points = 0;
    let mut reasons: BTreeMap<String, usize> = BTreeMap::new();
    for o in run(twin, &partial, 10_000) {
        match o {
            Outcome::Detected(e, _) => {
                partial_ok += 1;
                partial_points += e.len();
            }
            Outcome::Refused(m) => *reasons.entry(reason(&m)).or_default() += 1,
        }
    }
    let detected = whole.len() - refused_whole.len();
    eprintln!(
        "{name}: whole board {detected}/{} detected ({alternatives} with symmetric alternatives), \
         {} points, RMS {:.4} px, max {:.4} px; partial {partial_ok}/{} detected ({partial_points} \
         points), refusals by reason: {reasons:?}",
        whole.len(),
        st.n,
        st.rms(),
        st.max,
        partial.len()
    );
    for m in &refused_whole {
        eprintln!("  whole-board view refused: {m}");
    }
    assert!(
        detected * 100 >= 98 * whole.len(),
        "{name}: only {detected} of {} whole-board views detected",
        whole.len()
    );
    st
}

/// Asymmetric circle grid (`hp3-asymmetric`: 11 x 8, odd rows: no symmetry): centres
/// within 0.015 px RMS of the truth.
#[test]
fn asymmetric_grid_on_random_views() {
    let t = twin("hp3-asymmetric", serde_json::json!({}));
    let st = random_views("asymmetric circles 11 x 8", &t);
    assert!(st.rms() <= 0.015, "RMS {} px", st.rms());
}

/// Asymmetric grid with an even number of rows (half-turn symmetric) and light circles
/// on a dark plate: detected with the half turn as the alternative.
#[test]
fn asymmetric_grid_even_rows_light_circles() {
    let t = twin(
        "hp3-asymmetric",
        serde_json::json!({"board": {"rows": 10, "dark_circles": false}}),
    );
    let st = half_turn_views("asymmetric 10 x 8, light circles", &t, 5);
    assert!(st.rms() <= 0.015, "RMS {} px", st.rms());
}

/// 12 whole-board views of a board with one symmetry (a half turn): every one detected
/// with that alternative reported; returns the error statistics.
fn half_turn_views(name: &str, t: &Twin, seed: u64) -> Stats {
    assert_eq!(t.board.symmetries().len(), 1, "{name}");
    let views = RandomViews {
        count: 12,
        seed,
        ..RandomViews::whole_board()
    }
    .sample(t)
    .unwrap();
    let mut st = Stats::default();
    for o in run(t, &views, 0) {
        match o {
            Outcome::Detected(e, alts) => {
                assert_eq!(alts, 1, "{name}: the half turn is reported");
                st.add(&e);
            }
            Outcome::Refused(m) => panic!("{name}: whole-board view refused: {m}"),
        }
    }
    eprintln!(
        "{name}: {} points, RMS {:.4} px, max {:.4} px",
        st.n,
        st.rms(),
        st.max
    );
    st
}

/// A symmetric circle grid without markers: whole views carry the half turn as the
/// alternative, partial views (position on the board unknown) are refused, never
/// guessed.
#[test]
fn circle_grid_without_markers() {
    let t = twin("hp3-paper", serde_json::json!({"board": {"markers": []}}));
    let st = random_views("circles 8 x 11 without markers", &t);
    assert!(st.rms() <= 0.015, "RMS {} px", st.rms());
}

/// One marker at a corner (the ROS-Industrial layout) on a square grid: the marker
/// fixes the quarter turns too.
#[test]
fn square_grid_with_one_marker() {
    let t = twin(
        "hp3-paper",
        serde_json::json!({"board": {"rows": 8, "cols": 8, "markers": [[0, 0]],
                                     "marker_diameter_mm": 4.5}}),
    );
    assert!(t.board.symmetries().is_empty());
    let st = random_views("circles 8 x 8, one marker", &t);
    assert!(st.rms() <= 0.015, "RMS {} px", st.rms());
}

/// Chessboard (`hp3-chessboard`: 7 x 10 inner corners, rows + cols odd: the colours fix
/// the orientation): corners within 0.02 px RMS of the truth.
#[test]
fn chessboard_on_random_views() {
    let t = twin("hp3-chessboard", serde_json::json!({}));
    let st = random_views("chessboard 7 x 10", &t);
    assert!(st.rms() <= 0.02, "RMS {} px", st.rms());
}

/// A chessboard with rows + cols even (8 x 10): the half turn is reported, never
/// guessed.
#[test]
fn chessboard_even_counts_reports_the_half_turn() {
    let t = twin("hp3-chessboard", serde_json::json!({"board": {"rows": 6}}));
    let st = half_turn_views("chessboard 6 x 10", &t, 6);
    assert!(st.rms() <= 0.02, "RMS {} px", st.rms());
}
