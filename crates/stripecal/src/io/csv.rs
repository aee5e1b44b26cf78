//! `views.csv` and `scan.csv`.
//!
//! A header line, then one row per pose. The leading columns name images
//! (`board_image,laser_image` or `image`), the rest are either encoder readings
//! `q1,...,qN` (degrees, in that order) or the flange pose `T_base_hand` in a
//! controller's convention, told by the column names and in any column order: a
//! translation `x_mm,y_mm,z_mm` or `x_m,y_m,z_m` and one rotation `qw,qx,qy,qz`,
//! `rx_rad,ry_rad,rz_rad`, `rx_deg,ry_deg,rz_deg`, `a_deg,b_deg,c_deg` (KUKA),
//! `w_deg,p_deg,r_deg` (Fanuc) or `r11..r33` (the conventions are in [`super::poses`],
//! one file each). A header that mixes conventions, lacks or repeats a column, or names an
//! unknown one is an error on line 1; a row whose quaternion or matrix is not a rotation
//! (within 1e-3) is an error naming its line.
//!
//! No value column at all (`board_image,laser_image`, or `image` alone) is a fixed
//! sensor: a bench dataset, a fixed-sensor scan ([`RobotReading::Fixed`]). A dataset
//! is that as a whole or not at all: with pose columns in the header, a row whose pose
//! cells are all empty is an error naming its line.
//!
//! The writers write joint readings as they are and flange poses as
//! `x_mm,y_mm,z_mm,qw,qx,qy,qz` unless given other [`PoseColumns`]
//! ([`write_views_csv_with`], [`write_scan_csv_with`]).
//!
//! Fields are separated by commas and trimmed; CRLF line ends, a UTF-8 byte-order mark
//! and trailing empty lines are accepted. There is no quoting: a `"` anywhere is an
//! error (image names may not contain commas or quotes).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use super::atomic::{read_text, write_atomic};
use super::poses::{expected_header, Layout, PoseColumns};
use crate::error::{Error, Result};
use crate::model::kinematics::Robot;
use crate::model::{RobotReading, ScanFrame, View};

const VIEW_NAME_COLUMNS: [&str; 2] = ["board_image", "laser_image"];
const SCAN_NAME_COLUMNS: [&str; 1] = ["image"];

/// One parsed data row: file names (trimmed, possibly empty) and the reading.
pub(super) struct Row {
    pub line: usize,
    pub names: Vec<String>,
    pub reading: RobotReading,
}

fn reject_quotes(path: &Path, line_no: usize, line: &str) -> Result<()> {
    if line.contains('"') {
        return Err(Error::format(
            path,
            format!("line {line_no}"),
            "quoted fields are not supported (image names may not contain commas or quotes)",
        ));
    }
    Ok(())
}

/// The image columns of a camera dataset's tables (refused in a profile table).
const IMAGE_COLUMNS: [&str; 3] = ["board_image", "laser_image", "image"];

fn parse_header(
    path: &Path,
    header: &str,
    names: &[&str],
    robot: Option<&Robot>,
) -> Result<Layout> {
    let at = |msg: String| Error::format(path, "line 1", msg);
    let expected = expected_header(names);
    if header.trim().is_empty() {
        return Err(at(format!("empty header: expected {expected}")));
    }
    reject_quotes(path, 1, header)?;
    let fields: Vec<&str> = header.split(',').map(str::trim).collect();
    if fields.contains(&"profile") && !names.contains(&"profile") {
        return Err(at(format!(
            "column `profile` names profile files: this is a line profiler's table (read the \
             folder as a profile dataset or scan: ProfileDataset::load, ProfileScan::load); a \
             camera's header is {expected}"
        )));
    }
    if names == ["profile"] {
        let images: Vec<&str> = fields
            .iter()
            .copied()
            .filter(|f| IMAGE_COLUMNS.contains(f))
            .collect();
        if !images.is_empty() {
            return Err(at(format!(
                "column {} names images, but this is a profile dataset (rig.json sensor.kind = \
                 \"profiler\"): its table has a `profile` column (a profile file) and the \
                 joint or pose columns, e.g. `profile,q1,...,qN`",
                images.join(", ")
            )));
        }
    }
    for (i, name) in names.iter().enumerate() {
        match fields.get(i) {
            Some(f) if f == name => {}
            Some(f) => {
                return Err(at(format!(
                    "header column {} is `{f}`, expected `{name}` (the header must be {expected})",
                    i + 1
                )))
            }
            None => return Err(at(format!("header is too short: expected {expected}"))),
        }
    }
    let rest = &fields[names.len()..];
    let layout = Layout::of_header(rest, names.len() + 1).map_err(at)?;
    if let Some(msg) = layout.check_robot(robot) {
        return Err(at(msg));
    }
    Ok(layout)
}

