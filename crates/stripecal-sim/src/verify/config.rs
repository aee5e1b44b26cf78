//! The `verify` section's knobs: which scans, the artefacts' nominal sizes, the
//! certificate's uncertainties and the MPEs, with their validation.

use super::*;

/// Expanded (k = 2) uncertainties of the certificate, mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct UncertaintyCfg {
    pub diameter: f64,
    pub form: f64,
    pub length: f64,
    pub flatness: f64,
}

impl Default for UncertaintyCfg {
    fn default() -> Self {
        UncertaintyCfg {
            diameter: 0.001,
            form: 0.0005,
            length: 0.002,
            flatness: 0.001,
        }
    }
}

/// Maximum permissible errors the acceptance test applies, mm.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct MpeCfg {
    pub probing_form: f64,
    pub probing_size: f64,
    pub sphere_spacing: f64,
    pub flatness: f64,
}

impl Default for MpeCfg {
    fn default() -> Self {
        MpeCfg {
            probing_form: 0.05,
            probing_size: 0.03,
            sphere_spacing: 0.08,
            flatness: 0.05,
        }
    }
}

/// The `verify` knobs.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields, default)]
pub struct VerifyCfg {
    /// Write `verify/` (default false).
    pub enabled: bool,
    /// Nominal centre distance of the ball bar's spheres, mm.
    pub bar_length_mm: f64,
    /// Nominal diameter of both spheres, mm.
    pub sphere_diameter_mm: f64,
    /// Ball bar positions, the first N of [`BAR_PLACEMENTS`] (0..=7).
    pub bar_positions: usize,
    /// Plate positions, the first N of [`PLATE_PLACEMENTS`] (0..=3).
    pub plate_positions: usize,
    /// The plate's sides: along the sweep, along the stripe, mm. Along the stripe it is
    /// longer than the stripe seen in the image (~45 mm at 105 mm): the stripe fills the
    /// image's rows, it never ends on the plate.
    pub plate_size_mm: [f64; 2],
    /// The plate sweep stays this far inside the plate's edges across the sweep (the
    /// laser plane never reaches an edge: every stripe lies inside the plate), mm.
    pub plate_inset_mm: f64,
    pub plate_reflectance: f64,
    /// Sensor translation between frames, mm.
    pub step_mm: f64,
    /// Extra travel of the laser plane before and after the artefact, mm.
    pub margin_mm: f64,
    /// The certificate equals the truth (no calibration error of the artefacts).
    pub certificate_exact: bool,
    pub uncertainty_k2_mm: UncertaintyCfg,
    pub mpe_mm: MpeCfg,
}

impl Default for VerifyCfg {
    fn default() -> Self {
        VerifyCfg {
            enabled: false,
            bar_length_mm: 100.0,
            sphere_diameter_mm: 25.4,
            bar_positions: BAR_PLACEMENTS.len(),
            plate_positions: PLATE_PLACEMENTS.len(),
            plate_size_mm: [80.0, 70.0],
            plate_inset_mm: 5.0,
            plate_reflectance: 0.6,
            step_mm: 0.5,
            margin_mm: 2.0,
            certificate_exact: false,
            uncertainty_k2_mm: UncertaintyCfg::default(),
            mpe_mm: MpeCfg::default(),
        }
    }
}

impl VerifyCfg {
    /// Checks every value; the message names the knob.
    pub fn validate(&self) -> Result<(), SimError> {
        let bad = |k: &str, m: String| Err(SimError::Config(format!("verify.{k}: {m}")));
        let pos = |v: f64| v.is_finite() && v > 0.0;
        for (k, v) in [
            ("bar_length_mm", self.bar_length_mm),
            ("sphere_diameter_mm", self.sphere_diameter_mm),
            ("plate_size_mm[0]", self.plate_size_mm[0]),
            ("plate_size_mm[1]", self.plate_size_mm[1]),
            ("plate_reflectance", self.plate_reflectance),
            ("step_mm", self.step_mm),
        ] {
            if !pos(v) {
                return bad(k, format!("{v} must be finite and > 0"));
            }
        }
        if !(self.margin_mm.is_finite() && self.margin_mm >= 0.0) {
            return bad("margin_mm", format!("{} must be >= 0", self.margin_mm));
        }
        let i = self.plate_inset_mm;
        if !(i.is_finite() && i >= 0.0 && 2.0 * i < self.plate_size_mm[0] - self.step_mm) {
            return bad(
                "plate_inset_mm",
                format!(
                    "{i} must be >= 0 and leave more than one step of the plate to sweep \
                     (plate_size_mm[0] {})",
                    self.plate_size_mm[0]
                ),
            );
        }
        if self.sphere_diameter_mm >= 0.9 * self.bar_length_mm {
            return bad(
                "sphere_diameter_mm",
                format!(
                    "{} mm: the spheres must not touch (bar_length_mm {})",
                    self.sphere_diameter_mm, self.bar_length_mm
                ),
            );
        }
        if self.bar_positions > BAR_PLACEMENTS.len() {
            return bad(
                "bar_positions",
                format!("{} (at most {})", self.bar_positions, BAR_PLACEMENTS.len()),
            );
        }
        if self.plate_positions > PLATE_PLACEMENTS.len() {
            return bad(
                "plate_positions",
                format!(
                    "{} (at most {})",
                    self.plate_positions,
                    PLATE_PLACEMENTS.len()
                ),
            );
        }
        let u = &self.uncertainty_k2_mm;
        let m = &self.mpe_mm;
        for (k, v) in [
            ("uncertainty_k2_mm.diameter", u.diameter),
            ("uncertainty_k2_mm.form", u.form),
            ("uncertainty_k2_mm.length", u.length),
            ("uncertainty_k2_mm.flatness", u.flatness),
            ("mpe_mm.probing_form", m.probing_form),
            ("mpe_mm.probing_size", m.probing_size),
            ("mpe_mm.sphere_spacing", m.sphere_spacing),
            ("mpe_mm.flatness", m.flatness),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(k, format!("{v} must be finite and >= 0"));
            }
        }
        Ok(())
    }
}
