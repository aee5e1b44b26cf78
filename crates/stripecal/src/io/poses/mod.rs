//! The robot-pose columns of views.csv and scan.csv (spec/DATASET.md): encoder readings
//! `q1,...,qN`, or the flange pose `T_base_hand` as the controller reports it.
//!
//! ## Flange-pose columns
//!
//! The column NAMES say the convention, so the columns may come in any order
//! (`qx,qy,qz,qw,x_m,y_m,z_m` is ROS's order). A header has one translation and one
//! rotation, each complete:
//!
//! | columns | what | file |
//! |---|---|---|
//! | `x_mm,y_mm,z_mm` / `x_m,y_m,z_m` | translation, mm or m (kept in mm inside) | `translation.rs` |
//! | `qw,qx,qy,qz` | unit quaternion | `quaternion.rs` |
//! | `rx_rad,ry_rad,rz_rad` / `rx_deg,ry_deg,rz_deg` | rotation vector (axis times angle) | `rotation_vector.rs` |
//! | `a_deg,b_deg,c_deg` | KUKA: `R = Rz(A) Ry(B) Rx(C)` | `kuka_abc.rs` |
//! | `w_deg,p_deg,r_deg` | Fanuc / Yaskawa: `R = Rz(R) Ry(P) Rx(W)` | `fanuc_wpr.rs` |
//! | `r11,...,r33` | rotation matrix, row by row | `matrix.rs` |
//!
//! [`PoseColumns`] is such a header's layout: it turns a row's values into `T_base_hand`
//! ([`Iso3`], mm) and back. A quaternion or matrix slightly off (1e-3) is normalised; any
//! other is an error. Everything after reading sees only `T_base_hand`
//! (`RobotReading::FlangePose`).
//!
//! A new ROTATION convention is one file here implementing [`RotationConvention`] (its
//! column names, values -> rotation and back) and one entry in [`ROTATIONS`] (and,
//! optionally, a shorthand in [`SHORTHANDS`]); a new translation unit is one entry in
//! `translation::TRANSLATIONS`. The header logic, the readers and the writers need no
//! change.
//!
//! ## Shorthands
//!
//! [`convention_columns`] names the usual controller layouts (the Python API and the twin
//! accept these names wherever a header is expected):
//!
//! | name | columns |
//! |---|---|
//! | `quaternion` | `x_mm,y_mm,z_mm,qw,qx,qy,qz` (what the writers use by default) |
//! | `ros` | `x_m,y_m,z_m,qx,qy,qz,qw` (geometry_msgs/Pose) |
//! | `rotvec` | `x_mm,y_mm,z_mm,rx_rad,ry_rad,rz_rad` |
//! | `rotvec_deg` | `x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg` |
//! | `ur` | `x_m,y_m,z_m,rx_rad,ry_rad,rz_rad` (Universal Robots' TCP pose) |
//! | `kuka` | `x_mm,y_mm,z_mm,a_deg,b_deg,c_deg` |
//! | `fanuc` | `x_mm,y_mm,z_mm,w_deg,p_deg,r_deg` |
//! | `matrix` | `x_mm,y_mm,z_mm,r11,r12,r13,r21,r22,r23,r31,r32,r33` |

mod euler_zyx;
mod fanuc_wpr;
mod joints;
mod kuka_abc;
mod matrix;
mod quaternion;
mod rotation_vector;
mod translation;

use std::fmt;

use nalgebra::{Translation3, UnitQuaternion, Vector3};

use crate::error::{Error, Result};
use crate::model::geometry::Iso3;
use crate::model::kinematics::Robot;
use crate::model::RobotReading;
use translation::{Translation, TRANSLATIONS};

pub use matrix::MATRIX_TOL;
pub use quaternion::QUATERNION_TOL;

