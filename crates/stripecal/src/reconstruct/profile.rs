//! The point cloud of a profile scan (a calibrated line profiler, spec/DATASET.md "A
//! profile dataset").
//!
//! Each frame of scan.csv names a profile file (points `(x, z)` in mm in the profiler
//! frame `sensor`, on its plane y = 0) and a robot reading. A point is
//!
//! ```text
//! p_base = T_base_hand(q) * T_hand_sensor * (x, 0, z)
//! ```
//!
//! with `T_base_hand` the forward kinematics of the calibration's robot (its refined DH
//! rows when the robot was calibrated) for joint readings, or the flange pose as the
//! controller reported it, and `T_hand_sensor` the calibration's `hand_cam`. A fixed
//! profiler (scan.csv has the `profile` column alone) gives the points in the sensor
//! frame, `(x, 0, z)` as read; the PLY header then says `comment frame sensor`.
//!
//! Each point carries the properties `view` (its frame index, the row of scan.csv after
//! the header from 0), `x_mm` and `z_mm` (its sensor coordinates, so that the
//! calibration's uncertainty can be propagated to it later). Gaps (see
//! [`crate::io::parse_profile`]) are counted per frame in [`ProfileScanSummary::gaps`].
//!
//! A frame whose profile file is missing, unreadable or malformed stops the run with
//! [`Error::BadImage`] ([`BadFrame`]: the frame, its scan.csv line, the file and what is
//! wrong; the first such frame in frame order), or, with [`BadImage::Skip`], is left out
//! and listed in [`ProfileScanSummary::skipped`]. A robot reading that gives no pose
//! (joint readings with a calibration without a robot, a wrong joint count) always stops
//! the run, naming the frame and its line. Frames are read and mapped in parallel
//! (rayon).

use std::path::Path;

use nalgebra::Point3;
use rayon::prelude::*;

use super::points::ply_comments;
use super::{at_frame, BadImage};
use crate::error::{BadFrame, Error, Result};
use crate::io::read_profile;
use crate::model::geometry::Iso3;
use crate::model::kinematics::Robot;
use crate::model::{Cloud, Profile, ProfileScan, ProfilerCalibration, RobotReading};
use crate::reconstruct::ProfileFrame;

/// Options of [`reconstruct_profile_scan`].
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ProfileReconstructOptions {
    /// The vendor's "no point" sentinel; `None`: the scan's rig.json `sensor.invalid_z`
    /// (none without a rig.json).
    pub invalid_z: Option<f64>,
    /// What a frame whose profile cannot be read does: stop the run (the default) or be
    /// skipped and listed.
    pub on_bad_frame: BadImage,
}

/// What [`reconstruct_profile_scan`] did.
#[derive(Debug, Clone, PartialEq, Default)]
pub struct ProfileScanSummary {
    /// Frames in scan.csv.
    pub frames: usize,
    /// Points in the cloud.
    pub points: usize,
    /// Gaps per frame (0 for a skipped frame), in frame order.
    pub gaps: Vec<usize>,
    /// Frames left out (with [`BadImage::Skip`]), in frame order, each with the reason.
    pub skipped: Vec<BadFrame>,
    /// The points are in the sensor frame (a fixed profiler), not the base frame.
    pub sensor_frame: bool,
}

impl ProfileScanSummary {
    /// All gaps of the scan.
    pub fn total_gaps(&self) -> usize {
        self.gaps.iter().sum()
    }

    /// The PLY header comments of the cloud: `frame sensor` for a fixed profiler,
    /// `skipped_frames N` and one `skipped frame ...` line per skipped frame.
    pub fn ply_comments(&self) -> Vec<String> {
        ply_comments(self.sensor_frame.then_some("sensor"), &self.skipped)
    }
}

/// Why a profile file cannot be used (the reason of a [`BadFrame`]), from its read
/// error.
fn bad_profile_reason(path: &Path, e: Error) -> String {
    match e {
        Error::Io { source, .. } if !path.exists() => {
            format!("profile file does not exist ({source})")
        }
        Error::Io { source, .. } => format!("profile file cannot be read: {source}"),
        Error::Format {
            location, message, ..
        } => format!("profile file is malformed: {location}: {message}"),
        other => other.to_string(),
    }
}

