//! From linear radiance to a sensor image: illumination, vignetting, speckle, PSF,
//! photon and read noise, clipping and quantisation.

use rayon::prelude::*;

use stripecal::model::image::{AnyGray, AnyRgb, GrayImage, RgbImage};
use stripecal::Camera;

use crate::config::ImagingCfg;
use crate::render::LinearImage;
use crate::rng::Rng;

/// Which image of a view is being formed.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Exposure {
    /// Board lit, laser off.
    Board,
    /// Laser on, ambient dimmed.
    Laser,
    /// Board lit and laser on (single-image mode).
    Single,
}

/// Forms the sensor image. `seed`/`stream` make the noise reproducible per image.
pub fn form_image(
    lin: &LinearImage,
    cam: &Camera,
    im: &ImagingCfg,
    exposure: Exposure,
    seed: u64,
    stream: u64,
) -> AnyGray {
    let quant = form_channel(lin, cam, im, exposure, seed, stream, [1.0, 1.0]);
    let (width, height) = (lin.width, lin.height);
    if im.bit_depth == 16 {
        AnyGray::U16(GrayImage {
            width,
            height,
            data: quant,
        })
    } else {
        AnyGray::U8(GrayImage {
            width,
            height,
            data: quant.into_iter().map(|x| x as u8).collect(),
        })
    }
}

/// Forms an RGB image from one linear image per channel (`lins[c]`: the scene rendered
/// with that channel's reflectances): channel `c` is [`form_image`] with the ambient
/// scaled by `imaging.ambient_rgb[c]`, the laser light kept only in the laser colour's
/// channel, and its own noise (stream `stream` and the channel); the channels are
/// independent. Errors only on a bad `imaging.laser_colour`.
pub fn form_rgb(
    lins: [&LinearImage; 3],
    cam: &Camera,
    im: &ImagingCfg,
    exposure: Exposure,
    seed: u64,
    stream: u64,
) -> Result<AnyRgb, crate::SimError> {
    let laser = im.laser_channel()?;
    let chans: Vec<Vec<u16>> = (0..3)
        .map(|c| {
            let las = if c == laser { 1.0 } else { 0.0 };
            let s = stream ^ ((c as u64 + 1) << 56);
            form_channel(
                lins[c],
                cam,
                im,
                exposure,
                seed,
                s,
                [im.ambient_rgb[c], las],
            )
        })
        .collect();
    let n = chans[0].len();
    let mut data = Vec::with_capacity(3 * n);
    for ((r, g), b) in chans[0].iter().zip(&chans[1]).zip(&chans[2]) {
        data.extend([*r, *g, *b]);
    }
    let (width, height) = (lins[0].width, lins[0].height);
    Ok(if im.bit_depth == 16 {
        AnyRgb::U16(RgbImage {
            width,
            height,
            data,
        })
    } else {
        AnyRgb::U8(RgbImage {
            width,
            height,
            data: data.into_iter().map(|x| x as u8).collect(),
        })
    })
}

