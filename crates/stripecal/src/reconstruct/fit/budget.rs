//! Uncertainty budgets of fitted quantities, GUM style: each quantity is a linear form
//! in independent sources, kept in four parts that are combined in quadrature and
//! expanded with `k = 2`.
//!
//! ## The parts
//!
//! - **random**: the fit's own scatter from its residuals (the stripe's noise and
//!   whatever else scatters point to point), heteroscedasticity-consistent:
//!   `m / (m - p) N^-1 (sum_i J_i^T r_i^2 J_i) N^-1` rather than one variance for all
//!   points, `sigma^2 N^-1`, because a scan's weak and oblique profiles scatter more and
//!   decide the shape's size and tilt (`measure.rs`, `sandwich`); for a trimmed sphere
//!   fit `N` is replaced by the skipped fit's bread, `N` less its points at the
//!   trimming threshold (`measure.rs`, `trimmed_bread`);
//! - **calibration**: the calibration's covariance `C` carried through every point
//!   ([`crate::reconstruct::uncertainty`]): shared by all points of all scans measured
//!   with the calibration, it does not average out; `g^T C g` with `g` the quantity's
//!   gradient over the calibration's numbers;
//! - **robot**: the robot's repeatability / encoder figures, shared by the points of a
//!   frame, independent between frames;
//! - **systematic**: components a model leaves, e.g. what the curved-surface stripe bias
//!   correction cannot settle (one source shared by every sphere it corrects), and a
//!   reference value's certificate.
//!
//! ## A fit's sensitivity
//!
//! A least-squares fit `min sum r_i(beta, p_i)^2` moves, when its points move by
//! `dp_i`, by `d beta = -N^-1 sum_i J_i^T a_i^T dp_i` with `J_i = dr_i/d beta`,
//! `a_i = dr_i/dp_i` and `N = sum J_i^T J_i`. With `dp_i = R_base_cam J_c,i eta_f` and
//! `eta_f = M_f theta + (robot twist)` (the point chain), the fit's gradient over the
//! calibration's numbers is `-N^-1 sum_f (sum_{i in f} J_i^T a_i^T R J_c,i) M_f`, and its
//! gradient over frame f's robot twist the same sum's twist columns. A residual after
//! the refit moves by `a_i^T dp_i + J_i d beta` (used for the ranges: probing form,
//! flatness). The sphere: `r_i = |p_i - c| - R`, `J_i = [-n_i^T, -1]`, `a_i = n_i^T`;
//! the plane: `r_i = n . (p_i - c) - delta` tilted by `(a, b)` about its in-plane axes
//! `e1, e2`, `J_i = [e1 . (p_i - c), e2 . (p_i - c), -1]`, `a_i = n^T`.
//!
//! ## Ranges
//!
//! A range (largest minus smallest residual: probing form, flatness) is linear in the
//! two extreme points' residuals for the calibration and robot parts. Its random part
//! is the scatter of the extremes of `n` residuals of one-sigma `s`: each extreme's
//! one-sigma is `s pi / sqrt(6 * 2 ln n)` (the Gumbel limit), the range's `sqrt(2)`
//! times that.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicU64, Ordering};

use nalgebra::{DMatrix, DVector, SMatrix, Vector3};

use crate::error::{Error, Result};
use crate::model::RobotReading;
use crate::reconstruct::uncertainty::{FrameUncertainty, UncertaintyModel, ETA};

/// An independent unit source: `(owner, index, component)` (a fit's random or
/// systematic component, or a frame's robot twist component).
pub type Source = (u64, u32, u32);

/// The coverage factor of the expanded uncertainty.
pub const COVERAGE_K: f64 = 2.0;

static NEXT_ID: AtomicU64 = AtomicU64::new(1);

/// A fresh owner id for [`Source`]s (fits, scans).
pub fn new_source_id() -> u64 {
    NEXT_ID.fetch_add(1, Ordering::Relaxed)
}

/// A quantity's first-order dependence on every source of uncertainty.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct LinearForm {
    /// Gradient over the calibration's numbers ([`UncertaintyModel::names`]); empty: none.
    pub calibration: DVector<f64>,
    /// Coefficients of unit robot sources.
    pub robot: BTreeMap<Source, f64>,
    /// Coefficients of unit random sources.
    pub random: BTreeMap<Source, f64>,
    /// Coefficients of unit systematic sources.
    pub systematic: BTreeMap<Source, f64>,
}

impl LinearForm {
    /// `self + s * other`.
    pub fn add_scaled(&mut self, other: &LinearForm, s: f64) {
        if !other.calibration.is_empty() {
            if self.calibration.is_empty() {
                self.calibration = DVector::zeros(other.calibration.len());
            }
            self.calibration.axpy(s, &other.calibration, 1.0);
        }
        for (mine, theirs) in [
            (&mut self.robot, &other.robot),
            (&mut self.random, &other.random),
            (&mut self.systematic, &other.systematic),
        ] {
            for (k, v) in theirs {
                *mine.entry(*k).or_insert(0.0) += s * v;
            }
        }
    }

