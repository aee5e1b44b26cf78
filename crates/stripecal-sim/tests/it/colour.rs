//! The twin's colour images (`imaging.colour`, docs/twin.md): channels formed from
//! per-channel reflectances, the laser in its colour only, independent noise, rig.json's
//! `stripe.channel`, and the stripe found in the laser colour's channel.

use stripecal::model::image::{AnyGray, AnyImage, AnyRgb};
use stripecal::model::StripeChannel;
use stripecal::vision::stripe::{extract_stripe, stripe_signal, StripeOptions};
use stripecal_sim::{SimConfig, Twin};

fn twin(over: serde_json::Value) -> Twin {
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"seed": 5, "scan": {"enabled": false},
            "imaging": {"colour": true}}))
        .and_then(|c| c.with_overrides(&over))
        .unwrap();
    Twin::new(cfg).unwrap()
}

fn rgb8(c: &AnyRgb) -> &stripecal::model::image::RgbImage<u8> {
    match c {
        AnyRgb::U8(c) => c,
        AnyRgb::U16(_) => panic!("8-bit twin"),
    }
}

/// The standard deviation of channel `k` over the pixels where `keep` holds.
fn spread(
    c: &stripecal::model::image::RgbImage<u8>,
    k: usize,
    keep: impl Fn(usize) -> bool,
) -> f64 {
    let v: Vec<f64> = (0..c.width * c.height)
        .filter(|&i| keep(i))
        .map(|i| c.data[3 * i + k] as f64)
        .collect();
    let m = v.iter().sum::<f64>() / v.len() as f64;
    (v.iter().map(|x| (x - m).powi(2)).sum::<f64>() / v.len() as f64).sqrt()
}

#[test]
fn colour_views_carry_the_laser_in_its_channel_with_independent_noise() {
    let t = twin(serde_json::json!({}));
    let rig = t.rig().unwrap();
    assert_eq!(rig.stripe_channel, StripeChannel::Red);
    let q = t.calibration_poses().unwrap()[0].q_deg.clone();
    let v = t.render_view(&q, 0).unwrap();
    let (board, laser) = (v.board_rgb.as_ref().unwrap(), v.laser_rgb.as_ref().unwrap());
    // the gray images are the contract's BT.601 conversion of the colour ones
    assert_eq!(v.board_image.as_ref().unwrap(), &board.to_gray());
    assert_eq!(v.laser_image.as_ref().unwrap(), &laser.to_gray());
    // reproducible
    let again = t.render_view(&q, 0).unwrap();
    assert_eq!(again.laser_rgb.as_ref(), Some(laser));
    let l = rgb8(laser);
    let n = l.width * l.height;
    // green and blue see the same white board and ambient: they differ by noise only,
    // independent per channel (the difference's spread is sqrt(2) x 1 gray level)
    let d: Vec<f64> = (0..n)
        .map(|i| l.data[3 * i + 1] as f64 - l.data[3 * i + 2] as f64)
        .collect();
    let sd = (d.iter().map(|x| x * x).sum::<f64>() / n as f64).sqrt();
    assert!((sd / 2f64.sqrt() - 1.04).abs() < 0.1, "{sd}");
    // the stripe is in red only
    let hot = (0..n)
        .filter(|&i| l.data[3 * i] as i32 - l.data[3 * i + 1] as i32 > 50)
        .count();
    assert!(hot > 500, "{hot}");
    // the red channel's stripe is what a gray twin of the same laser shows: its peaks
    // are ~1 / 0.299 of BT.601 gray's
    let img = AnyImage::Rgb(laser.clone());
    let o = StripeOptions {
        direction: t.direction,
        ..StripeOptions::default()
    };
    // (on the scan lines where both find the stripe: gray loses the weakest ones)
    let peaks = |ch| {
        let s = stripe_signal(&img, ch, &o).unwrap();
        let st = extract_stripe(s.view().unwrap(), &o).unwrap();
        st.points
            .iter()
            .map(|p| ((p.u.round() as i64, p.v.round() as i64), p.peak as f64))
            .collect::<std::collections::HashMap<_, _>>()
    };
    let (red, gray) = (peaks(StripeChannel::Red), peaks(StripeChannel::Gray));
    let mut r: Vec<f64> = red
        .iter()
        .filter_map(|(k, p)| gray.get(k).map(|g| p / g))
        .collect();
    assert!(r.len() > 100, "{}", r.len());
    r.sort_by(f64::total_cmp);
    let ratio = r[r.len() / 2];
    assert!((ratio - 1.0 / 0.299).abs() < 0.3, "{ratio}");
}

