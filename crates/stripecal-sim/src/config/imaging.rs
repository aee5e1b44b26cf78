//! The twin's image-formation knobs (gray and colour images, the laser's colour) and
//! rig.json's stripe channel they imply.

use serde::{Deserialize, Serialize};

use super::{bad, SimConfig};
use crate::SimError;

/// Image formation.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImagingCfg {
    /// 8 or 16.
    pub bit_depth: u8,
    /// Samples per pixel side (>= 4); pixels on a reflectance edge get 4x more per side.
    pub supersample: usize,
    /// Ambient illumination of board images (fraction of full scale on a reflectance-1 surface).
    pub ambient: f64,
    /// Ambient of laser images (dimmed), same unit.
    pub laser_ambient: f64,
    /// One image per view holding both circles and stripe.
    pub single_image: bool,
    /// Ambient of single images.
    pub single_image_ambient: f64,
    pub plate_reflectance: f64,
    pub circle_reflectance: f64,
    pub table_reflectance: f64,
    pub sphere_reflectance: f64,
    /// Relative fall-off at the image corners (0 = none): `1 - v * (r / r_corner)^2`.
    pub vignetting: f64,
    /// Gaussian PSF sigma, px (0 = none).
    pub psf_sigma_px: f64,
    /// Read noise sigma in gray levels of the 8-bit scale (x257 for 16-bit).
    pub noise_gray: f64,
    /// Full-well capacity in electrons for photon (shot) noise; 0 disables it.
    pub full_well_e: f64,
    /// Laser peak radiance on a reflectance-1 surface at normal incidence, fraction of
    /// full scale (> 1 saturates).
    pub laser_peak: f64,
    /// Gaussian sigma of the laser sheet's thickness, mm.
    pub laser_sigma_mm: f64,
    /// Laser emitter position in the camera frame (on the laser plane); `None` puts it
    /// at the foot of the perpendicular from the camera centre to the plane.
    pub laser_emitter_mm: Option<[f64; 3]>,
    /// Speckle contrast (std of the multiplicative factor), 0 = none.
    pub speckle_contrast: f64,
    /// Speckle grain size (Gaussian correlation sigma), px.
    pub speckle_grain_px: f64,
    /// A reflection of the laser line (a shiny part of the scene): a second, weaker
    /// copy of the laser light, this fraction of it (0: none), displaced in the image by
    /// `reflection_offset_px` (whole pixels, x then y). Not part of the stripe's truth.
    #[serde(default)]
    pub reflection_ratio: f64,
    #[serde(default = "default_reflection_offset")]
    pub reflection_offset_px: [i32; 2],
    /// Colour images: the calibration views and the ball scan are rendered as RGB
    /// (written as RGB PNGs) from per-channel reflectances, ambient and laser colour,
    /// with independent noise of `noise_gray` in each channel (default `false`: gray).
    #[serde(default)]
    pub colour: bool,
    /// Colour images: the laser's colour, `"red"`, `"green"` or `"blue"`: its light is
    /// in that channel only, at `laser_peak`.
    #[serde(default = "default_laser_colour")]
    pub laser_colour: String,
    /// Colour images: the ambient light's level per channel (R, G, B), relative to
    /// `ambient`, `laser_ambient` and `single_image_ambient` (`[1, 1, 1]`: white
    /// daylight).
    #[serde(default = "default_white")]
    pub ambient_rgb: [f64; 3],
    /// Colour images: the plate's reflectance per channel; `None`: `plate_reflectance`
    /// in every channel (white).
    #[serde(default)]
    pub plate_rgb: Option<[f64; 3]>,
    /// Colour images: the printed features' (circles', squares') reflectance per
    /// channel; `None`: `circle_reflectance` in every channel (black ink).
    #[serde(default)]
    pub ink_rgb: Option<[f64; 3]>,
}

pub(super) fn default_reflection_offset() -> [i32; 2] {
    [40, 0]
}

pub(super) fn default_laser_colour() -> String {
    "red".into()
}

pub(super) fn default_white() -> [f64; 3] {
    [1.0; 3]
}

