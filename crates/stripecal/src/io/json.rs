//! A small reading layer over `serde_json::Value` that turns every mistake into an
//! [`Error::Format`] naming the file and the key path (`board.rows`,
//! `robot.joints[2].a_mm`), plus helpers to build and print JSON.

use std::path::Path;

use nalgebra::Vector3;
use serde_json::{Map, Value};

use crate::error::{Error, Result};
use crate::model::geometry::{iso_from_rotvec, iso_to_rotvec, Iso3, MAX_ROTVEC_ANGLE_RAD};

/// The location used for errors about the top-level object.
const TOP: &str = "top level";

/// Parses JSON text; syntax errors name the line and column. A key that appears twice in
/// one object is an error naming its key path and line (serde_json keeps the last value
/// silently: a rig.json with two `pitch_mm` would be read with the one the user did not
/// look at).
pub(super) fn parse(file: &Path, text: &str) -> Result<Value> {
    use serde::de::DeserializeSeed;
    let mut de = serde_json::Deserializer::from_str(text);
    let value = Strict {
        path: String::new(),
    }
    .deserialize(&mut de)
    .and_then(|v| de.end().map(|()| v));
    value.map_err(|e| {
        let msg = e.to_string();
        // serde_json appends " at line L column C"; the location already says it.
        let msg = match msg.rfind(" at line ") {
            Some(i) if e.line() > 0 => msg[..i].to_string(),
            _ => msg,
        };
        // a repeated key is well-formed JSON, but not a document with one meaning
        let what = if msg.starts_with("key `") {
            msg
        } else {
            format!("invalid JSON: {msg}")
        };
        Error::format(
            file,
            format!("line {}, column {}", e.line(), e.column()),
            what,
        )
    })
}

/// Builds a [`Value`] as serde_json does, refusing a key repeated in one object; `path`
/// is the key path of the value being read (`board`, `robot.joints[2]`).
struct Strict {
    path: String,
}

impl<'de> serde::de::DeserializeSeed<'de> for Strict {
    type Value = Value;

    fn deserialize<D: serde::Deserializer<'de>>(
        self,
        d: D,
    ) -> std::result::Result<Value, D::Error> {
        d.deserialize_any(self)
    }
}

impl<'de> serde::de::Visitor<'de> for Strict {
    type Value = Value;

    fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("any JSON value")
    }

    fn visit_bool<E>(self, v: bool) -> std::result::Result<Value, E> {
        Ok(Value::Bool(v))
    }

    fn visit_i64<E>(self, v: i64) -> std::result::Result<Value, E> {
        Ok(Value::from(v))
    }

    fn visit_u64<E>(self, v: u64) -> std::result::Result<Value, E> {
        Ok(Value::from(v))
    }

    fn visit_f64<E>(self, v: f64) -> std::result::Result<Value, E> {
        Ok(Value::from(v))
    }

    fn visit_str<E>(self, v: &str) -> std::result::Result<Value, E> {
        Ok(Value::String(v.to_owned()))
    }

    fn visit_string<E>(self, v: String) -> std::result::Result<Value, E> {
        Ok(Value::String(v))
    }

    fn visit_unit<E>(self) -> std::result::Result<Value, E> {
        Ok(Value::Null)
    }

    fn visit_none<E>(self) -> std::result::Result<Value, E> {
        Ok(Value::Null)
    }

    fn visit_some<D: serde::Deserializer<'de>>(self, d: D) -> std::result::Result<Value, D::Error> {
        serde::de::DeserializeSeed::deserialize(self, d)
    }

    fn visit_seq<A: serde::de::SeqAccess<'de>>(
        self,
        mut seq: A,
    ) -> std::result::Result<Value, A::Error> {
        let mut items = Vec::new();
        loop {
            let seed = Strict {
                path: format!("{}[{}]", self.path, items.len()),
            };
            match seq.next_element_seed(seed)? {
                Some(v) => items.push(v),
                None => return Ok(Value::Array(items)),
            }
        }
    }

    fn visit_map<A: serde::de::MapAccess<'de>>(
        self,
        mut map: A,
    ) -> std::result::Result<Value, A::Error> {
        let mut out = Map::new();
        while let Some(key) = map.next_key::<String>()? {
            let path = if self.path.is_empty() {
                key.clone()
            } else {
                format!("{}.{key}", self.path)
            };
            if out.contains_key(&key) {
                return Err(serde::de::Error::custom(format_args!(
                    "key `{path}` appears twice in one object (which value is meant cannot be \
                     told; JSON readers differ: some keep the first, others the last)"
                )));
            }
            let v = map.next_value_seed(Strict { path })?;
            out.insert(key, v);
        }
        Ok(Value::Object(out))
    }
}

