//! CPU time per image of `StripeExtractor::extract_into` on the hp3-paper twin laser image
//! (view 0), from the on-CPU ns of the thread (/proc/thread-self/schedstat): time-sharing
//! with other jobs does not count. Args: cases (mem,cols,auto,rows_t,auto_t or all; or
//! `check`: cols on the image vs auto on the transposed image, bit for bit) and seconds.
//! Linux only. See BENCHMARKS.md "Vision: stripes".
use std::hint::black_box;
use stripecal::model::image::{AnyGray, GrayImage};
use stripecal::model::StripeDirection;
use stripecal::vision::stripe::{StripeExtractor, StripeOptions};
use stripecal_sim::{SimConfig, Twin};

fn cpu_ns() -> u64 {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").unwrap();
    s.split_whitespace().next().unwrap().parse().unwrap()
}
fn transpose(i: &GrayImage<u8>) -> GrayImage<u8> {
    let mut o = GrayImage::new(i.height, i.width);
    for y in 0..i.height {
        for x in 0..i.width {
            o.data[x * i.height + y] = i.data[y * i.width + x];
        }
    }
    o
}
fn main() {
    let which = std::env::args().nth(1).unwrap_or("all".into());
    let secs: f64 = std::env::args()
        .nth(2)
        .map(|s| s.parse().unwrap())
        .unwrap_or(3.0);
    let twin = Twin::new(SimConfig::hp3_paper()).unwrap();
    let poses = twin.calibration_poses().unwrap();
    let view = twin.render_view(&poses[0].q_deg, 0).unwrap();
    let Some(AnyGray::U8(laser)) = view.laser_image else {
        panic!()
    };
    let lt = AnyGray::U8(transpose(&laser));
    let bytes = laser.data.clone();
    let laser = AnyGray::U8(laser);
    let img = laser.view().unwrap();
    let img_t = lt.view().unwrap();
    let run = |name: &str, f: &mut dyn FnMut()| {
        if which != "all" && !which.split(',').any(|w| w == name) {
            return;
        }
        let mut best = f64::INFINITY;
        let mut all = Vec::new();
        let reps = (secs / 0.25).ceil() as usize;
        for _ in 0..reps {
            let t0 = cpu_ns();
            let mut n = 0u64;
            while cpu_ns() - t0 < 250_000_000 {
                for _ in 0..20 {
                    f();
                }
                n += 20;
            }
            let cpu = (cpu_ns() - t0) as f64 / n as f64 / 1e3;
            best = best.min(cpu);
            all.push(cpu);
        }
        all.sort_by(|a, b| a.partial_cmp(b).unwrap());
        println!(
            "{name:10} cpu min {best:7.1} us/img  median {:7.1}  ({:.0}/s at min)",
            all[all.len() / 2],
            1e6 / best
        );
    };
    if which == "check" {
        let mut a = StripeExtractor::new(StripeOptions {
            direction: StripeDirection::Cols,
            ..Default::default()
        })
        .unwrap();
        let mut b = StripeExtractor::new(StripeOptions::default()).unwrap();
        let (mut pa, mut pb) = (Vec::new(), Vec::new());
        a.extract_into(img, &mut pa).unwrap();
        let d = b.extract_into(img_t, &mut pb).unwrap();
        let mut maxd = 0f64;
        let mut neq = 0;
        for (p, q) in pa.iter().zip(&pb) {
            maxd = maxd.max((p.u - q.v).abs()).max((p.v - q.u).abs());
            if p.u != q.v
                || p.v != q.u
                || p.peak != q.peak
                || p.width_px != q.width_px
                || p.flags != q.flags
                || p.support_px != q.support_px
            {
                neq += 1;
            }
        }
        println!(
            "dir {d:?} n {} {} maxdiff {maxd:e} unequal {neq}",
            pa.len(),
            pb.len()
        );
        return;
    }
    run("mem", &mut || {
        black_box(
            black_box(&bytes)
                .iter()
                .fold(0u32, |a, &v| a.wrapping_add(v as u32)),
        );
    });
    for (name, dir, v) in [
        ("cols", StripeDirection::Cols, img),
        ("auto", StripeDirection::Auto, img),
        ("rows_t", StripeDirection::Rows, img_t),
        ("auto_t", StripeDirection::Auto, img_t),
    ] {
        let mut ex = StripeExtractor::new(StripeOptions {
            direction: dir,
            ..Default::default()
        })
        .unwrap();
        let mut out = Vec::new();
        run(name, &mut || {
            ex.extract_into(black_box(v), &mut out).unwrap();
        });
    }
}
