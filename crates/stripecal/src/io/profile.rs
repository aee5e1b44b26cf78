//! A profile file of a calibrated line profiler (spec/DATASET.md "A profile dataset").
//!
//! CSV: a header naming at least `x_mm` and `z_mm` (in any order; further columns such
//! as `intensity` are allowed and not read), then one point `(x, z)` per line, mm in the
//! profiler frame `sensor` (x along the laser line, z along the measuring range, the
//! point at `(x, 0, z)`). The order of the points is not relied on.
//!
//! ## Gaps
//!
//! Profilers report "no point here" in the z field. A point is a gap (skipped and
//! counted in [`Profile::gaps`]) when its z is
//! - empty,
//! - a non-finite number as Rust's `f64` parser reads it, which is case-insensitive:
//!   `nan`, `NaN`, `inf`, `+inf`, `-inf`, `Infinity`, `-INFINITY`...,
//! - the rig's `sensor.invalid_z` sentinel: equal to it, or within `1e-9` of it
//!   relative to its magnitude (`|z - s| <= 1e-9 * max(|s|, 1)`, so a sentinel printed
//!   with fewer digits still matches, and no measured z comes near it).
//!
//! Everything else is an error naming the file, the line and the column
//! (`line N, column x_mm`) and the text found: an x that is empty or not finite, any
//! field read that is not a number, a row too short to hold both columns. Fields are
//! trimmed; CRLF line ends, a UTF-8 byte-order mark and trailing blank lines are
//! accepted; a blank line before the last point is an error (a truncated or spliced
//! file).
//!
//! ## Speed
//!
//! The file is read once into memory and parsed in place: no regex, no allocation per
//! line or field (only the output vector grows); a 3000-point profile parses in a few
//! tens of microseconds (see the test `a_3000_point_profile_parses_fast`).

use std::path::Path;

use super::atomic::read_text;
use crate::error::{Error, Result};
use crate::model::Profile;

/// How close (relative to the sentinel's magnitude, at least 1) a z must be to
/// `invalid_z` to be read as a gap.
pub const INVALID_Z_REL_TOL: f64 = 1e-9;

const X: &str = "x_mm";
const Z: &str = "z_mm";

/// Reads a profile file; `invalid_z` is the rig's `sensor.invalid_z` (see the module
/// docs for what is a gap and what is an error).
pub fn read_profile(path: impl AsRef<Path>, invalid_z: Option<f64>) -> Result<Profile> {
    let path = path.as_ref();
    parse_profile(&read_text(path)?, path, invalid_z)
}

/// Whether `z` is the sentinel `s`.
fn is_sentinel(z: f64, s: f64) -> bool {
    (z - s).abs() <= INVALID_Z_REL_TOL * s.abs().max(1.0)
}

/// The columns of `x_mm` and `z_mm` in a header line.
fn header_columns(path: &Path, header: &str) -> Result<(usize, usize)> {
    let mut x = None;
    let mut z = None;
    for (i, f) in header.split(',').enumerate() {
        let slot = match f.trim() {
            X => &mut x,
            Z => &mut z,
            _ => continue,
        };
        if slot.is_some() {
            return Err(Error::format(
                path,
                "line 1",
                format!("header names `{}` twice", f.trim()),
            ));
        }
        *slot = Some(i);
    }
    match (x, z) {
        (Some(x), Some(z)) => Ok((x, z)),
        _ => {
            let missing: Vec<&str> = [(X, x), (Z, z)]
                .iter()
                .filter(|(_, c)| c.is_none())
                .map(|(n, _)| *n)
                .collect();
            Err(Error::format(
                path,
                "line 1",
                format!(
                    "the header {:?} has no column {}: a profile's header names x_mm and z_mm \
                     (in any order; further columns are ignored)",
                    header.trim(),
                    missing.join(" or ")
                ),
            ))
        }
    }
}