/// One convention of rotation columns.
pub(crate) trait RotationConvention: Sync {
    /// The column names, in the order [`Self::to_rotation`] takes the values.
    fn columns(&self) -> &'static [&'static str];
    /// What the columns hold, for messages ("a unit quaternion").
    fn describe(&self) -> &'static str;
    /// The rotation of finite values in [`Self::columns`] order; an error says what is
    /// wrong and shows the values.
    fn to_rotation(&self, values: &[f64]) -> std::result::Result<UnitQuaternion<f64>, String>;
    /// The values of a rotation in [`Self::columns`] order.
    fn values(&self, r: &UnitQuaternion<f64>) -> Vec<f64>;
}

/// Every rotation convention; a header has exactly one.
static ROTATIONS: [&dyn RotationConvention; 6] = [
    &quaternion::UnitQuaternionColumns,
    &rotation_vector::RADIANS,
    &rotation_vector::DEGREES,
    &kuka_abc::KukaAbc,
    &fanuc_wpr::FanucWpr,
    &matrix::RotationMatrix,
];

/// The named layouts of [`convention_columns`], as headers.
static SHORTHANDS: [(&str, &str); 8] = [
    ("quaternion", "x_mm,y_mm,z_mm,qw,qx,qy,qz"),
    ("ros", "x_m,y_m,z_m,qx,qy,qz,qw"),
    ("rotvec", "x_mm,y_mm,z_mm,rx_rad,ry_rad,rz_rad"),
    ("rotvec_deg", "x_mm,y_mm,z_mm,rx_deg,ry_deg,rz_deg"),
    ("ur", "x_m,y_m,z_m,rx_rad,ry_rad,rz_rad"),
    ("kuka", "x_mm,y_mm,z_mm,a_deg,b_deg,c_deg"),
    ("fanuc", "x_mm,y_mm,z_mm,w_deg,p_deg,r_deg"),
    (
        "matrix",
        "x_mm,y_mm,z_mm,r11,r12,r13,r21,r22,r23,r31,r32,r33",
    ),
];

/// The shorthand names [`convention_columns`] knows.
pub fn convention_names() -> Vec<&'static str> {
    SHORTHANDS.iter().map(|(n, _)| *n).collect()
}

/// The columns of a named layout (see the module docs): `quaternion`, `ros`, `rotvec`,
/// `rotvec_deg`, `ur`, `kuka`, `fanuc` or `matrix`; `None` for any other name.
pub fn convention_columns(name: &str) -> Option<Vec<&'static str>> {
    SHORTHANDS
        .iter()
        .find(|(n, _)| *n == name)
        .map(|(_, h)| h.split(',').collect())
}

/// Where one value column goes.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Slot {
    /// Translation component 0..3.
    Translation(usize),
    /// Rotation value, index into the convention's columns.
    Rotation(usize),
}

/// Which registry entry a column name belongs to, and where in it.
#[derive(Clone, Copy)]
enum Owner {
    /// `TRANSLATIONS[group].columns[k]`.
    Translation { group: usize, k: usize },
    /// `ROTATIONS[group].columns()[k]`.
    Rotation { group: usize, k: usize },
}

impl Owner {
    fn of(name: &str) -> Option<Owner> {
        TRANSLATIONS
            .iter()
            .enumerate()
            .find_map(|(group, t)| {
                let k = t.columns.iter().position(|c| *c == name)?;
                Some(Owner::Translation { group, k })
            })
            .or_else(|| {
                ROTATIONS.iter().enumerate().find_map(|(group, r)| {
                    let k = r.columns().iter().position(|c| *c == name)?;
                    Some(Owner::Rotation { group, k })
                })
            })
    }
}

/// The layout of a header's flange-pose columns: one translation unit and one rotation
/// convention, in the header's column order.
#[derive(Clone)]
pub struct PoseColumns {
    names: Vec<&'static str>,
    translation: &'static Translation,
    rotation: &'static dyn RotationConvention,
    slots: Vec<Slot>,
}

