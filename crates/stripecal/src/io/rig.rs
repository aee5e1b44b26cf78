//! `rig.json` (format `stripecal/rig@1`): camera size, board, robot, stripe hint.

use std::path::Path;

use serde_json::{Map, Value};

use super::atomic::{read_text, write_atomic};
use super::json::{invalid_message, num, parse, to_pretty, Obj, Val};
use super::sensor::sensor_kind_of;
use crate::error::{Error, Result};
use crate::model::board::{Board, BoardKind};
use crate::model::camera::DistortionModel;
use crate::model::kinematics::{DhJoint, Robot};
use crate::model::{Rig, SensorKind, StripeChannel, StripeDirection};

/// The `format` value of rig.json.
pub(super) const RIG_FORMAT: &str = "stripecal/rig@1";

/// Parses rig.json text; `path` is used in error messages only.
///
/// Required: `format`, `camera.width`, `camera.height`, `board.rows`, `board.cols`, and
/// for circle grids (`"kind"` `"circles"`, the default, or `"asymmetric_circles"`)
/// `board.pitch_mm` and `board.circle_diameter_mm`, plus `board.marker_diameter_mm`
/// when `markers` is not empty; for chessboards `board.square_mm` (a `pitch_mm`, if
/// given, must equal it). `markers` defaults to the L `[[0,0],[0,1],[1,0]]` for
/// `"circles"` and is empty (and must be) for the other kinds.
/// Unknown keys are ignored. An optional `"sensor": {"kind": "camera"}` is accepted; a
/// profiler's rig (`sensor.kind = "profiler"`) is refused, naming
/// [`super::read_profile_rig`].
pub fn rig_from_json(path: &Path, text: &str) -> Result<Rig> {
    let doc = parse(path, text)?;
    let root = Obj::root(path, &doc)?;
    root.check_format(RIG_FORMAT)?;
    if sensor_kind_of(&root)? == SensorKind::Profiler {
        return Err(Error::format(
            path,
            "sensor.kind",
            "rig.json describes a profiler (sensor.kind = \"profiler\"); this reader is for \
             a camera rig: read it as a profile dataset (read_profile_rig, \
             ProfileDataset::load)",
        ));
    }

    let cam = root.obj("camera")?;
    let width = cam.positive_u32("width")?;
    let height = cam.positive_u32("height")?;
    let distortion_model = match cam.opt("distortion_model") {
        None => DistortionModel::default(),
        Some(v) => distortion_model_from(&v)?,
    };

    let board = board_from(&root.obj("board")?)?;

    let robot = match root.opt_obj("robot")? {
        None => None,
        Some(r) => Some(robot_from(&r)?),
    };

    let stripe = root.opt_obj("stripe")?;
    let stripe_direction = match stripe.as_ref().and_then(|s| s.opt("direction")) {
        None => StripeDirection::default(),
        Some(v) => StripeDirection::from_name(v.str()?).map_err(|_| {
            v.err(format!(
                "expected \"auto\", \"rows\" or \"cols\", got {:?}",
                v.str().unwrap_or_default()
            ))
        })?,
    };
    let stripe_channel = match stripe.as_ref().and_then(|s| s.opt("channel")) {
        None => StripeChannel::default(),
        Some(v) => StripeChannel::from_name(v.str()?).map_err(|_| {
            v.err(format!(
                "unknown laser colour {:?}: expected \"gray\", \"red\", \"green\", \"blue\" or \
                 \"auto\"",
                v.str().unwrap_or_default()
            ))
        })?,
    };

    Ok(Rig {
        width,
        height,
        distortion_model,
        board,
        robot,
        stripe_direction,
        stripe_channel,
    })
}

/// A distortion model name (`radial1`, `radial2`, `opencv5`).
pub(super) fn distortion_model_from(v: &Val<'_>) -> Result<DistortionModel> {
    let s = v.str()?;
    DistortionModel::from_name(s).map_err(|_| {
        v.err(format!(
            "expected \"radial1\", \"radial2\" or \"opencv5\", got {s:?}"
        ))
    })
}

