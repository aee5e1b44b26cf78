//! PLY point clouds.
//!
//! Written: `binary_little_endian` (default) or `ascii`, one `vertex` element with
//! `property double x`, `y`, `z` and then one `property double NAME` per extra
//! per-point property of the [`Cloud`].
//!
//! Read: `ascii`, `binary_little_endian` and `binary_big_endian`; vertex properties of
//! any PLY scalar type (`char/int8`, `uchar/uint8`, `short/int16`, `ushort/uint16`,
//! `int/int32`, `uint/uint32`, `float/float32`, `double/float64`). `x`, `y`, `z` are
//! required; every other scalar vertex property is kept (as f64) in
//! [`Cloud::properties`]. List properties and other elements (faces...) are read past
//! and dropped. `comment` and `obj_info` lines are allowed.

use std::fmt::Write as _;
use std::path::Path;

use super::atomic::write_atomic;
use crate::error::{Error, Result};
use crate::model::Cloud;

/// The encoding of a written PLY file.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum PlyFormat {
    /// `binary_little_endian 1.0` (compact, exact).
    #[default]
    BinaryLittleEndian,
    /// `ascii 1.0` (shortest round-trip decimal text).
    Ascii,
}

// ---------------------------------------------------------------- header model

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Scalar {
    I8,
    U8,
    I16,
    U16,
    I32,
    U32,
    F32,
    F64,
}

impl Scalar {
    fn from_name(s: &str) -> Option<Scalar> {
        Some(match s {
            "char" | "int8" => Scalar::I8,
            "uchar" | "uint8" => Scalar::U8,
            "short" | "int16" => Scalar::I16,
            "ushort" | "uint16" => Scalar::U16,
            "int" | "int32" => Scalar::I32,
            "uint" | "uint32" => Scalar::U32,
            "float" | "float32" => Scalar::F32,
            "double" | "float64" => Scalar::F64,
            _ => return None,
        })
    }

    fn size(self) -> usize {
        match self {
            Scalar::I8 | Scalar::U8 => 1,
            Scalar::I16 | Scalar::U16 => 2,
            Scalar::I32 | Scalar::U32 | Scalar::F32 => 4,
            Scalar::F64 => 8,
        }
    }

    fn is_integer(self) -> bool {
        !matches!(self, Scalar::F32 | Scalar::F64)
    }

    /// Decodes one value from exactly `self.size()` bytes.
    fn decode(self, b: &[u8], big_endian: bool) -> f64 {
        macro_rules! num {
            ($t:ty, $n:expr) => {{
                let mut a = [0u8; $n];
                a.copy_from_slice(&b[..$n]);
                if big_endian {
                    <$t>::from_be_bytes(a) as f64
                } else {
                    <$t>::from_le_bytes(a) as f64
                }
            }};
        }
        match self {
            Scalar::I8 => b[0] as i8 as f64,
            Scalar::U8 => b[0] as f64,
            Scalar::I16 => num!(i16, 2),
            Scalar::U16 => num!(u16, 2),
            Scalar::I32 => num!(i32, 4),
            Scalar::U32 => num!(u32, 4),
            Scalar::F32 => num!(f32, 4),
            Scalar::F64 => num!(f64, 8),
        }
    }
}

#[derive(Debug, Clone, Copy)]
enum PropKind {
    Scalar(Scalar),
    List { count: Scalar, item: Scalar },
}

#[derive(Debug, Clone)]
struct Prop {
    name: String,
    kind: PropKind,
}

#[derive(Debug, Clone)]
struct Element {
    name: String,
    count: usize,
    props: Vec<Prop>,
}

#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Encoding {
    Ascii,
    LittleEndian,
    BigEndian,
}

struct Header {
    encoding: Encoding,
    elements: Vec<Element>,
    /// Byte offset of the data.
    data_start: usize,
    /// Number of header lines (the data's first line for ASCII is this + 1).
    lines: usize,
}

