//! Colour laser images: the one-channel signal the stripe extractor runs on
//! (`stripe.channel` of rig.json, spec/DATASET.md), and the `auto` decision.
//!
//! ## The signal of a colour
//!
//! For `red`, `green` or `blue` the stripe is found in **that colour's channel, as it
//! is**: `S = R` for a red laser (8- or 16-bit, the same scale as the image). The other
//! two channels are not subtracted; the extractor's own local background (a line
//! through two flanks just outside the stripe, module docs of [`super`]) removes the
//! ambient light under the stripe instead. Why, with independent noise `sigma` per
//! channel and a red laser adding `L` to the red channel only:
//!
//! | signal                        | laser signal | noise           | noise / signal, relative to gray |
//! |-------------------------------|--------------|-----------------|----------------------------------|
//! | BT.601 gray `0.299 R + 0.587 G + 0.114 B` | `0.299 L` | `0.669 sigma` | 1 |
//! | `R - (G + B) / 2`             | `L`          | `1.225 sigma`   | 0.55                             |
//! | `R - smooth((G + B) / 2)`     | `L`          | `~1.01 sigma`   | 0.45, plus edge artefacts        |
//! | **`R`** (chosen)              | `L`          | `sigma`         | **0.45**                         |
//!
//! Subtracting the other channels cancels a white or gray background exactly, but adds
//! their noise; the centre of the stripe depends only on the few pixels of its window
//! and the two flanks, over which a white board's ambient is a straight line the
//! extractor removes anyway. What the subtraction would remove beyond that is the board's
//! printed structure (dark circles, squares) where the stripe crosses it, and there the
//! laser's own reflection changes with the ink as well, so the centre is biased whatever
//! the background: those points are flagged ([`super::FLAG_EDGE`],
//! [`super::FLAG_UNEVEN_BACKGROUND`]) and left out of calibration, exactly as in gray
//! images, whose background shows the same structure (a white board with dark ink has
//! the same reflectance pattern in every channel). A smoothed ambient estimate (a box of
//! `(G + B) / 2`) keeps the noise near `sigma` but leaves a ridge-like artefact of the
//! blur along every ink edge. The measured numbers (the twin's colour images, red line
//! over the white circle board, noise 1 gray level per channel, PSF 0.7 px) are in
//! docs/colour.md.
//!
//! A colour channel also sees saturation where gray cannot: a stripe that clips the red
//! channel is flagged [`super::FLAG_SATURATED`] (or rejected) in `R`, but in gray it is
//! a smaller, silently flattened peak.
//!
//! ## `auto`
//!
//! Decided from laser images ([`channel_scores`], [`choose_channel`]): in each of the
//! four signals (gray, red, green, blue) the stripe is extracted and scored by its
//! points' summed peak-to-noise ratio, `sum(peak) / sigma`, with `sigma` the signal's
//! noise measured in the image itself (the trimmed spread of neighbouring pixels'
//! differences, [`noise_sigma`]). A colour wins when its score beats gray's by
//! [`AUTO_MARGIN`]; otherwise (a white or yellowish laser, gray images) gray. A red laser
//! over a white board scores about 2.4 times gray in red; a white laser scores about
//! 1.5 times higher in gray than in any one channel.

use std::borrow::Cow;

use rayon::prelude::*;

use super::{extract_stripe, StripeOptions};
use crate::error::{Error, Result};
use crate::model::image::{AnyGray, AnyImage, Pixel};
use crate::model::StripeChannel;

/// A colour channel is chosen by `auto` only when its score exceeds gray's by this
/// factor (the contract's default wins when the two are close).
pub const AUTO_MARGIN: f64 = 1.1;

/// The signals `auto` compares, in the order of [`channel_scores`].
pub const SCORED: [StripeChannel; 4] = [
    StripeChannel::Gray,
    StripeChannel::Red,
    StripeChannel::Green,
    StripeChannel::Blue,
];