impl PartialEq for PoseColumns {
    fn eq(&self, other: &Self) -> bool {
        self.names == other.names
    }
}

impl fmt::Debug for PoseColumns {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "PoseColumns({})", self.names.join(","))
    }
}

impl Default for PoseColumns {
    /// `x_mm,y_mm,z_mm,qw,qx,qy,qz`, what the writers use unless told otherwise.
    fn default() -> Self {
        Self::parse(&["x_mm", "y_mm", "z_mm", "qw", "qx", "qy", "qz"])
            .expect("the default pose columns are valid")
    }
}

/// `a, b and c` / `a` for messages.
fn list(names: &[&str]) -> String {
    names.join(", ")
}

/// The farthest a flange may be from the robot base (mm): 100 m. A translation beyond it
/// is not a robot's (most often millimetres under `x_m,y_m,z_m` columns).
pub const MAX_FLANGE_DISTANCE_MM: f64 = 1e5;

/// A number for a message: as written when short, else in exponent form (`{}` of 1e308
/// prints 309 digits).
pub(crate) fn short(x: f64) -> String {
    let s = format!("{x}");
    if s.len() <= 24 {
        s
    } else {
        format!("{x:e}")
    }
}

/// The pose columns a header may have, for messages.
fn pose_columns_hint() -> String {
    let t: Vec<String> = TRANSLATIONS.iter().map(|t| t.columns.join(",")).collect();
    let r: Vec<String> = ROTATIONS.iter().map(|r| r.columns().join(",")).collect();
    format!(
        "a translation ({}) and exactly one rotation ({}), in any order",
        t.join(" or "),
        r.join(" or ")
    )
}

impl PoseColumns {
    /// The layout of a header's pose columns `names` (trimmed, in header order). The
    /// error says what is wrong: an unknown or duplicated column, two rotation
    /// conventions or translation units, a missing column.
    pub fn parse(names: &[&str]) -> std::result::Result<PoseColumns, String> {
        let mut owners = Vec::with_capacity(names.len());
        for (i, name) in names.iter().enumerate() {
            if names[..i].contains(name) {
                return Err(format!("column `{name}` appears twice"));
            }
            match Owner::of(name) {
                Some(o) => owners.push(o),
                None if joints::is_joint_column(name) => {
                    return Err(format!(
                        "column `{name}` is a joint reading: a header has joint readings \
                         `q1,...,qN` or pose columns, not both"
                    ))
                }
                None => {
                    return Err(format!(
                        "unknown column `{name}`: expected joint readings `q1,...,qN` or pose \
                         columns: {}",
                        pose_columns_hint()
                    ))
                }
            }
        }
        // Per registry entry, the columns of it the header has (in header order).
        let mut tr_present = vec![Vec::new(); TRANSLATIONS.len()];
        let mut rot_present = vec![Vec::new(); ROTATIONS.len()];
        for (name, o) in names.iter().zip(&owners) {
            match *o {
                Owner::Translation { group, .. } => tr_present[group].push(*name),
                Owner::Rotation { group, .. } => rot_present[group].push(*name),
            }
        }
        let used = |present: &[Vec<&str>]| -> Vec<usize> {
            (0..present.len())
                .filter(|&g| !present[g].is_empty())
                .collect()
        };
        let (tr_used, rot_used) = (used(&tr_present), used(&rot_present));
        if rot_used.len() > 1 {
            let said: Vec<String> = rot_used
                .iter()
                .map(|&r| format!("{} ({})", list(&rot_present[r]), ROTATIONS[r].describe()))
                .collect();
            return Err(format!(
                "header has {} rotation conventions: {}; give exactly one",
                rot_used.len(),
                said.join(" and ")
            ));
        }
        if tr_used.len() > 1 {
            let said: Vec<String> = tr_used
                .iter()
                .map(|&t| format!("{} ({})", list(&tr_present[t]), TRANSLATIONS[t].unit))
                .collect();
            return Err(format!(
                "header has the translation in {}; give one unit",
                said.join(" and ")
            ));
        }
        let Some(&t) = tr_used.first() else {
            return Err(format!(
                "header has no translation columns: expected {}",
                pose_columns_hint()
            ));
        };
        let Some(&r) = rot_used.first() else {
            return Err(format!(
                "header has no rotation columns: expected {}",
                pose_columns_hint()
            ));
        };
        let (translation, rotation) = (&TRANSLATIONS[t], ROTATIONS[r]);
        for (have, all) in [
            (&tr_present[t], &translation.columns[..]),
            (&rot_present[r], rotation.columns()),
        ] {
            let missing: Vec<&str> = all.iter().copied().filter(|c| !have.contains(c)).collect();
            if !missing.is_empty() {
                let have: Vec<&str> = all.iter().copied().filter(|c| have.contains(c)).collect();
                return Err(format!(
                    "header has {} but not {}",
                    list(&have),
                    list(&missing)
                ));
            }
        }
        let (names, slots) = owners
            .iter()
            .map(|o| match *o {
                Owner::Translation { k, .. } => (translation.columns[k], Slot::Translation(k)),
                Owner::Rotation { k, .. } => (rotation.columns()[k], Slot::Rotation(k)),
            })
            .unzip();
        Ok(PoseColumns {
            names,
            translation,
            rotation,
            slots,
        })
    }

