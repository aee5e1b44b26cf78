//! A profiler's calibration from profiles of a reference sphere (spec/DATASET.md, "A
//! profile dataset"): from the profiles and the robot readings to `T_hand_sensor`, the
//! sphere and, with joint readings, the robot.
//!
//! ## Steps
//!
//! 1. Arcs ([`crate::calib::profile::arc`]): each profile's arc of the sphere; a profile
//!    without one (the line missed the sphere) is named and left out.
//! 2. Consensus ([`consensus`]): the closed-form start
//!    ([`crate::calib::profile::start`]) over the views with an arc; a view whose circle
//!    the others' solution cannot place (a pose paired with the wrong profile) is named
//!    and left out, worst first, while enough remain.
//! 3. The one-stage adjustment ([`crate::calib::joint::profile`]) from the chosen start,
//!    its points re-selected; the DH corrections with `--robot`.
//! 4. The mirror test ([`checks::mirror`]): the adjustment again from the mirrored
//!    start; when it fits about as well the calibration fails, naming the plane the
//!    sphere's centres lie in.
//! 5. The gates ([`checks`]): views whose points do not fit, undetermined numbers,
//!    convergence; the declared diameter against the data's estimate.
//! 6. Leave-one-view-out ([`loo`], DECISIONS 3): each view's profile against the sphere
//!    predicted by the others from its robot pose.

mod checks;
mod consensus;
mod loo;
mod prepare;
mod record;

use nalgebra::Vector3;

use crate::calib::joint::profile::{profile_adjustment, ProfileFit, ProfileOptions};
use crate::calib::joint::{RobotMode, RobotOptions};
use crate::calib::profile::arc::ArcOptions;
use crate::error::{Error, Result};
use crate::model::{
    Profile, ProfileDataset, ProfileRig, ProfilerCalibration, QualityCheck, QualityFailure,
    RobotReading,
};

pub use checks::{DiameterCheck, MirrorTest};
pub use loo::{ProfileLoo, ProfileLooView};
pub use prepare::{prepare, Prepared};

/// One profile of the dataset, read.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileInput {
    /// Its row in views.csv (0-based).
    pub view: usize,
    /// Its line in views.csv (1-based, the header is line 1).
    pub line: usize,
    /// The profile file as named in views.csv.
    pub file: String,
    pub profile: Profile,
    pub reading: RobotReading,
}

/// Options of [`calibrate_profiles`].
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileCalibrateOptions {
    /// The robot's DH corrections (`--robot`; needs joint readings).
    pub robot: RobotMode,
    /// Compute the leave-one-view-out figures (default true).
    pub leave_one_out: bool,
    /// Return a calibration that failed a gate instead of an error, marked.
    pub accept_poor: bool,
}

impl Default for ProfileCalibrateOptions {
    fn default() -> Self {
        ProfileCalibrateOptions {
            robot: RobotMode::Fixed,
            leave_one_out: true,
            accept_poor: false,
        }
    }
}

/// What the calibration did with one profile.
#[derive(Debug, Clone, PartialEq)]
pub struct ProfileViewStatus {
    pub view: usize,
    pub line: usize,
    pub file: String,
    /// Points read, gaps skipped.
    pub points: usize,
    pub gaps: usize,
    /// Points of its arc, and of the sphere in the final fit.
    pub arc_points: usize,
    pub sphere_points: usize,
    /// Points not on the sphere (table, stand, spikes): `points - sphere_points`.
    pub rejected: usize,
    /// RMS distance of its sphere points from the fitted sphere, mm.
    pub rms_mm: Option<f64>,
    /// The side of the profile plane the sphere's centre lies on (+1: sensor y > 0).
    pub side: Option<f64>,
    /// The sphere's centre as the sensor saw it in this view (fitted), mm.
    pub centre_in_sensor: Option<Vector3<f64>>,
    pub used: bool,
    /// Why it was left out.
    pub note: Option<String>,
}

/// The result of a profiler's calibration.
#[derive(Debug, Clone)]
pub struct ProfileReport {
    pub calibration: ProfilerCalibration,
    pub fit: ProfileFit,
    pub views: Vec<ProfileViewStatus>,
    pub mirror: MirrorTest,
    pub diameter_check: Option<DiameterCheck>,
    pub leave_one_out: Option<ProfileLoo>,
    pub warnings: Vec<String>,
}

/// The arc options for a rig: circles up to the sphere's radius (with a margin for
/// noise) when declared.
fn arc_options(rig: &ProfileRig) -> ArcOptions {
    ArcOptions {
        max_radius: rig.diameter_mm.map_or(1000.0, |d| 0.5 * d * 1.02 + 0.2),
        ..ArcOptions::default()
    }
}

