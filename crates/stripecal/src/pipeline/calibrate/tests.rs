//! Unit tests of the pipeline's stages on exact synthetic inputs: the pairing stage, the stripe-extent and usability checks, the labelling pass-through and the
//! records the report writes.

use nalgebra::Vector3;

use super::labels::resolve_labellings;
use super::pairing::check_pairing;
use super::report::view_records_from;
use super::views::{check_usable, kept};
use super::{CalibrateOptions, ViewStatus};
use crate::calib::{CircleObs, ViewObs};
use crate::model::board::Board;
use crate::model::geometry::{iso_from_rotvec, Iso3};
use crate::numerics::rng::SplitMix64;

/// A random pose: rotation up to `max_angle` rad about a random axis, translation
/// components uniform in `[-t, t]` mm.
fn random_iso(rng: &mut SplitMix64, max_angle: f64, t: f64) -> Iso3 {
    let axis = Vector3::new(rng.normal(), rng.normal(), rng.normal()).normalize();
    let angle = max_angle * rng.uniform();
    let tr = Vector3::new(
        t * (2.0 * rng.uniform() - 1.0),
        t * (2.0 * rng.uniform() - 1.0),
        t * (2.0 * rng.uniform() - 1.0),
    );
    iso_from_rotvec(&(axis * angle), &tr)
}

fn view(i: usize, base_hand: Option<Iso3>) -> ViewObs {
    ViewObs {
        view: i,
        circles: vec![CircleObs {
            row: 0,
            col: 0,
            u: 1.0,
            v: 2.0,
        }],
        stripe: vec![[3.0, 4.0]],
        reading: None,
        base_hand,
        alternatives: Vec::new(),
        stripe_shape: None,
    }
}

/// `n` views of an exact `A_i X = Z B_i` rig: the views and their `T_cam_board`.
fn exact_rig(n: usize, x: &Iso3, z: &Iso3, seed: u64) -> (Vec<ViewObs>, Vec<Iso3>) {
    let mut rng = SplitMix64(seed);
    let mut obs = Vec::new();
    let mut poses = Vec::new();
    for i in 0..n {
        let a = random_iso(&mut rng, 1.2, 300.0);
        let b = z.inverse() * a * x; // T_board_cam
        obs.push(view(i, Some(a)));
        poses.push(b.inverse());
    }
    (obs, poses)
}

fn status_of(obs: &[ViewObs]) -> Vec<ViewStatus> {
    obs.iter().map(ViewStatus::observed).collect()
}

#[test]
fn outlier_stage_leaves_out_the_view_with_a_wrong_robot_pose() {
    let mut rng = SplitMix64(11);
    let x = random_iso(&mut rng, 3.0, 80.0);
    let z = random_iso(&mut rng, 3.0, 600.0);
    let (mut obs, poses) = exact_rig(8, &x, &z, 5);
    // view 3's joints were mistyped: its flange pose is 2 degrees off
    let bad = iso_from_rotvec(
        &Vector3::new(0.0, 2f64.to_radians(), 0.0),
        &Vector3::zeros(),
    );
    obs[3].base_hand = obs[3].base_hand.map(|a| a * bad);
    obs[6].base_hand = None;
    let mut warnings = Vec::new();
    let mut status = status_of(&obs);
    let opts = CalibrateOptions::default();
    let p = check_pairing(&obs, &poses, &[], &opts, &mut warnings, &mut status).unwrap();
    let (sol, keep) = (p.axzb, p.keep);
    assert_eq!(keep, [true, true, true, false, true, true, false, true]);
    assert!(warnings[0].starts_with("view 6: left out, no robot pose"));
    assert!(warnings[1].contains("view 3: its robot pose does not fit its image"));
    assert!(p.check.passed && p.check.views == [3], "{:?}", p.check);
    assert!(status[3]
        .note
        .as_deref()
        .unwrap()
        .contains("check its joint readings"));
    // the others are exact: X and Z recovered to round-off
    assert!((sol.x.rotation.angle_to(&x.rotation)) < 1e-9);
    assert!((sol.z.translation.vector - z.translation.vector).norm() < 1e-6);
}

#[test]
fn outlier_stage_keeps_every_consistent_view() {
    let mut rng = SplitMix64(12);
    let x = random_iso(&mut rng, 3.0, 80.0);
    let z = random_iso(&mut rng, 3.0, 600.0);
    let (obs, poses) = exact_rig(6, &x, &z, 7);
    let mut warnings = Vec::new();
    let mut status = status_of(&obs);
    let p = check_pairing(
        &obs,
        &poses,
        &[],
        &CalibrateOptions::default(),
        &mut warnings,
        &mut status,
    )
    .unwrap();
    assert!(p.keep.iter().all(|&k| k));
    assert!(p.check.passed && p.check.views.is_empty());
    assert!(status.iter().all(|s| s.note.is_none()));
}

