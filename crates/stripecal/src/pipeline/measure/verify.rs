//! The VDI/VDE 2634 Part 2 style acceptance test (`stripecal verify`): scans of
//! certified artefacts measured with full budgets, the four characteristics against the
//! user's maximum permissible errors.
//!
//! ## Input
//!
//! A folder with `artefacts.json` (the certificates and MPEs, spec/DATASET.md; never
//! the twin's truth), a manifest `verify.csv` (header `scan,artefact`, one line per
//! scan: the scan folder, relative to the manifest, and the name of a ball bar, a plane
//! or a sphere of artefacts.json) and the scan folders (scan.csv + images, as
//! `stripecal reconstruct` reads).
//!
//! ## The characteristics (per measurement; the test's value is the largest |value|)
//!
//! - **Probing error form** `PF`: the range of a sphere's radial residuals (largest
//!   minus smallest, inliers of the 3-sigma trimming), every sphere measured.
//! - **Probing error size** `PS`: measured minus certified diameter.
//! - **Sphere-spacing error** `SD`: measured minus certified centre distance of a ball
//!   bar, in every position.
//! - **Flatness measurement error** `F`: the range of a plate's residuals from its fitted
//!   plane.
//!
//! Each value carries its expanded uncertainty `U` (k = 2, [`Budget`]: random,
//! calibration, robot, systematic; the certificate's uncertainty added to the
//! systematic part for PS, SD and F). A characteristic **passes** when `|value| <= MPE`;
//! it **conforms** (ISO 14253-1: conformity proven) when `|value| + U <= MPE`.

use std::ops::ControlFlow;
use std::path::{Path, PathBuf};

use serde_json::{json, Value};

use crate::error::{Error, Result};
use crate::io::read_artefacts;
use crate::model::artefacts::{ArtefactSphere, Artefacts, BallBar, CertificateUncertainty};
use crate::model::{Calibration, ProfilerCalibration, RobotReading};
use crate::reconstruct::fit::Budget;
use crate::reconstruct::{
    load_profile_frames, load_scan, profile_scan_points, reconstruct_scan,
    ProfileReconstructOptions, ReconstructOptions, ScanPoints, UncertaintyModel,
};

use super::{
    budget_to_json, measure_scan_ball_bar, measure_scan_plane, measure_scan_sphere,
    profiler_uncertainty_model, scan_readings, scan_uncertainty_model, BallBarReport,
    MeasureOptions, SphereReport,
};

/// The four characteristics.
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord)]
pub enum Characteristic {
    ProbingForm,
    ProbingSize,
    SphereSpacing,
    Flatness,
}

impl Characteristic {
    /// The key used in JSON and the MPE table (`probing_form`, ...).
    pub fn key(self) -> &'static str {
        match self {
            Characteristic::ProbingForm => "probing_form",
            Characteristic::ProbingSize => "probing_size",
            Characteristic::SphereSpacing => "sphere_spacing",
            Characteristic::Flatness => "flatness",
        }
    }

    /// The standard's symbol.
    pub fn symbol(self) -> &'static str {
        match self {
            Characteristic::ProbingForm => "PF",
            Characteristic::ProbingSize => "PS",
            Characteristic::SphereSpacing => "SD",
            Characteristic::Flatness => "F",
        }
    }

    fn mpe(self, a: &Artefacts) -> f64 {
        let m = &a.mpe_mm;
        match self {
            Characteristic::ProbingForm => m.probing_form,
            Characteristic::ProbingSize => m.probing_size,
            Characteristic::SphereSpacing => m.sphere_spacing,
            Characteristic::Flatness => m.flatness,
        }
    }
}

/// One measured value of a characteristic.
#[derive(Debug, Clone, PartialEq)]
pub struct VerifyRow {
    pub characteristic: Characteristic,
    /// The scan folder (as in the manifest).
    pub scan: String,
    /// What was measured: `bar/A`, `bar`, `plate`, ...
    pub artefact: String,
    /// The error (or form), mm, with its budget.
    pub budget: Budget,
    pub mpe_mm: f64,
}

impl VerifyRow {
    /// `|value| <= MPE`.
    pub fn passed(&self) -> bool {
        self.budget.value.abs() <= self.mpe_mm
    }

    /// `|value| + U <= MPE`.
    pub fn conforms(&self) -> bool {
        self.budget.value.abs() + self.budget.expanded <= self.mpe_mm
    }
}