/// Calibrates a profiler from its profiles (module docs).
pub fn calibrate_profiles(
    inputs: &[ProfileInput],
    rig: &ProfileRig,
    opts: &ProfileCalibrateOptions,
) -> Result<ProfileReport> {
    prepare::check_inputs(inputs)?;
    let robot = match opts.robot {
        RobotMode::Fixed => None,
        mode => Some(RobotOptions {
            nominal: rig.robot.clone().ok_or_else(|| {
                Error::InvalidInput(format!(
                    "--robot {} needs rig.json's robot (DH table) and joint readings",
                    mode.name()
                ))
            })?,
            mode,
        }),
    };
    let mut warnings = Vec::new();
    let mut status: Vec<ProfileViewStatus> = inputs.iter().map(status_of).collect();
    // 1. arcs, 2. consensus and the start
    let (obs, starts) = prepare::arcs_and_consensus(inputs, rig, &mut status, &mut warnings)?;
    let popts = ProfileOptions {
        robot: robot.clone(),
        ..ProfileOptions::default()
    };
    let start = prepare::start_of(rig, &starts.chosen);
    // 3. the adjustment, its views judged
    let mut fit = profile_adjustment(&obs, &start, &popts)?;
    let (obs, left) = checks::poor_views(obs, &mut fit, &start, &popts)?;
    for (row, note) in left {
        if let Some(s) = status.iter_mut().find(|s| s.view == row) {
            s.note = Some(note.clone());
        }
        warnings.push(note);
    }
    // 4. the mirror
    let mirror = checks::mirror(&obs, &fit, &prepare::start_of(rig, &starts.mirror), &popts)?;
    // 5. gates and checks
    let checks_out: Vec<QualityCheck> = vec![
        checks::views_check(&status, obs.len()),
        mirror.check(),
        checks::determined(&fit),
        checks::converged(&fit),
    ];
    let diameter_check = match rig.diameter_mm {
        Some(d) => Some(checks::diameter(&obs, &fit, d, &popts)?),
        None => None,
    };
    if let Some(dc) = diameter_check.as_ref().filter(|d| d.disagrees) {
        warnings.push(dc.message());
    }
    // 6. leave-one-out
    let leave_one_out = if opts.leave_one_out && obs.len() > crate::calib::profile::start::MIN_VIEWS
    {
        Some(loo::leave_one_out(&obs, &fit, &popts)?)
    } else {
        None
    };
    record::fill_status(&mut status, &obs, &fit);
    let failed: Vec<QualityCheck> = checks_out.iter().filter(|c| !c.passed).cloned().collect();
    let calibration = record::calibration(
        rig,
        &fit,
        &status,
        &checks_out,
        record::SelfChecks {
            mirror: &mirror,
            diameter: diameter_check.as_ref(),
            loo: leave_one_out.as_ref(),
        },
        &warnings,
        opts.accept_poor && !failed.is_empty(),
    );
    if !failed.is_empty() && !opts.accept_poor {
        return Err(Error::Quality(Box::new(QualityFailure::new(failed))));
    }
    Ok(ProfileReport {
        calibration,
        fit,
        views: status,
        mirror,
        diameter_check,
        leave_one_out,
        warnings,
    })
}

/// Loads a profile dataset folder and calibrates it ([`calibrate_profile_dataset_loaded`]).
pub fn calibrate_profile_dataset(
    root: impl AsRef<std::path::Path>,
    opts: &ProfileCalibrateOptions,
) -> Result<ProfileReport> {
    calibrate_profile_dataset_loaded(&ProfileDataset::load(root)?, opts)
}

/// Reads a loaded profile dataset's profiles (a malformed file is an error naming it and
/// the line) and calibrates ([`calibrate_profiles`]).
pub fn calibrate_profile_dataset_loaded(
    ds: &ProfileDataset,
    opts: &ProfileCalibrateOptions,
) -> Result<ProfileReport> {
    calibrate_profiles(&profile_inputs(ds)?, &ds.rig, opts)
}

/// A loaded profile dataset's profiles, read in parallel, with their readings (a
/// malformed file is an error naming it and the line).
pub fn profile_inputs(ds: &ProfileDataset) -> Result<Vec<ProfileInput>> {
    use rayon::prelude::*;
    ds.views
        .par_iter()
        .enumerate()
        .map(|(i, v)| {
            Ok(ProfileInput {
                view: i,
                line: v.line,
                file: v.profile.display().to_string(),
                profile: crate::io::read_profile(ds.profile_path(&v.profile), ds.rig.invalid_z)?,
                reading: v.reading.clone(),
            })
        })
        .collect()
}

/// `view 3 (views.csv line 5, profiles/p3.csv)`.
pub(crate) fn view_name(i: &ProfileInput) -> String {
    format!("view {} (views.csv line {}, {})", i.view, i.line, i.file)
}

fn status_of(i: &ProfileInput) -> ProfileViewStatus {
    ProfileViewStatus {
        view: i.view,
        line: i.line,
        file: i.file.clone(),
        points: i.profile.points.len(),
        gaps: i.profile.gaps,
        arc_points: 0,
        sphere_points: 0,
        rejected: i.profile.points.len(),
        rms_mm: None,
        side: None,
        centre_in_sensor: None,
        used: false,
        note: None,
    }
}

#[cfg(test)]
mod tests;