fn board_from(b: &Obj<'_>) -> Result<Board> {
    let kind = match b.opt("kind") {
        None => BoardKind::Circles,
        Some(v) => {
            let s = v.str()?;
            BoardKind::from_name(s).map_err(|_| {
                v.err(format!(
                    "expected \"circles\", \"asymmetric_circles\" or \"chessboard\", got {s:?}"
                ))
            })?
        }
    };
    let rows = b.positive_usize("rows")?;
    let cols = b.positive_usize("cols")?;
    let markers = match b.opt("markers") {
        // the contract's default L for circle grids; the other kinds have none
        None if kind == BoardKind::Circles => Board::default_markers(),
        None => Vec::new(),
        Some(v) => {
            let mut markers = Vec::new();
            for item in v.arr()? {
                let pair = item.arr()?;
                if pair.len() != 2 {
                    return Err(item.err(format!(
                        "expected a [row, col] pair, got an array of {} items",
                        pair.len()
                    )));
                }
                markers.push([pair[0].count()?, pair[1].count()?]);
            }
            if !markers.is_empty() && kind != BoardKind::Circles {
                return Err(v.err(format!(
                    "a board of kind \"{}\" has no markers (only \"circles\" grids do)",
                    kind.name()
                )));
            }
            markers
        }
    };
    let (pitch_mm, circle_diameter_mm, marker_diameter_mm, square_mm) = match kind {
        BoardKind::Circles | BoardKind::AsymmetricCircles => {
            let circle = b.positive_f64("circle_diameter_mm")?;
            // needed only when there are markers
            let marker = if markers.is_empty() {
                b.opt_positive_f64("marker_diameter_mm")?.unwrap_or(circle)
            } else {
                b.positive_f64("marker_diameter_mm")?
            };
            (pitch_in_range(b, "pitch_mm")?, circle, marker, None)
        }
        BoardKind::Chessboard => {
            let square = pitch_in_range(b, "square_mm")?;
            let pitch = b.opt_positive_f64("pitch_mm")?.unwrap_or(square);
            if pitch != square {
                return Err(b.err(format!(
                    "a chessboard's pitch_mm ({pitch}) must equal its square_mm ({square})"
                )));
            }
            (square, 0.0, 0.0, Some(square))
        }
    };
    let dark_circles = b.opt_bool("dark_circles")?.unwrap_or(true);
    let board = Board {
        kind,
        rows,
        cols,
        pitch_mm,
        circle_diameter_mm,
        marker_diameter_mm,
        markers,
        dark_circles,
        square_mm,
    };
    board.validate().map_err(|e| b.err(invalid_message(e)))?;
    Ok(board)
}

/// The smallest and largest board pitch rig.json may give (mm): a printed target's
/// spacing is between a micrometre and ten metres. A value outside (`1e-9`, `1e300`:
/// metres or a typo) made every view's homography fail without naming the key.
pub const PITCH_RANGE_MM: (f64, f64) = (1e-3, 1e4);

/// `board.<key>` (the pitch or the square size): a positive number within
/// [`PITCH_RANGE_MM`].
fn pitch_in_range(b: &Obj<'_>, key: &str) -> Result<f64> {
    let v = b.req(key)?;
    let x = v.positive_f64()?;
    let (lo, hi) = PITCH_RANGE_MM;
    if !(lo..=hi).contains(&x) {
        return Err(v.err(format!(
            "{} mm is not a board's spacing: expected {lo} to {hi} mm (millimetres, the \
             distance between neighbouring {})",
            super::poses::short(x),
            if key == "square_mm" {
                "corners"
            } else {
                "circle centres"
            }
        )));
    }
    Ok(x)
}

/// A robot `{"name": ..., "joints": [{theta0_deg, alpha_deg, a_mm, d_mm, beta_deg?}, ...],
/// "repeatability_mm": ..., "encoder_sigma_deg": ...}`. `name` is optional (default
/// empty), so are the two figures (finite, >= 0).
pub(super) fn robot_from(r: &Obj<'_>) -> Result<Robot> {
    let name = r.opt_str("name")?.unwrap_or_default().to_string();
    let joints_val = r.req("joints")?;
    let items = joints_val.arr()?;
    if items.is_empty() {
        return Err(joints_val.err("expected at least one DH row, got an empty array"));
    }
    let mut joints = Vec::with_capacity(items.len());
    for item in &items {
        let j = item.obj()?;
        joints.push(DhJoint {
            theta0_deg: j.f64("theta0_deg")?,
            alpha_deg: j.f64("alpha_deg")?,
            a_mm: j.f64("a_mm")?,
            d_mm: j.f64("d_mm")?,
            beta_deg: j
                .opt("beta_deg")
                .map(|v| v.f64())
                .transpose()?
                .unwrap_or(0.0),
        });
    }
    let figure = |key: &str| r.opt(key).map(|v| v.nonneg_f64()).transpose();
    let robot = Robot {
        name,
        joints,
        repeatability_mm: figure("repeatability_mm")?,
        encoder_sigma_deg: figure("encoder_sigma_deg")?,
    };
    robot.validate().map_err(|e| r.err(invalid_message(e)))?;
    Ok(robot)
}