/// The one-channel image the stripe of `img` is found in for `channel` (module docs):
/// gray images as they are and colour ones by BT.601 luma for `Gray`; the colour's
/// channel for `Red`, `Green`, `Blue`; for `Auto` the choice [`choose_channel`] makes on
/// this image alone. A colour name with a gray image is an [`Error::InvalidInput`]
/// (callers that read the image from a file name it: [`stripe_signal_of_file`]).
pub fn stripe_signal<'a>(
    img: &'a AnyImage,
    channel: StripeChannel,
    opts: &StripeOptions,
) -> Result<Cow<'a, AnyGray>> {
    let channel = match channel {
        StripeChannel::Auto => {
            let scores = channel_scores(img, opts)?;
            choose_channel(&[scores])
        }
        c => c,
    };
    match (img, channel.rgb_index()) {
        (AnyImage::Gray(g), None) => Ok(Cow::Borrowed(g)),
        (AnyImage::Rgb(c), None) => Ok(Cow::Owned(c.to_gray())),
        (AnyImage::Rgb(c), Some(k)) => Ok(Cow::Owned(c.channel(k))),
        (AnyImage::Gray(_), Some(_)) => Err(Error::InvalidInput(gray_image_message(channel))),
    }
}

/// What is wrong with a colour name for a gray image.
fn gray_image_message(channel: StripeChannel) -> String {
    format!(
        "stripe channel \"{}\" needs a colour laser image, this one is gray (one channel): \
         set stripe.channel to \"gray\" or \"auto\"",
        channel.name()
    )
}

/// [`stripe_signal`] of an image read from `path`: a colour name with a gray image is
/// an [`Error::Format`] naming the file (location `stripe.channel`).
pub fn stripe_signal_of_file<'a>(
    path: &std::path::Path,
    img: &'a AnyImage,
    channel: StripeChannel,
    opts: &StripeOptions,
) -> Result<Cow<'a, AnyGray>> {
    if !img.is_colour() && channel.rgb_index().is_some() {
        return Err(Error::format(
            path,
            format!("stripe.channel \"{}\"", channel.name()),
            format!(
                "a gray laser image has no {} channel: the stripe of a gray image is found \
                 in gray (set stripe.channel to \"gray\" or \"auto\", or give colour images)",
                channel.name()
            ),
        ));
    }
    stripe_signal(img, channel, opts)
}

/// The noise of a one-channel image, in its gray levels: the spread of the differences
/// of horizontally neighbouring pixels (every other row) divided by `sqrt(2)`. The
/// spread is first taken from the 80 % smallest differences in magnitude, then twice
/// from those within 3 of it (so the board's edges and the stripe do not count), each
/// corrected for its truncation under a Gaussian law. Never below the rounding noise of
/// one gray level (`1 / sqrt(12)`).
pub fn noise_sigma(img: &AnyGray) -> f64 {
    match img {
        AnyGray::U8(i) => noise_of(&i.data, i.width, i.height),
        AnyGray::U16(i) => noise_of(&i.data, i.width, i.height),
    }
}

fn noise_of<T: Pixel>(data: &[T], w: usize, h: usize) -> f64 {
    let floor = 1.0 / 12f64.sqrt();
    if w < 2 || h == 0 {
        return floor;
    }
    let mut d: Vec<u32> = Vec::with_capacity((w - 1) * h.div_ceil(2));
    for y in (0..h).step_by(2) {
        let row = &data[y * w..(y + 1) * w];
        d.extend(
            row.windows(2)
                .map(|p| p[0].to_u32().abs_diff(p[1].to_u32())),
        );
    }
    let keep = (d.len() * 4 / 5).max(1);
    let (small, _, _) = d.select_nth_unstable(keep - 1);
    let mut sum = 0.0f64;
    for &x in small.iter() {
        sum += (x as f64) * (x as f64);
    }
    let kth = d[keep - 1] as f64;
    sum += kth * kth;
    // E[d^2 | |d| < z sigma_d] = sigma_d^2 (1 - 2 z phi(z) / (2 Phi(z) - 1)): z = 1.2816
    // for the central 80 %, z = 3 below
    let trimmed = 1.0 - 2.0 * 1.281_551_6 * 0.175_498_3 / 0.8;
    let mut var_d = sum / keep as f64 / trimmed;
    let within3 = 1.0 - 6.0 * 0.004_431_8 / 0.997_300_2;
    for _ in 0..2 {
        let t = 3.0 * var_d.sqrt();
        let (mut s, mut n) = (0.0f64, 0usize);
        for &x in &d {
            let x = x as f64;
            if x <= t {
                s += x * x;
                n += 1;
            }
        }
        if n == 0 {
            break;
        }
        var_d = s / n as f64 / within3;
    }
    (var_d / 2.0).sqrt().max(floor)
}

