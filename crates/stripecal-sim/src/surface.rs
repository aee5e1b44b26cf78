//! Reconstruction error against truth: signed distances of base-frame points to the
//! nearest true surface of the twin's world (the sphere, the plate the target is printed
//! on, the table).
//!
//! truth.json (simulators may add keys) holds the surfaces beside the contract's
//! `sphere`: `"table": {"normal": [...], "d_mm": ...}`, the table plane in the BASE
//! frame (`n . p = d`, `n` pointing up, towards the camera), and `"plate": {"normal",
//! "d_mm", "extent_mm": [x0, x1, y0, y1]}`, the plate's surface plane (base frame) and
//! its extent in board coordinates (`base_board` maps them to the base frame).

use nalgebra::{Point3, Vector3};
use serde_json::{json, Value};

use stripecal::model::Truth;

use crate::dataset::Twin;
use crate::SimError;

/// A plane `normal . p = d_mm` (base frame), `normal` a unit vector.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct TablePlane {
    pub normal: Vector3<f64>,
    pub d_mm: f64,
}

impl TablePlane {
    /// `{"normal": [...], "d_mm": ...}`.
    pub fn to_json(&self) -> Value {
        json!({"normal": [self.normal.x, self.normal.y, self.normal.z], "d_mm": self.d_mm})
    }

    /// From `{"normal": [...], "d_mm": ...}` (normalised).
    pub fn from_json(v: &Value, what: &str) -> Result<TablePlane, SimError> {
        let bad = || SimError::Config(format!("truth `{what}`: expected {{normal: [3], d_mm}}"));
        let n: Vec<f64> = v
            .get("normal")
            .and_then(|n| serde_json::from_value(n.clone()).ok())
            .ok_or_else(bad)?;
        let d = v.get("d_mm").and_then(Value::as_f64).ok_or_else(bad)?;
        if n.len() != 3 {
            return Err(bad());
        }
        let n = Vector3::new(n[0], n[1], n[2]);
        let len = n.norm();
        if !(len.is_finite() && len > 0.0 && d.is_finite()) {
            return Err(bad());
        }
        Ok(TablePlane {
            normal: n / len,
            d_mm: d / len,
        })
    }

    /// Signed distance of `p`: positive on the normal's side.
    pub fn signed_distance(&self, p: &Vector3<f64>) -> f64 {
        self.normal.dot(p) - self.d_mm
    }
}

impl Twin {
    /// The table plane in the base frame (normal up, towards the camera): the table lies
    /// `board.plate_thickness_mm` behind the printed surface.
    pub fn table_plane(&self) -> TablePlane {
        let up = self.base_board.rotation * -Vector3::z();
        let p = self.base_board * Point3::new(0.0, 0.0, self.cfg.board.plate_thickness_mm);
        TablePlane {
            normal: up,
            d_mm: up.dot(&p.coords),
        }
    }

    /// truth.json's `plate`: the plate's surface plane (base frame) and its extent
    /// (board coordinates).
    pub fn plate_json(&self) -> Value {
        let up = self.base_board.rotation * -Vector3::z();
        let d = up.dot(&self.base_board.translation.vector);
        let e = crate::target::plate_extent(&self.board, self.cfg.board.plate_margin_mm);
        json!({"normal": [up.x, up.y, up.z], "d_mm": d, "extent_mm": e})
    }

    /// [`surface_errors`] against this twin's truth (sphere included when scans are on).
    pub fn surface_errors(&self, points: &[Vector3<f64>]) -> Result<Vec<f64>, SimError> {
        surface_errors(&self.truth(true), points)
    }
}

/// Signed distance (mm) of every base-frame point to the nearest true surface of
/// `truth`: the sphere (`|p - c| - r`, if the truth has one), the plate (where the
/// point's foot lies on it; positive above it) and the table plane (`truth.extra
/// ["table"]`, positive above it). Points far from every surface are returned too (the
/// caller decides). An error when the truth has no `table` (not the twin's).
pub fn surface_errors(truth: &Truth, points: &[Vector3<f64>]) -> Result<Vec<f64>, SimError> {
    let table = TablePlane::from_json(
        truth.extra.get("table").ok_or_else(|| {
            SimError::Config("the truth has no `table` (written by the twin only)".into())
        })?,
        "table",
    )?;
    let plate = match truth.extra.get("plate") {
        Some(v) => {
            let e: [f64; 4] = v
                .get("extent_mm")
                .and_then(|e| serde_json::from_value(e.clone()).ok())
                .ok_or_else(|| SimError::Config("truth `plate`: no extent_mm".into()))?;
            Some(e)
        }
        None => None,
    };
    let board_base = truth.base_board.inverse();
    Ok(points
        .iter()
        .map(|p| {
            let mut best = table.signed_distance(p);
            let mut consider = |e: f64| {
                if e.abs() < best.abs() {
                    best = e;
                }
            };
            if let Some(s) = &truth.sphere {
                consider((p - s.center_mm).norm() - 0.5 * s.diameter_mm);
            }
            if let Some([x0, x1, y0, y1]) = plate {
                let b = board_base * Point3::from(*p);
                if b.x >= x0 && b.x <= x1 && b.y >= y0 && b.y <= y1 {
                    consider(-b.z);
                }
            }
            best
        })
        .collect())
}