fn parse_header(path: &Path, bytes: &[u8]) -> Result<Header> {
    let mut pos = 0;
    let mut line_no = 0;
    let mut encoding = None;
    let mut elements: Vec<Element> = Vec::new();
    loop {
        line_no += 1;
        let at = |msg: String| Error::format(path, format!("line {line_no}"), msg);
        let Some(nl) = bytes[pos..].iter().position(|&b| b == b'\n') else {
            return Err(if line_no == 1 && !bytes.starts_with(b"ply") {
                at("not a PLY file (the first line must be `ply`)".into())
            } else {
                at("the header has no `end_header` line (truncated file?)".into())
            });
        };
        let raw = &bytes[pos..pos + nl];
        pos += nl + 1;
        let raw = raw.strip_suffix(b"\r").unwrap_or(raw);
        let Ok(line) = std::str::from_utf8(raw) else {
            return Err(at(if line_no == 1 {
                "not a PLY file (the first line must be `ply`)".into()
            } else {
                "header line is not text".into()
            }));
        };
        let words: Vec<&str> = line.split_whitespace().collect();
        if line_no == 1 {
            if words != ["ply"] {
                return Err(at("not a PLY file (the first line must be `ply`)".into()));
            }
            continue;
        }
        match words.as_slice() {
            [] => {}
            ["comment", ..] | ["obj_info", ..] => {}
            ["format", fmt, version] => {
                if encoding.is_some() {
                    return Err(at("a second `format` line".into()));
                }
                if !version.starts_with('1') {
                    return Err(at(format!(
                        "unsupported PLY version {version}, expected 1.0"
                    )));
                }
                encoding = Some(match *fmt {
                    "ascii" => Encoding::Ascii,
                    "binary_little_endian" => Encoding::LittleEndian,
                    "binary_big_endian" => Encoding::BigEndian,
                    other => {
                        return Err(at(format!(
                            "unknown format {other:?}: expected ascii, binary_little_endian or binary_big_endian"
                        )))
                    }
                });
            }
            ["element", name, count] => {
                let count: usize = count.parse().map_err(|_| {
                    at(format!(
                        "element {name}: count {count:?} is not a non-negative integer"
                    ))
                })?;
                if elements.iter().any(|e| e.name == *name) {
                    return Err(at(format!("element {name} is declared twice")));
                }
                elements.push(Element {
                    name: name.to_string(),
                    count,
                    props: Vec::new(),
                });
            }
            ["property", "list", count, item, name] => {
                let (Some(c), Some(i)) = (Scalar::from_name(count), Scalar::from_name(item)) else {
                    return Err(at(format!("unknown property type in `{}`", line.trim())));
                };
                if !c.is_integer() {
                    return Err(at(format!(
                        "list count type {count:?} is not an integer type"
                    )));
                }
                add_property(&mut elements, name, PropKind::List { count: c, item: i })
                    .map_err(at)?;
            }
            ["property", ty, name] => {
                let Some(t) = Scalar::from_name(ty) else {
                    return Err(at(format!("unknown property type {ty:?}")));
                };
                add_property(&mut elements, name, PropKind::Scalar(t)).map_err(at)?;
            }
            ["end_header"] => break,
            _ => {
                return Err(at(format!("unexpected header line `{}`", line.trim())));
            }
        }
    }
    let Some(encoding) = encoding else {
        return Err(Error::format(path, "header", "no `format` line"));
    };
    Ok(Header {
        encoding,
        elements,
        data_start: pos,
        lines: line_no,
    })
}

fn add_property(
    elements: &mut [Element],
    name: &str,
    kind: PropKind,
) -> std::result::Result<(), String> {
    let Some(e) = elements.last_mut() else {
        return Err(format!("property {name} comes before any `element` line"));
    };
    if e.props.iter().any(|p| p.name == name) {
        return Err(format!(
            "element {}: property {name} is declared twice",
            e.name
        ));
    }
    e.props.push(Prop {
        name: name.to_string(),
        kind,
    });
    Ok(())
}

