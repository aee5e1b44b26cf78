//! Loading a profile dataset folder and a profile scan folder (spec/DATASET.md "A
//! profile dataset").
//!
//! - A dataset: `rig.json` (a profiler's, [`super::read_profile_rig`]) and `views.csv`
//!   with the header `profile,q1,...,qN` or `profile,` and flange-pose columns (any
//!   convention and column order, exactly as a camera dataset's views.csv: the same
//!   parser, [`super::csv`]). A profile dataset needs robot poses (no pose columns is an
//!   error) and at least one view; every profile file named must exist.
//! - A scan: `scan.csv` with the header `profile` and the same pose columns, or
//!   `profile` alone (a fixed profiler: points in the sensor frame), and an optional
//!   rig.json (a profiler's).
//!
//! The `profile` column comes first, as the image columns of a camera dataset do. A
//! header with `board_image`, `laser_image` or `image` is refused with a message saying
//! that this is a profile dataset. Profile paths are kept as written (relative to the
//! folder); [`ProfileDataset::profile_path`] resolves them.

use std::path::{Path, PathBuf};

use super::atomic::read_text;
use super::csv::parse_table;
use super::dataset::{check_files_exist, check_joints_have_robot, read_if_present};
use super::profile_rig::read_profile_rig;
use super::sensor::sensor_kind;
use crate::error::{Error, Result};
use crate::model::kinematics::Robot;
use crate::model::{ProfileDataset, ProfileScan, ProfileView, RobotReading, SensorKind};

/// The file column of a profile table.
const PROFILE_COLUMNS: [&str; 1] = ["profile"];

/// The trimmed fields of a CSV text's first line.
fn header_fields(text: &str) -> Vec<&str> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let line = text.split('\n').next().unwrap_or("");
    line.split(',').map(str::trim).collect()
}

/// Reads a profile table (views.csv or scan.csv): header `profile,` + pose columns.
fn read_profile_table(path: &Path, robot: Option<&Robot>) -> Result<Vec<ProfileView>> {
    let text = read_text(path)?;
    let rows = parse_table(path, &text, &PROFILE_COLUMNS, robot)?;
    Ok(rows
        .into_iter()
        .map(|mut r| ProfileView {
            line: r.line,
            profile: PathBuf::from(std::mem::take(&mut r.names[0])),
            reading: r.reading,
        })
        .collect())
}

impl ProfileDataset {
    /// Loads `root/rig.json` (a profiler's) and `root/views.csv`, checking that the views
    /// carry robot poses that fit the rig's robot and that every profile file exists.
    /// Never reads truth.json.
    pub fn load(root: impl AsRef<Path>) -> Result<ProfileDataset> {
        let root = root.as_ref().to_path_buf();
        let rig = read_profile_rig(root.join("rig.json"))?;
        let views_path = root.join("views.csv");
        let views = read_profile_table(&views_path, rig.robot.as_ref())?;
        let Some(first) = views.first() else {
            return Err(Error::format(
                &views_path,
                "line 2",
                "views.csv has no views",
            ));
        };
        if first.reading == RobotReading::Fixed {
            return Err(Error::format(
                &views_path,
                "line 1",
                "a profile dataset needs robot poses: joint readings q1..qN or flange-pose \
                 columns (e.g. profile,x_mm,y_mm,z_mm,qw,qx,qy,qz) after `profile`",
            ));
        }
        check_joints_have_robot(&views_path, rig.robot.as_ref(), &first.reading)?;
        let names = views.iter().map(|v| (v.line, v.profile.as_path()));
        check_files_exist(&root, "views.csv", "profile", names)?;
        Ok(ProfileDataset { root, rig, views })
    }

    /// The full path of a profile named in the dataset.
    pub fn profile_path(&self, rel: &Path) -> PathBuf {
        self.root.join(rel)
    }
}

