//! The one error type of the core crate.
//!
//! Every public fallible function returns [`Result`]. Variants say *where* (file, line,
//! key, view) and *what* was expected, so a user can fix the input without reading code.

use std::path::PathBuf;

/// Errors of the stripecal core crate.
#[derive(Debug, thiserror::Error)]
pub enum Error {
    /// An operating-system level failure reading or writing a file.
    #[error("{path}: {source}")]
    Io {
        path: PathBuf,
        #[source]
        source: std::io::Error,
    },
    /// A file whose content does not follow spec/DATASET.md. `location` is a line
    /// (`line 3`), a column (`line 3, column q2`) or a JSON key path (`board.rows`).
    #[error("{path}: {location}: {message}")]
    Format {
        path: PathBuf,
        location: String,
        message: String,
    },
    /// An image that cannot be decoded or exceeds the decoder limits.
    #[error("{path}: cannot read image: {message}")]
    Image { path: PathBuf, message: String },
    /// An argument outside the domain of a function (wrong length, NaN, non-positive size...).
    #[error("invalid input: {0}")]
    InvalidInput(String),
    /// An iterative method that did not reach its tolerance.
    #[error("{what} did not converge after {iterations} iterations (residual {residual:.3e})")]
    NotConverged {
        what: &'static str,
        iterations: usize,
        residual: f64,
    },
    /// A geometric configuration where the requested quantity does not exist
    /// (a point behind the camera, a ray parallel to a plane...).
    #[error("degenerate geometry: {0}")]
    Degenerate(String),
    /// An image in which the expected target (circle grid, stripe) cannot be found or
    /// indexed without guessing; the message says what was found.
    #[error("detection failed: {0}")]
    Detection(String),
    /// A calibration that is not trustworthy: its quality gates failed (views that
    /// disagree and cannot be left out, undetermined parameters, no convergence). It
    /// carries the failed checks and, when one could be computed, the calibration for
    /// inspection ([`crate::model::QualityFailure`]).
    #[error("{0}")]
    Quality(Box<crate::model::QualityFailure>),
    /// A scan frame whose image cannot be used (missing, unreadable, truncated or
    /// corrupted, the wrong size or bit depth): which frame, where and why.
    #[error("{0}")]
    BadImage(BadFrame),
    /// The caller stopped the run (a progress callback asked to stop); nothing is
    /// returned.
    #[error("cancelled")]
    Cancelled,
}

/// A scan frame whose image cannot be used: the error of a reconstruction that stops at
/// bad images, and one entry of the skipped frames of one that skips them.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct BadFrame {
    /// Index of the frame (the row of scan.csv after the header, from 0; a point's
    /// `view` property).
    pub frame: usize,
    /// Its line in scan.csv (the header is line 1).
    pub line: usize,
    /// The image file (the scan folder joined with the name in scan.csv).
    pub path: PathBuf,
    /// What is wrong with it.
    pub reason: String,
}

impl std::fmt::Display for BadFrame {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "frame {} (scan.csv line {}): image {}: {}",
            self.frame,
            self.line,
            self.path.display(),
            self.reason
        )
    }
}

/// `Result` with the crate's [`Error`].
pub type Result<T> = std::result::Result<T, Error>;

impl Error {
    /// Shorthand for a [`Error::Format`] error.
    pub fn format(
        path: impl Into<PathBuf>,
        location: impl Into<String>,
        message: impl Into<String>,
    ) -> Self {
        Error::Format {
            path: path.into(),
            location: location.into(),
            message: message.into(),
        }
    }

    /// Shorthand for a [`Error::Io`] error.
    pub fn io(path: impl Into<PathBuf>, source: std::io::Error) -> Self {
        Error::Io {
            path: path.into(),
            source,
        }
    }
}
