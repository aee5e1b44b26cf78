//! From a dataset (or from observations) to a calibration: the paper's multi-stage
//! pipeline and the one-stage adjustment on top of it.
//!
//! ## Steps
//!
//! 1. Observations ([`observe_dataset`]): per view, circles detected in the board image;
//!    the stripe extracted from the laser image (the rig's stripe direction), points
//!    whose support shows a reflectance edge in the board image dropped (single-image
//!    views, where the laser image is the board image, use the single-image edge test);
//!    `T_base_hand` from the joints by forward kinematics of the rig's (nominal) robot,
//!    or the reported flange pose. A view whose board is not found is left out with a
//!    warning naming it; images and joints stay paired by row.
//! 2. Camera ([`crate::calib::camera`]): Zhang, then LM with the bias-free centre model.
//! 3. Stripe points on the board: each is intersected with its view's board plane and
//!    kept when it falls inside the circle grid's extent grown by half a pitch (points on
//!    the table or beyond the plate belong to another surface).
//! 4. Laser plane ([`crate::calib::laser_plane`]) and `AX = ZB`
//!    ([`crate::calib::axzb`]). Views whose robot pose disagrees with their board pose
//!    (`A_i X` vs `Z B_i`, leave-one-out) far beyond the others are left out as outliers
//!    with a warning and the figures (a swapped or mistyped joint reading).
//! 5. `Method::Paper` stops here; `Method::OneStage` (default) runs
//!    [`crate::calib::joint`] from these values.

use std::path::Path;

use nalgebra::Vector2;
use rayon::prelude::*;
use serde_json::{json, Map, Value};

use crate::calib::axzb::{solve_axzb, AxzbSolution};
use crate::calib::camera::{calibrate_camera, CameraCalibration, CameraOptions};
use crate::calib::conic::CentreModel;
use crate::calib::consensus::{self, Candidates, Decision};
use crate::calib::joint::{joint_adjustment, JointOptions, JointResult, JointStart};
use crate::calib::laser_plane::{backproject_to_board, fit_laser_plane, LaserPlaneFit};
use crate::calib::{CircleObs, ViewObs};
use crate::error::{Error, Result};
use crate::io::load_gray_info;
use crate::model::board::Board;
use crate::model::camera::{DistortionModel, PARAM_NAMES};
use crate::model::geometry::Iso3;
use crate::model::{Calibration, Dataset, Quality, Rig};
use crate::numerics::robust::median;
use crate::vision::stripe::{extract_stripe, flag_reflectance_edges, EdgeOptions, StripeOptions};
use crate::vision::target::{detect_target, TargetOptions};

/// Which pipeline.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum Method {
    /// The paper's: camera, then plane, then linear AX = ZB.
    Paper,
    /// The paper's stages, then the one-stage adjustment of everything.
    #[default]
    OneStage,
}

impl Method {
    /// `paper` or `one-stage`.
    pub fn name(self) -> &'static str {
        match self {
            Method::Paper => "paper",
            Method::OneStage => "one-stage",
        }
    }
    /// Parses [`Method::name`].
    pub fn from_name(s: &str) -> Result<Method> {
        match s {
            "paper" => Ok(Method::Paper),
            "one-stage" => Ok(Method::OneStage),
            o => Err(Error::InvalidInput(format!(
                "unknown calibration method {o:?}: expected \"paper\" or \"one-stage\""
            ))),
        }
    }
}

/// Options of the calibration pipeline.
#[derive(Debug, Clone, PartialEq)]
pub struct CalibrateOptions {
    /// Distortion model (default: the rig's).
    pub distortion: Option<DistortionModel>,
    pub method: Method,
    /// Huber loss in the one-stage adjustment.
    pub robust: bool,
    pub centre_model: CentreModel,
    /// Target detection (every kind).
    pub target: TargetOptions,
    pub stripe: StripeOptions,
    pub edges: EdgeOptions,
    /// Leave-one-out AX = ZB consistency: a view is an outlier when its rotation error
    /// exceeds `max(outlier_factor * median, outlier_min_deg)` or its translation error
    /// `max(outlier_factor * median, outlier_min_rel * stand-off)`.
    pub outlier_factor: f64,
    pub outlier_min_deg: f64,
    pub outlier_min_rel: f64,
}