impl ProfileScan {
    /// Loads `root/scan.csv` (and `root/rig.json`, a profiler's, when present), checking
    /// that every profile file exists. `robot` checks the joint count when the scan has
    /// no rig.json (or its rig no robot).
    pub fn load(root: impl AsRef<Path>, robot: Option<&Robot>) -> Result<ProfileScan> {
        let scan = ProfileScan::read(root, robot)?;
        let names = scan.frames.iter().map(|f| (f.line, f.profile.as_path()));
        check_files_exist(&scan.root, "scan.csv", "profile", names)?;
        Ok(scan)
    }

    /// [`ProfileScan::load`] without checking that the profile files exist: for a reader
    /// that reads each frame's profile itself and reports the frame
    /// ([`crate::reconstruct::reconstruct_profile_scan`]).
    pub fn read(root: impl AsRef<Path>, robot: Option<&Robot>) -> Result<ProfileScan> {
        let root = root.as_ref().to_path_buf();
        let rig = read_if_present(&root.join("rig.json"), |p| read_profile_rig(p))?;
        let robot = rig.as_ref().and_then(|r| r.robot.as_ref()).or(robot);
        let csv_path = root.join("scan.csv");
        let frames = read_profile_table(&csv_path, robot)?;
        if frames.is_empty() {
            return Err(Error::format(&csv_path, "line 2", "scan has no frames"));
        }
        Ok(ProfileScan { root, rig, frames })
    }

    /// A scan of a fixed profiler: scan.csv has the `profile` column alone; its points
    /// are in the sensor frame.
    pub fn is_fixed(&self) -> bool {
        self.frames
            .first()
            .is_some_and(|f| f.reading == RobotReading::Fixed)
    }

    /// The full path of a profile named in the scan.
    pub fn profile_path(&self, rel: &Path) -> PathBuf {
        self.root.join(rel)
    }
}

/// Whether the scan folder `root` is a profile scan: its scan.csv's header has a
/// `profile` column (an error when scan.csv cannot be read).
pub fn is_profile_scan(root: impl AsRef<Path>) -> Result<bool> {
    let text = read_text(&root.as_ref().join("scan.csv"))?;
    Ok(header_fields(&text).contains(&PROFILE_COLUMNS[0]))
}