/// Where the vertex element's values go: index of each property in the output
/// (0..3 = x, y, z; 3.. = extra properties), `None` for dropped list properties.
fn vertex_slots(path: &Path, e: &Element) -> Result<(Vec<Option<usize>>, Vec<String>)> {
    let mut slots = Vec::with_capacity(e.props.len());
    let mut extra = Vec::new();
    let mut xyz = [false; 3];
    for p in &e.props {
        let axis = ["x", "y", "z"].iter().position(|a| *a == p.name);
        match (p.kind, axis) {
            (PropKind::Scalar(_), Some(a)) => {
                xyz[a] = true;
                slots.push(Some(a));
            }
            (PropKind::List { .. }, Some(_)) => {
                return Err(Error::format(
                    path,
                    "header",
                    format!("vertex property {} is a list, expected a number", p.name),
                ))
            }
            (PropKind::Scalar(_), None) => {
                slots.push(Some(3 + extra.len()));
                extra.push(p.name.clone());
            }
            (PropKind::List { .. }, None) => slots.push(None),
        }
    }
    if let Some(a) = xyz.iter().position(|&f| !f) {
        return Err(Error::format(
            path,
            "header",
            format!(
                "the vertex element has no `{}` property",
                ["x", "y", "z"][a]
            ),
        ));
    }
    Ok((slots, extra))
}

// ---------------------------------------------------------------- reading

/// Accumulates vertex values.
struct Sink {
    points: Vec<[f64; 3]>,
    extra: Vec<Vec<f64>>,
    current: Vec<f64>,
}

impl Sink {
    fn new(n_extra: usize, capacity: usize) -> Sink {
        Sink {
            points: Vec::with_capacity(capacity),
            extra: (0..n_extra).map(|_| Vec::with_capacity(capacity)).collect(),
            current: vec![0.0; 3 + n_extra],
        }
    }

    fn finish_vertex(&mut self) {
        self.points
            .push([self.current[0], self.current[1], self.current[2]]);
        for (dst, &v) in self.extra.iter_mut().zip(&self.current[3..]) {
            dst.push(v);
        }
    }
}

fn item_name(e: &Element, i: usize) -> String {
    if e.name == "vertex" {
        format!("vertex {i}")
    } else {
        format!("element {} item {i}", e.name)
    }
}

fn truncated(path: &Path, e: &Element, i: usize) -> Error {
    Error::format(
        path,
        item_name(e, i),
        format!(
            "file ends early: {} {} declared, data stops at item {i} (truncated file?)",
            e.count, e.name
        ),
    )
}

fn read_binary(
    path: &Path,
    data: &[u8],
    h: &Header,
    slots: &[Option<usize>],
    sink: &mut Sink,
) -> Result<()> {
    let big = h.encoding == Encoding::BigEndian;
    let mut pos = 0usize;
    // An element without properties has no data, whatever its count says (which may be
    // 2^64 - 1: not a loop to run).
    for e in h.elements.iter().filter(|e| !e.props.is_empty()) {
        let is_vertex = e.name == "vertex";
        for i in 0..e.count {
            for (k, p) in e.props.iter().enumerate() {
                match p.kind {
                    PropKind::Scalar(t) => {
                        let end = pos + t.size();
                        let Some(b) = data.get(pos..end) else {
                            return Err(truncated(path, e, i));
                        };
                        if is_vertex {
                            if let Some(s) = slots[k] {
                                sink.current[s] = t.decode(b, big);
                            }
                        }
                        pos = end;
                    }
                    PropKind::List { count, item } => {
                        let end = pos + count.size();
                        let Some(b) = data.get(pos..end) else {
                            return Err(truncated(path, e, i));
                        };
                        let n = count.decode(b, big);
                        if n < 0.0 {
                            return Err(Error::format(
                                path,
                                item_name(e, i),
                                format!("list {} has a negative length {n}", p.name),
                            ));
                        }
                        // n is an integer below 2^32, so it fits a usize exactly.
                        let skip = (n as usize).checked_mul(item.size());
                        match skip.and_then(|s| end.checked_add(s)) {
                            Some(next) if next <= data.len() => pos = next,
                            _ => return Err(truncated(path, e, i)),
                        }
                    }
                }
            }
            if is_vertex {
                sink.finish_vertex();
            }
        }
    }
    // Bytes after the last element (some writers add a newline) are ignored.
    Ok(())
}

/// Whitespace-separated tokens of ASCII data with their line numbers.
struct Tokens<'a> {
    lines: std::iter::Enumerate<std::str::Lines<'a>>,
    first_line: usize,
    current: Option<(usize, std::str::SplitWhitespace<'a>)>,
}