/// The score of each signal of [`SCORED`] for one laser image: the summed peak height
/// of the stripe points found in it (points flagged as biased left out) divided by the
/// signal's noise ([`noise_sigma`]); 0 where no stripe is found. A gray image scores
/// only gray (the colours 0).
pub fn channel_scores(img: &AnyImage, opts: &StripeOptions) -> Result<[f64; 4]> {
    let mut out = [0.0; 4];
    for (k, ch) in SCORED.iter().enumerate() {
        if ch.rgb_index().is_some() && !img.is_colour() {
            continue;
        }
        let sig = stripe_signal(img, *ch, opts)?;
        let sigma = noise_sigma(&sig);
        out[k] = match extract_stripe(sig.view()?, opts) {
            Ok(s) => {
                s.points
                    .iter()
                    .filter(|p| p.trusted())
                    .fold(0.0, |acc, p| acc + p.peak as f64)
                    / sigma
            }
            Err(Error::Detection(_)) => 0.0,
            Err(e) => return Err(e),
        };
    }
    Ok(out)
}

/// The `auto` choice from the laser images `load` gives for `paths` (in parallel),
/// those it cannot read or decode (`None`) and those that cannot be scored left out
/// (a scan's bad frames are reported by the reconstruction itself).
pub fn decide_channel_lenient(
    paths: &[std::path::PathBuf],
    load: impl Fn(&std::path::Path) -> Option<AnyImage> + Sync,
    opts: &StripeOptions,
) -> StripeChannel {
    let scores: Vec<[f64; 4]> = paths
        .par_iter()
        .filter_map(|p| channel_scores(&load(p)?, opts).ok())
        .collect();
    choose_channel(&scores)
}

/// The `auto` choice from the scores of some laser images ([`channel_scores`]): the
/// colour with the highest summed score when it beats gray's sum by [`AUTO_MARGIN`],
/// otherwise gray (also when any image is gray: its colour scores are 0 and a colour
/// name would be an error for it).
pub fn choose_channel(scores: &[[f64; 4]]) -> StripeChannel {
    let mut sum = [0.0f64; 4];
    for s in scores {
        if s[1..].iter().all(|&x| x == 0.0) && s[0] > 0.0 {
            // a gray image (or no colour stripe at all): gray
            return StripeChannel::Gray;
        }
        for k in 0..4 {
            sum[k] += s[k];
        }
    }
    let (best, score) = (1..4)
        .map(|k| (k, sum[k]))
        .fold((0, f64::NEG_INFINITY), |a, b| if b.1 > a.1 { b } else { a });
    if score > AUTO_MARGIN * sum[0] && score > 0.0 {
        SCORED[best]
    } else {
        StripeChannel::Gray
    }
}

/// At most this many laser images of a dataset or scan decide `auto` (evenly spread
/// over its views or frames).
pub const AUTO_IMAGES: usize = 5;