/// The quantised samples of [`form_image`] (`<=` the bit depth's maximum) with the
/// ambient level scaled by `scale[0]` and the laser light by `scale[1]` (`[1, 1]`: the
/// gray image, bit for bit).
fn form_channel(
    lin: &LinearImage,
    cam: &Camera,
    im: &ImagingCfg,
    exposure: Exposure,
    seed: u64,
    stream: u64,
    scale: [f64; 2],
) -> Vec<u16> {
    let (w, h) = (lin.width, lin.height);
    let (amb, las) = match exposure {
        Exposure::Board => (im.ambient, 0.0),
        Exposure::Laser => (im.laser_ambient, 1.0),
        Exposure::Single => (im.single_image_ambient, 1.0),
    };
    let (amb, las) = if scale == [1.0, 1.0] {
        (amb, las)
    } else {
        (amb * scale[0], las * scale[1])
    };
    let speckle = if las > 0.0 && im.speckle_contrast > 0.0 {
        Some(speckle_field(
            w,
            h,
            im.speckle_contrast,
            im.speckle_grain_px,
            seed,
            stream ^ 0x5bec,
        ))
    } else {
        None
    };
    // Vignetting about the principal point, normalised at the farthest corner.
    let corners = [
        (0.0, 0.0),
        (w as f64 - 1.0, 0.0),
        (0.0, h as f64 - 1.0),
        (w as f64 - 1.0, h as f64 - 1.0),
    ];
    let rc2 = corners
        .iter()
        .map(|(x, y)| (x - cam.u0).powi(2) + (y - cam.v0).powi(2))
        .fold(1.0f64, f64::max);
    let mut img: Vec<f64> = vec![0.0; w * h];
    img.par_chunks_mut(w).enumerate().for_each(|(row, out)| {
        for (col, o) in out.iter_mut().enumerate() {
            let i = row * w + col;
            let r2 = ((col as f64 - cam.u0).powi(2) + (row as f64 - cam.v0).powi(2)) / rc2;
            let vig = 1.0 - im.vignetting * r2;
            let mut l = lin.laser[i] as f64;
            if im.reflection_ratio > 0.0 {
                // the reflection: the laser light seen `reflection_offset_px` away
                let (sx, sy) = (
                    col as i64 - im.reflection_offset_px[0] as i64,
                    row as i64 - im.reflection_offset_px[1] as i64,
                );
                if sx >= 0 && sy >= 0 && (sx as usize) < w && (sy as usize) < h {
                    l += im.reflection_ratio * lin.laser[sy as usize * w + sx as usize] as f64;
                }
            }
            l *= las;
            if let Some(s) = &speckle {
                l *= s[i] as f64;
            }
            *o = vig * (amb * lin.ambient[i] as f64 + l);
        }
    });
    if im.psf_sigma_px > 0.0 {
        img = gaussian_blur(&img, w, h, im.psf_sigma_px);
    }
    let maxv = if im.bit_depth == 16 { 65535.0 } else { 255.0 };
    let read_sigma = im.noise_gray * maxv / 255.0;
    let full_well = im.full_well_e;
    let quant: Vec<u16> = img
        .par_chunks(w)
        .enumerate()
        .flat_map_iter(|(row, line)| {
            let mut rng = Rng::new(
                seed,
                stream.wrapping_mul(1_000_003).wrapping_add(row as u64 + 1),
            );
            line.iter()
                .map(|&x| {
                    let mut v = x.max(0.0);
                    if full_well > 0.0 {
                        // Photon noise: electrons ~ Poisson(v * full_well), Gaussian approx.
                        let e = v * full_well;
                        v = (e + e.sqrt() * rng.normal()) / full_well;
                    }
                    let mut g = v * maxv;
                    if read_sigma > 0.0 {
                        g += read_sigma * rng.normal();
                    }
                    g.round().clamp(0.0, maxv) as u16
                })
                .collect::<Vec<u16>>()
        })
        .collect();
    quant
}

/// Separable Gaussian blur with mirrored borders (kernel radius ceil(4 sigma)).
pub fn gaussian_blur(img: &[f64], w: usize, h: usize, sigma: f64) -> Vec<f64> {
    let r = (4.0 * sigma).ceil() as isize;
    let mut k: Vec<f64> = (-r..=r)
        .map(|i| (-0.5 * (i as f64 / sigma).powi(2)).exp())
        .collect();
    let s: f64 = k.iter().sum();
    k.iter_mut().for_each(|x| *x /= s);
    let mirror = |i: isize, n: usize| -> usize {
        let n = n as isize;
        let mut i = i;
        if n == 1 {
            return 0;
        }
        while i < 0 || i >= n {
            if i < 0 {
                i = -i;
            }
            if i >= n {
                i = 2 * (n - 1) - i;
            }
        }
        i as usize
    };
    let mut tmp = vec![0.0; w * h];
    tmp.par_chunks_mut(w).enumerate().for_each(|(row, out)| {
        let line = &img[row * w..(row + 1) * w];
        for (x, o) in out.iter_mut().enumerate() {
            *o = k
                .iter()
                .enumerate()
                .map(|(j, kv)| kv * line[mirror(x as isize + j as isize - r, w)])
                .sum();
        }
    });
    let mut out = vec![0.0; w * h];
    out.par_chunks_mut(w).enumerate().for_each(|(row, o)| {
        for (j, kv) in k.iter().enumerate() {
            let src = mirror(row as isize + j as isize - r, h);
            let line = &tmp[src * w..(src + 1) * w];
            if j == 0 {
                // The first tap written, not added to the zeros read: a fresh buffer's
                // pages are then faulted in once, by this write, instead of mapped to
                // the shared zero page by a read and copied on the write after it (a
                // TLB flush on every core the process runs on, page by page). The same
                // sums: `0.0 + x` as before.
                for (x, v) in o.iter_mut().enumerate() {
                    *v = 0.0 + kv * line[x];
                }
            } else {
                for (x, v) in o.iter_mut().enumerate() {
                    *v += kv * line[x];
                }
            }
        }
    });
    out
}

/// A multiplicative speckle field: mean 1, std `contrast`, Gaussian-correlated over
/// `grain` px, never negative.
fn speckle_field(
    w: usize,
    h: usize,
    contrast: f64,
    grain: f64,
    seed: u64,
    stream: u64,
) -> Vec<f32> {
    let mut rng = Rng::new(seed, stream);
    let white: Vec<f64> = (0..w * h).map(|_| rng.normal()).collect();
    let f = gaussian_blur(&white, w, h, grain);
    // Blurring white noise by a Gaussian of sigma g leaves std 1 / (2 sqrt(pi) g).
    let std = 1.0 / (2.0 * std::f64::consts::PI.sqrt() * grain);
    f.into_iter()
        .map(|x| (1.0 + contrast * x / std).max(0.0) as f32)
        .collect()
}
