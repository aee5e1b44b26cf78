//! Sphere fit results (spec "The sphere fit"): `{"diameter_mm", "center_mm", "rms_mm",
//! "points", "outliers"}` and any other keys (uncertainties) in `extra`.

use std::path::Path;

use serde_json::{Map, Value};

use super::atomic::{read_text, write_atomic};
use super::json::{append_extra, num, parse, to_pretty, vec3_value, Obj};
use crate::error::{Error, Result};
use crate::model::SphereFit;

const SPHERE_FIT_KEYS: [&str; 5] = ["diameter_mm", "center_mm", "rms_mm", "points", "outliers"];

/// Reads a sphere fit `{"diameter_mm", "center_mm": [x, y, z], "rms_mm", "points",
/// "outliers"}`; other keys are kept in `extra`.
pub fn read_sphere_fit(p: impl AsRef<Path>) -> Result<SphereFit> {
    let path = p.as_ref();
    let text = read_text(path)?;
    let doc = parse(path, &text)?;
    let root = Obj::root(path, &doc)?;
    Ok(SphereFit {
        diameter_mm: root.positive_f64("diameter_mm")?,
        center_mm: root.vec3("center_mm")?,
        rms_mm: root.nonneg_f64("rms_mm")?,
        points: root.count("points")?,
        outliers: root.count("outliers")?,
        extra: root.extra(&SPHERE_FIT_KEYS),
    })
}

/// The sphere fit's JSON text (pretty-printed, final newline).
pub fn sphere_fit_to_json(s: &SphereFit) -> String {
    let mut m = Map::new();
    m.insert("diameter_mm".into(), num(s.diameter_mm));
    m.insert("center_mm".into(), vec3_value(&s.center_mm));
    m.insert("rms_mm".into(), num(s.rms_mm));
    m.insert("points".into(), Value::from(s.points));
    m.insert("outliers".into(), Value::from(s.outliers));
    append_extra(&mut m, &s.extra);
    to_pretty(&Value::Object(m))
}

/// Writes a sphere fit atomically (values must be finite, the diameter positive).
pub fn write_sphere_fit(p: impl AsRef<Path>, s: &SphereFit) -> Result<()> {
    let ok = s.diameter_mm.is_finite()
        && s.diameter_mm > 0.0
        && s.center_mm.iter().all(|x| x.is_finite())
        && s.rms_mm.is_finite()
        && s.rms_mm >= 0.0;
    if !ok {
        return Err(Error::InvalidInput(format!(
            "sphere fit: diameter {} / centre {:?} / rms {} must be finite (diameter > 0, rms >= 0)",
            s.diameter_mm, s.center_mm, s.rms_mm
        )));
    }
    write_atomic(p, sphere_fit_to_json(s).as_bytes())
}