    /// The layout named by `spec`: a single shorthand name (`"ros"`, see
    /// [`convention_columns`]), a single comma-separated header (`"x_m,y_m,z_m,qx,qy,qz,qw"`)
    /// or the column names one by one.
    pub fn from_spec(spec: &[&str]) -> std::result::Result<PoseColumns, String> {
        match spec {
            [one] => match convention_columns(one.trim()) {
                Some(cols) => Self::parse(&cols),
                None => {
                    let cols: Vec<&str> = one.split(',').map(str::trim).collect();
                    if let [name] = cols[..] {
                        if Owner::of(name).is_none() {
                            return Err(format!(
                                "unknown pose convention {name:?}: expected one of {} or pose \
                                 column names",
                                convention_names().join(", ")
                            ));
                        }
                    }
                    Self::parse(&cols)
                }
            },
            _ => {
                let cols: Vec<&str> = spec.iter().map(|s| s.trim()).collect();
                Self::parse(&cols)
            }
        }
    }

    /// The column names in order.
    pub fn names(&self) -> &[&'static str] {
        &self.names
    }

    /// The number of columns.
    pub fn len(&self) -> usize {
        self.names.len()
    }

    /// Always false: a layout has a translation and a rotation.
    pub fn is_empty(&self) -> bool {
        self.names.is_empty()
    }

