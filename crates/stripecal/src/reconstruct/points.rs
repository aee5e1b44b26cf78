//! The reconstructed points of a scan (struct of arrays), their PLY cloud, and the
//! frame tag errors carry.

use crate::error::{BadFrame, Error};
use crate::model::Cloud;
use crate::vision::stripe::FLAG_SATURATED;

use super::DropCounts;

/// Reconstructed points of one or many frames (struct of arrays, all the same length).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct ScanPoints {
    /// Points in the robot base frame, mm.
    pub points_mm: Vec<[f64; 3]>,
    /// Index of the frame each point comes from (the row of the input / scan.csv).
    pub frame: Vec<u32>,
    /// Sub-pixel stripe centre, px. For a profile scan
    /// ([`crate::reconstruct::profile_scan_points`]) the profile point's `x` (`u_px`) and
    /// `z` (`v_px`) in the sensor frame, mm: what addresses a point in its frame's chain
    /// ([`crate::reconstruct::UncertaintyModel::profiler`]).
    pub u_px: Vec<f64>,
    pub v_px: Vec<f64>,
    /// Stripe peak above the local background, gray levels of the image (zero for a
    /// profile scan).
    pub intensity: Vec<f32>,
    /// The stripe's full width at half maximum across the line, px (what the
    /// curved-surface bias model reads: the sheet's thickness as the camera sees it;
    /// zero for a profile scan).
    pub width_px: Vec<f32>,
    /// Per-point covariance in the base frame, mm^2, upper triangle `xx, xy, xz, yy,
    /// yz, zz` ([`crate::reconstruct::point_covariances`]); empty unless asked for.
    pub covariance_mm2: Vec<[f64; 6]>,
    /// The stripe point's `FLAG_*` bits.
    pub flags: Vec<u8>,
    /// Points dropped (all frames so far).
    pub dropped: DropCounts,
    /// Frames left out because their image could not be used (a scan reconstructed
    /// with [`super::BadImage::Skip`]), in frame order, each with the reason.
    pub skipped: Vec<BadFrame>,
    /// The points are in the camera frame (a fixed-sensor scan, no poses), not the base
    /// frame: the PLY header says `comment frame cam`.
    pub camera_frame: bool,
    /// The points of a line profiler's scan: `u_px`/`v_px` hold each point's profile
    /// coordinates `x`, `z` (mm, sensor frame), the PLY names them `x_mm`, `z_mm` (and
    /// has no `intensity`/`flags`), and a fixed profiler's frame is `sensor`.
    pub profiler: bool,
}

impl ScanPoints {
    /// Point `i`'s stripe holds a saturated pixel ([`FLAG_SATURATED`]; `false` without
    /// flags).
    pub fn saturated(&self, i: usize) -> bool {
        self.flags.get(i).is_some_and(|&b| b & FLAG_SATURATED != 0)
    }

    /// Number of points.
    pub fn len(&self) -> usize {
        self.points_mm.len()
    }

    /// No points.
    pub fn is_empty(&self) -> bool {
        self.points_mm.is_empty()
    }

    /// Empties every vector, keeping their memory.
    pub fn clear(&mut self) {
        self.points_mm.clear();
        self.frame.clear();
        self.u_px.clear();
        self.v_px.clear();
        self.intensity.clear();
        self.width_px.clear();
        self.covariance_mm2.clear();
        self.flags.clear();
        self.dropped = DropCounts::default();
        self.skipped.clear();
    }

    /// Appends another set (its frame indices kept as they are).
    pub fn append(&mut self, o: &ScanPoints) {
        self.points_mm.extend_from_slice(&o.points_mm);
        self.frame.extend_from_slice(&o.frame);
        self.u_px.extend_from_slice(&o.u_px);
        self.v_px.extend_from_slice(&o.v_px);
        self.intensity.extend_from_slice(&o.intensity);
        self.width_px.extend_from_slice(&o.width_px);
        self.covariance_mm2.extend_from_slice(&o.covariance_mm2);
        self.flags.extend_from_slice(&o.flags);
        self.dropped.add(&o.dropped);
        self.skipped.extend_from_slice(&o.skipped);
    }

    /// Keeps the points whose frame `keep` accepts (the drop counts and the skipped
    /// frames are left as they are).
    pub(super) fn retain_frames(&mut self, keep: impl Fn(u32) -> bool) {
        let mask: Vec<bool> = self.frame.iter().map(|&f| keep(f)).collect();
        fn retain<T>(v: &mut Vec<T>, mask: &[bool]) {
            let mut i = 0;
            v.retain(|_| {
                i += 1;
                mask[i - 1]
            });
        }
        retain(&mut self.points_mm, &mask);
        retain(&mut self.u_px, &mask);
        retain(&mut self.v_px, &mask);
        retain(&mut self.intensity, &mask);
        retain(&mut self.width_px, &mask);
        if !self.covariance_mm2.is_empty() {
            retain(&mut self.covariance_mm2, &mask);
        }
        retain(&mut self.flags, &mask);
        retain(&mut self.frame, &mask);
    }

