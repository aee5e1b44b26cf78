//! The quality gates' verdicts: what a calibration checked about itself before it was
//! trusted (calibration.json `quality.checks`), and the failure that carries a
//! calibration nobody should use.

use std::fmt;

/// One quality gate and its verdict.
#[derive(Debug, Clone, PartialEq)]
pub struct QualityCheck {
    /// The gate: `pairing` (robot poses against images), `views` (a view's residuals
    /// against the others'), `determined` (every estimated number has a meaningful
    /// one-sigma), `converged` (the adjustment reached its tolerance).
    pub name: String,
    pub passed: bool,
    /// What was measured, against what limit, and what to do.
    pub message: String,
    /// The views (views.csv rows, 0-based) the check names as suspect.
    pub views: Vec<usize>,
}

impl QualityCheck {
    /// A gate that passed.
    pub fn pass(name: &str, message: impl Into<String>) -> Self {
        QualityCheck {
            name: name.into(),
            passed: true,
            message: message.into(),
            views: Vec::new(),
        }
    }

    /// A gate that failed, naming `views`.
    pub fn fail(name: &str, message: impl Into<String>, views: Vec<usize>) -> Self {
        QualityCheck {
            name: name.into(),
            passed: false,
            message: message.into(),
            views,
        }
    }
}

/// A calibration that failed its quality gates: the failed checks and, when a
/// calibration could still be computed (from the views that agree), that calibration
/// for inspection. Returned as [`crate::Error::Quality`]; with
/// `CalibrateOptions::accept_poor` the calibration is returned instead, marked.
#[derive(Debug, Clone)]
pub struct QualityFailure {
    pub failed: Vec<QualityCheck>,
    pub report: Option<Box<crate::pipeline::CalibrationReport>>,
}

impl fmt::Display for QualityFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "the calibration failed its quality checks")?;
        for c in &self.failed {
            write!(f, "; {}: {}", c.name, c.message)?;
        }
        if self.report.is_none() {
            write!(f, " (no calibration could be computed)")?;
        }
        Ok(())
    }
}
