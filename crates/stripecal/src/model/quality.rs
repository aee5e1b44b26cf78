//! The quality gates' verdicts: what a calibration checked about itself before it was
//! trusted (calibration.json `quality.checks`), and the failure that carries a
//! calibration nobody should use.

use std::any::Any;
use std::fmt;
use std::sync::Arc;

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
///
/// The crate's one error type sits below the layer that calibrates, so the calibration
/// to inspect is held without naming its type here; the layer that made it reads it
/// back typed (the pipeline's `QualityFailure::report`, a `CalibrationReport`).
#[derive(Debug, Clone)]
pub struct QualityFailure {
    pub failed: Vec<QualityCheck>,
    inspection: Option<Arc<dyn Any + Send + Sync>>,
}

impl QualityFailure {
    /// A failure with nothing to inspect (no calibration could be computed).
    pub fn new(failed: Vec<QualityCheck>) -> Self {
        QualityFailure {
            failed,
            inspection: None,
        }
    }

    /// A failure with the calibration of the views that agree, for inspection.
    pub fn with_inspection<T: Any + Send + Sync>(failed: Vec<QualityCheck>, result: T) -> Self {
        QualityFailure {
            failed,
            inspection: Some(Arc::new(result)),
        }
    }

    /// The calibration to inspect, as the type that made it (`None`: none, or another
    /// type).
    pub fn inspection<T: Any>(&self) -> Option<&T> {
        self.inspection.as_deref()?.downcast_ref()
    }

    /// Whether a calibration could still be computed.
    pub fn has_inspection(&self) -> bool {
        self.inspection.is_some()
    }
}

impl fmt::Display for QualityFailure {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "the calibration failed its quality checks")?;
        for c in &self.failed {
            write!(f, "; {}: {}", c.name, c.message)?;
        }
        if !self.has_inspection() {
            write!(f, " (no calibration could be computed)")?;
        }
        Ok(())
    }
}