fn parse_number(path: &Path, line_no: usize, column: &str, raw: &str) -> Result<f64> {
    match raw.parse::<f64>() {
        Ok(x) if x.is_finite() => Ok(x),
        _ => Err(Error::format(
            path,
            format!("line {line_no}, column {column}"),
            format!("{column} = {raw:?} is not a finite number"),
        )),
    }
}

/// Parses a whole table. `names` are the leading file columns (`board_image,laser_image`,
/// `image`, or a profiler's `profile`), the rest the pose columns of [`Layout`].
pub(super) fn parse_table(
    path: &Path,
    text: &str,
    names: &[&str],
    robot: Option<&Robot>,
) -> Result<Vec<Row>> {
    let lines: Vec<&str> = text
        .split('\n')
        .map(|l| l.strip_suffix('\r').unwrap_or(l))
        .collect();
    let layout = parse_header(path, lines.first().copied().unwrap_or(""), names, robot)?;
    let value_columns = layout.column_names();
    let ncols = names.len() + value_columns.len();
    // Trailing empty lines are allowed; empty lines before the last row are not.
    let last = lines
        .iter()
        .rposition(|l| !l.trim().is_empty())
        .unwrap_or(0);

    let mut rows = Vec::with_capacity(last);
    for (i, line) in lines.iter().enumerate().take(last + 1).skip(1) {
        let line_no = i + 1;
        if line.trim().is_empty() {
            return Err(Error::format(
                path,
                format!("line {line_no}"),
                "empty line (only trailing empty lines are allowed)",
            ));
        }
        reject_quotes(path, line_no, line)?;
        let fields: Vec<&str> = line.split(',').map(str::trim).collect();
        if fields.len() != ncols {
            return Err(Error::format(
                path,
                format!("line {line_no}"),
                format!("expected {ncols} columns, found {}", fields.len()),
            ));
        }
        let row_names: Vec<String> = fields[..names.len()]
            .iter()
            .map(|s| s.to_string())
            .collect();
        // The first image column is always required.
        if row_names[0].is_empty() {
            return Err(Error::format(
                path,
                format!("line {line_no}, column {}", names[0]),
                format!("{} is empty", names[0]),
            ));
        }
        let pose_cells = &fields[names.len()..];
        if !pose_cells.is_empty() && pose_cells.iter().all(|c| c.is_empty()) {
            return Err(Error::format(
                path,
                format!("line {line_no}"),
                format!(
                    "the pose cells ({}) are empty: a dataset is a bench dataset (no pose \
                     columns in the header) as a whole or not at all",
                    value_columns.join(",")
                ),
            ));
        }
        let mut values = Vec::with_capacity(value_columns.len());
        for (raw, col) in fields[names.len()..].iter().zip(&value_columns) {
            values.push(parse_number(path, line_no, col, raw)?);
        }
        let reading = layout
            .reading(values)
            .map_err(|(cols, msg)| Error::format(path, format!("line {line_no}, {cols}"), msg))?;
        rows.push(Row {
            line: line_no,
            names: row_names,
            reading,
        });
    }
    check_unique_files(path, names, &rows)?;
    Ok(rows)
}

/// A file name as a key: `.` components and repeated separators dropped, so that
/// `images/./a.png` and `images//a.png` are `images/a.png`.
fn name_key(name: &str) -> String {
    let p = Path::new(name);
    let parts: Vec<String> = p
        .components()
        .filter(|c| !matches!(c, std::path::Component::CurDir))
        .map(|c| c.as_os_str().to_string_lossy().into_owned())
        .collect();
    parts.join("/")
}