impl Default for CalibrateOptions {
    fn default() -> Self {
        CalibrateOptions {
            distortion: None,
            method: Method::OneStage,
            robust: false,
            centre_model: CentreModel::ConicExact,
            target: TargetOptions::default(),
            stripe: StripeOptions::default(),
            edges: EdgeOptions::default(),
            outlier_factor: 8.0,
            outlier_min_deg: 0.1,
            outlier_min_rel: 0.005,
        }
    }
}

/// What the pipeline did with one view.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewStatus {
    /// Row in views.csv (0-based).
    pub view: usize,
    pub circles: usize,
    /// Stripe points extracted / used on the board.
    pub stripe_points: usize,
    pub stripe_used: usize,
    pub used: bool,
    /// Why it was left out, if it was.
    pub note: Option<String>,
}

/// The paper's stages.
#[derive(Debug, Clone)]
pub struct Stages {
    pub camera: CameraCalibration,
    pub plane: LaserPlaneFit,
    pub axzb: AxzbSolution,
}

/// The result of the pipeline.
#[derive(Debug, Clone)]
pub struct CalibrationReport {
    /// The calibration (spec's calibration.json content, with quality and uncertainty).
    pub calibration: Calibration,
    pub method: Method,
    pub stages: Stages,
    /// The adjustment's figures (the one-stage result, or the paper result evaluated
    /// with the same residuals for `Method::Paper`).
    pub adjustment: JointResult,
    pub views: Vec<ViewStatus>,
    pub warnings: Vec<String>,
}

/// Detects circles and stripes of every view of a dataset (in parallel over views).
///
/// Returns the observations of the views whose board was found, and warnings naming the
/// others. Image files that cannot be read are errors (naming the file).
pub fn observe_dataset(
    ds: &Dataset,
    opts: &CalibrateOptions,
) -> Result<(Vec<ViewObs>, Vec<String>)> {
    let rig = &ds.rig;
    let lossy = std::sync::atomic::AtomicUsize::new(0);
    let mut stripe_opts = opts.stripe.clone();
    stripe_opts.direction = rig.stripe_direction;
    let results: Vec<Result<std::result::Result<ViewObs, String>>> = ds
        .views
        .par_iter()
        .enumerate()
        .map(|(i, v)| -> Result<std::result::Result<ViewObs, String>> {
            let tag = format!("view {i} (views.csv line {})", v.line);
            let base_hand = v
                .reading
                .base_hand(rig.robot.as_ref())
                .map_err(|e| Error::InvalidInput(format!("{tag}: robot pose: {e}")))?;
            let (board_img, info) = load_gray_info(ds.image_path(&v.board_image))?;
            if board_img.size() != (rig.width as usize, rig.height as usize) {
                return Err(Error::InvalidInput(format!(
                    "{tag}: {} is {} x {}, rig.json says {} x {}",
                    v.board_image.display(),
                    board_img.size().0,
                    board_img.size().1,
                    rig.width,
                    rig.height
                )));
            }
            if info.lossy {
                lossy.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            }
            let bview = board_img.view()?;
            let det = match detect_target(bview, &rig.board, &opts.target) {
                Ok(g) => g,
                Err(e) => return Ok(Err(format!("{tag}: left out, board not found: {e}"))),
            };
            let circles = det
                .points
                .iter()
                .map(|c| CircleObs {
                    row: c.row,
                    col: c.col,
                    u: c.u,
                    v: c.v,
                })
                .collect();
            let mut stripe = Vec::new();
            if let Some(lp) = &v.laser_image {
                let single = lp == &v.board_image;
                let laser_img;
                let lview = if single {
                    bview
                } else {
                    let (img, info) = load_gray_info(ds.image_path(lp))?;
                    if info.lossy {
                        lossy.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
                    }
                    laser_img = img;
                    if laser_img.size() != board_img.size() {
                        return Err(Error::InvalidInput(format!(
                            "{tag}: {} and {} differ in size",
                            lp.display(),
                            v.board_image.display()
                        )));
                    }
                    laser_img.view()?
                };
                match extract_stripe(lview, &stripe_opts) {
                    Ok(mut s) => {
                        let eo = EdgeOptions {
                            single_image: single,
                            ..opts.edges.clone()
                        };
                        flag_reflectance_edges(&mut s, bview, &eo)?;
                        stripe = s
                            .points
                            .iter()
                            .filter(|p| p.trusted())
                            .map(|p| [p.u, p.v])
                            .collect();
                    }
                    Err(Error::Detection(_)) => {}
                    Err(e) => return Err(e),
                }
            }
            Ok(Ok(ViewObs {
                view: i,
                circles,
                stripe,
                reading: Some(v.reading.clone()),
                base_hand: Some(base_hand),
                alternatives: det.alternatives,
            }))
        })
        .collect();
    let mut obs = Vec::new();
    let mut warnings = Vec::new();
    let lossy = lossy.into_inner();
    if lossy > 0 {
        warnings.push(format!(
            "{lossy} image(s) are JPEG: lossy compression costs accuracy (accepted; PNG, TIFF \
             or BMP keep every grey level)"
        ));
    }
    for r in results {
        match r? {
            Ok(o) => obs.push(o),
            Err(w) => warnings.push(w),
        }
    }
    Ok((obs, warnings))
}