/// `T_base_sensor` of one frame: `T_base_hand(q) * T_hand_sensor`, the identity for a
/// fixed profiler.
fn base_sensor(calib: &ProfilerCalibration, reading: &RobotReading) -> Result<Iso3> {
    match reading {
        RobotReading::Fixed => Ok(Iso3::identity()),
        RobotReading::Joints(_) if calib.robot.is_none() => Err(Error::InvalidInput(
            "joint readings given, but the calibration has no robot (it was calibrated from \
             flange poses): give the scan's flange poses"
                .into(),
        )),
        r => Ok(r.base_hand(calib.robot.as_ref())? * calib.hand_sensor),
    }
}

/// A profile scan's frames as read: each kept frame's index (its row of scan.csv after
/// the header, from 0) with its reading and profile, and what was done (gaps, skipped
/// frames; `points` 0). Files are read in parallel; a bad profile file stops the run or
/// is skipped as `opts` says (module docs).
pub fn read_profile_scan(
    scan: &ProfileScan,
    opts: &ProfileReconstructOptions,
) -> Result<(Vec<(usize, ProfileFrame)>, ProfileScanSummary)> {
    let invalid_z = opts
        .invalid_z
        .or_else(|| scan.rig.as_ref().and_then(|r| r.invalid_z));
    let parts: Vec<std::result::Result<Profile, String>> = scan
        .frames
        .par_iter()
        .map(|f| {
            let path = scan.profile_path(&f.profile);
            read_profile(&path, invalid_z).map_err(|e| bad_profile_reason(&path, e))
        })
        .collect();
    let mut summary = ProfileScanSummary {
        frames: scan.frames.len(),
        gaps: vec![0; scan.frames.len()],
        sensor_frame: scan.is_fixed(),
        ..Default::default()
    };
    let mut frames = Vec::with_capacity(parts.len());
    for (i, part) in parts.into_iter().enumerate() {
        let f = &scan.frames[i];
        match part {
            Ok(profile) => {
                summary.gaps[i] = profile.gaps;
                frames.push((i, (f.reading.clone(), profile)));
            }
            Err(reason) => {
                let bad = BadFrame {
                    frame: i,
                    line: f.line,
                    path: scan.profile_path(&f.profile),
                    reason,
                };
                if opts.on_bad_frame == BadImage::Stop {
                    return Err(Error::BadImage(bad));
                }
                summary.skipped.push(bad);
            }
        }
    }
    Ok((frames, summary))
}

/// A profile scan folder's frames ([`ProfileScan::load`], [`read_profile_scan`]), one
/// per row of scan.csv: a frame skipped as `opts` says keeps its place with its reading
/// and an empty profile, so the frame numbers of
/// [`profile_scan_points`](super::profile_scan_points) are scan.csv's rows; and what was
/// done.
pub fn load_profile_frames(
    dir: &Path,
    robot: Option<&Robot>,
    opts: &ProfileReconstructOptions,
) -> Result<(Vec<ProfileFrame>, ProfileScanSummary)> {
    let scan = ProfileScan::load(dir, robot)?;
    let (read, summary) = read_profile_scan(&scan, opts)?;
    let mut read = read.into_iter().peekable();
    let frames = scan
        .frames
        .iter()
        .enumerate()
        .map(|(i, f)| match read.next_if(|(k, _)| *k == i) {
            Some((_, frame)) => frame,
            None => (f.reading.clone(), Profile::default()),
        })
        .collect();
    Ok((frames, summary))
}

