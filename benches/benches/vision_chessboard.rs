//! Criterion benchmark of chessboard detection on a 768 x 576 synthetic image: a 9 x 6
//! board (rows 6, cols 9) about 60 % of the image wide, tilted 30 degrees and turned
//! 12 degrees, Gaussian PSF 0.7 px, noise 1 gray level, 8 bits; built here.
//! Run: `cargo bench -p stripecal-benches --bench vision_chessboard`. With
//! `STRIPECAL_CHESS_PNG=path.png` the image is also written there (and the true corners
//! beside it as `path.png.csv`) so OpenCV can be timed on the same pixels.

use criterion::{criterion_group, criterion_main, Criterion};
use nalgebra::{Matrix3, Rotation3, Unit, Vector3};
use std::hint::black_box;

use stripecal::image::{AnyGray, GrayImage};
use stripecal::vision::chessboard::{detect_chessboard, ChessboardOptions};
use stripecal::Board;

const W: usize = 768;
const H: usize = 576;

/// Board-to-image homography (pixels) of the benchmark pose.
fn pose(b: &Board) -> Matrix3<f64> {
    let e = b.pattern_extent();
    let f = 1.2 * W as f64;
    let z = f * (e[1] - e[0]) / (0.6 * W as f64);
    let axis = Unit::new_normalize(Vector3::new(0.8, 0.6, 0.0));
    let rot = (Rotation3::from_axis_angle(&Vector3::z_axis(), 12f64.to_radians())
        * Rotation3::from_axis_angle(&axis, 30f64.to_radians()))
    .into_inner();
    let c = Vector3::new(0.5 * (e[0] + e[1]), 0.5 * (e[2] + e[3]), 0.0);
    let t = Vector3::new(0.0, 0.0, z) - rot * c;
    let k = Matrix3::new(
        f,
        0.0,
        0.5 * (W as f64 - 1.0),
        0.0,
        f,
        0.5 * (H as f64 - 1.0),
        0.0,
        0.0,
        1.0,
    );
    k * Matrix3::from_columns(&[rot.column(0).into_owned(), rot.column(1).into_owned(), t])
}

/// The scene convolved with the PSF and the pixel box: area means over quarter
/// pixels, the PSF on that grid, 4 x 4 means; then noise (a fixed LCG) and rounding.
fn render(b: &Board, h: &Matrix3<f64>) -> Vec<u8> {
    const S: usize = 4;
    let hinv = h.try_inverse().expect("pose");
    let val = |u: f64, v: f64| {
        let q = hinv * Vector3::new(u, v, 1.0);
        if b.ink_at(q.x / q.z, q.y / q.z).is_some() {
            30.0
        } else {
            200.0
        }
    };
    let (sw, sh) = (W * S, H * S);
    let sub = 1.0 / S as f64;
    let mut fine = vec![0f64; sw * sh];
    for y in 0..sh {
        for x in 0..sw {
            let (u0, v0) = (x as f64 * sub - 0.5, y as f64 * sub - 0.5);
            let c = [
                val(u0, v0),
                val(u0 + sub, v0),
                val(u0, v0 + sub),
                val(u0 + sub, v0 + sub),
            ];
            fine[y * sw + x] = if c.iter().all(|&p| p == c[0]) {
                c[0]
            } else {
                let mut acc = 0.0;
                for sy in 0..8 {
                    for sx in 0..8 {
                        acc += val(
                            u0 + (sx as f64 + 0.5) * sub / 8.0,
                            v0 + (sy as f64 + 0.5) * sub / 8.0,
                        );
                    }
                }
                acc / 64.0
            };
        }
    }
    let s = 0.7 * S as f64;
    let r = (4.0 * s).ceil() as i64;
    let k: Vec<f64> = (-r..=r)
        .map(|d| (-((d * d) as f64) / (2.0 * s * s)).exp())
        .collect();
    let ks: f64 = k.iter().sum();
    let blur = |src: &[f64], horizontal: bool| {
        let mut out = vec![0f64; sw * sh];
        for y in 0..sh {
            for x in 0..sw {
                let mut acc = 0.0;
                for (o, kv) in k.iter().enumerate() {
                    let d = o as i64 - r;
                    let (xx, yy) = if horizontal {
                        ((x as i64 + d).clamp(0, sw as i64 - 1) as usize, y)
                    } else {
                        (x, (y as i64 + d).clamp(0, sh as i64 - 1) as usize)
                    };
                    acc += kv * src[yy * sw + xx];
                }
                out[y * sw + x] = acc / ks;
            }
        }
        out
    };
    let fine = blur(&blur(&fine, true), false);
    let mut state = 12345u64;
    let mut uniform = || {
        state = state
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        ((state >> 11) as f64 + 0.5) / (1u64 << 53) as f64
    };
    (0..W * H)
        .map(|k| {
            let (x, y) = (k % W, k / W);
            let mut acc = 0.0;
            for sy in 0..S {
                for sx in 0..S {
                    acc += fine[(y * S + sy) * sw + x * S + sx];
                }
            }
            let (a, b2) = (uniform(), uniform());
            let n = (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * b2).cos();
            (acc / (S * S) as f64 + n).round().clamp(0.0, 255.0) as u8
        })
        .collect()
}

fn chessboard(c: &mut Criterion) {
    let board = Board::chessboard(6, 9, 20.0).unwrap();
    let h = pose(&board);
    let data = render(&board, &h);
    let img = AnyGray::U8(GrayImage {
        width: W,
        height: H,
        data,
    });
    if let Ok(path) = std::env::var("STRIPECAL_CHESS_PNG") {
        stripecal::io::save_gray_png(&path, &img).unwrap();
        let mut csv = String::from("row,col,u,v\n");
        for (r, col) in board.indices() {
            let p = board.center(r, col);
            let q = h * Vector3::new(p.x, p.y, 1.0);
            csv += &format!("{r},{col},{:.6},{:.6}\n", q.x / q.z, q.y / q.z);
        }
        std::fs::write(format!("{path}.csv"), csv).unwrap();
    }
    let opts = ChessboardOptions::default();
    let d = detect_chessboard(img.view().unwrap(), &board, &opts).unwrap();
    assert_eq!(d.points.len(), 54);
    let mut g = c.benchmark_group("vision_chessboard");
    g.bench_function("detect_chessboard_9x6_768x576", |b| {
        b.iter(|| detect_chessboard(black_box(img.view().unwrap()), &board, &opts).unwrap())
    });
    g.finish();
}

criterion_group!(benches, chessboard);
criterion_main!(benches);
