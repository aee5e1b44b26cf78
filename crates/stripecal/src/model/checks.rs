//! What a calibration says about itself without ground truth: the board's scale as the
//! robot implies it, and the leave-one-view-out prediction figures.

/// The board's printed scale as the robot's translations imply it (the robot fixes the
/// metric scale; rig.json's board is `scale` times too small when `scale > 1`).
#[derive(Debug, Clone, PartialEq)]
pub struct BoardScaleCheck {
    /// The scale the robot implies (1: rig.json's board is right).
    pub scale: f64,
    /// Its one-sigma.
    pub sigma: f64,
    /// rig.json's pitch (circle grids) or square (chessboards), mm.
    pub declared_mm: f64,
    /// `scale * declared_mm`.
    pub implied_mm: f64,
    /// Whether the calibration estimated the scale (`--estimate-board-scale`) and used
    /// it; otherwise it held rig.json's and this is a check.
    pub estimated: bool,
    /// Whether rig.json disagrees with the robot: `|scale - 1|` beyond 3 sigma and
    /// beyond the tolerance.
    pub disagrees: bool,
    /// The tolerance on `|scale - 1|` below which no disagreement is reported.
    pub tolerance: f64,
}

/// The leave-one-view-out figures of one view: its observations predicted by the
/// calibration solved without it, from its robot pose alone.
#[derive(Debug, Clone, PartialEq)]
pub struct LooView {
    /// Row in views.csv (0-based).
    pub view: usize,
    /// Target points compared.
    pub points: usize,
    /// RMS length of (predicted - detected) target point, px.
    pub board_rms_px: f64,
    /// RMS distance on the predicted board plane between each detected point's ray and
    /// the point's predicted position, mm.
    pub board_rms_mm: f64,
    /// Stripe points compared (0 without a laser image or a laser plane).
    pub stripe_points: usize,
    /// RMS distance of the view's stripe points (triangulated with the laser plane)
    /// from its predicted board plane, mm (`None` without stripe points).
    pub stripe_rms_mm: Option<f64>,
    /// Whether the view disagrees with the others: its `board_rms_px` beyond
    /// [`LOO_DISAGREE_FACTOR`] times the median over views.
    pub disagrees: bool,
    /// What the calibration without the view predicts for it (`None` without a laser
    /// plane): enough to score any stripe points of the view
    /// ([`crate::pipeline::held_out_laser_board`]).
    pub fold: Option<LooFold>,
}

/// What the calibration without view `view` predicts for that view: its camera and
/// laser plane, and the view's board pose in the camera frame (from its robot pose and
/// the fold's hand-eye and robot-world; on the bench from its own target points with
/// the fold's camera).
#[derive(Debug, Clone, PartialEq)]
pub struct LooFold {
    pub camera: crate::model::camera::Camera,
    pub plane: crate::model::geometry::Plane,
    pub cam_board: crate::model::geometry::Iso3,
}

/// The held-out laser->board distance (DECISIONS 8): every stripe point of every view,
/// triangulated with the laser plane of the calibration without that view, against the
/// board plane that calibration predicts for the view; absolute distances pooled over
/// all points of all views.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LaserBoardFigure {
    /// Median of the absolute distances, mm.
    pub median_mm: f64,
    /// Their 95th percentile, mm.
    pub p95_mm: f64,
    /// Points scored.
    pub points: usize,
}

impl LaserBoardFigure {
    /// The figure of absolute distances `d` (mm); `None` for none.
    pub fn of(d: &mut [f64]) -> Option<LaserBoardFigure> {
        if d.is_empty() {
            return None;
        }
        d.sort_by(f64::total_cmp);
        let q = |p: f64| {
            // linear interpolation between order statistics (numpy's default)
            let x = p * (d.len() - 1) as f64;
            let (i, f) = (x.floor() as usize, x - x.floor());
            d[i] + f * (d[(i + 1).min(d.len() - 1)] - d[i])
        };
        Some(LaserBoardFigure {
            median_mm: q(0.5),
            p95_mm: q(0.95),
            points: d.len(),
        })
    }
}

/// A view whose leave-one-out figure exceeds this many times the median disagrees.
pub const LOO_DISAGREE_FACTOR: f64 = 3.0;

/// The leave-one-view-out figures of a calibration.
#[derive(Debug, Clone, PartialEq)]
pub struct LeaveOneOut {
    pub views: Vec<LooView>,
    pub median_board_rms_px: f64,
    pub median_board_rms_mm: f64,
    pub median_stripe_rms_mm: Option<f64>,
    /// The held-out laser->board distance over the calibration's own stripe points
    /// (DECISIONS 8; `None` without a laser plane).
    pub laser_board: Option<LaserBoardFigure>,
}