/// The verification's result: every measured value, in manifest order.
#[derive(Debug, Clone)]
pub struct VerifyReport {
    pub artefacts: Artefacts,
    pub rows: Vec<VerifyRow>,
    /// Measured sphere diameters, centres and the fits' RMS per scan and sphere, for
    /// the report (`(scan, sphere name, report)`).
    pub spheres: Vec<(String, String, SphereReport)>,
}

impl VerifyReport {
    /// The worst row (largest |value|) of a characteristic, `None` when not measured.
    pub fn worst(&self, c: Characteristic) -> Option<&VerifyRow> {
        self.rows
            .iter()
            .filter(|r| r.characteristic == c)
            .max_by(|a, b| a.budget.value.abs().total_cmp(&b.budget.value.abs()))
    }

    /// Every measured characteristic passes.
    pub fn passed(&self) -> bool {
        self.rows.iter().all(|r| r.passed())
    }

    /// The report as JSON (`stripecal/verify@1`).
    pub fn to_json(&self) -> Value {
        let budget = budget_to_json;
        let rows: Vec<Value> = self
            .rows
            .iter()
            .map(|r| {
                json!({"characteristic": r.characteristic.key(), "symbol": r.characteristic.symbol(),
                       "scan": r.scan, "artefact": r.artefact, "mpe_mm": r.mpe_mm,
                       "passed": r.passed(), "conforms": r.conforms(), "budget": budget(&r.budget)})
            })
            .collect();
        let mut summary = serde_json::Map::new();
        for c in ALL {
            if let Some(w) = self.worst(c) {
                let n = self.rows.iter().filter(|r| r.characteristic == c).count();
                let all_pass = self
                    .rows
                    .iter()
                    .filter(|r| r.characteristic == c)
                    .all(|r| r.passed());
                summary.insert(
                    c.key().into(),
                    json!({"symbol": c.symbol(), "worst_mm": w.budget.value, "expanded_mm": w.budget.expanded,
                           "mpe_mm": w.mpe_mm, "measurements": n, "passed": all_pass,
                           "conforms": self.rows.iter().filter(|r| r.characteristic == c).all(|r| r.conforms())}),
                );
            }
        }
        json!({"format": "stripecal/verify@1", "passed": self.passed(), "summary": summary, "rows": rows})
    }
}

/// The characteristics in table order.
pub const ALL: [Characteristic; 4] = [
    Characteristic::ProbingForm,
    Characteristic::ProbingSize,
    Characteristic::SphereSpacing,
    Characteristic::Flatness,
];

/// Options of [`verify`].
#[derive(Debug, Clone, PartialEq, Default)]
pub struct VerifyOptions {
    pub measure: MeasureOptions,
    pub reconstruct: ReconstructOptions,
    /// The artefacts file (`None`: `artefacts.json` in the folder).
    pub artefacts: Option<PathBuf>,
}

/// Reads `verify.csv`: `(scan folder, artefact name)` per line, in order.
pub fn read_manifest(path: &Path) -> Result<Vec<(String, String)>> {
    let text = std::fs::read_to_string(path).map_err(|e| Error::io(path, e))?;
    let mut out = Vec::new();
    let mut lines = text
        .lines()
        .enumerate()
        .filter(|(_, l)| !l.trim().is_empty());
    let header = lines
        .next()
        .map(|(_, l)| l.trim().trim_start_matches('\u{feff}'));
    if header != Some("scan,artefact") {
        return Err(Error::format(
            path,
            "line 1",
            format!(
                "expected the header `scan,artefact`, got {:?}",
                header.unwrap_or("")
            ),
        ));
    }
    for (i, l) in lines {
        let cells: Vec<&str> = l.split(',').map(|c| c.trim()).collect();
        if cells.len() != 2 || cells.iter().any(|c| c.is_empty()) {
            return Err(Error::format(
                path,
                format!("line {}", i + 1),
                format!("expected `scan,artefact`, got {l:?}"),
            ));
        }
        out.push((cells[0].to_string(), cells[1].to_string()));
    }
    if out.is_empty() {
        return Err(Error::format(path, "line 2", "no scans listed"));
    }
    Ok(out)
}