/// Refuses a file named on two rows of a table: a repeated row (or an image paired with
/// two poses) would count one observation twice, doubling its weight and making the
/// uncertainties too small, silently. The error is on the later line and names the
/// earlier one. One row may name one file twice (`laser_image` = `board_image`: one
/// image holds both).
fn check_unique_files(path: &Path, columns: &[&str], rows: &[Row]) -> Result<()> {
    let mut seen: std::collections::HashMap<String, (usize, usize)> =
        std::collections::HashMap::new();
    for (k, row) in rows.iter().enumerate() {
        for (c, name) in row.names.iter().enumerate() {
            if name.is_empty() {
                continue;
            }
            let key = name_key(name);
            match seen.get(&key) {
                Some(&(j, _)) if j == k => {}
                Some(&(j, c0)) => {
                    let first = &rows[j];
                    let msg = if first.names == row.names && first.reading == row.reading {
                        format!(
                            "repeats line {} exactly ({} {name}, the same {}): the row would \
                             be counted twice, its weight doubled and the uncertainties too \
                             small; remove one of the two lines",
                            first.line,
                            columns[c],
                            if row.reading == RobotReading::Fixed {
                                "row"
                            } else {
                                "robot pose"
                            }
                        )
                    } else {
                        format!(
                            "{} {name} is named on line {} already ({}): one file is one \
                             observation, on one line only (counted twice it would double its \
                             weight{})",
                            columns[c],
                            first.line,
                            columns[c0],
                            if row.reading != first.reading {
                                ", paired with two different robot poses"
                            } else {
                                ""
                            }
                        )
                    };
                    return Err(Error::format(
                        path,
                        format!("line {}, column {}", row.line, columns[c]),
                        msg,
                    ));
                }
                None => {
                    seen.insert(key, (k, c));
                }
            }
        }
    }
    Ok(())
}

/// Reads views.csv: header `board_image,laser_image,q1,...,qN` or
/// `board_image,laser_image,` and flange-pose columns in any convention and order (see
/// the module docs), e.g. `board_image,laser_image,x_mm,y_mm,z_mm,qw,qx,qy,qz`. With
/// `robot`, N must equal its number of joints. An empty `laser_image` gives `None`.
pub fn read_views_csv(p: impl AsRef<Path>, robot: Option<&Robot>) -> Result<Vec<View>> {
    let path = p.as_ref();
    let text = read_text(path)?;
    let rows = parse_table(path, &text, &VIEW_NAME_COLUMNS, robot)?;
    Ok(rows
        .into_iter()
        .map(|mut r| {
            let laser = std::mem::take(&mut r.names[1]);
            View {
                line: r.line,
                board_image: PathBuf::from(std::mem::take(&mut r.names[0])),
                laser_image: (!laser.is_empty()).then(|| PathBuf::from(laser)),
                reading: r.reading,
            }
        })
        .collect())
}

/// Reads scan.csv: header `image,q1,...,qN` or `image,` and flange-pose columns (as
/// [`read_views_csv`]). With `robot`, N must equal its number of joints.
pub fn read_scan_csv(p: impl AsRef<Path>, robot: Option<&Robot>) -> Result<Vec<ScanFrame>> {
    let path = p.as_ref();
    let text = read_text(path)?;
    let rows = parse_table(path, &text, &SCAN_NAME_COLUMNS, robot)?;
    Ok(rows
        .into_iter()
        .map(|mut r| ScanFrame {
            line: r.line,
            image: PathBuf::from(std::mem::take(&mut r.names[0])),
            reading: r.reading,
        })
        .collect())
}

// ---------------------------------------------------------------- writers

/// An image name as it can be written: UTF-8, no commas, quotes, line breaks or
/// surrounding spaces (the reader trims fields).
pub(super) fn name_field(
    what: &str,
    row: usize,
    p: Option<&Path>,
    required: bool,
) -> Result<String> {
    let Some(p) = p else {
        return if required {
            Err(Error::InvalidInput(format!(
                "{what} of row {row} is missing"
            )))
        } else {
            Ok(String::new())
        };
    };
    let s = p.to_str().ok_or_else(|| {
        Error::InvalidInput(format!(
            "{what} of row {row} ({}) is not valid UTF-8",
            p.display()
        ))
    })?;
    if s.is_empty() && required {
        return Err(Error::InvalidInput(format!("{what} of row {row} is empty")));
    }
    if s.contains([',', '"', '\n', '\r']) || s.trim() != s {
        return Err(Error::InvalidInput(format!(
            "{what} of row {row} ({s:?}) cannot be written to CSV: it contains a comma, quote, line break or surrounding spaces"
        )));
    }
    Ok(s.to_string())
}

