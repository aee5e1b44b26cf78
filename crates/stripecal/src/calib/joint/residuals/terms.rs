//! The adjustment's observations: each used view's circle centres and stripe points,
//! collected from the views (with their robot poses and joint readings).

use crate::calib::ViewObs;
use crate::error::{Error, Result};
use crate::model::board::Board;
use crate::model::geometry::Iso3;

/// One circle observation.
#[derive(Debug, Clone, Copy)]
pub(in crate::calib::joint) struct CircleTerm {
    /// Index of the view among the views used.
    pub view: usize,
    pub row: usize,
    pub col: usize,
    /// Centre on the board, mm.
    pub centre: (f64, f64),
    pub radius: f64,
    /// Detected imaged centre, px.
    pub u: f64,
    pub v: f64,
}

/// One stripe point.
#[derive(Debug, Clone, Copy)]
pub(in crate::calib::joint) struct StripeTerm {
    /// Index of the view among the views used.
    pub view: usize,
    pub u: f64,
    pub v: f64,
}

/// The observations of the views used.
#[derive(Debug, Clone, Default)]
pub(in crate::calib::joint) struct Terms {
    /// `T_base_hand` of each used view.
    pub a: Vec<Iso3>,
    /// Dataset row (`ViewObs::view`) of each used view.
    pub used: Vec<usize>,
    /// The joint readings of each used view (`None`: the controller reported the
    /// flange pose).
    pub q: Vec<Option<Vec<f64>>>,
    pub circles: Vec<CircleTerm>,
    pub stripes: Vec<StripeTerm>,
}

impl Terms {
    /// The terms of the views with a robot pose and an observation (the others skipped
    /// with a warning); errors on a non-finite observation or a circle off the board.
    pub fn collect(views: &[ViewObs], board: &Board, warnings: &mut Vec<String>) -> Result<Terms> {
        Self::collect_views(views, board, false, warnings)
    }

    /// The terms of the views with an observation, on the bench: no robot pose is
    /// needed (`a` holds the identity for each; the board poses are estimated).
    pub fn collect_bench(
        views: &[ViewObs],
        board: &Board,
        warnings: &mut Vec<String>,
    ) -> Result<Terms> {
        Self::collect_views(views, board, true, warnings)
    }

    fn collect_views(
        views: &[ViewObs],
        board: &Board,
        bench: bool,
        warnings: &mut Vec<String>,
    ) -> Result<Terms> {
        let mut t = Terms::default();
        for v in views {
            let bh = if bench {
                Iso3::identity()
            } else if let Some(bh) = v.base_hand {
                bh
            } else {
                warnings.push(format!("view {}: left out, no robot pose", v.view));
                continue;
            };
            if v.circles.is_empty() && v.stripe.is_empty() {
                warnings.push(format!("view {}: left out, no observation", v.view));
                continue;
            }
            let vi = t.a.len();
            t.a.push(bh);
            t.used.push(v.view);
            t.q.push(match &v.reading {
                Some(crate::model::RobotReading::Joints(q)) => Some(q.clone()),
                _ => None,
            });
            for c in &v.circles {
                if !(c.u.is_finite() && c.v.is_finite())
                    || c.row >= board.rows
                    || c.col >= board.cols
                {
                    return Err(Error::InvalidInput(format!(
                        "view {}: circle ({}, {}) at ({}, {}) is not a valid observation",
                        v.view, c.row, c.col, c.u, c.v
                    )));
                }
                let ctr = board.center(c.row, c.col);
                t.circles.push(CircleTerm {
                    view: vi,
                    row: c.row,
                    col: c.col,
                    centre: (ctr.x, ctr.y),
                    radius: 0.5 * board.diameter(c.row, c.col),
                    u: c.u,
                    v: c.v,
                });
            }
            for s in &v.stripe {
                if !(s[0].is_finite() && s[1].is_finite()) {
                    return Err(Error::InvalidInput(format!(
                        "view {}: stripe point ({}, {}) is not finite",
                        v.view, s[0], s[1]
                    )));
                }
                t.stripes.push(StripeTerm {
                    view: vi,
                    u: s[0],
                    v: s[1],
                });
            }
        }
        Ok(t)
    }
}