    /// `sum_k g_k forms_k`.
    pub fn combination(forms: &[&LinearForm], g: &[f64]) -> LinearForm {
        let mut out = LinearForm::default();
        for (f, s) in forms.iter().zip(g) {
            out.add_scaled(f, *s);
        }
        out
    }

    /// The budget of a quantity of value `value` with this form, the calibration's
    /// covariance `cov` (over the same numbers).
    pub fn budget(&self, value: f64, cov: &DMatrix<f64>) -> Budget {
        let ss = |m: &BTreeMap<Source, f64>| m.values().fold(0.0, |a, v| a + v * v).sqrt();
        let calibration = if self.calibration.is_empty() || cov.is_empty() {
            0.0
        } else {
            (self.calibration.dot(&(cov * &self.calibration)))
                .max(0.0)
                .sqrt()
        };
        Budget::new(
            value,
            ss(&self.random),
            calibration,
            ss(&self.robot),
            ss(&self.systematic),
        )
    }
}

/// A GUM budget: standard uncertainties per part (mm, or the quantity's unit), their
/// combination and the expanded uncertainty `U = k u_c` (`k = 2`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Budget {
    pub value: f64,
    pub random: f64,
    pub calibration: f64,
    pub robot: f64,
    pub systematic: f64,
    /// `sqrt(random^2 + calibration^2 + robot^2 + systematic^2)`.
    pub combined: f64,
    pub k: f64,
    /// `k * combined`: the headline.
    pub expanded: f64,
}

impl Budget {
    /// A budget from its parts.
    pub fn new(value: f64, random: f64, calibration: f64, robot: f64, systematic: f64) -> Self {
        let combined =
            (random * random + calibration * calibration + robot * robot + systematic * systematic)
                .sqrt();
        Budget {
            value,
            random,
            calibration,
            robot,
            systematic,
            combined,
            k: COVERAGE_K,
            expanded: COVERAGE_K * combined,
        }
    }

    /// The same budget with another independent standard uncertainty added to the
    /// systematic part (e.g. a reference value's certificate).
    pub fn with_systematic(&self, value: f64, extra: f64) -> Budget {
        Budget::new(
            value,
            self.random,
            self.calibration,
            self.robot,
            self.systematic.hypot(extra),
        )
    }
}

/// The frames of one scan with their uncertainty, built on first use.
pub struct ScanFrames<'a> {
    model: &'a UncertaintyModel,
    readings: &'a [RobotReading],
    frames: BTreeMap<u32, FrameUncertainty>,
    /// The scan's owner id for robot sources.
    pub id: u64,
}

impl<'a> ScanFrames<'a> {
    /// The frames of a scan whose readings are `readings` (indexed by frame number).
    pub fn new(model: &'a UncertaintyModel, readings: &'a [RobotReading]) -> Self {
        ScanFrames {
            model,
            readings,
            frames: BTreeMap::new(),
            id: new_source_id(),
        }
    }

    /// The model.
    pub fn model(&self) -> &UncertaintyModel {
        self.model
    }

    /// Frame `f`.
    pub fn frame(&mut self, f: u32) -> Result<&FrameUncertainty> {
        if !self.frames.contains_key(&f) {
            let reading = self.readings.get(f as usize).ok_or_else(|| {
                Error::InvalidInput(format!(
                    "frame {f}: the scan has {} frame readings",
                    self.readings.len()
                ))
            })?;
            let fu = self.model.frame(reading)?;
            self.frames.insert(f, fu);
        }
        Ok(&self.frames[&f])
    }
}

/// One point of a fit: pixel (a profiler's point: its profile `x, z`, mm), frame,
/// `a_i = dr_i/dp_i` (base frame) and `J_i` (row).
pub struct FitRow<'r> {
    pub u: f64,
    pub v: f64,
    pub frame: u32,
    pub a: Vector3<f64>,
    pub j: &'r [f64],
}

type Row19 = SMatrix<f64, 1, ETA>;

/// The linearised points of a fit: each row's `e_i = a_i^T R J_c,i` (1 x 19).
pub struct Sensitivity {
    /// Per fit parameter, its form (calibration and robot parts; random and systematic
    /// empty: the caller adds them).
    pub params: Vec<LinearForm>,
    /// `N^-1` (q x q): with the residuals' variance, the fit's random covariance.
    pub ninv: DMatrix<f64>,
    /// Per frame: `M_f` (its calibration map) and the robot twist's Cholesky factor.
    frames: BTreeMap<u32, (DMatrix<f64>, SMatrix<f64, 6, 6>)>,
    scan: u64,
}

