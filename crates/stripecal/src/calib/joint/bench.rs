//! The bench: the sensor calibrated on its own, the board moved by hand (a views.csv
//! without pose columns, spec/DATASET.md). The same one-stage adjustment with the robot
//! chain absent: the camera and the laser plane (global blocks), and each view's board
//! pose `T_cam_board(i)` as a free per-view block ([`super::layout::Block::BoardPose`]).
//! `X`, `Z` and the board scale are held (at the identity and 1; the bench cannot
//! determine a board scale: a larger board farther away images alike).
//!
//! The residuals are the robot's: circle centres and stripe points against the line
//! where the laser plane meets the view's board plane. A view's board pose reaches them
//! through `Z`'s slots: with `A_i = X = I`, `T_cam_board = (A_i X)^-1 Z = Z`, so the
//! derivatives along `Z`'s slots of a view's rows are that view's board-pose columns
//! (the robot-pose correction reaches its rows through `X`'s the same way). The solve
//! schedule, the variance components, the covariance (`camera.*`, `laser_plane.*` under
//! the contract's names, the board poses estimated alongside) and the per-view report
//! are the adjustment's own.

use super::finish::{finish, FinalSolve};
use super::layout::ParamLayout;
use super::residuals::{JointProblem, Terms};
use super::{free_blocks, solve, JointOptions, JointResult, JointStart};
use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::board::Board;
use crate::model::geometry::Iso3;

/// The bench adjustment (module docs) over `views`, each view's board pose starting at
/// `board_poses` (`T_cam_board`, one per view, in `views`' order: e.g. Zhang's).
/// `start.hand_cam` and `start.base_board` are not used (the result holds the
/// identity); `opts.free` says whether the camera and the laser plane are estimated
/// (the others are held anyway); `opts.robot_noise` and `opts.robot` do not apply.
///
/// With the camera and the plane held only the board poses are estimated (any number of
/// views: each pose from its own observations).
///
/// Errors: [`Error::InvalidInput`] when `board_poses` does not match `views`, for fewer
/// than 3 views with an observation while the camera is estimated (2 with stripe points
/// when only the plane is), non-finite observations, stripe points without a starting plane;
/// [`Error::Degenerate`] when a view's stripe line cannot be formed; solver errors.
pub fn bench_adjustment(
    views: &[ViewObs],
    board: &Board,
    start: &JointStart,
    board_poses: &[Iso3],
    opts: &JointOptions,
) -> Result<JointResult> {
    board.validate()?;
    start.camera.validate()?;
    if board_poses.len() != views.len() {
        return Err(Error::InvalidInput(format!(
            "the bench adjustment needs one starting board pose per view: {} views, {} poses",
            views.len(),
            board_poses.len()
        )));
    }
    let finite = |t: &Iso3| {
        t.translation.vector.iter().all(|x| x.is_finite())
            && t.rotation.coords.iter().all(|x| x.is_finite())
    };
    if let Some((v, _)) = views.iter().zip(board_poses).find(|(_, t)| !finite(t)) {
        return Err(Error::InvalidInput(format!(
            "view {}: its starting board pose is not finite",
            v.view
        )));
    }
    let mut warnings = Vec::new();
    let terms = Terms::collect_bench(views, board, &mut warnings)?;
    let opts = JointOptions {
        robot_noise: false,
        robot: None,
        board_scale: 1.0,
        ..opts.clone()
    };
    let held_chain = JointOptions {
        free: super::FreeBlocks {
            hand_cam: false,
            base_board: false,
            board_scale: false,
            ..opts.free
        },
        ..opts.clone()
    };
    // With the camera and plane held only the board poses are estimated (one view
    // suffices: its pose from its own circles, the leave-one-out's).
    let free = free_blocks(&terms, start, &held_chain)?;
    if terms.used.is_empty() {
        return Err(Error::InvalidInput(
            "the bench adjustment has no view with an observation".into(),
        ));
    }
    let poses: Vec<Iso3> = terms
        .used
        .iter()
        .filter_map(|id| views.iter().position(|v| v.view == *id))
        .map(|i| board_poses[i])
        .collect();
    let start = JointStart {
        hand_cam: Iso3::identity(),
        base_board: Iso3::identity(),
        ..start.clone()
    };
    let layout = ParamLayout::bench(&start, &free, &terms.used, &poses);
    let mut problem = JointProblem::new(&start.camera, &layout, terms, &opts);
    let (res, iterations) = solve(&mut problem, layout.encode(), &opts, false)?;
    let solved = FinalSolve {
        layout: &layout,
        problem: &problem,
        res,
        iterations,
    };
    finish(&start, free, &opts, solved, warnings, None)
}