/// Parses a profile file's text (as [`read_profile`]); `path` is used in error messages
/// only.
pub fn parse_profile(text: &str, path: &Path, invalid_z: Option<f64>) -> Result<Profile> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let mut lines = text.split('\n');
    let header = lines.next().unwrap_or("");
    if header.trim().is_empty() {
        return Err(Error::format(
            path,
            "line 1",
            "empty header: a profile file starts with a header naming x_mm and z_mm",
        ));
    }
    let (ix, iz) = header_columns(path, header)?;
    let need = ix.max(iz) + 1;
    let mut profile = Profile {
        // a point takes at least 4 bytes ("1,2\n")
        points: Vec::with_capacity(text.len() / 16),
        gaps: 0,
    };
    // Line number of a blank line not yet known to be trailing.
    let mut blank: Option<usize> = None;
    for (k, line) in lines.enumerate() {
        let line_no = k + 2;
        if line.trim().is_empty() {
            blank.get_or_insert(line_no);
            continue;
        }
        if let Some(b) = blank {
            return Err(Error::format(
                path,
                format!("line {b}"),
                "blank line (only trailing blank lines are allowed)",
            ));
        }
        let (mut x, mut z) = (None, None);
        let mut n = 0;
        for (i, f) in line.split(',').take(need).enumerate() {
            n = i + 1;
            if i == ix {
                x = Some(f.trim());
            } else if i == iz {
                z = Some(f.trim());
            }
        }
        let (Some(xs), Some(zs)) = (x, z) else {
            return Err(Error::format(
                path,
                format!("line {line_no}"),
                format!(
                    "{n} fields, but x_mm and z_mm are columns {} and {} of the header",
                    ix + 1,
                    iz + 1
                ),
            ));
        };
        let at = |column: &str, msg: String| {
            Error::format(path, format!("line {line_no}, column {column}"), msg)
        };
        let z = if zs.is_empty() {
            f64::NAN
        } else {
            zs.parse::<f64>()
                .map_err(|_| at(Z, format!("z_mm = {zs:?} is not a number")))?
        };
        let gap = !z.is_finite() || invalid_z.is_some_and(|s| is_sentinel(z, s));
        let x = match xs.parse::<f64>() {
            Ok(x) if x.is_finite() => x,
            _ if xs.is_empty() => return Err(at(X, "x_mm is empty".into())),
            _ => return Err(at(X, format!("x_mm = {xs:?} is not a finite number"))),
        };
        if gap {
            profile.gaps += 1;
        } else {
            profile.points.push([x, z]);
        }
    }
    Ok(profile)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn parse(text: &str, invalid_z: Option<f64>) -> Result<Profile> {
        parse_profile(text, Path::new("profiles/p.csv"), invalid_z)
    }

    /// The location and message of a format error naming the profile file.
    fn at(e: Error) -> (String, String) {
        match e {
            Error::Format {
                path,
                location,
                message,
            } => {
                assert_eq!(path, Path::new("profiles/p.csv"));
                (location, message)
            }
            other => panic!("expected a format error, got {other:?}"),
        }
    }

    #[test]
    fn reads_points_in_any_column_order_with_extra_columns() {
        let p = parse("x_mm,z_mm\n-1.5,200.25\n0,201\n1.5e0,202.125\n", None).unwrap();
        assert_eq!(p.points, vec![[-1.5, 200.25], [0.0, 201.0], [1.5, 202.125]]);
        assert_eq!(p.gaps, 0);
        let p = parse(
            "\u{feff}intensity, z_mm ,x_mm,flag\r\n12,200.5,-3,a\r\n9, 201.0 , -2.5 ,b\r\n\r\n\n",
            None,
        )
        .unwrap();
        assert_eq!(p.points, vec![[-3.0, 200.5], [-2.5, 201.0]]);
        // a header alone is an empty profile (the profiler saw nothing)
        assert_eq!(parse("x_mm,z_mm\n", None).unwrap(), Profile::default());
    }

    #[test]
    fn gap_spellings_are_skipped_and_counted() {
        let spellings = [
            "",
            "nan",
            "NaN",
            "NAN",
            "inf",
            "-inf",
            "+inf",
            "Inf",
            "-INF",
            "infinity",
            "Infinity",
            "-Infinity",
        ];
        let mut text = String::from("x_mm,z_mm\n0,100\n");
        for (i, s) in spellings.iter().enumerate() {
            text.push_str(&format!("{},{s}\n", i + 1));
        }
        text.push_str("99,101\n");
        let p = parse(&text, None).unwrap();
        assert_eq!(p.gaps, spellings.len());
        assert_eq!(p.points, vec![[0.0, 100.0], [99.0, 101.0]]);
    }

    #[test]
    fn invalid_z_sentinel_is_a_gap_exactly_or_within_1e9_relative() {
        let s = -99999.9999;
        let text = "x_mm,z_mm\n0,-99999.9999\n1,-99999.99990001\n2,-99999.999\n3,150\n";
        let p = parse(text, Some(s)).unwrap();
        // 1e-8 off is inside 1e-9 * 1e5 = 1e-4 (a gap); 9e-4 off is not (a point)
        assert_eq!(p.gaps, 2);
        assert_eq!(p.points, vec![[2.0, -99999.999], [3.0, 150.0]]);
        // without a sentinel the same values are points
        assert_eq!(parse(text, None).unwrap().points.len(), 4);
        // a small sentinel: 0 means "no point" for some vendors
        let p = parse("x_mm,z_mm\n0,0\n1,1e-12\n2,1e-6\n", Some(0.0)).unwrap();
        assert_eq!((p.gaps, p.points.len()), (2, 1));
    }

    #[test]
    fn bad_numbers_name_file_line_column_and_text() {
        let (loc, msg) = at(parse("x_mm,z_mm\n0,1\n1,abc\n", None).unwrap_err());
        assert_eq!(loc, "line 3, column z_mm");
        assert!(msg.contains("\"abc\""), "{msg}");
        let (loc, msg) = at(parse("z_mm,x_mm\n1,0\n1,1.2.3\n", None).unwrap_err());
        assert_eq!(loc, "line 3, column x_mm");
        assert!(msg.contains("\"1.2.3\""), "{msg}");
        for bad_x in ["nan", "inf", "-Infinity"] {
            let (loc, msg) = at(parse(&format!("x_mm,z_mm\n{bad_x},1\n"), None).unwrap_err());
            assert_eq!(loc, "line 2, column x_mm");
            assert!(msg.contains("not a finite number"), "{msg}");
        }
        let (loc, msg) = at(parse("x_mm,z_mm\n,5\n", None).unwrap_err());
        assert_eq!(loc, "line 2, column x_mm");
        assert!(msg.contains("empty"), "{msg}");
        // an empty x is an error even when z is a gap
        let (loc, _) = at(parse("x_mm,z_mm\n,nan\n", None).unwrap_err());
        assert_eq!(loc, "line 2, column x_mm");
        // a row too short for the z column
        let (loc, msg) = at(parse("x_mm,i,z_mm\n1,2\n", None).unwrap_err());
        assert_eq!(loc, "line 2");
        assert!(msg.contains("columns 1 and 3"), "{msg}");
        // quoted numbers are text, not numbers
        let (loc, _) = at(parse("x_mm,z_mm\n\"1\",2\n", None).unwrap_err());
        assert_eq!(loc, "line 2, column x_mm");
    }

    #[test]
    fn header_errors_name_line_1() {
        for (text, want) in [
            ("", "empty header"),
            ("\n1,2\n", "empty header"),
            ("x_mm,y_mm\n1,2\n", "no column z_mm"),
            ("x,z\n1,2\n", "no column x_mm or z_mm"),
            ("x_mm,z_mm,x_mm\n1,2,3\n", "twice"),
        ] {
            let (loc, msg) = at(parse(text, None).unwrap_err());
            assert_eq!(loc, "line 1", "{text:?}");
            assert!(msg.contains(want), "{text:?}: {msg}");
        }
    }

    #[test]
    fn blank_lines_inside_are_errors_trailing_ones_are_not() {
        let (loc, _) = at(parse("x_mm,z_mm\n1,2\n\n3,4\n", None).unwrap_err());
        assert_eq!(loc, "line 3");
        assert_eq!(
            parse("x_mm,z_mm\n1,2\n  \n\r\n", None).unwrap().points,
            vec![[1.0, 2.0]]
        );
    }

    #[test]
    fn reads_a_file_and_names_a_missing_one() {
        let dir = tempfile::tempdir().unwrap();
        let path = dir.path().join("p.csv");
        std::fs::write(&path, "x_mm,z_mm,intensity\n1,2,3\n4,,5\n").unwrap();
        let p = read_profile(&path, None).unwrap();
        assert_eq!((p.points, p.gaps), (vec![[1.0, 2.0]], 1));
        let e = read_profile(dir.path().join("none.csv"), None).unwrap_err();
        assert!(
            matches!(&e, Error::Io { path, .. } if path.ends_with("none.csv")),
            "{e:?}"
        );
    }

    #[test]
    fn a_3000_point_profile_parses_fast() {
        let mut text = String::from("x_mm,z_mm,intensity\n");
        for i in 0..3000 {
            let x = -45.0 + 0.03 * i as f64;
            let z = 250.0 + (x * 0.1).sin();
            if i % 50 == 0 {
                text.push_str(&format!("{x:.6},nan,0\n"));
            } else {
                text.push_str(&format!("{x:.6},{z:.6},{}\n", i % 255));
            }
        }
        let path = Path::new("p.csv");
        let mut best = f64::INFINITY;
        for _ in 0..20 {
            let t0 = std::time::Instant::now();
            let p = parse_profile(&text, path, None).unwrap();
            best = best.min(t0.elapsed().as_secs_f64());
            assert_eq!((p.points.len(), p.gaps), (2940, 60));
        }
        eprintln!(
            "a 3000-point profile parses in {:.1} us (best of 20)",
            best * 1e6
        );
        // "well under 1 ms" in an unoptimised test build, on a shared machine
        assert!(best < 1e-3, "best of 20: {best:.2e} s");
    }
}