impl<'a> Tokens<'a> {
    fn new(text: &'a str, first_line: usize) -> Tokens<'a> {
        Tokens {
            lines: text.lines().enumerate(),
            first_line,
            current: None,
        }
    }

    fn next_token(&mut self) -> Option<(usize, &'a str)> {
        loop {
            if let Some((line, words)) = &mut self.current {
                if let Some(w) = words.next() {
                    return Some((*line, w));
                }
            }
            let (i, l) = self.lines.next()?;
            self.current = Some((self.first_line + i, l.split_whitespace()));
        }
    }
}

fn read_ascii(
    path: &Path,
    data: &[u8],
    h: &Header,
    slots: &[Option<usize>],
    sink: &mut Sink,
) -> Result<()> {
    let text = std::str::from_utf8(data).map_err(|e| {
        let line = h.lines
            + 1
            + data[..e.valid_up_to()]
                .iter()
                .filter(|&&b| b == b'\n')
                .count();
        Error::format(path, format!("line {line}"), "ASCII PLY data is not text")
    })?;
    let mut tokens = Tokens::new(text, h.lines + 1);
    for e in h.elements.iter().filter(|e| !e.props.is_empty()) {
        let is_vertex = e.name == "vertex";
        for i in 0..e.count {
            for (k, p) in e.props.iter().enumerate() {
                let mut next = |what: &str| -> Result<f64> {
                    let Some((line, tok)) = tokens.next_token() else {
                        return Err(truncated(path, e, i));
                    };
                    match tok.parse::<f64>() {
                        Ok(v) => Ok(v),
                        Err(_) => Err(Error::format(
                            path,
                            format!("line {line}"),
                            format!(
                                "{}, property {}{what}: expected a number, got {tok:?}",
                                item_name(e, i),
                                p.name
                            ),
                        )),
                    }
                };
                match p.kind {
                    PropKind::Scalar(_) => {
                        let v = next("")?;
                        if is_vertex {
                            if let Some(s) = slots[k] {
                                sink.current[s] = v;
                            }
                        }
                    }
                    PropKind::List { .. } => {
                        let n = next(" (list length)")?;
                        if !(n >= 0.0 && n.fract() == 0.0 && n <= u32::MAX as f64) {
                            return Err(Error::format(
                                path,
                                item_name(e, i),
                                format!("list {} has an invalid length {n}", p.name),
                            ));
                        }
                        for _ in 0..n as usize {
                            next(" (list item)")?;
                        }
                    }
                }
            }
            if is_vertex {
                sink.finish_vertex();
            }
        }
    }
    if let Some((line, tok)) = tokens.next_token() {
        return Err(Error::format(
            path,
            format!("line {line}"),
            format!("unexpected data {tok:?} after the last element (element counts too small?)"),
        ));
    }
    Ok(())
}

/// Reads a PLY point cloud (see the module documentation for what is accepted).
/// Truncated data is an [`Error::Format`] naming the vertex (`vertex 17`).
pub fn read_ply(p: impl AsRef<Path>) -> Result<Cloud> {
    let path = p.as_ref();
    let bytes = std::fs::read(path).map_err(|e| Error::io(path, e))?;
    let h = parse_header(path, &bytes)?;
    let Some(vertex) = h.elements.iter().find(|e| e.name == "vertex") else {
        return Err(Error::format(path, "header", "no `element vertex` line"));
    };
    let (slots, extra_names) = vertex_slots(path, vertex)?;
    let data = &bytes[h.data_start..];
    // Do not trust the declared count for allocation: each vertex takes at least one
    // byte per property in binary and two (a digit and a separator) in ASCII.
    let min_record = vertex.props.len().max(1) * if h.encoding == Encoding::Ascii { 2 } else { 1 };
    let capacity = vertex.count.min(data.len() / min_record);
    let mut sink = Sink::new(extra_names.len(), capacity);
    match h.encoding {
        Encoding::Ascii => read_ascii(path, data, &h, &slots, &mut sink)?,
        Encoding::LittleEndian | Encoding::BigEndian => {
            read_binary(path, data, &h, &slots, &mut sink)?
        }
    }
    Ok(Cloud {
        points: sink.points,
        properties: extra_names.into_iter().zip(sink.extra).collect(),
    })
}

// ---------------------------------------------------------------- writing

fn check_cloud(c: &Cloud) -> Result<()> {
    let n = c.points.len();
    for (i, (name, values)) in c.properties.iter().enumerate() {
        if name.is_empty() || !name.chars().all(|ch| ch.is_ascii_graphic()) {
            return Err(Error::InvalidInput(format!(
                "PLY property name {name:?} must be non-empty printable ASCII without spaces"
            )));
        }
        if ["x", "y", "z"].contains(&name.as_str())
            || c.properties[..i].iter().any(|(other, _)| other == name)
        {
            return Err(Error::InvalidInput(format!(
                "PLY property name {name:?} is used twice"
            )));
        }
        if values.len() != n {
            return Err(Error::InvalidInput(format!(
                "PLY property {name:?} has {} values for {n} points",
                values.len()
            )));
        }
    }
    Ok(())
}

fn header_text(c: &Cloud, f: PlyFormat, comments: &[String]) -> String {
    let mut h = String::from("ply\n");
    h.push_str(match f {
        PlyFormat::BinaryLittleEndian => "format binary_little_endian 1.0\n",
        PlyFormat::Ascii => "format ascii 1.0\n",
    });
    if comments.iter().any(|c| c == "frame cam") {
        h.push_str("comment stripecal point cloud: x y z in mm, camera frame\n");
    } else if comments.iter().any(|c| c == "frame sensor") {
        h.push_str("comment stripecal point cloud: x y z in mm, profiler sensor frame\n");
    } else {
        h.push_str("comment stripecal point cloud: x y z in mm, robot base frame\n");
    }
    for text in comments {
        let _ = writeln!(h, "comment {text}");
    }
    let _ = writeln!(h, "element vertex {}", c.points.len());
    for name in ["x", "y", "z"] {
        let _ = writeln!(h, "property double {name}");
    }
    for (name, _) in &c.properties {
        let _ = writeln!(h, "property double {name}");
    }
    h.push_str("end_header\n");
    h
}

/// Writes a point cloud atomically: `x y z` and every extra property as doubles.
/// Errors when a property's length differs from the number of points or its name is
/// not a valid PLY name (or is `x`, `y`, `z` or repeated).
pub fn write_ply(p: impl AsRef<Path>, c: &Cloud, f: PlyFormat) -> Result<()> {
    write_ply_with_comments(p, c, f, &[])
}

/// [`write_ply`] with extra header lines `comment TEXT`, one per entry (after the
/// stripecal comment; readers skip them). A comment with a control character (a line
/// break) is [`Error::InvalidInput`].
pub fn write_ply_with_comments(
    p: impl AsRef<Path>,
    c: &Cloud,
    f: PlyFormat,
    comments: &[String],
) -> Result<()> {
    check_cloud(c)?;
    if let Some(bad) = comments.iter().find(|t| t.chars().any(char::is_control)) {
        return Err(Error::InvalidInput(format!(
            "PLY comment {bad:?} has a control character (comments are one line each)"
        )));
    }
    let header = header_text(c, f, comments);
    let per_point = 3 + c.properties.len();
    let out = match f {
        PlyFormat::BinaryLittleEndian => {
            let mut out = Vec::with_capacity(header.len() + c.points.len() * per_point * 8);
            out.extend_from_slice(header.as_bytes());
            for (i, pt) in c.points.iter().enumerate() {
                for v in pt {
                    out.extend_from_slice(&v.to_le_bytes());
                }
                for (_, values) in &c.properties {
                    out.extend_from_slice(&values[i].to_le_bytes());
                }
            }
            out
        }
        PlyFormat::Ascii => {
            let mut s = header;
            for (i, pt) in c.points.iter().enumerate() {
                // `{}` prints the shortest text that parses back to the same f64.
                let _ = write!(s, "{} {} {}", pt[0], pt[1], pt[2]);
                for (_, values) in &c.properties {
                    let _ = write!(s, " {}", values[i]);
                }
                s.push('\n');
            }
            s.into_bytes()
        }
    };
    write_atomic(p, &out)
}