/// Runs the acceptance test on the folder `dir` (module docs). `progress(stage, done,
/// total)` reports each scan; `Break` stops the run ([`Error::Cancelled`]).
pub fn verify(
    calibration: &Calibration,
    dir: &Path,
    opts: &VerifyOptions,
    progress: &mut dyn FnMut(&str, usize, usize) -> ControlFlow<()>,
) -> Result<VerifyReport> {
    let load = |path: &Path, cb: &mut dyn FnMut(usize, usize, usize) -> ControlFlow<()>| {
        let scan = load_scan(path, calibration)?;
        let points = reconstruct_scan(calibration, &scan, &opts.reconstruct, cb)?;
        let model = scan_uncertainty_model(calibration, &scan, &opts.measure.uncertainty);
        Ok((points, model, scan_readings(&scan)))
    };
    verify_scans(&load, dir, opts, progress)
}

/// [`verify`] with a line profiler's calibration: the scans are profile scans (a
/// `profile` column in scan.csv), their points mapped with `T_hand_sensor` and measured
/// with the profiler's point budget.
pub fn verify_profiler(
    calibration: &ProfilerCalibration,
    dir: &Path,
    opts: &VerifyOptions,
    progress: &mut dyn FnMut(&str, usize, usize) -> ControlFlow<()>,
) -> Result<VerifyReport> {
    let model = profiler_uncertainty_model(calibration, &opts.measure.uncertainty)?;
    let load = |path: &Path, cb: &mut dyn FnMut(usize, usize, usize) -> ControlFlow<()>| {
        let (frames, _) = load_profile_frames(
            path,
            calibration.robot.as_ref(),
            &ProfileReconstructOptions::default(),
        )?;
        let points = profile_scan_points(&frames, calibration)?;
        let n = frames.len();
        if cb(n, n, points.len()).is_break() {
            return Err(Error::Cancelled);
        }
        Ok((
            points,
            Ok(model.clone()),
            frames.into_iter().map(|f| f.0).collect(),
        ))
    };
    verify_scans(&load, dir, opts, progress)
}

/// What verifying needs of one scan folder: its points, the points' uncertainty model
/// and the frames' readings (by frame index); the callback reports `(frames done, frames,
/// points)`. The model is a result of its own: its error is raised as it is, without the
/// scan's tag.
type ScanLoader<'a> = dyn Fn(
        &Path,
        &mut dyn FnMut(usize, usize, usize) -> ControlFlow<()>,
    ) -> Result<(ScanPoints, Result<UncertaintyModel>, Vec<RobotReading>)>
    + 'a;