#[test]
fn stripe_extent_is_the_grid_grown_by_half_a_pitch() {
    let board = Board::hp3_paper();
    let (lo, hi) = grid_extent(&board);
    let (mut xmin, mut xmax) = (f64::INFINITY, f64::NEG_INFINITY);
    for (r, c) in board.indices() {
        let p = board.center(r, c);
        xmin = xmin.min(p.x);
        xmax = xmax.max(p.x);
    }
    assert_eq!(lo.x, xmin - 0.5 * board.pitch_mm);
    assert_eq!(hi.x, xmax + 0.5 * board.pitch_mm);
    assert!(lo.y < hi.y);
}

#[test]
fn kept_views_and_usability() {
    let obs: Vec<ViewObs> = (0..4).map(|i| view(i, Some(Iso3::identity()))).collect();
    let poses = vec![Iso3::identity(); 4];
    let (o, p) = kept(&obs, &poses, &[true, false, true, true]);
    assert_eq!(o.iter().map(|v| v.view).collect::<Vec<_>>(), [0, 2, 3]);
    assert_eq!(p.len(), 3);
    assert!(check_usable(&o, &[]).is_ok());
    let e = check_usable(&o[..2], &["view 1: gone".to_string()]).unwrap_err();
    assert!(e
        .to_string()
        .contains("at least 3 usable views, 2 left (view 1: gone)"));
    // Views without stripe points are usable: the calibration then has no laser plane.
    let mut dark = o.clone();
    for v in &mut dark {
        v.stripe.clear();
    }
    assert!(check_usable(&dark, &[]).is_ok());
}

#[test]
fn labellings_pass_through_when_every_image_decides() {
    let obs: Vec<ViewObs> = (0..3).map(|i| view(i, Some(Iso3::identity()))).collect();
    let poses: Vec<(usize, Iso3)> = vec![(2, Iso3::identity()), (0, Iso3::identity())];
    let mut warnings = Vec::new();
    let (labelled, note) = resolve_labellings(&obs, &poses, &Board::hp3_paper(), &mut warnings);
    // in the camera calibration's order, views it dropped (1) absent
    let views: Vec<usize> = labelled
        .iter()
        .map(|l| l.as_ref().unwrap().0.view)
        .collect();
    assert_eq!(views, [2, 0]);
    assert!(note.is_none() && warnings.is_empty());
}

#[test]
fn view_records_carry_status_and_finite_figures() {
    let obs: Vec<ViewObs> = (0..3).map(|i| view(i, None)).collect();
    let mut status = status_of(&obs);
    status[0].used = true;
    status[0].stripe_used = 1;
    status[2].note = Some("left out: why".into());
    // per view: (view, circle rms, stripe rms, outlier)
    let figures = [(0, 0.1, f64::NAN, false), (1, 0.2, 0.3, true)];
    let r = view_records_from(&status, &figures);
    assert_eq!(r[0].circle_rms_px, Some(0.1));
    assert_eq!(r[0].stripe_rms_px, None);
    assert_eq!((r[0].used, r[0].stripe_points), (true, 1));
    assert_eq!(r[1].outlier, Some(true));
    assert_eq!((r[2].outlier, r[2].circle_rms_px), (None, None));
    assert_eq!(r[2].note.as_deref(), Some("left out: why"));
}

/// The board-frame rectangle the stripe points had to fall in before the selection by
/// the board plane ([`super::stripe_select`]): a circle grid's centres grown by half a
/// pitch, a chessboard's squares.
fn grid_extent(board: &Board) -> (nalgebra::Vector2<f64>, nalgebra::Vector2<f64>) {
    use crate::model::board::BoardKind;
    use nalgebra::Vector2;
    if board.kind == BoardKind::Chessboard {
        let e = board.pattern_extent();
        return (Vector2::new(e[0], e[2]), Vector2::new(e[1], e[3]));
    }
    let (mut lo, mut hi) = (
        Vector2::new(f64::INFINITY, f64::INFINITY),
        Vector2::new(f64::NEG_INFINITY, f64::NEG_INFINITY),
    );
    for (r, c) in board.indices() {
        let p = board.center(r, c);
        lo = lo.inf(&Vector2::new(p.x, p.y));
        hi = hi.sup(&Vector2::new(p.x, p.y));
    }
    let m = 0.5 * board.pitch_mm;
    (lo.add_scalar(-m), hi.add_scalar(m))
}