#[cfg(test)]
mod tests {
    use nalgebra::Vector3;

    use super::*;
    use crate::calib::conic::{predict_centre, CentreModel};
    use crate::calib::laser_plane::stripe_line_in_view;
    use crate::calib::CircleObs;
    use crate::model::camera::{Camera, DistortionModel, Intrinsics};
    use crate::model::geometry::{iso_from_rotvec, Plane};

    struct Bench {
        cam: Camera,
        plane: Plane,
        poses: Vec<Iso3>,
        views: Vec<ViewObs>,
    }

    /// Exact observations of a board held in six poses (tilted up to ~0.35 rad, 100 to
    /// 130 mm away) before a fixed camera and laser.
    fn bench() -> Bench {
        let cam = Camera::new(
            768,
            576,
            Intrinsics {
                fu: 1270.0,
                fv: 1320.0,
                u0: 380.0,
                v0: 290.0,
            },
            DistortionModel::Radial2,
            [0.05, -0.02, 0.0, 0.0, 0.0],
        )
        .unwrap();
        let plane = Plane::new(Vector3::new(0.629, -0.0492, 0.7759), 79.87).unwrap();
        let board = Board::hp3_paper();
        let poses: Vec<Iso3> = [
            ([3.1, 0.05, 0.0], [-18.0, -12.0, 112.0]),
            ([2.9, 0.3, 0.1], [-20.0, -10.0, 105.0]),
            ([3.0, -0.25, -0.1], [-15.0, -14.0, 120.0]),
            ([3.3, 0.1, 0.2], [-22.0, -8.0, 128.0]),
            ([2.95, -0.1, 0.35], [-16.0, -15.0, 100.0]),
            ([3.2, 0.2, -0.3], [-19.0, -11.0, 115.0]),
        ]
        .iter()
        .map(|(w, t)| iso_from_rotvec(&Vector3::from(*w), &Vector3::from(*t)))
        .collect();
        let views = poses
            .iter()
            .enumerate()
            .map(|(i, cb)| {
                let circles = board
                    .indices()
                    .map(|(r, c)| {
                        let uv = predict_centre(
                            &cam,
                            cb,
                            &board.center(r, c),
                            0.5 * board.diameter(r, c),
                            CentreModel::ConicExact,
                        )
                        .unwrap();
                        CircleObs {
                            row: r,
                            col: c,
                            u: uv.x,
                            v: uv.y,
                        }
                    })
                    .collect();
                let l = stripe_line_in_view(&plane, cb, &cam).unwrap();
                let stripe = (-20..20)
                    .map(|s| {
                        let uv = cam
                            .project(&(l.point_cam + l.direction_cam * (s as f64)))
                            .unwrap();
                        [uv.x, uv.y]
                    })
                    .collect();
                ViewObs {
                    view: i,
                    circles,
                    stripe,
                    reading: None,
                    base_hand: None,
                    alternatives: Vec::new(),
                    stripe_shape: None,
                }
            })
            .collect();
        Bench {
            cam,
            plane,
            poses,
            views,
        }
    }