/// Pretty-prints a value (2-space indent) with a final newline.
pub(super) fn to_pretty(v: &Value) -> String {
    // Serialising a `Value` to a String cannot fail (keys are strings, no I/O).
    let mut s = serde_json::to_string_pretty(v).unwrap_or_else(|_| "null".into());
    s.push('\n');
    s
}

/// A short rendering of a JSON value for error messages.
fn describe(v: &Value) -> String {
    const MAX: usize = 60;
    let s = match v {
        Value::Array(a) => {
            let full = serde_json::to_string(v).unwrap_or_default();
            if full.chars().count() <= MAX {
                full
            } else {
                format!("an array of {} items", a.len())
            }
        }
        Value::Object(_) => "an object".to_string(),
        other => serde_json::to_string(other).unwrap_or_default(),
    };
    if s.chars().count() > MAX {
        let cut: String = s.chars().take(MAX).collect();
        format!("{cut}...")
    } else {
        s
    }
}

/// A JSON value at a key path of a file.
#[derive(Clone)]
pub(super) struct Val<'a> {
    file: &'a Path,
    path: String,
    v: &'a Value,
}

/// A JSON object at a key path of a file.
#[derive(Clone)]
pub(super) struct Obj<'a> {
    file: &'a Path,
    path: String,
    map: &'a Map<String, Value>,
}

