//! Measures the stripe centre error against truth in colour laser images for the ways a
//! laser colour's contrast can be formed (docs/colour.md):
//! `cargo run --release -p stripecal-sim --example colour_contrast -- [SEEDS] [OVERRIDES_JSON]`.
//!
//! The twin renders the calibration views of `hp3-paper` in colour (a red line over the
//! white circle board, `imaging.colour`), and, with the same seed, in gray (the
//! equivalent gray image: the laser and ambient of the red channel). Per signal: the
//! stripe is extracted (default options, the twin's direction), flagged against the
//! board image's reflectance edges, and its trusted points on the board compared with
//! the true centre line of the same scan line: RMS and 95th percentile of the error
//! along the scan line, px, and the points kept.

use stripecal::model::image::{AnyGray, AnyRgb, GrayImage};
use stripecal::vision::stripe::{
    extract_stripe, flag_reflectance_edges, EdgeOptions, StripeDirection, StripeOptions,
};
use stripecal_sim::{SimConfig, Twin};

/// `f(r, g, b)` per pixel, as a 16-bit image on the 8-bit scale x 257 with `offset`
/// (8-bit gray levels) added, clamped.
fn signal(c: &AnyRgb, offset: f64, f: impl Fn(usize, f64, f64, f64) -> f64) -> AnyGray {
    let AnyRgb::U8(c) = c else {
        panic!("8-bit twin")
    };
    let data = (0..c.width * c.height)
        .map(|i| {
            let p = &c.data[3 * i..3 * i + 3];
            let v = f(i, p[0] as f64, p[1] as f64, p[2] as f64) + offset;
            (v * 257.0).round().clamp(0.0, 65535.0) as u16
        })
        .collect();
    AnyGray::U16(GrayImage {
        width: c.width,
        height: c.height,
        data,
    })
}

/// A box mean of `(g + b) / 2` over `(2 r + 1)^2` pixels (clamped at the borders).
fn box_other(c: &AnyRgb, r: usize) -> Vec<f64> {
    let AnyRgb::U8(c) = c else {
        panic!("8-bit twin")
    };
    let (w, h) = (c.width, c.height);
    let o: Vec<f64> = (0..w * h)
        .map(|i| 0.5 * (c.data[3 * i + 1] as f64 + c.data[3 * i + 2] as f64))
        .collect();
    let mut out = vec![0.0; w * h];
    for y in 0..h {
        for x in 0..w {
            let (mut s, mut n) = (0.0, 0.0);
            for yy in y.saturating_sub(r)..(y + r + 1).min(h) {
                for xx in x.saturating_sub(r)..(x + r + 1).min(w) {
                    s += o[yy * w + xx];
                    n += 1.0;
                }
            }
            out[y * w + x] = s / n;
        }
    }
    out
}

#[derive(Default)]
struct Acc {
    err: Vec<f64>,
    lines: usize,
}

impl Acc {
    fn report(&mut self, name: &str) {
        self.err.sort_by(|a, b| a.abs().total_cmp(&b.abs()));
        let n = self.err.len();
        let rms = (self.err.iter().fold(0.0, |a, e| a + e * e) / n.max(1) as f64).sqrt();
        let p95 = self.err.get(n * 95 / 100).map_or(f64::NAN, |e| e.abs());
        println!(
            "{name:<34} rms {rms:.4} px   p95 {p95:.4} px   points {n:>5} of {} truth lines",
            self.lines
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let seeds: u64 = args.get(1).map_or(3, |s| s.parse().expect("seeds"));
    let over: serde_json::Value = args.get(2).map_or(serde_json::json!({}), |s| {
        serde_json::from_str(s).expect("JSON")
    });
    let names = [
        "gray (BT.601)",
        "R",
        "R - (G+B)/2",
        "R - box5x5((G+B)/2)",
        "gray twin, same laser (equivalent)",
    ];
    let mut acc: Vec<Acc> = (0..names.len()).map(|_| Acc::default()).collect();
    for seed in 0..seeds {
        let base = SimConfig::hp3_paper()
            .with_overrides(&serde_json::json!({"seed": seed, "scan": {"enabled": false}}))
            .and_then(|c| c.with_overrides(&over))
            .expect("config");
        let colour = base
            .with_overrides(&serde_json::json!({"imaging": {"colour": true}}))
            .expect("colour");
        let tc = Twin::new(colour).expect("twin");
        let tg = Twin::new(base).expect("twin");
        let opts = StripeOptions {
            direction: tc.direction,
            ..StripeOptions::default()
        };
        for (i, pose) in tc.calibration_poses().expect("poses").iter().enumerate() {
            let rc = tc.render_view(&pose.q_deg, i).expect("render");
            let rg = tg.render_view(&pose.q_deg, i).expect("render");
            let c = rc.laser_rgb.as_ref().expect("colour");
            let amb = box_other(c, 2);
            let signals = [
                c.to_gray(),
                c.channel(0),
                signal(c, 32.0, |_, r, g, b| r - 0.5 * (g + b)),
                signal(c, 32.0, |i, r, _, _| r - amb[i]),
                rg.laser_image.clone().expect("laser"),
            ];
            let truth: std::collections::HashMap<i64, f64> = rc
                .stripe
                .iter()
                .filter(|p| p.surface == "board")
                .map(|p| match tc.direction {
                    StripeDirection::Rows => (p.u.round() as i64, p.v),
                    _ => (p.v.round() as i64, p.u),
                })
                .collect();
            for (k, s) in signals.iter().enumerate() {
                acc[k].lines += truth.len();
                let Ok(mut st) = extract_stripe(s.view().unwrap(), &opts) else {
                    continue;
                };
                let board = if k == 4 {
                    &rg.board_image
                } else {
                    &rc.board_image
                };
                flag_reflectance_edges(
                    &mut st,
                    board.as_ref().unwrap().view().unwrap(),
                    &EdgeOptions::default(),
                )
                .unwrap();
                for p in st.points.iter().filter(|p| p.trusted()) {
                    let (line, pos) = match st.direction {
                        StripeDirection::Rows => (p.u.round() as i64, p.v),
                        _ => (p.v.round() as i64, p.u),
                    };
                    if let Some(t) = truth.get(&line) {
                        acc[k].err.push(pos - t);
                    }
                }
            }
        }
    }
    println!("{seeds} seeds, colour twin hp3-paper (red laser, white board), overrides {over}");
    for (a, n) in acc.iter_mut().zip(names) {
        a.report(n);
    }
}