    /// The rotation's columns (in its own order), for messages.
    pub fn rotation_columns(&self) -> &'static [&'static str] {
        self.rotation.columns()
    }

    /// `T_base_hand` (mm) of one row's values in column order; an error says what is
    /// wrong (a count, a non-finite value, a flange farther than
    /// [`MAX_FLANGE_DISTANCE_MM`] from the base, a quaternion or matrix that is not a
    /// rotation).
    pub fn to_iso(&self, values: &[f64]) -> std::result::Result<Iso3, String> {
        self.to_iso_at(values).map_err(|(_, m)| m)
    }

    /// [`Self::to_iso`] with the columns the error is about (`x_m`, `x_m, y_m, z_m`,
    /// `qx, qy, qz, qw`), for a reader's location.
    pub(super) fn to_iso_at(&self, values: &[f64]) -> std::result::Result<Iso3, (String, String)> {
        let all = || list(&self.names);
        if values.len() != self.names.len() {
            return Err((
                all(),
                format!(
                    "{} values given for the {} columns {}",
                    values.len(),
                    self.names.len(),
                    self.names.join(",")
                ),
            ));
        }
        if let Some((x, name)) = values.iter().zip(&self.names).find(|(x, _)| !x.is_finite()) {
            return Err((
                name.to_string(),
                format!("{name} = {x} is not a finite number"),
            ));
        }
        let mut t = Vector3::zeros();
        let mut r = vec![0.0; self.rotation.columns().len()];
        let mut raw = [0.0; 3];
        for ((&x, slot), name) in values.iter().zip(&self.slots).zip(&self.names) {
            match *slot {
                Slot::Translation(k) => {
                    raw[k] = x;
                    t[k] = x * self.translation.mm_per_unit;
                    // 1e306 m overflows in mm
                    if !t[k].is_finite() {
                        return Err((
                            name.to_string(),
                            format!("{name} = {} is too large (not finite in mm)", short(x)),
                        ));
                    }
                }
                Slot::Rotation(k) => r[k] = x,
            }
        }
        let distance = t.norm();
        if distance.is_nan() || distance > MAX_FLANGE_DISTANCE_MM {
            let tr = &self.translation;
            let cols = list(&tr.columns);
            let shown = format!("({}, {}, {})", short(raw[0]), short(raw[1]), short(raw[2]));
            let hint =
                if tr.mm_per_unit > 1.0 && distance / tr.mm_per_unit <= MAX_FLANGE_DISTANCE_MM {
                    // the same numbers in millimetres would be a robot's flange
                    " (these numbers look like millimetres: name the columns x_mm,y_mm,z_mm)"
                        .to_string()
                } else {
                    String::new()
                };
            return Err((
                cols.clone(),
                format!(
                    "{cols} = {shown} {} puts the flange {} m from the robot base, more \
                     than the {} m a robot's flange can be{hint}",
                    tr.unit,
                    short(distance / 1000.0),
                    MAX_FLANGE_DISTANCE_MM / 1000.0
                ),
            ));
        }
        let rotation = self
            .rotation
            .to_rotation(&r)
            .map_err(|m| (list(self.rotation.columns()), m))?;
        if !rotation.coords.iter().all(|c| c.is_finite()) {
            return Err((
                list(self.rotation.columns()),
                format!(
                    "{} ({}) = [{}] is not a finite rotation",
                    self.rotation.describe(),
                    list(self.rotation.columns()),
                    r.iter().map(|&x| short(x)).collect::<Vec<_>>().join(", ")
                ),
            ));
        }
        Ok(Iso3::from_parts(Translation3::from(t), rotation))
    }

    /// The values of `T_base_hand` (mm) in column order (never `-0`).
    pub fn to_values(&self, t: &Iso3) -> Vec<f64> {
        let tr = t.translation.vector / self.translation.mm_per_unit;
        let r = self.rotation.values(&t.rotation);
        self.slots
            .iter()
            .map(|slot| match *slot {
                Slot::Translation(k) => tr[k],
                Slot::Rotation(k) => r[k],
            } + 0.0)
            .collect()
    }

    /// "a flange pose (x_m, y_m, z_m, qx, qy, qz, qw)", for messages.
    pub fn describe(&self) -> String {
        format!("a flange pose ({})", list(&self.names))
    }
}

/// `T_base_hand` (mm) of a controller's pose values in the columns `columns` (the names
/// of the values in order, e.g. `["x_m", "y_m", "z_m", "qx", "qy", "qz", "qw"]`; a single
/// shorthand or comma-separated header is accepted too, see [`PoseColumns::from_spec`]).
/// Errors ([`Error::InvalidInput`]) name what is wrong.
pub fn pose_to_matrix(values: &[f64], columns: &[&str]) -> Result<Iso3> {
    let cols = PoseColumns::from_spec(columns).map_err(Error::InvalidInput)?;
    cols.to_iso(values).map_err(Error::InvalidInput)
}