impl<'a> Val<'a> {
    /// The top-level value of a file.
    pub fn root(file: &'a Path, v: &'a Value) -> Val<'a> {
        Val {
            file,
            path: String::new(),
            v,
        }
    }

    fn location(&self) -> &str {
        if self.path.is_empty() {
            TOP
        } else {
            &self.path
        }
    }

    /// An [`Error::Format`] at this value's key path.
    pub fn err(&self, msg: impl Into<String>) -> Error {
        Error::format(self.file, self.location(), msg)
    }

    fn expected(&self, what: &str) -> Error {
        self.err(format!("expected {what}, got {}", describe(self.v)))
    }

    /// Whether the value is `null`.
    pub fn is_null(&self) -> bool {
        self.v.is_null()
    }

    /// A finite number.
    pub fn f64(&self) -> Result<f64> {
        match self.v.as_f64() {
            Some(x) if x.is_finite() => Ok(x),
            _ => Err(self.expected("a number")),
        }
    }

    /// A finite number `> 0`.
    pub fn positive_f64(&self) -> Result<f64> {
        match self.v.as_f64() {
            Some(x) if x.is_finite() && x > 0.0 => Ok(x),
            _ => Err(self.expected("a positive number")),
        }
    }

    /// A finite number `>= 0`.
    pub fn nonneg_f64(&self) -> Result<f64> {
        match self.v.as_f64() {
            Some(x) if x.is_finite() && x >= 0.0 => Ok(x),
            _ => Err(self.expected("a non-negative number")),
        }
    }

    /// An integer `>= 0` (an integral float such as `8.0` is accepted).
    fn integer(&self) -> Option<u64> {
        let n = self.v.as_number()?;
        if let Some(u) = n.as_u64() {
            return Some(u);
        }
        let x = n.as_f64()?;
        // 2^53: beyond it a float no longer holds every integer.
        (x >= 0.0 && x.fract() == 0.0 && x <= 9_007_199_254_740_992.0).then_some(x as u64)
    }

    /// A non-negative integer that fits a `usize`.
    pub fn count(&self) -> Result<usize> {
        self.integer()
            .and_then(|u| usize::try_from(u).ok())
            .ok_or_else(|| self.expected("a non-negative integer"))
    }

    /// A positive integer that fits a `usize`.
    pub fn positive_usize(&self) -> Result<usize> {
        match self.integer().and_then(|u| usize::try_from(u).ok()) {
            Some(u) if u > 0 => Ok(u),
            _ => Err(self.expected("a positive integer")),
        }
    }

    /// A positive integer that fits a `u32`.
    pub fn positive_u32(&self) -> Result<u32> {
        match self.integer().and_then(|u| u32::try_from(u).ok()) {
            Some(u) if u > 0 => Ok(u),
            _ => Err(self.expected("a positive integer (at most 4294967295)")),
        }
    }

    /// A string.
    pub fn str(&self) -> Result<&'a str> {
        self.v.as_str().ok_or_else(|| self.expected("a string"))
    }

    /// `true` or `false`.
    pub fn bool(&self) -> Result<bool> {
        self.v
            .as_bool()
            .ok_or_else(|| self.expected("true or false"))
    }

    /// An object.
    pub fn obj(&self) -> Result<Obj<'a>> {
        match self.v {
            Value::Object(map) => Ok(Obj {
                file: self.file,
                path: self.path.clone(),
                map,
            }),
            _ => Err(self.expected("an object")),
        }
    }

    /// An array; its items carry the paths `key[i]`.
    pub fn arr(&self) -> Result<Vec<Val<'a>>> {
        match self.v {
            Value::Array(items) => Ok(items
                .iter()
                .enumerate()
                .map(|(i, v)| Val {
                    file: self.file,
                    path: format!("{}[{i}]", self.path),
                    v,
                })
                .collect()),
            _ => Err(self.expected("an array")),
        }
    }

    /// An array of exactly `N` finite numbers.
    pub fn f64_array<const N: usize>(&self) -> Result<[f64; N]> {
        let what = format!("an array of {N} numbers");
        let items = match self.v {
            Value::Array(items) if items.len() == N => self.arr()?,
            _ => return Err(self.expected(&what)),
        };
        let mut out = [0.0; N];
        for (o, item) in out.iter_mut().zip(&items) {
            *o = item.f64()?;
        }
        Ok(out)
    }

    /// An array of 3 finite numbers.
    pub fn vec3(&self) -> Result<Vector3<f64>> {
        let [x, y, z] = self.f64_array::<3>()?;
        Ok(Vector3::new(x, y, z))
    }
}

