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
}