/// Reconstructs a profile scan folder's point cloud with a profiler's calibration (see
/// the module docs). Returns the cloud (properties `view`, `x_mm`, `z_mm`) and what was
/// done; write it with [`crate::io::write_ply_with_comments`] and
/// [`ProfileScanSummary::ply_comments`].
pub fn reconstruct_profile_scan(
    scan: &ProfileScan,
    calib: &ProfilerCalibration,
    opts: &ProfileReconstructOptions,
) -> Result<(Cloud, ProfileScanSummary)> {
    // every reading's pose first: a reading without one stops the run, naming its frame
    let poses: Vec<Iso3> = scan
        .frames
        .iter()
        .enumerate()
        .map(|(i, f)| base_sensor(calib, &f.reading).map_err(|e| at_frame(e, i, Some(f.line))))
        .collect::<Result<_>>()?;
    let (frames, mut summary) = read_profile_scan(scan, opts)?;
    let mut cloud = Cloud {
        points: Vec::new(),
        properties: ["view", "x_mm", "z_mm"]
            .iter()
            .map(|n| (n.to_string(), Vec::new()))
            .collect(),
    };
    for (i, (_, profile)) in &frames {
        let t = poses[*i];
        cloud.points.extend(
            profile
                .points
                .iter()
                .map(|&[x, z]| -> [f64; 3] { (t * Point3::new(x, 0.0, z)).coords.into() }),
        );
        let n = profile.points.len();
        let props = &mut cloud.properties;
        props[0].1.extend(std::iter::repeat_n(*i as f64, n));
        props[1].1.extend(profile.points.iter().map(|p| p[0]));
        props[2].1.extend(profile.points.iter().map(|p| p[1]));
    }
    summary.points = cloud.points.len();
    Ok((cloud, summary))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::io::{read_ply, write_ply_with_comments, PlyFormat};
    use crate::model::geometry::{iso_from_rotvec, iso_to_matrix};
    use crate::model::kinematics::Robot;
    use crate::model::{ProfileView, ProfilerQuality};
    use nalgebra::{Matrix4, Vector3, Vector4};
    use std::fs;
    use std::path::PathBuf;

    fn calib(robot: Option<Robot>) -> ProfilerCalibration {
        ProfilerCalibration {
            hand_sensor: iso_from_rotvec(
                &Vector3::new(0.2, 2.8, -0.3),
                &Vector3::new(10.0, -5.0, 120.0),
            ),
            robot,
            sphere_center_mm: Vector3::zeros(),
            sphere_diameter_mm: 25.0,
            quality: ProfilerQuality::default(),
            uncertainty: Default::default(),
            covariance: None,
            records: Default::default(),
            extra: Default::default(),
        }
    }

    /// A scan folder with two profiles, frames `readings`, profile 1 missing when
    /// `missing`.
    fn scan(readings: Vec<RobotReading>, missing: bool) -> (tempfile::TempDir, ProfileScan) {
        let dir = tempfile::tempdir().unwrap();
        fs::write(
            dir.path().join("a.csv"),
            "x_mm,z_mm,intensity\n-1.5,200,1\n0,nan,2\n2.25,201.5,3\n",
        )
        .unwrap();
        if !missing {
            fs::write(dir.path().join("b.csv"), "z_mm,x_mm\n-99,4\n150,-3\n").unwrap();
        }
        let frames = readings
            .into_iter()
            .enumerate()
            .map(|(i, reading)| ProfileView {
                line: i + 2,
                profile: PathBuf::from(if i % 2 == 0 { "a.csv" } else { "b.csv" }),
                reading,
            })
            .collect();
        let s = ProfileScan {
            root: dir.path().to_path_buf(),
            rig: Some(crate::model::ProfileRig {
                robot: None,
                invalid_z: Some(-99.0),
                diameter_mm: None,
            }),
            frames,
        };
        (dir, s)
    }

    /// `T * (x, 0, z)` with 4x4 matrices (an independent path from the isometry's).
    fn by_matrix(t: &Matrix4<f64>, x: f64, z: f64) -> [f64; 3] {
        let p = t * Vector4::new(x, 0.0, z, 1.0);
        [p[0], p[1], p[2]]
    }

    fn close(a: &[f64; 3], b: &[f64; 3]) -> bool {
        (0..3).all(|k| (a[k] - b[k]).abs() < 1e-9)
    }

    #[test]
    fn joint_readings_map_through_the_robot_and_the_hand_eye() {
        let robot = Robot::hp3();
        let q = [
            vec![10.0, -20.0, 30.0, 5.0, -45.0, 60.0],
            vec![0.0, 5.0, -5.0, 0.0, 30.0, 0.0],
        ];
        let c = calib(Some(robot.clone()));
        let (_d, s) = scan(q.iter().cloned().map(RobotReading::Joints).collect(), false);
        let (cloud, sum) =
            reconstruct_profile_scan(&s, &c, &ProfileReconstructOptions::default()).unwrap();
        // a.csv: 2 points, 1 gap (nan); b.csv: the rig's sentinel -99 is a gap
        assert_eq!(sum.gaps, vec![1, 1]);
        assert_eq!(
            (sum.points, sum.total_gaps(), sum.sensor_frame),
            (3, 2, false)
        );
        let hs = iso_to_matrix(&c.hand_sensor);
        let want = [
            by_matrix(
                &(iso_to_matrix(&robot.forward(&q[0]).unwrap()) * hs),
                -1.5,
                200.0,
            ),
            by_matrix(
                &(iso_to_matrix(&robot.forward(&q[0]).unwrap()) * hs),
                2.25,
                201.5,
            ),
            by_matrix(
                &(iso_to_matrix(&robot.forward(&q[1]).unwrap()) * hs),
                -3.0,
                150.0,
            ),
        ];
        for (got, want) in cloud.points.iter().zip(&want) {
            assert!(close(got, want), "{got:?} vs {want:?}");
        }
        let prop = |n: &str| &cloud.properties.iter().find(|p| p.0 == n).unwrap().1;
        assert_eq!(prop("view"), &vec![0.0, 0.0, 1.0]);
        assert_eq!(prop("x_mm"), &vec![-1.5, 2.25, -3.0]);
        assert_eq!(prop("z_mm"), &vec![200.0, 201.5, 150.0]);
        // the points lie on the sensor plane y = 0: back in the sensor frame, y is 0
        let back = (robot.forward(&q[0]).unwrap() * c.hand_sensor).inverse()
            * Point3::from(Vector3::from(cloud.points[1]));
        assert!(back.y.abs() < 1e-9, "{back:?}");
        // joint readings without a robot in the calibration name the frame and line
        let e = reconstruct_profile_scan(&s, &calib(None), &Default::default()).unwrap_err();
        assert!(
            e.to_string()
                .starts_with("invalid input: frame 0 (scan.csv line 2)"),
            "{e}"
        );
    }

    #[test]
    fn flange_poses_and_a_fixed_profiler() {
        let t0 = iso_from_rotvec(
            &Vector3::new(0.0, 0.0, 1.0),
            &Vector3::new(500.0, 0.0, 300.0),
        );
        let c = calib(None);
        let (_d, s) = scan(vec![RobotReading::FlangePose(t0)], false);
        let (cloud, _) = reconstruct_profile_scan(&s, &c, &Default::default()).unwrap();
        let m = iso_to_matrix(&t0) * iso_to_matrix(&c.hand_sensor);
        assert!(close(&cloud.points[0], &by_matrix(&m, -1.5, 200.0)));

        let (d, s) = scan(vec![RobotReading::Fixed, RobotReading::Fixed], false);
        // an explicit sentinel overrides the rig's: -99 is then a point
        let opts = ProfileReconstructOptions {
            invalid_z: Some(-12345.0),
            ..Default::default()
        };
        let (cloud, sum) = reconstruct_profile_scan(&s, &c, &opts).unwrap();
        assert!(sum.sensor_frame);
        assert_eq!(
            cloud.points,
            vec![
                [-1.5, 0.0, 200.0],
                [2.25, 0.0, 201.5],
                [4.0, 0.0, -99.0],
                [-3.0, 0.0, 150.0]
            ]
        );
        assert_eq!(sum.gaps, vec![1, 0]);
        let ply = d.path().join("cloud.ply");
        write_ply_with_comments(&ply, &cloud, PlyFormat::Ascii, &sum.ply_comments()).unwrap();
        let text = fs::read_to_string(&ply).unwrap();
        assert!(text.contains("comment frame sensor\n"), "{text}");
        assert!(text.contains("profiler sensor frame"), "{text}");
        assert_eq!(read_ply(&ply).unwrap(), cloud);
    }

    #[test]
    fn a_missing_or_malformed_profile_names_frame_line_and_file() {
        let (d, s) = scan(vec![RobotReading::Fixed; 3], true);
        let e = reconstruct_profile_scan(&s, &calib(None), &Default::default()).unwrap_err();
        let Error::BadImage(b) = e else {
            panic!("{e:?}")
        };
        assert_eq!((b.frame, b.line), (1, 3));
        assert_eq!(b.path, d.path().join("b.csv"));
        assert!(b.reason.contains("does not exist"), "{}", b.reason);

        fs::write(d.path().join("b.csv"), "x_mm,z_mm\n1,2\n3,oops\n").unwrap();
        let e = reconstruct_profile_scan(&s, &calib(None), &Default::default()).unwrap_err();
        let Error::BadImage(b) = e else {
            panic!("{e:?}")
        };
        assert_eq!(b.frame, 1);
        assert!(b.reason.contains("line 3, column z_mm"), "{}", b.reason);
        assert!(b.reason.contains("\"oops\""), "{}", b.reason);

        let opts = ProfileReconstructOptions {
            on_bad_frame: BadImage::Skip,
            ..Default::default()
        };
        let (cloud, sum) = reconstruct_profile_scan(&s, &calib(None), &opts).unwrap();
        assert_eq!(sum.skipped.len(), 1);
        assert_eq!(sum.skipped[0].frame, 1);
        // frames 0 and 2 (a.csv, 2 points each) are kept
        assert_eq!(cloud.points.len(), 4);
        assert_eq!(cloud.properties[0].1, vec![0.0, 0.0, 2.0, 2.0]);
        assert_eq!(sum.ply_comments()[1], "skipped_frames 1");
    }
}