impl<'a> Obj<'a> {
    /// The top-level object of a file (error if the document is not an object).
    pub fn root(file: &'a Path, v: &'a Value) -> Result<Obj<'a>> {
        Val::root(file, v).obj()
    }

    fn location(&self) -> &str {
        if self.path.is_empty() {
            TOP
        } else {
            &self.path
        }
    }

    fn child_path(&self, key: &str) -> String {
        if self.path.is_empty() {
            key.to_string()
        } else {
            format!("{}.{key}", self.path)
        }
    }

    /// An [`Error::Format`] at this object's key path.
    pub fn err(&self, msg: impl Into<String>) -> Error {
        Error::format(self.file, self.location(), msg)
    }

    /// The raw map.
    pub fn map(&self) -> &'a Map<String, Value> {
        self.map
    }

    /// The value of `key`; `None` when absent or `null`.
    pub fn opt(&self, key: &str) -> Option<Val<'a>> {
        match self.map.get(key) {
            None | Some(Value::Null) => None,
            Some(v) => Some(Val {
                file: self.file,
                path: self.child_path(key),
                v,
            }),
        }
    }

    /// The value of `key`; "missing key `a.b`" when absent or `null`.
    pub fn req(&self, key: &str) -> Result<Val<'a>> {
        self.opt(key)
            .ok_or_else(|| self.err(format!("missing key `{}`", self.child_path(key))))
    }

    pub fn f64(&self, key: &str) -> Result<f64> {
        self.req(key)?.f64()
    }

    pub fn positive_f64(&self, key: &str) -> Result<f64> {
        self.req(key)?.positive_f64()
    }

    pub fn nonneg_f64(&self, key: &str) -> Result<f64> {
        self.req(key)?.nonneg_f64()
    }

    pub fn opt_positive_f64(&self, key: &str) -> Result<Option<f64>> {
        self.opt(key).map(|v| v.positive_f64()).transpose()
    }

    pub fn count(&self, key: &str) -> Result<usize> {
        self.req(key)?.count()
    }

    pub fn positive_usize(&self, key: &str) -> Result<usize> {
        self.req(key)?.positive_usize()
    }

    pub fn positive_u32(&self, key: &str) -> Result<u32> {
        self.req(key)?.positive_u32()
    }

    pub fn opt_str(&self, key: &str) -> Result<Option<&'a str>> {
        self.opt(key).map(|v| v.str()).transpose()
    }

    pub fn opt_bool(&self, key: &str) -> Result<Option<bool>> {
        self.opt(key).map(|v| v.bool()).transpose()
    }

    pub fn obj(&self, key: &str) -> Result<Obj<'a>> {
        self.req(key)?.obj()
    }

    pub fn opt_obj(&self, key: &str) -> Result<Option<Obj<'a>>> {
        self.opt(key).map(|v| v.obj()).transpose()
    }

    pub fn vec3(&self, key: &str) -> Result<Vector3<f64>> {
        self.req(key)?.vec3()
    }

    /// Checks the `format` key equals `expected`.
    pub fn check_format(&self, expected: &str) -> Result<()> {
        let v = self.req("format")?;
        match v.v.as_str() {
            Some(s) if s == expected => Ok(()),
            _ => Err(v.err(format!("expected {:?}, got {}", expected, describe(v.v)))),
        }
    }

    /// A copy of the keys not listed in `known`, in file order.
    pub fn extra(&self, known: &[&str]) -> Map<String, Value> {
        self.map
            .iter()
            .filter(|(k, _)| !known.contains(&k.as_str()))
            .map(|(k, v)| (k.clone(), v.clone()))
            .collect()
    }

    /// A rigid transform `{"rotation_vector": [..] (radians), "translation_mm": [..]}`.
    pub fn pose(&self) -> Result<Iso3> {
        let r = self.vec3("rotation_vector")?;
        let angle = r.norm();
        if !angle.is_finite() || angle > MAX_ROTVEC_ANGLE_RAD {
            return Err(self.req("rotation_vector")?.err(format!(
                "expected a rotation vector (radians) of angle at most {MAX_ROTVEC_ANGLE_RAD:e}, \
                 got one of angle {angle:e}"
            )));
        }
        let t = self.vec3("translation_mm")?;
        Ok(iso_from_rotvec(&r, &t))
    }
}

/// The message of an `InvalidInput` (from a `validate`), or the error's text.
pub(super) fn invalid_message(e: Error) -> String {
    match e {
        Error::InvalidInput(m) => m,
        other => other.to_string(),
    }
}

/// A number (non-finite values become `null`, as serde_json does).
pub(super) fn num(x: f64) -> Value {
    Value::from(x)
}

/// `[x, y, z]`.
pub(super) fn vec3_value(v: &Vector3<f64>) -> Value {
    Value::Array(v.iter().map(|&x| num(x)).collect())
}

/// `{"rotation_vector": [...], "translation_mm": [...]}`.
pub(super) fn pose_value(t: &Iso3) -> Value {
    let (r, t) = iso_to_rotvec(t);
    let mut m = Map::new();
    m.insert("rotation_vector".into(), vec3_value(&r));
    m.insert("translation_mm".into(), vec3_value(&t));
    Value::Object(m)
}

/// Appends `extra` to `m`, skipping keys `m` already has (known keys win).
pub(super) fn append_extra(m: &mut Map<String, Value>, extra: &Map<String, Value>) {
    for (k, v) in extra {
        if !m.contains_key(k) {
            m.insert(k.clone(), v.clone());
        }
    }
}