impl ImagingCfg {
    /// The laser colour's channel (0 red, 1 green, 2 blue).
    pub fn laser_channel(&self) -> Result<usize, SimError> {
        match self.laser_colour.as_str() {
            "red" => Ok(0),
            "green" => Ok(1),
            "blue" => Ok(2),
            other => Err(SimError::Config(format!(
                "imaging.laser_colour: {other:?} (expected \"red\", \"green\" or \"blue\")"
            ))),
        }
    }

    /// The reflection's knobs, as truth.json's sim_config leaves them out of twins
    /// without one (so their truth.json is what it was before they existed).
    pub const REFLECTION_KNOBS: [&'static str; 2] = ["reflection_ratio", "reflection_offset_px"];

    /// The knobs of colour images, as truth.json's sim_config leaves them out of gray
    /// twins (so a gray twin's truth.json is what it was before they existed).
    pub const COLOUR_KNOBS: [&'static str; 5] = [
        "colour",
        "laser_colour",
        "ambient_rgb",
        "plate_rgb",
        "ink_rgb",
    ];

    /// The levels, sigmas and factors (the colours: [`Self::validate_colours`]).
    pub(super) fn validate(&self) -> Result<(), SimError> {
        let im = self;
        if im.bit_depth != 8 && im.bit_depth != 16 {
            return bad(
                "imaging.bit_depth",
                format!("{} (expected 8 or 16)", im.bit_depth),
            );
        }
        if im.supersample < 4 || im.supersample > 32 {
            return bad(
                "imaging.supersample",
                format!("{} (expected 4..=32)", im.supersample),
            );
        }
        for (k, v) in [
            ("imaging.psf_sigma_px", im.psf_sigma_px),
            ("imaging.noise_gray", im.noise_gray),
            ("imaging.full_well_e", im.full_well_e),
            ("imaging.speckle_contrast", im.speckle_contrast),
            ("imaging.ambient", im.ambient),
            ("imaging.laser_ambient", im.laser_ambient),
            ("imaging.laser_peak", im.laser_peak),
            ("imaging.vignetting", im.vignetting),
            ("imaging.reflection_ratio", im.reflection_ratio),
        ] {
            if !(v.is_finite() && v >= 0.0) {
                return bad(k, format!("{v} must be finite and >= 0"));
            }
        }
        if im.laser_sigma_mm.is_nan()
            || im.laser_sigma_mm <= 0.0
            || im.speckle_grain_px.is_nan()
            || im.speckle_grain_px <= 0.0
        {
            return bad(
                "imaging.laser_sigma_mm",
                "laser sigma and speckle grain must be > 0".into(),
            );
        }
        if im.vignetting >= 1.0 {
            return bad(
                "imaging.vignetting",
                format!("{} must be < 1", im.vignetting),
            );
        }
        Ok(())
    }

    /// The laser's colour and the colour images' reflectances.
    pub(super) fn validate_colours(&self) -> Result<(), SimError> {
        let im = self;
        im.laser_channel()?;
        for (k, v) in [
            ("imaging.ambient_rgb", Some(im.ambient_rgb)),
            ("imaging.plate_rgb", im.plate_rgb),
            ("imaging.ink_rgb", im.ink_rgb),
        ] {
            if let Some(v) = v {
                if v.iter().any(|x| !(x.is_finite() && *x >= 0.0)) {
                    return bad(k, format!("{v:?} must be finite and >= 0"));
                }
            }
        }
        Ok(())
    }
}

impl SimConfig {
    /// rig.json's `stripe.channel` (see [`SimConfig::stripe_channel`]).
    pub fn stripe_channel_model(&self) -> Result<stripecal::model::StripeChannel, SimError> {
        use stripecal::model::StripeChannel;
        match &self.stripe_channel {
            Some(name) => StripeChannel::from_name(name)
                .map_err(|e| SimError::Config(format!("stripe_channel: {e}"))),
            None if self.imaging.colour => {
                Ok(StripeChannel::ALL[1 + self.imaging.laser_channel()?])
            }
            None => Ok(StripeChannel::Gray),
        }
    }
}