impl Sensitivity {
    /// The sensitivity of a fit of `q` parameters with normal matrix `n` (= `sum J_i^T
    /// J_i`) to its points `rows`.
    pub fn new<'r>(
        frames: &mut ScanFrames<'_>,
        n: &DMatrix<f64>,
        rows: impl Iterator<Item = FitRow<'r>>,
    ) -> Result<Sensitivity> {
        let q = n.nrows();
        let ninv = n
            .clone()
            .try_inverse()
            .ok_or_else(|| Error::Degenerate("fit budget: singular normal matrix".into()))?;
        let neg_ninv = -&ninv;
        let mut s_f: BTreeMap<u32, DMatrix<f64>> = BTreeMap::new();
        for row in rows {
            let e = row_e(frames, &row)?;
            let s = s_f
                .entry(row.frame)
                .or_insert_with(|| DMatrix::zeros(q, ETA));
            for (r, jr) in row.j.iter().enumerate() {
                for c in 0..ETA {
                    s[(r, c)] += jr * e[c];
                }
            }
        }
        let p = frames.model().names().len();
        let mut cal = DMatrix::zeros(q, p);
        let mut robot: Vec<BTreeMap<Source, f64>> = vec![BTreeMap::new(); q];
        let mut maps = BTreeMap::new();
        let scan = frames.id;
        for (f, s) in &s_f {
            let fu = frames.frame(*f)?;
            let k = &neg_ninv * s;
            if p > 0 {
                cal += &k * fu.map();
            }
            let l = robot_factor(fu);
            let kt = k.columns(13, 6) * l;
            for (r, m) in robot.iter_mut().enumerate() {
                for c in 0..6 {
                    if kt[(r, c)] != 0.0 {
                        m.insert((scan, *f, c as u32), kt[(r, c)]);
                    }
                }
            }
            maps.insert(*f, (fu.map().clone(), l));
        }
        let params = (0..q)
            .map(|r| LinearForm {
                calibration: if p > 0 {
                    cal.row(r).transpose()
                } else {
                    DVector::zeros(0)
                },
                robot: std::mem::take(&mut robot[r]),
                ..Default::default()
            })
            .collect();
        Ok(Sensitivity {
            params,
            ninv,
            frames: maps,
            scan,
        })
    }

    /// The form of one point's residual after the refit: `a^T dp + J d beta`.
    pub fn residual_form(
        &self,
        frames: &mut ScanFrames<'_>,
        row: &FitRow<'_>,
    ) -> Result<LinearForm> {
        let e = row_e(frames, row)?;
        let mut out = LinearForm::combination(&self.params.iter().collect::<Vec<_>>(), row.j);
        let (map, l) = match self.frames.get(&row.frame) {
            Some(x) => (x.0.clone(), x.1),
            None => {
                let fu = frames.frame(row.frame)?;
                (fu.map().clone(), robot_factor(fu))
            }
        };
        if map.ncols() > 0 {
            let g = (e * map).transpose();
            if out.calibration.is_empty() {
                out.calibration = DVector::zeros(g.len());
            }
            out.calibration += g;
        }
        let t = e.columns(13, 6) * l;
        for c in 0..6 {
            *out.robot
                .entry((self.scan, row.frame, c as u32))
                .or_insert(0.0) += t[c];
        }
        Ok(out)
    }
}

/// `e_i = a_i^T R_base_cam J_c,i` of a row.
fn row_e(frames: &mut ScanFrames<'_>, row: &FitRow<'_>) -> Result<Row19> {
    let fu = frames.frame(row.frame)?;
    let l = fu.local(row.u, row.v)?;
    let ar = row.a.transpose() * fu.rotation();
    Ok(ar * l.j_eta)
}

/// A Cholesky-like factor `L` of a frame's robot twist covariance (`L L^T`), from its
/// symmetric eigen decomposition (the covariance may be singular).
fn robot_factor(fu: &FrameUncertainty) -> SMatrix<f64, 6, 6> {
    let s = fu.robot_sigma();
    if s.iter().all(|x| *x == 0.0) {
        return SMatrix::zeros();
    }
    let e = s.symmetric_eigen();
    let mut l = e.eigenvectors;
    for c in 0..6 {
        let v = e.eigenvalues[c].max(0.0).sqrt();
        for r in 0..6 {
            l[(r, c)] *= v;
        }
    }
    l
}

/// The random one-sigma of the range of `n` residuals of one-sigma `s` (module docs).
pub fn range_random_sigma(s: f64, n: usize) -> f64 {
    if n < 3 {
        return s * std::f64::consts::SQRT_2;
    }
    let ln = (n as f64).ln();
    std::f64::consts::SQRT_2 * s * std::f64::consts::PI / (6.0 * 2.0 * ln).sqrt()
}