    fn perturbed(b: &Bench) -> (JointStart, Vec<Iso3>) {
        let mut p = b.cam.params();
        p[0] += 3.0;
        p[1] -= 2.0;
        p[2] += 1.5;
        p[3] -= 1.0;
        let d = iso_from_rotvec(
            &Vector3::new(0.002, -0.001, 0.003),
            &Vector3::new(0.3, -0.2, 0.4),
        );
        let start = JointStart {
            camera: b.cam.with_params(&p),
            plane: Some(
                Plane::new(
                    b.plane.normal + Vector3::new(0.01, -0.01, 0.005),
                    b.plane.d + 0.5,
                )
                .unwrap(),
            ),
            hand_cam: Iso3::identity(),
            base_board: Iso3::identity(),
        };
        (start, b.poses.iter().map(|t| d * t).collect())
    }

    /// Exact observations: the camera, the plane and every board pose are recovered.
    #[test]
    fn exact_bench_observations_recover_camera_plane_and_board_poses() {
        let b = bench();
        let (start, poses) = perturbed(&b);
        let r = bench_adjustment(
            &b.views,
            &Board::hp3_paper(),
            &start,
            &poses,
            &JointOptions::default(),
        )
        .unwrap();
        let (p, t) = (r.camera.params(), b.cam.params());
        for i in 0..9 {
            assert!(
                (p[i] - t[i]).abs() <= 1e-6 * t[i].abs().max(1e-3),
                "{i}: {} vs {}",
                p[i],
                t[i]
            );
        }
        let plane = r.plane.unwrap();
        assert!((plane.normal - b.plane.normal).norm() < 1e-9);
        assert!((plane.d - b.plane.d).abs() < 1e-7);
        assert_eq!(r.board_poses.len(), b.poses.len());
        for ((v, got), want) in r.board_poses.iter().zip(&b.poses) {
            let dr = got.rotation.angle_to(&want.rotation);
            let dt = (got.translation.vector - want.translation.vector).norm();
            assert!(dr < 1e-9 && dt < 1e-7, "view {v}: {dr} {dt}");
        }
        assert_eq!(r.hand_cam, Iso3::identity());
        let names = &r.named_covariance.parameters;
        assert!(names
            .iter()
            .all(|n| n.starts_with("camera.") || n.starts_with("laser_plane.")));
        assert!(names.contains(&"laser_plane.d_mm".to_string()), "{names:?}");
        let Err(e) = bench_adjustment(
            &b.views,
            &Board::hp3_paper(),
            &start,
            &poses[1..],
            &JointOptions::default(),
        ) else {
            panic!("expected an error: {}", "one pose short")
        };
        assert!(
            e.to_string().contains("one starting board pose per view"),
            "{e}"
        );
    }

    /// The board-pose columns of the Jacobian (through `Z`'s slots) and the camera's and
    /// plane's match central differences.
    #[test]
    fn bench_jacobian_matches_central_differences() {
        let b = bench();
        let (start, poses) = perturbed(&b);
        let board = Board::hp3_paper();
        let mut w = Vec::new();
        let terms = Terms::collect_bench(&b.views, &board, &mut w).unwrap();
        let free = super::super::FreeBlocks::default();
        let layout = ParamLayout::bench(&start, &free, &terms.used, &poses);
        let opts = JointOptions {
            variance_components: false,
            initial_sigma_px: (0.5, 2.0),
            ..JointOptions::default()
        };
        let pr = JointProblem::new(&start.camera, &layout, terms, &opts);
        let p = layout.encode();
        assert_eq!(p.len(), 6 + 3 + 6 * b.views.len());
        let step = |j: usize| {
            if j < 4 {
                1e-5 * p[j].abs().max(1e-2)
            } else {
                1e-6
            }
        };
        let worst =
            crate::numerics::lm::assert_jacobian_matches_fd(&pr, &p, step, 1e-9, 1e-5, "bench");
        println!("bench: largest relative FD difference {worst:.2e}");
    }
}