    /// The points `idx` (in that order) with their frames, pixels and properties; the
    /// drop counts and skipped frames as they are.
    pub fn subset(&self, idx: &[usize]) -> ScanPoints {
        let p = self;
        ScanPoints {
            points_mm: idx.iter().map(|&i| p.points_mm[i]).collect(),
            frame: idx.iter().map(|&i| p.frame[i]).collect(),
            u_px: idx.iter().map(|&i| p.u_px[i]).collect(),
            v_px: idx.iter().map(|&i| p.v_px[i]).collect(),
            intensity: idx.iter().map(|&i| p.intensity[i]).collect(),
            width_px: idx.iter().map(|&i| p.width_px[i]).collect(),
            flags: idx.iter().map(|&i| p.flags[i]).collect(),
            covariance_mm2: if p.covariance_mm2.len() == p.len() {
                idx.iter().map(|&i| p.covariance_mm2[i]).collect()
            } else {
                vec![]
            },
            dropped: p.dropped,
            skipped: p.skipped.clone(),
            camera_frame: p.camera_frame,
            profiler: p.profiler,
        }
    }

    /// The PLY header comments of the cloud: `skipped_frames N`, then one
    /// `skipped frame ...` line per skipped frame (which, where and why; control
    /// characters replaced by spaces).
    pub fn ply_comments(&self) -> Vec<String> {
        let frame = if self.profiler { "sensor" } else { "cam" };
        ply_comments(self.camera_frame.then_some(frame), &self.skipped)
    }

    /// The PLY cloud: `x y z` and the properties `view` (frame index), `u`, `v`,
    /// `intensity`, `flags` (spec/DATASET.md "The point cloud"), and with per-point
    /// covariances `cov_xx cov_xy cov_xz cov_yy cov_yz cov_zz` (mm^2).
    pub fn to_cloud(&self) -> Cloud {
        if self.profiler {
            let mut c = Cloud {
                points: self.points_mm.clone(),
                properties: vec![
                    (
                        "view".into(),
                        self.frame.iter().map(|&f| f as f64).collect(),
                    ),
                    ("x_mm".into(), self.u_px.clone()),
                    ("z_mm".into(), self.v_px.clone()),
                ],
            };
            self.push_covariance(&mut c);
            return c;
        }
        let mut c = Cloud {
            points: self.points_mm.clone(),
            properties: vec![
                (
                    "view".into(),
                    self.frame.iter().map(|&f| f as f64).collect(),
                ),
                ("u".into(), self.u_px.clone()),
                ("v".into(), self.v_px.clone()),
                (
                    "intensity".into(),
                    self.intensity.iter().map(|&f| f as f64).collect(),
                ),
                (
                    "flags".into(),
                    self.flags.iter().map(|&f| f as f64).collect(),
                ),
            ],
        };
        self.push_covariance(&mut c);
        c
    }

    /// The per-point covariances as the PLY's `cov_*` properties, when there are any.
    fn push_covariance(&self, c: &mut Cloud) {
        if self.covariance_mm2.len() == self.points_mm.len() && !self.points_mm.is_empty() {
            for (k, name) in ["cov_xx", "cov_xy", "cov_xz", "cov_yy", "cov_yz", "cov_zz"]
                .iter()
                .enumerate()
            {
                c.properties.push((
                    name.to_string(),
                    self.covariance_mm2.iter().map(|v| v[k]).collect(),
                ));
            }
        }
    }
}

/// The PLY header comments of a scan's cloud: `frame NAME` when the points are not in
/// the base frame (`cam`, `sensor`), `skipped_frames N`, then one `skipped frame ...`
/// line per skipped frame (control characters replaced by spaces).
pub(super) fn ply_comments(frame: Option<&str>, skipped: &[BadFrame]) -> Vec<String> {
    let mut c = Vec::with_capacity(2 + skipped.len());
    if let Some(f) = frame {
        c.push(format!("frame {f}"));
    }
    c.push(format!("skipped_frames {}", skipped.len()));
    for b in skipped {
        let text = format!("skipped {b}");
        c.push(
            text.chars()
                .map(|ch| if ch.is_control() { ' ' } else { ch })
                .collect(),
        );
    }
    c
}

/// Puts `frame i` (and the scan.csv line, when known) in front of an error's message,
/// keeping its kind.
pub fn at_frame(e: Error, frame: usize, line: Option<usize>) -> Error {
    let tag = match line {
        Some(l) => format!("frame {frame} (scan.csv line {l})"),
        None => format!("frame {frame}"),
    };
    match e {
        Error::InvalidInput(m) => Error::InvalidInput(format!("{tag}: {m}")),
        Error::Degenerate(m) => Error::Degenerate(format!("{tag}: {m}")),
        Error::Detection(m) => Error::Detection(format!("{tag}: {m}")),
        Error::Format {
            path,
            location,
            message,
        } => Error::Format {
            path,
            location: format!("{tag}: {location}"),
            message,
        },
        other => other,
    }
}