/// The indices of the images `auto` looks at among `n`: all when `n <=`
/// [`AUTO_IMAGES`], else [`AUTO_IMAGES`] evenly spread, first and last included.
pub fn auto_sample(n: usize) -> Vec<usize> {
    if n <= AUTO_IMAGES {
        return (0..n).collect();
    }
    let k = AUTO_IMAGES;
    let mut v: Vec<usize> = (0..k).map(|i| i * (n - 1) / (k - 1)).collect();
    v.dedup();
    v
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::image::{AnyRgb, GrayImage, RgbImage};

    /// A red (or `rgb`-coloured) Gaussian stripe along the columns over a white
    /// background of `bg` with dark squares, pseudo-random noise of ~`noise` per channel.
    fn colour_stripe(
        w: usize,
        h: usize,
        rgb: [f64; 3],
        amp: f64,
        bg: f64,
        noise: f64,
    ) -> RgbImage<u8> {
        let mut s = 42u64;
        let mut data = Vec::with_capacity(w * h * 3);
        for y in 0..h {
            let c = 30.3 + 0.1 * y as f64;
            for x in 0..w {
                let ink = if (x / 9 + y / 9) % 3 == 0 { 0.2 } else { 1.0 };
                let t = (x as f64 - c) / 1.5;
                let laser = amp * (-0.5 * t * t).exp() * ink;
                for ch in rgb {
                    // a sum of 4 uniforms: ~Gaussian, std noise
                    let mut n = 0.0;
                    for _ in 0..4 {
                        s = s
                            .wrapping_mul(6364136223846793005)
                            .wrapping_add(1442695040888963407);
                        n += (s >> 40) as f64 / (1u64 << 24) as f64 - 0.5;
                    }
                    let v = bg * ink + laser * ch + n * noise * 3f64.sqrt();
                    data.push(v.round().clamp(0.0, 255.0) as u8);
                }
            }
        }
        RgbImage {
            width: w,
            height: h,
            data,
        }
    }

    #[test]
    fn red_signal_is_the_red_channel_and_gray_is_bt601() {
        let c = colour_stripe(64, 40, [1.0, 0.0, 0.0], 120.0, 60.0, 1.0);
        let img = AnyImage::Rgb(AnyRgb::U8(c.clone()));
        let o = StripeOptions::default();
        let r = stripe_signal(&img, StripeChannel::Red, &o).unwrap();
        assert_eq!(*r, AnyGray::U8(c.channel(0)));
        let g = stripe_signal(&img, StripeChannel::Gray, &o).unwrap();
        assert_eq!(*g, AnyGray::U8(c.to_gray()));
        let gray = AnyImage::Gray(AnyGray::U8(GrayImage::new(8, 8)));
        assert!(matches!(
            stripe_signal(&gray, StripeChannel::Gray, &o).unwrap(),
            Cow::Borrowed(_)
        ));
        let e = stripe_signal(&gray, StripeChannel::Green, &o).unwrap_err();
        assert!(e.to_string().contains("\"green\" needs a colour"), "{e}");
        let e = stripe_signal_of_file(
            std::path::Path::new("a/laser.png"),
            &gray,
            StripeChannel::Red,
            &o,
        )
        .unwrap_err();
        assert!(matches!(e, Error::Format { .. }), "{e:?}");
        assert!(
            e.to_string()
                .starts_with("a/laser.png: stripe.channel \"red\""),
            "{e}"
        );
    }

    #[test]
    fn noise_estimate_is_close_and_ignores_edges() {
        for noise in [1.0, 3.0] {
            let c = colour_stripe(300, 200, [1.0, 0.0, 0.0], 120.0, 100.0, noise);
            // green: the board and its ink edges, no stripe
            let s = noise_sigma(&AnyGray::U8(c.channel(1)));
            assert!((s / noise - 1.0).abs() < 0.2, "{s} vs {noise}");
        }
        let flat = AnyGray::U8(GrayImage {
            width: 20,
            height: 20,
            data: vec![7; 400],
        });
        assert!((noise_sigma(&flat) - 1.0 / 12f64.sqrt()).abs() < 1e-12);
    }

    #[test]
    fn auto_picks_the_laser_colour_and_gray_for_white() {
        let o = StripeOptions::default();
        for (rgb, want) in [
            ([1.0, 0.0, 0.0], StripeChannel::Red),
            ([0.0, 1.0, 0.0], StripeChannel::Green),
            ([0.0, 0.0, 1.0], StripeChannel::Blue),
            ([1.0, 1.0, 1.0], StripeChannel::Gray),
        ] {
            let img = AnyImage::Rgb(AnyRgb::U8(colour_stripe(160, 120, rgb, 120.0, 60.0, 1.0)));
            let s = channel_scores(&img, &o).unwrap();
            assert_eq!(choose_channel(&[s]), want, "{rgb:?}: {s:?}");
            let sig = stripe_signal(&img, StripeChannel::Auto, &o).unwrap();
            let direct = stripe_signal(&img, want, &o).unwrap();
            assert_eq!(sig, direct);
        }
        let gray = AnyImage::Gray(AnyGray::U8(
            colour_stripe(160, 120, [1.0, 0.0, 0.0], 120.0, 60.0, 1.0).channel(0),
        ));
        let s = channel_scores(&gray, &o).unwrap();
        assert!(s[0] > 0.0 && s[1..] == [0.0; 3], "{s:?}");
        assert_eq!(choose_channel(&[s]), StripeChannel::Gray);
        assert_eq!(choose_channel(&[]), StripeChannel::Gray);
        assert_eq!(auto_sample(3), vec![0, 1, 2]);
        assert_eq!(auto_sample(12), vec![0, 2, 5, 8, 11]);
    }
}