/// The values of `T_base_hand` (mm) in the columns `columns` (as [`pose_to_matrix`]);
/// [`Error::InvalidInput`] when a value would not be finite (a transform with NaN).
pub fn matrix_to_pose(t: &Iso3, columns: &[&str]) -> Result<Vec<f64>> {
    let cols = PoseColumns::from_spec(columns).map_err(Error::InvalidInput)?;
    let values = cols.to_values(t);
    if let Some((x, name)) = values
        .iter()
        .zip(cols.names())
        .find(|(x, _)| !x.is_finite())
    {
        return Err(Error::InvalidInput(format!(
            "the transform is not a finite rigid transform: {name} would be {x}"
        )));
    }
    Ok(values)
}

/// A table's value columns: joint readings or a flange pose.
#[derive(Clone, Debug, PartialEq)]
pub(super) enum Layout {
    /// `q1..qN`, N columns.
    Joints(usize),
    /// Flange-pose columns.
    Flange(PoseColumns),
    /// No pose column (a bench dataset, a fixed-sensor scan).
    Fixed,
}

impl Layout {
    /// The layout of a header whose value columns are `rest`, the first of which is
    /// header column `first` (1-based).
    pub fn of_header(rest: &[&str], first: usize) -> std::result::Result<Layout, String> {
        if rest.is_empty() {
            return Ok(Layout::Fixed);
        }
        if rest.iter().any(|c| joints::is_joint_column(c)) {
            joints::check_header(rest, first).map(Layout::Joints)
        } else {
            PoseColumns::parse(rest).map(Layout::Flange)
        }
    }

    /// The layout a reading is written in, with its values: joints as they are, flange
    /// poses in `pose`'s columns.
    pub fn of_reading(r: &RobotReading, pose: &PoseColumns) -> (Layout, Vec<f64>) {
        match r {
            RobotReading::Joints(q) => (Layout::Joints(q.len()), q.clone()),
            RobotReading::FlangePose(t) => (Layout::Flange(pose.clone()), pose.to_values(t)),
            RobotReading::Fixed => (Layout::Fixed, Vec::new()),
        }
    }

    /// What is wrong with this layout for `robot` (the joint count), if anything.
    pub fn check_robot(&self, robot: Option<&Robot>) -> Option<String> {
        match self {
            Layout::Joints(n) => joints::check_robot(*n, robot),
            Layout::Flange(_) | Layout::Fixed => None,
        }
    }

    /// The value column names in order.
    pub fn column_names(&self) -> Vec<String> {
        match self {
            Layout::Joints(n) => joints::columns(*n),
            Layout::Flange(p) => p.names().iter().map(|s| s.to_string()).collect(),
            Layout::Fixed => Vec::new(),
        }
    }

    /// The reading of one row's (finite) values; an error names the columns at fault
    /// (for the location) and says what is wrong.
    pub fn reading(&self, values: Vec<f64>) -> std::result::Result<RobotReading, (String, String)> {
        match self {
            Layout::Joints(_) => Ok(RobotReading::Joints(values)),
            Layout::Fixed => Ok(RobotReading::Fixed),
            Layout::Flange(p) => {
                p.to_iso_at(&values)
                    .map(RobotReading::FlangePose)
                    .map_err(|(cols, m)| {
                        let what = if cols.contains(',') {
                            "columns"
                        } else {
                            "column"
                        };
                        (format!("{what} {cols}"), m)
                    })
            }
        }
    }

    /// How a row is described in messages ("6 joint readings", "a flange pose (...)").
    pub fn describe(&self) -> String {
        match self {
            Layout::Joints(n) => format!("{n} joint readings"),
            Layout::Flange(p) => p.describe(),
            Layout::Fixed => "no pose (a fixed sensor)".to_string(),
        }
    }
}

/// The contract's headers for image columns `names`, for messages.
pub(super) fn expected_header(names: &[&str]) -> String {
    let n = names.join(",");
    format!(
        "`{n},q1,...,qN` or `{n},` followed by pose columns: {}",
        pose_columns_hint()
    )
}