#[test]
fn per_channel_reflectances_render_per_channel() {
    // red ink on a white board: in red the circles are as bright as the board
    let t = twin(serde_json::json!({"imaging": {"ink_rgb": [0.9, 0.08, 0.08]}}));
    let q = t.calibration_poses().unwrap()[0].q_deg.clone();
    let v = t.render_view(&q, 0).unwrap();
    let b = rgb8(v.board_rgb.as_ref().unwrap());
    // inside the image's central part (the board), green shows the circles, red not
    let (w, h) = (b.width, b.height);
    let centre = |i: usize| {
        let (x, y) = (i % w, i / w);
        x > w / 3 && x < 2 * w / 3 && y > h / 3 && y < 2 * h / 3
    };
    let (r, g) = (spread(b, 0, centre), spread(b, 1, centre));
    assert!(g > 20.0 && r < 0.25 * g, "red {r}, green {g}");
    // a green laser: the stripe in green, rig.json says green
    let t = twin(serde_json::json!({"imaging": {"laser_colour": "green"}}));
    assert_eq!(t.rig().unwrap().stripe_channel, StripeChannel::Green);
    let v = t.render_view(&q, 0).unwrap();
    let l = rgb8(v.laser_rgb.as_ref().unwrap());
    let hot = (0..l.width * l.height)
        .filter(|&i| l.data[3 * i + 1] as i32 - l.data[3 * i] as i32 > 50)
        .count();
    assert!(hot > 500, "{hot}");
    // an explicit rig channel, and bad knobs named
    let t = twin(serde_json::json!({"stripe_channel": "auto"}));
    assert_eq!(t.rig().unwrap().stripe_channel, StripeChannel::Auto);
    for (over, knob) in [
        (
            serde_json::json!({"imaging": {"laser_colour": "infrared"}}),
            "imaging.laser_colour",
        ),
        (
            serde_json::json!({"imaging": {"ambient_rgb": [1, -1, 1]}}),
            "imaging.ambient_rgb",
        ),
        (
            serde_json::json!({"stripe_channel": "purple"}),
            "stripe_channel",
        ),
    ] {
        let e = SimConfig::hp3_paper().with_overrides(&over).unwrap_err();
        assert!(e.to_string().contains(knob), "{e}");
    }
}

#[test]
fn colour_off_keeps_gray_renders() {
    // the colour knobs without `colour` change nothing
    let base = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"seed": 5, "scan": {"enabled": false}}))
        .unwrap();
    let knobs = base
        .with_overrides(&serde_json::json!({"imaging": {"laser_colour": "blue",
            "ambient_rgb": [1.0, 0.5, 0.2], "ink_rgb": [0.9, 0.1, 0.1]}}))
        .unwrap();
    let (a, b) = (Twin::new(base).unwrap(), Twin::new(knobs).unwrap());
    let q = a.calibration_poses().unwrap()[0].q_deg.clone();
    let (va, vb) = (a.render_view(&q, 0).unwrap(), b.render_view(&q, 0).unwrap());
    assert!(va.laser_rgb.is_none() && vb.board_rgb.is_none());
    assert_eq!(va.laser_image, vb.laser_image);
    assert_eq!(va.board_image, vb.board_image);
    assert!(matches!(va.laser_image, Some(AnyGray::U8(_))));
    assert_eq!(a.rig().unwrap().stripe_channel, StripeChannel::Gray);
}