fn verify_scans(
    load: &ScanLoader<'_>,
    dir: &Path,
    opts: &VerifyOptions,
    progress: &mut dyn FnMut(&str, usize, usize) -> ControlFlow<()>,
) -> Result<VerifyReport> {
    let art_path = opts
        .artefacts
        .clone()
        .unwrap_or_else(|| dir.join("artefacts.json"));
    let artefacts = read_artefacts(&art_path)?;
    let manifest = read_manifest(&dir.join("verify.csv"))?;
    let mut rows = Vec::new();
    let mut spheres = Vec::new();
    for (k, (scan_name, art)) in manifest.iter().enumerate() {
        let stage = format!("{scan_name} ({art})");
        // Errors without a file name get the scan's; the others name their file.
        let tag = |e: Error| match e {
            Error::InvalidInput(m) => {
                Error::InvalidInput(format!("verify: scan {scan_name} ({art}): {m}"))
            }
            Error::Degenerate(m) => {
                Error::Degenerate(format!("verify: scan {scan_name} ({art}): {m}"))
            }
            e => e,
        };
        let total = manifest.len();
        let mut cb = |done: usize, frames: usize, _pts: usize| {
            progress(&stage, k * frames + done, total * frames.max(1))
        };
        let (points, model, readings) = load(&dir.join(scan_name), &mut cb).map_err(tag)?;
        let model = model?;
        let unc = artefacts.uncertainty_k2_mm;
        let mpe = |c: Characteristic| c.mpe(&artefacts);
        let row = |c: Characteristic, what: String, b: Budget| VerifyRow {
            characteristic: c,
            scan: scan_name.clone(),
            artefact: what,
            budget: b,
            mpe_mm: mpe(c),
        };
        if let Some(bar) = artefacts.ball_bars.iter().find(|b| &b.name == art) {
            let cert = [
                artefacts
                    .sphere(&bar.spheres[0])
                    .expect("checked on reading"),
                artefacts
                    .sphere(&bar.spheres[1])
                    .expect("checked on reading"),
            ];
            let mut mo = opts.measure.clone();
            let (lo, hi) = (
                cert[0].diameter_mm.min(cert[1].diameter_mm),
                cert[0].diameter_mm.max(cert[1].diameter_mm),
            );
            mo.fit.diameter_range_mm = Some([0.8 * lo, 1.2 * hi]);
            let m = measure_scan_ball_bar(&model, &readings, &points, &mo).map_err(tag)?;
            let (bar_rows, bar_spheres) = ball_bar_rows(bar, cert, &m, &unc);
            rows.extend(bar_rows.into_iter().map(|(c, what, b)| row(c, what, b)));
            spheres.extend(
                bar_spheres
                    .into_iter()
                    .map(|(name, s)| (scan_name.clone(), name, s)),
            );
        } else if let Some(p) = artefacts.planes.iter().find(|p| &p.name == art) {
            let m = measure_scan_plane(&model, &readings, &points, &opts.measure).map_err(tag)?;
            let f = m.measurement.flatness;
            rows.push(row(
                Characteristic::Flatness,
                p.name.clone(),
                f.with_systematic(f.value, 0.5 * unc.flatness),
            ));
        } else if let Some(s) = artefacts.sphere(art) {
            let mut mo = opts.measure.clone();
            mo.fit.diameter_range_mm = Some([0.8 * s.diameter_mm, 1.2 * s.diameter_mm]);
            let m = measure_scan_sphere(&model, &readings, &points, &mo).map_err(tag)?;
            rows.push(row(
                Characteristic::ProbingForm,
                s.name.clone(),
                m.measurement.form,
            ));
            let ps = m.measurement.diameter.with_systematic(
                m.measurement.diameter.value - s.diameter_mm,
                0.5 * unc.diameter,
            );
            rows.push(row(Characteristic::ProbingSize, s.name.clone(), ps));
            spheres.push((scan_name.clone(), s.name.clone(), m));
        } else {
            return Err(Error::format(
                dir.join("verify.csv"),
                format!("line {}", k + 2),
                format!(
                    "artefact {art:?} is not a ball bar, plane or sphere of {}",
                    art_path.display()
                ),
            ));
        }
    }
    Ok(VerifyReport {
        artefacts,
        rows,
        spheres,
    })
}

/// A row's figure before its scan and MPE are attached: `(characteristic, artefact,
/// budget)`.
type RowFigure = (Characteristic, String, Budget);

/// A measured ball bar's rows against its certificates `cert` (`bar.spheres`' order):
/// each sphere's form and size (the found spheres matched to the certificates by
/// diameter) and their spacing against the bar's length; and the spheres by
/// certificate name.
fn ball_bar_rows(
    bar: &BallBar,
    cert: [&ArtefactSphere; 2],
    m: &BallBarReport,
    unc: &CertificateUncertainty,
) -> (Vec<RowFigure>, Vec<(String, SphereReport)>) {
    let mut rows = Vec::new();
    let mut spheres = Vec::new();
    // Match the found spheres to the certificates by diameter.
    let d = |i: usize| m.spheres[i].fit.diameter_mm;
    let swap = (d(0) - cert[1].diameter_mm).abs() + (d(1) - cert[0].diameter_mm).abs()
        < (d(0) - cert[0].diameter_mm).abs() + (d(1) - cert[1].diameter_mm).abs();
    let order = if swap { [1, 0] } else { [0, 1] };
    for (c, &i) in cert.iter().zip(&order) {
        let s = &m.spheres[i];
        let what = format!("{}/{}", bar.name, c.name);
        rows.push((
            Characteristic::ProbingForm,
            what.clone(),
            s.measurement.form,
        ));
        let ps = s.measurement.diameter.with_systematic(
            s.measurement.diameter.value - c.diameter_mm,
            0.5 * unc.diameter,
        );
        rows.push((Characteristic::ProbingSize, what, ps));
        spheres.push((c.name.clone(), s.clone()));
    }
    let sd = m
        .distance
        .with_systematic(m.distance.value - bar.length_mm, 0.5 * unc.length);
    rows.push((Characteristic::SphereSpacing, bar.name.clone(), sd));
    (rows, spheres)
}