/// The JSON object of a robot.
pub(super) fn robot_value(r: &Robot) -> Value {
    let joints = r
        .joints
        .iter()
        .map(|j| {
            let mut m = Map::new();
            m.insert("theta0_deg".into(), num(j.theta0_deg));
            m.insert("alpha_deg".into(), num(j.alpha_deg));
            m.insert("a_mm".into(), num(j.a_mm));
            m.insert("d_mm".into(), num(j.d_mm));
            if j.beta_deg != 0.0 {
                m.insert("beta_deg".into(), num(j.beta_deg));
            }
            Value::Object(m)
        })
        .collect();
    let mut m = Map::new();
    m.insert("name".into(), Value::from(r.name.clone()));
    m.insert("joints".into(), Value::Array(joints));
    for (key, v) in [
        ("repeatability_mm", r.repeatability_mm),
        ("encoder_sigma_deg", r.encoder_sigma_deg),
    ] {
        if let Some(x) = v {
            m.insert(key.into(), num(x));
        }
    }
    Value::Object(m)
}

fn board_value(b: &Board) -> Value {
    let mut m = Map::new();
    m.insert("kind".into(), Value::from(b.kind.name()));
    m.insert("rows".into(), Value::from(b.rows));
    m.insert("cols".into(), Value::from(b.cols));
    match b.kind {
        BoardKind::Chessboard => {
            m.insert("square_mm".into(), num(b.pitch_mm));
        }
        BoardKind::Circles | BoardKind::AsymmetricCircles => {
            m.insert("pitch_mm".into(), num(b.pitch_mm));
            m.insert("circle_diameter_mm".into(), num(b.circle_diameter_mm));
            if !b.markers.is_empty() {
                m.insert("marker_diameter_mm".into(), num(b.marker_diameter_mm));
            }
            let markers = b
                .markers
                .iter()
                .map(|[r, c]| Value::Array(vec![Value::from(*r), Value::from(*c)]))
                .collect();
            m.insert("markers".into(), Value::Array(markers));
            m.insert("dark_circles".into(), Value::from(b.dark_circles));
        }
    }
    Value::Object(m)
}

/// rig.json text (pretty-printed, 2-space indent, final newline). The `robot` key is
/// left out when the rig has none, `stripe.channel` when it is the default `gray` (so
/// a gray rig's file is what it was before the key existed).
pub fn rig_to_json(r: &Rig) -> String {
    let mut cam = Map::new();
    cam.insert("width".into(), Value::from(r.width));
    cam.insert("height".into(), Value::from(r.height));
    cam.insert(
        "distortion_model".into(),
        Value::from(r.distortion_model.name()),
    );
    let mut m = Map::new();
    m.insert("format".into(), Value::from(RIG_FORMAT));
    m.insert("camera".into(), Value::Object(cam));
    m.insert("board".into(), board_value(&r.board));
    if let Some(robot) = &r.robot {
        m.insert("robot".into(), robot_value(robot));
    }
    let mut stripe = Map::new();
    stripe.insert("direction".into(), Value::from(r.stripe_direction.name()));
    if r.stripe_channel != StripeChannel::Gray {
        stripe.insert("channel".into(), Value::from(r.stripe_channel.name()));
    }
    m.insert("stripe".into(), Value::Object(stripe));
    to_pretty(&Value::Object(m))
}

/// Reads and checks `rig.json`.
pub fn read_rig(p: impl AsRef<Path>) -> Result<Rig> {
    let path = p.as_ref();
    let text = read_text(path)?;
    rig_from_json(path, &text)
}

/// Writes `rig.json` atomically. The rig is checked first (board, robot, size) so the
/// file written can always be read back.
pub fn write_rig(p: impl AsRef<Path>, r: &Rig) -> Result<()> {
    if r.width == 0 || r.height == 0 {
        return Err(Error::InvalidInput(format!(
            "rig camera size {}x{} must be positive",
            r.width, r.height
        )));
    }
    r.board.validate()?;
    if let Some(robot) = &r.robot {
        robot.validate()?;
    }
    write_atomic(p, rig_to_json(r).as_bytes())
}