pub(super) fn push_reading(
    out: &mut String,
    row: usize,
    r: &RobotReading,
    pose: &PoseColumns,
) -> Result<()> {
    let (_, values) = Layout::of_reading(r, pose);
    for x in values {
        if !x.is_finite() {
            return Err(Error::InvalidInput(format!(
                "row {row} has a non-finite robot value ({x})"
            )));
        }
        // `{}` of an f64 prints the shortest text that parses back to the same value.
        let _ = write!(out, ",{x}");
    }
    out.push('\n');
    Ok(())
}

/// The common layout of all rows (error when rows differ or there are none).
pub(super) fn common_layout<'a>(
    what: &str,
    readings: impl Iterator<Item = &'a RobotReading>,
    pose: &PoseColumns,
) -> Result<Layout> {
    let mut layout: Option<Layout> = None;
    for (i, r) in readings.enumerate() {
        let (l, _) = Layout::of_reading(r, pose);
        match &layout {
            None => {
                if l == Layout::Joints(0) {
                    return Err(Error::InvalidInput(format!(
                        "{what} row 1 has no joint readings"
                    )));
                }
                layout = Some(l);
            }
            Some(first) if *first != l => {
                return Err(Error::InvalidInput(format!(
                    "{what} row {} has {}, row 1 has {}: all rows must use the same columns",
                    i + 1,
                    l.describe(),
                    first.describe()
                )))
            }
            Some(_) => {}
        }
    }
    layout.ok_or_else(|| {
        Error::InvalidInput(format!(
            "no {what} rows to write (the header depends on the rows)"
        ))
    })
}

pub(super) fn header_line(names: &[&str], layout: &Layout) -> String {
    let mut cols: Vec<String> = names.iter().map(|s| s.to_string()).collect();
    cols.extend(layout.column_names());
    let mut h = cols.join(",");
    h.push('\n');
    h
}

/// Writes views.csv atomically in the format [`read_views_csv`] reads, flange poses as
/// `x_mm,y_mm,z_mm,qw,qx,qy,qz`. All views must use the same columns (same joint count,
/// or all flange poses). `View::line` is ignored.
pub fn write_views_csv(p: impl AsRef<Path>, views: &[View]) -> Result<()> {
    write_views_csv_with(p, views, &PoseColumns::default())
}

/// [`write_views_csv`] with flange poses written in the columns `pose` (in its order),
/// e.g. `PoseColumns::from_spec(&["ros"])`. Joint readings are written as they are.
pub fn write_views_csv_with(p: impl AsRef<Path>, views: &[View], pose: &PoseColumns) -> Result<()> {
    let layout = common_layout("views.csv", views.iter().map(|v| &v.reading), pose)?;
    let mut out = header_line(&VIEW_NAME_COLUMNS, &layout);
    for (i, v) in views.iter().enumerate() {
        let row = i + 1;
        let board = name_field("board_image", row, Some(&v.board_image), true)?;
        let laser = name_field("laser_image", row, v.laser_image.as_deref(), false)?;
        out.push_str(&board);
        out.push(',');
        out.push_str(&laser);
        push_reading(&mut out, row, &v.reading, pose)?;
    }
    write_atomic(p, out.as_bytes())
}

/// Writes scan.csv atomically in the format [`read_scan_csv`] reads, flange poses as
/// `x_mm,y_mm,z_mm,qw,qx,qy,qz`. All frames must use the same columns.
/// `ScanFrame::line` is ignored.
pub fn write_scan_csv(p: impl AsRef<Path>, frames: &[ScanFrame]) -> Result<()> {
    write_scan_csv_with(p, frames, &PoseColumns::default())
}

/// [`write_scan_csv`] with flange poses written in the columns `pose` (in its order).
pub fn write_scan_csv_with(
    p: impl AsRef<Path>,
    frames: &[ScanFrame],
    pose: &PoseColumns,
) -> Result<()> {
    let layout = common_layout("scan.csv", frames.iter().map(|f| &f.reading), pose)?;
    let mut out = header_line(&SCAN_NAME_COLUMNS, &layout);
    for (i, f) in frames.iter().enumerate() {
        let row = i + 1;
        out.push_str(&name_field("image", row, Some(&f.image), true)?);
        push_reading(&mut out, row, &f.reading, pose)?;
    }
    write_atomic(p, out.as_bytes())
}
