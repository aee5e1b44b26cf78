//! The kind of sensor a rig.json or calibration.json describes (`"sensor": {"kind":
//! ...}`, spec/DATASET.md "A profile dataset"): `"camera"` (the default when the key is
//! absent: a camera and a laser plane) or `"profiler"` (a calibrated line profiler).
//! Callers dispatch on it before choosing a reader; each reader refuses the other kind
//! with a message saying which reader to use.

use std::path::Path;

use super::atomic::read_text;
use super::json::{parse, Obj};
use crate::error::Result;
use crate::model::SensorKind;

/// The accepted `sensor.kind` names, for messages.
const KIND_NAMES: &str = "\"camera\" or \"profiler\"";

/// The `sensor.kind` of a parsed rig.json or calibration.json (absent: camera; an
/// unknown name: an error at `sensor.kind` naming the accepted ones).
pub(super) fn sensor_kind_of(root: &Obj<'_>) -> Result<SensorKind> {
    let Some(sensor) = root.opt_obj("sensor")? else {
        return Ok(SensorKind::Camera);
    };
    let Some(v) = sensor.opt("kind") else {
        return Ok(SensorKind::Camera);
    };
    match v.str()? {
        "camera" => Ok(SensorKind::Camera),
        "profiler" => Ok(SensorKind::Profiler),
        other => Err(v.err(format!(
            "unknown sensor kind {other:?}: expected {KIND_NAMES}"
        ))),
    }
}

/// The sensor kind of a JSON file's text.
fn kind_of_text(path: &Path, text: &str) -> Result<SensorKind> {
    let doc = parse(path, text)?;
    sensor_kind_of(&Obj::root(path, &doc)?)
}

/// The `sensor.kind` of a rig.json: [`SensorKind::Camera`] when absent; an unknown
/// value is an [`crate::Error::Format`] at `sensor.kind` naming the accepted names. The
/// rest of the file is not checked (the reader of that kind does it).
pub fn sensor_kind(rig_json: impl AsRef<Path>) -> Result<SensorKind> {
    let path = rig_json.as_ref();
    kind_of_text(path, &read_text(path)?)
}

/// The `sensor.kind` of a calibration.json (as [`sensor_kind`]), so a caller can choose
/// between [`super::read_calibration`] and [`super::read_profiler_calibration`].
pub fn calibration_sensor_kind(path: impl AsRef<Path>) -> Result<SensorKind> {
    sensor_kind(path)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::error::Error;

    fn kind(text: &str) -> Result<SensorKind> {
        kind_of_text(Path::new("rig.json"), text)
    }

    #[test]
    fn absent_is_camera_and_names_are_read() {
        assert_eq!(kind("{}").unwrap(), SensorKind::Camera);
        assert_eq!(kind(r#"{"sensor": {}}"#).unwrap(), SensorKind::Camera);
        assert_eq!(
            kind(r#"{"sensor": {"kind": "camera"}}"#).unwrap(),
            SensorKind::Camera
        );
        assert_eq!(
            kind(r#"{"sensor": {"kind": "profiler", "invalid_z": -1}}"#).unwrap(),
            SensorKind::Profiler
        );
    }

    #[test]
    fn unknown_kind_names_the_key_and_the_choices() {
        let e = kind(r#"{"sensor": {"kind": "lidar"}}"#).unwrap_err();
        match e {
            Error::Format {
                location, message, ..
            } => {
                assert_eq!(location, "sensor.kind");
                assert!(message.contains("\"lidar\""), "{message}");
                assert!(message.contains("\"camera\" or \"profiler\""), "{message}");
            }
            other => panic!("{other:?}"),
        }
        let e = kind(r#"{"sensor": {"kind": 3}}"#).unwrap_err();
        assert!(e.to_string().contains("sensor.kind"), "{e}");
    }
}