/// The board-frame rectangle the stripe points must fall in: a circle grid's centres
/// grown by half a pitch, a chessboard's squares.
fn grid_extent(board: &Board) -> (Vector2<f64>, Vector2<f64>) {
    if board.kind == crate::model::board::BoardKind::Chessboard {
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

/// A view after the labelling choice: the relabelled view with its `T_cam_board`, or
/// `(view, why it is left out)`.
type Labelled = std::result::Result<(ViewObs, Iso3), (usize, String)>;

/// Chooses, for every view whose image leaves its labelling open (a symmetric board),
/// the labelling that agrees with the robot poses of the others ([`consensus`]), and
/// relabels its points and board pose. Views that cannot be decided are left out with
/// the reason (and a warning). Returns the views in `poses` order and, when the board
/// frame itself was fixed by the first view's labelling (no view's image fixes it), the
/// contract's note `"first view"`.
fn resolve_labellings(
    views: &[ViewObs],
    poses: &[(usize, Iso3)],
    board: &Board,
    warnings: &mut Vec<String>,
) -> (Vec<Labelled>, Option<String>) {
    let items: Vec<(&ViewObs, Iso3)> = poses
        .iter()
        .filter_map(|(view, cb)| views.iter().find(|v| v.view == *view).map(|v| (v, *cb)))
        .collect();
    if items.iter().all(|(v, _)| v.alternatives.is_empty()) {
        return (
            items
                .into_iter()
                .map(|(v, cb)| Ok((v.clone(), cb)))
                .collect(),
            None,
        );
    }
    // candidates: the detected labelling, then each alternative (T_board_cam = M B)
    let motions: Vec<Vec<(Option<crate::model::board::Symmetry>, Iso3)>> = items
        .iter()
        .map(|(v, _)| {
            std::iter::once((None, Iso3::identity()))
                .chain(
                    v.alternatives
                        .iter()
                        .map(|s| (Some(*s), consensus::symmetry_motion(board, s))),
                )
                .collect()
        })
        .collect();
    // views without a robot pose cannot take part (left as detected)
    let with_robot: Vec<usize> = (0..items.len())
        .filter(|&k| items[k].0.base_hand.is_some())
        .collect();
    let cands: Vec<Candidates> = with_robot
        .iter()
        .map(|&k| Candidates {
            a: items[k].0.base_hand.unwrap_or_else(Iso3::identity),
            b: motions[k]
                .iter()
                .map(|(_, m)| m * items[k].1.inverse())
                .collect(),
        })
        .collect();
    let decisions = consensus::choose(&cands);
    let frame_fixed_by_first = items.iter().all(|(v, _)| !v.alternatives.is_empty());
    let mut out = Vec::with_capacity(items.len());
    for (k, (v, cb)) in items.iter().enumerate() {
        let Some(pos) = with_robot.iter().position(|&j| j == k) else {
            out.push(Ok(((*v).clone(), *cb)));
            continue;
        };
        match decisions[pos] {
            Decision::Chosen { index, .. } => {
                let (sym, m) = motions[k][index];
                let mut v2 = (*v).clone();
                if let Some(s) = sym {
                    for c in v2.circles.iter_mut() {
                        if let Some((r, cc)) = s.apply(board, c.row, c.col) {
                            (c.row, c.col) = (r, cc);
                        }
                    }
                    v2.circles.sort_by_key(|c| (c.row, c.col));
                }
                v2.alternatives.clear();
                // T_cam_board of the new labelling: T_cam_board M^-1
                out.push(Ok((v2, cb * m.inverse())));
            }
            Decision::Undecided { best, second } => {
                let why = if best > 25.0 {
                    "none of its labellings agrees with the robot poses of the other views \
                     (its robot pose, or its image, is wrong?)"
                } else {
                    "its labellings agree about equally well with the robot poses of the other \
                     views"
                };
                let msg = format!(
                    "view {}: left out: its orientation on the symmetric board cannot be told: \
                     {why} (the two best disagree by {:.1} and {:.1} sigma; sigma = 0.2 deg / \
                     1 mm of screw motion)",
                    v.view,
                    best.sqrt(),
                    second.sqrt()
                );
                warnings.push(msg.clone());
                out.push(Err((v.view, msg)));
            }
        }
    }
    let note = frame_fixed_by_first.then(|| "first view".to_string());
    (out, note)
}

/// Leave-one-out candidate: score, view, its error, the others' median error.
type Candidate = (f64, usize, (f64, f64), (f64, f64));

/// Rotation (deg) and translation (mm) disagreement of `A X` and `Z B`.
fn axzb_error(a: &Iso3, x: &Iso3, z: &Iso3, b: &Iso3) -> (f64, f64) {
    let l = a * x;
    let r = z * b;
    (
        l.rotation.angle_to(&r.rotation).to_degrees(),
        (l.translation.vector - r.translation.vector).norm(),
    )
}

/// Runs the pipeline on observations (see the module docs). `views` are the views whose
/// board was found; `rig` gives the board, image size, distortion model and robot.
pub fn calibrate_observations(
    views: &[ViewObs],
    rig: &Rig,
    opts: &CalibrateOptions,
) -> Result<CalibrationReport> {
    let board = &rig.board;
    let model = opts.distortion.unwrap_or(rig.distortion_model);
    let mut warnings = Vec::new();
    let mut status: Vec<ViewStatus> = views
        .iter()
        .map(|v| ViewStatus {
            view: v.view,
            circles: v.circles.len(),
            stripe_points: v.stripe.len(),
            stripe_used: 0,
            used: false,
            note: None,
        })
        .collect();
    for v in views {
        if let Some(t) = v.base_hand {
            if !t.to_homogeneous().iter().all(|x| x.is_finite()) {
                return Err(Error::InvalidInput(format!(
                    "view {}: the robot pose is not finite",
                    v.view
                )));
            }
        }
    }
    // 2. Camera.
    // The one-stage adjustment refines the camera with the requested centre model; its
    // starting camera only needs the first-order conic model (much cheaper).
    let one_stage = opts.method == Method::OneStage;
    let mut cam_opts = CameraOptions {
        centre_model: if one_stage && opts.centre_model == CentreModel::ConicExact {
            CentreModel::Conic
        } else {
            opts.centre_model
        },
        ..Default::default()
    };
    if one_stage {
        // A starting point: the joint adjustment converges from it.
        cam_opts.lm.ftol = 1e-8;
        cam_opts.lm.xtol = 1e-8;
    }
    let camcal = calibrate_camera(views, board, rig.width, rig.height, model, &cam_opts)?;
    warnings.extend(camcal.warnings.iter().cloned());
    // Labellings the images leave open, from the robot poses.
    let (labelled, frame_note) = resolve_labellings(views, &camcal.poses, board, &mut warnings);
    for (view, note) in labelled.iter().filter_map(|l| l.as_ref().err()) {
        if let Some(s) = status.iter_mut().find(|s| s.view == *view) {
            s.note = Some(note.clone());
        }
    }
    // 3. Stripe points on the board.
    let (lo, hi) = grid_extent(board);
    let mut obs: Vec<ViewObs> = Vec::new();
    let mut poses: Vec<Iso3> = Vec::new();
    for (v, cb) in labelled.iter().filter_map(|l| l.as_ref().ok()) {
        let bc = cb.inverse();
        let stripe: Vec<[f64; 2]> = v
            .stripe
            .iter()
            .filter(|uv| match backproject_to_board(&camcal.camera, cb, uv) {
                Ok(p) => {
                    let q = bc * nalgebra::Point3::from(p);
                    q.x >= lo.x && q.x <= hi.x && q.y >= lo.y && q.y <= hi.y
                }
                Err(_) => false,
            })
            .copied()
            .collect();
        obs.push(ViewObs {
            stripe,
            ..v.clone()
        });
        poses.push(*cb);
    }
    // 4. Robot poses, AX = ZB with leave-one-out outlier rejection.
    let mut keep: Vec<bool> = obs.iter().map(|v| v.base_hand.is_some()).collect();
    for (v, k) in obs.iter().zip(&keep) {
        if !k {
            warnings.push(format!("view {}: left out, no robot pose", v.view));
        }
    }
    let solve = |keep: &[bool]| -> Result<AxzbSolution> {
        let (mut a, mut b) = (Vec::new(), Vec::new());
        for ((v, cb), k) in obs.iter().zip(&poses).zip(keep) {
            if let (true, Some(bh)) = (*k, v.base_hand) {
                a.push(bh);
                b.push(cb.inverse());
            }
        }
        solve_axzb(&a, &b)
    };
    let standoff = {
        let mut d: Vec<f64> = poses.iter().map(|p| p.translation.vector.norm()).collect();
        median(&mut d).unwrap_or(0.0)
    };
    let mut axzb = solve(&keep)?;
    loop {
        let active: Vec<usize> = (0..obs.len()).filter(|&i| keep[i]).collect();
        if active.len() <= 3 {
            break;
        }
        // Leave one out: the view whose removal lets the others agree best is the
        // candidate; it is an outlier when its own disagreement under the others'
        // solution is far beyond theirs.
        let mut best: Option<Candidate> = None;
        for &i in &active {
            let mut k2 = keep.clone();
            k2[i] = false;
            let Ok(s) = solve(&k2) else {
                continue;
            };
            let err_of = |j: usize| {
                axzb_error(
                    &obs[j].base_hand.unwrap_or_else(Iso3::identity),
                    &s.x,
                    &s.z,
                    &poses[j].inverse(),
                )
            };
            let mut rot: Vec<f64> = Vec::new();
            let mut tr: Vec<f64> = Vec::new();
            for &j in active.iter().filter(|&&j| j != i) {
                let e = err_of(j);
                rot.push(e.0);
                tr.push(e.1);
            }
            let (mr, mt) = (
                median(&mut rot).unwrap_or(0.0),
                median(&mut tr).unwrap_or(0.0),
            );
            let score = mr / opts.outlier_min_deg + mt / (opts.outlier_min_rel * standoff);
            if best.is_none_or(|b| score < b.0) {
                best = Some((score, i, err_of(i), (mr, mt)));
            }
        }
        let worst = best.and_then(|(_, i, (er, et), (mr, mt))| {
            let lim_r = (opts.outlier_factor * mr).max(opts.outlier_min_deg);
            let lim_t = (opts.outlier_factor * mt).max(opts.outlier_min_rel * standoff);
            (er > lim_r || et > lim_t).then_some((i, (er, et), (mr, mt)))
        });
        let Some((i, (er, et), (mr, mt))) = worst else {
            break;
        };
        keep[i] = false;
        let msg = format!(
            "view {}: left out as an outlier: its robot pose disagrees with its board pose by \
             {er:.3} deg / {et:.3} mm (others: median {mr:.4} deg / {mt:.4} mm); check its \
             joint readings",
            obs[i].view
        );
        warnings.push(msg.clone());
        if let Some(s) = status.iter_mut().find(|s| s.view == obs[i].view) {
            s.note = Some(msg);
        }
        axzb = solve(&keep)?;
    }
    warnings.extend(axzb.warnings.iter().cloned());
    let used_obs: Vec<ViewObs> = obs
        .iter()
        .zip(&keep)
        .filter(|(_, k)| **k)
        .map(|(v, _)| v.clone())
        .collect();
    let used_poses: Vec<Iso3> = poses
        .iter()
        .zip(&keep)
        .filter(|(_, k)| **k)
        .map(|(p, _)| *p)
        .collect();
    if used_obs.len() < 3 {
        return Err(Error::InvalidInput(format!(
            "calibration needs at least 3 usable views, {} left ({})",
            used_obs.len(),
            warnings.join("; ")
        )));
    }
    if used_obs.iter().all(|v| v.stripe.is_empty()) {
        return Err(Error::InvalidInput(
            "no usable laser image: no view has stripe points on the board".into(),
        ));
    }
    // Laser plane.
    let pv: Vec<(Iso3, Vec<[f64; 2]>)> = used_poses
        .iter()
        .zip(&used_obs)
        .map(|(p, v)| (*p, v.stripe.clone()))
        .collect();
    let plane = fit_laser_plane(&pv, &camcal.camera)?;
    warnings.extend(plane.warnings.iter().cloned());
    let start = JointStart {
        camera: camcal.camera.clone(),
        plane: plane.plane,
        hand_cam: axzb.x,
        base_board: axzb.z,
    };
    let mut jopts = JointOptions {
        centre_model: opts.centre_model,
        robust: opts.robust,
        ..Default::default()
    };
    if opts.method == Method::Paper {
        jopts.lm.max_iterations = 0;
        jopts.robust = false;
    }
    let adj = joint_adjustment(&used_obs, board, &start, &jopts)?;
    warnings.extend(adj.warnings.iter().cloned());
    for s in status.iter_mut() {
        if let Some(v) = used_obs.iter().find(|v| v.view == s.view) {
            s.used = true;
            s.stripe_used = v.stripe.len();
        } else if s.note.is_none() {
            s.note = Some("left out by the camera calibration".into());
        }
    }
    let (camera, laser_plane, hand_cam, base_board) = match opts.method {
        Method::Paper => (
            start.camera.clone(),
            start.plane,
            start.hand_cam,
            start.base_board,
        ),
        Method::OneStage => (adj.camera.clone(), adj.plane, adj.hand_cam, adj.base_board),
    };
    let uncertainty = match opts.method {
        Method::OneStage => uncertainty_json(&adj),
        Method::Paper => {
            let mut u = Map::new();
            u.insert("camera".into(), camera_sigma_json(&camcal.camera_sigma));
            u.insert(
                "laser_plane".into(),
                json!({"normal": plane.sigma.normal.as_slice(), "d_mm": plane.sigma.d_mm}),
            );
            u
        }
    };
    let mut extra = Map::new();
    extra.insert("method".into(), json!(opts.method.name()));
    extra.insert("centre_model".into(), json!(opts.centre_model.name()));
    if let Some(note) = frame_note {
        extra.insert("base_board_orientation".into(), json!(note));
    }
    extra.insert("stripe_rms_mm".into(), json!(adj.stripe_rms_mm));
    extra.insert(
        "residual_sigma_px".into(),
        json!({"circle": adj.sigma_px.0, "stripe": adj.sigma_px.1}),
    );
    extra.insert(
        "views".into(),
        Value::Array(
            status
                .iter()
                .map(|s| {
                    let r = adj.views.iter().find(|r| r.view == s.view);
                    json!({
                        "view": s.view,
                        "used": s.used,
                        "circles": s.circles,
                        "stripe_points": s.stripe_used,
                        "circle_rms_px": r.map(|r| finite_or_null(r.circle_rms_px)),
                        "stripe_rms_px": r.map(|r| finite_or_null(r.stripe_rms_px)),
                        "outlier": r.map(|r| r.outlier),
                        "note": s.note,
                    })
                })
                .collect(),
        ),
    );
    if !warnings.is_empty() {
        extra.insert("warnings".into(), json!(warnings));
    }
    let calibration = Calibration {
        camera,
        laser_plane,
        hand_cam,
        base_board,
        robot: rig.robot.clone(),
        quality: Quality {
            circle_rms_px: adj.circle_rms_px,
            stripe_rms_px: adj.stripe_rms_px,
            views_used: used_obs.len(),
        },
        uncertainty,
        extra,
    };
    Ok(CalibrationReport {
        calibration,
        method: opts.method,
        stages: Stages {
            camera: camcal,
            plane,
            axzb,
        },
        adjustment: adj,
        views: status,
        warnings,
    })
}

fn finite_or_null(x: f64) -> Value {
    if x.is_finite() {
        json!(x)
    } else {
        Value::Null
    }
}

fn camera_sigma_json(s: &[f64; 9]) -> Value {
    let mut m = Map::new();
    for (i, name) in PARAM_NAMES.iter().enumerate().take(4) {
        m.insert((*name).into(), finite_or_null(s[i]));
    }
    m.insert(
        "distortion".into(),
        Value::Array(s[4..].iter().map(|x| finite_or_null(*x)).collect()),
    );
    Value::Object(m)
}

fn uncertainty_json(adj: &JointResult) -> Map<String, Value> {
    let s = &adj.sigma;
    let mut u = Map::new();
    u.insert("camera".into(), camera_sigma_json(&s.camera));
    u.insert(
        "laser_plane".into(),
        json!({
            "normal": s.plane_normal.iter().map(|x| finite_or_null(*x)).collect::<Vec<_>>(),
            "d_mm": finite_or_null(s.plane_d_mm),
        }),
    );
    for (k, t) in [("hand_cam", &s.hand_cam), ("base_board", &s.base_board)] {
        u.insert(
            k.into(),
            json!({
                "rotation_vector": t.rotation_vector.iter().map(|x| finite_or_null(*x)).collect::<Vec<_>>(),
                "translation_mm": t.translation_mm.iter().map(|x| finite_or_null(*x)).collect::<Vec<_>>(),
            }),
        );
    }
    u
}

/// Loads a dataset folder, observes it and calibrates it ([`calibrate_dataset_loaded`]).
pub fn calibrate_dataset(
    root: impl AsRef<Path>,
    opts: &CalibrateOptions,
) -> Result<CalibrationReport> {
    calibrate_dataset_loaded(&Dataset::load(root)?, opts)
}

/// Observes and calibrates a loaded dataset: [`observe_dataset`], then
/// [`calibrate_observations`]; views left out by the detection are listed in the
/// report's views and warnings.
pub fn calibrate_dataset_loaded(
    ds: &Dataset,
    opts: &CalibrateOptions,
) -> Result<CalibrationReport> {
    let (obs, mut warnings) = observe_dataset(ds, opts)?;
    if obs.len() < 3 && obs.len() < ds.views.len() {
        // Not an input the adjustment could start from because views were refused: say
        // which views and why.
        let why: Vec<&String> = warnings
            .iter()
            .filter(|w| w.contains("board not found"))
            .collect();
        return Err(Error::Detection(format!(
            "the board ({} x {} {}) was found in {} of {} views, at least 3 are needed: {}",
            ds.rig.board.rows,
            ds.rig.board.cols,
            ds.rig.board.kind.name(),
            obs.len(),
            ds.views.len(),
            why.iter()
                .map(|w| w.as_str())
                .collect::<Vec<_>>()
                .join("; ")
        )));
    }
    let mut rep = calibrate_observations(&obs, &ds.rig, opts)?;
    for v in 0..ds.views.len() {
        if !rep.views.iter().any(|s| s.view == v) {
            rep.views.push(ViewStatus {
                view: v,
                circles: 0,
                stripe_points: 0,
                stripe_used: 0,
                used: false,
                note: warnings
                    .iter()
                    .find(|w| w.starts_with(&format!("view {v} ")))
                    .cloned(),
            });
        }
    }
    rep.views.sort_by_key(|s| s.view);
    warnings.append(&mut rep.warnings);
    rep.warnings = warnings;
    if !rep.warnings.is_empty() {
        rep.calibration
            .extra
            .insert("warnings".into(), json!(rep.warnings));
    }
    Ok(rep)
}