/// Whether the dataset folder `root` is a profile dataset: its rig.json says
/// `sensor.kind = "profiler"` (an error when rig.json cannot be read or names an
/// unknown kind).
pub fn is_profile_dataset(root: impl AsRef<Path>) -> Result<bool> {
    Ok(sensor_kind(root.as_ref().join("rig.json"))? == SensorKind::Profiler)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::Dataset;
    use std::fs;

    const RIG_JOINTS: &str = r#"{"format": "stripecal/rig@1",
        "sensor": {"kind": "profiler", "invalid_z": -99999.9999},
        "artefact": {"kind": "sphere", "diameter_mm": 80.0},
        "robot": {"name": "two", "joints": [
            {"theta0_deg": 0, "alpha_deg": -90, "a_mm": 100, "d_mm": 300},
            {"theta0_deg": 0, "alpha_deg": 0, "a_mm": 250, "d_mm": 0}]}}"#;
    const RIG_FLANGE: &str = r#"{"format": "stripecal/rig@1", "sensor": {"kind": "profiler"},
        "artefact": {"kind": "sphere", "diameter_mm": null}}"#;

    /// A folder with rig.json, a table and the profile files it names.
    fn folder(rig: Option<&str>, table: &str, csv: &str, profiles: &[&str]) -> tempfile::TempDir {
        let dir = tempfile::tempdir().unwrap();
        if let Some(r) = rig {
            fs::write(dir.path().join("rig.json"), r).unwrap();
        }
        fs::write(dir.path().join(table), csv).unwrap();
        fs::create_dir(dir.path().join("p")).unwrap();
        for p in profiles {
            fs::write(dir.path().join(p), "x_mm,z_mm\n0,200\n").unwrap();
        }
        dir
    }

    fn format_error(e: Error) -> (PathBuf, String, String) {
        match e {
            Error::Format {
                path,
                location,
                message,
            } => (path, location, message),
            other => panic!("expected a format error, got {other:?}"),
        }
    }

    #[test]
    fn loads_joint_readings() {
        let d = folder(
            Some(RIG_JOINTS),
            "views.csv",
            "profile,q1,q2\np/a.csv,10,-20.5\np/b.csv,0,3\n",
            &["p/a.csv", "p/b.csv"],
        );
        let ds = ProfileDataset::load(d.path()).unwrap();
        assert_eq!(ds.rig.diameter_mm, Some(80.0));
        assert_eq!(ds.views.len(), 2);
        assert_eq!(ds.views[0].line, 2);
        assert_eq!(ds.views[0].profile, Path::new("p/a.csv"));
        assert_eq!(ds.views[0].reading, RobotReading::Joints(vec![10.0, -20.5]));
        assert_eq!(
            ds.profile_path(&ds.views[1].profile),
            d.path().join("p/b.csv")
        );
        assert!(is_profile_dataset(d.path()).unwrap());
    }

    #[test]
    fn loads_flange_poses_in_any_convention() {
        // ROS order, metres: the same parser as a camera dataset's views.csv
        let d = folder(
            Some(RIG_FLANGE),
            "views.csv",
            "profile,x_m,y_m,z_m,qx,qy,qz,qw\np/a.csv,0.5,-0.25,1,0,0,0.6,0.8\n",
            &["p/a.csv"],
        );
        let ds = ProfileDataset::load(d.path()).unwrap();
        let RobotReading::FlangePose(t) = &ds.views[0].reading else {
            panic!("{:?}", ds.views[0].reading)
        };
        let want = nalgebra::Vector3::new(500.0, -250.0, 1000.0);
        assert!((t.translation.vector - want).norm() < 1e-9);
        // a rotation of 2 * atan2(0.6, 0.8) about z
        let angle = 2.0 * 0.6f64.atan2(0.8);
        assert!((t.rotation.angle() - angle).abs() < 1e-12);
        assert!(ds.rig.robot.is_none());
    }

    #[test]
    fn refuses_image_columns_saying_it_is_a_profile_dataset() {
        let d = folder(
            Some(RIG_JOINTS),
            "views.csv",
            "board_image,laser_image,q1,q2\na.png,b.png,0,0\n",
            &[],
        );
        let (path, loc, msg) = format_error(ProfileDataset::load(d.path()).unwrap_err());
        assert!(path.ends_with("views.csv"));
        assert_eq!(loc, "line 1");
        assert!(msg.contains("board_image, laser_image"), "{msg}");
        assert!(msg.contains("this is a profile dataset"), "{msg}");
        // and the camera loader refuses the profiler rig
        let e = Dataset::load(d.path()).unwrap_err();
        assert!(
            e.to_string().contains("rig.json describes a profiler"),
            "{e}"
        );
    }

    #[test]
    fn joints_without_robot_no_poses_and_no_views_are_errors() {
        let d = folder(
            Some(RIG_FLANGE),
            "views.csv",
            "profile,q1,q2\np/a.csv,0,0\n",
            &["p/a.csv"],
        );
        let (_, loc, msg) = format_error(ProfileDataset::load(d.path()).unwrap_err());
        assert_eq!(loc, "line 1");
        assert!(msg.contains("need a robot (DH table) in rig.json"), "{msg}");

        let d = folder(
            Some(RIG_JOINTS),
            "views.csv",
            "profile\np/a.csv\n",
            &["p/a.csv"],
        );
        let (_, loc, msg) = format_error(ProfileDataset::load(d.path()).unwrap_err());
        assert_eq!(loc, "line 1");
        assert!(msg.contains("needs robot poses"), "{msg}");

        let d = folder(Some(RIG_JOINTS), "views.csv", "profile,q1,q2\n", &[]);
        let (_, loc, msg) = format_error(ProfileDataset::load(d.path()).unwrap_err());
        assert_eq!(
            (loc.as_str(), msg.as_str()),
            ("line 2", "views.csv has no views")
        );

        // the joint count is checked against the rig's robot
        let d = folder(
            Some(RIG_JOINTS),
            "views.csv",
            "profile,q1,q2,q3\np/a.csv,0,0,0\n",
            &["p/a.csv"],
        );
        let (_, loc, msg) = format_error(ProfileDataset::load(d.path()).unwrap_err());
        assert_eq!(loc, "line 1");
        assert!(msg.contains("3 joint columns, robot has 2"), "{msg}");
    }

    #[test]
    fn a_missing_profile_names_views_csv_and_the_line() {
        let d = folder(
            Some(RIG_JOINTS),
            "views.csv",
            "profile,q1,q2\np/a.csv,0,0\np/gone.csv,1,1\n",
            &["p/a.csv"],
        );
        let (path, loc, msg) = format_error(ProfileDataset::load(d.path()).unwrap_err());
        assert!(path.ends_with("views.csv"));
        assert_eq!(loc, "line 3");
        assert!(msg.contains("profile") && msg.contains("gone.csv"), "{msg}");
        // a bad number in a pose column names the line and column
        let d = folder(
            Some(RIG_JOINTS),
            "views.csv",
            "profile,q1,q2\np/a.csv,0,x\n",
            &["p/a.csv"],
        );
        let (_, loc, _) = format_error(ProfileDataset::load(d.path()).unwrap_err());
        assert_eq!(loc, "line 2, column q2");
    }

    #[test]
    fn scans_fixed_posed_and_with_a_rig() {
        let d = folder(
            None,
            "scan.csv",
            "profile\np/a.csv\np/b.csv\n",
            &["p/a.csv"],
        );
        assert!(is_profile_scan(d.path()).unwrap());
        let s = ProfileScan::read(d.path(), None).unwrap();
        assert!(s.is_fixed() && s.rig.is_none());
        assert_eq!(s.frames.len(), 2);
        // load checks the files, read does not
        let (path, loc, _) = format_error(ProfileScan::load(d.path(), None).unwrap_err());
        assert!(path.ends_with("scan.csv"));
        assert_eq!(loc, "line 3");

        let d = folder(
            Some(RIG_JOINTS),
            "scan.csv",
            "profile,q1,q2\np/a.csv,1,2\n",
            &["p/a.csv"],
        );
        let s = ProfileScan::load(d.path(), None).unwrap();
        assert!(!s.is_fixed());
        assert_eq!(s.rig.as_ref().unwrap().invalid_z, Some(-99999.9999));
        // without a rig, the caller's robot checks the joint count
        let d = folder(
            None,
            "scan.csv",
            "profile,q1,q2\np/a.csv,1,2\n",
            &["p/a.csv"],
        );
        let e = ProfileScan::load(d.path(), Some(&Robot::hp3())).unwrap_err();
        assert!(
            e.to_string().contains("2 joint columns, robot has 6"),
            "{e}"
        );

        // the camera's scan reader refuses a profile scan, saying what it is
        let (_, loc, msg) = format_error(crate::model::Scan::read(d.path(), None).unwrap_err());
        assert_eq!(loc, "line 1");
        assert!(msg.contains("this is a line profiler's table"), "{msg}");

        // a camera scan is not a profile scan, and is refused by the profile reader
        let d = folder(None, "scan.csv", "image,q1\na.png,0\n", &[]);
        assert!(!is_profile_scan(d.path()).unwrap());
        let (_, loc, msg) = format_error(ProfileScan::read(d.path(), None).unwrap_err());
        assert_eq!(loc, "line 1");
        assert!(msg.contains("column image names images"), "{msg}");
    }
}
