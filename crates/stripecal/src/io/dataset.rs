//! Loading a calibration dataset folder and a scan folder.

use std::path::{Path, PathBuf};

use super::{read_rig, read_scan_csv, read_views_csv};
use crate::error::{Error, Result};
use crate::model::kinematics::Robot;
use crate::model::{Dataset, RobotReading, Scan};

impl Dataset {
    /// Loads `root/rig.json` and `root/views.csv` and checks that every image named
    /// exists and that joint columns match the robot. Never reads truth.json.
    pub fn load(root: impl AsRef<Path>) -> Result<Dataset> {
        let root = root.as_ref().to_path_buf();
        let rig = read_rig(root.join("rig.json"))?;
        let views_path = root.join("views.csv");
        let views = read_views_csv(&views_path, rig.robot.as_ref())?;
        if views.is_empty() {
            return Err(Error::format(
                &views_path,
                "line 2",
                "views.csv has no views",
            ));
        }
        check_joints_have_robot(&views_path, rig.robot.as_ref(), &views[0].reading)?;
        let names = views.iter().flat_map(|v| {
            std::iter::once((v.line, v.board_image.as_path()))
                .chain(v.laser_image.as_deref().map(|l| (v.line, l)))
        });
        check_files_exist(&root, "views.csv", "image", names)?;
        Ok(Dataset { root, rig, views })
    }

    /// The full path of an image named in the dataset.
    pub fn image_path(&self, rel: &Path) -> PathBuf {
        self.root.join(rel)
    }
}

impl Scan {
    /// Loads `root/scan.csv` (and `root/rig.json` when present), checking images exist.
    /// `robot` is used to check the joint count when the scan has no rig.json.
    pub fn load(root: impl AsRef<Path>, robot: Option<&Robot>) -> Result<Scan> {
        let scan = Scan::read(root, robot)?;
        let names = scan.frames.iter().map(|f| (f.line, f.image.as_path()));
        check_files_exist(&scan.root, "scan.csv", "image", names)?;
        Ok(scan)
    }

    /// [`Scan::load`] without checking that the images exist: for a reader that checks
    /// each frame's image itself (the reconstruction, which may skip bad frames).
    pub fn read(root: impl AsRef<Path>, robot: Option<&Robot>) -> Result<Scan> {
        let root = root.as_ref().to_path_buf();
        let rig = read_if_present(&root.join("rig.json"), |p| read_rig(p))?;
        let robot = rig.as_ref().and_then(|r| r.robot.as_ref()).or(robot);
        let csv_path = root.join("scan.csv");
        let frames = read_scan_csv(&csv_path, robot)?;
        if frames.is_empty() {
            return Err(Error::format(&csv_path, "line 2", "scan has no frames"));
        }
        Ok(Scan { root, rig, frames })
    }

    /// The full path of an image named in the scan.
    pub fn image_path(&self, rel: &Path) -> PathBuf {
        self.root.join(rel)
    }
}

/// `read(path)` when the file exists, `None` otherwise (a scan's optional rig.json).
pub(super) fn read_if_present<T>(
    path: &Path,
    read: impl FnOnce(&Path) -> Result<T>,
) -> Result<Option<T>> {
    if path.exists() {
        read(path).map(Some)
    } else {
        Ok(None)
    }
}

/// Checks that every file named in the table `root/csv` exists: `(line, name)` pairs.
pub(super) fn check_files_exist<'a>(
    root: &Path,
    csv: &str,
    what: &str,
    names: impl Iterator<Item = (usize, &'a Path)>,
) -> Result<()> {
    let csv_path = root.join(csv);
    for (line, rel) in names {
        check_file_exists(root, &csv_path, line, what, rel)?;
    }
    Ok(())
}

/// Checks that the file `rel` (an `image`, a `profile`) named on `line` of `csv` is a
/// regular file under `root` (not missing, a folder, a FIFO, a device or a broken
/// symbolic link: [`super::atomic::file_problem`] says which).
fn check_file_exists(root: &Path, csv: &Path, line: usize, what: &str, rel: &Path) -> Result<()> {
    let p = root.join(rel);
    if let Some((_, why)) = super::atomic::file_problem(&p) {
        return Err(Error::format(
            csv,
            format!("line {line}"),
            format!("{what} {} {why}", p.display()),
        ));
    }
    Ok(())
}

/// Joint columns need a robot (a DH table) in rig.json: an error on line 1 of `csv`
/// when the first row has joint readings and there is none.
pub(super) fn check_joints_have_robot(
    csv: &Path,
    robot: Option<&Robot>,
    first: &RobotReading,
) -> Result<()> {
    if robot.is_none() && matches!(first, RobotReading::Joints(_)) {
        return Err(Error::format(
            csv,
            "line 1",
            "joint columns q1..qN need a robot (DH table) in rig.json; \
             without one, use flange-pose columns (e.g. x_mm,y_mm,z_mm,qw,qx,qy,qz)",
        ));
    }
    Ok(())
}
