//! CPU time per image of `detect_chessboard` (one thread; on-CPU ns of the thread from
//! /proc/thread-self/schedstat, so time-sharing with other jobs does not count) on the
//! images of issue 41: the `hp3-chessboard` twin (7 x 10, 768 x 576, view 0), the
//! `visp_franka` photographs (9 x 6, 640 x 480; skipped when ../shared/realdata is
//! absent) and a 28 x 17 twin board at 1928 x 1208 (view 0). Not a benchmark (criterion's
//! `vision_targets` and scripts/bench_chessboard.py are): a tool to see where the time
//! goes (`perf record` on it) and to compare corners before and after a change.
//!
//! Run: `cargo run --release -p stripecal-benches --example chess_prof -- MODE [ARG]`:
//! - `time [SECONDS]` (default 2): best and median CPU ms per image, per case;
//! - `loop CASE SECONDS`: detections of one case (`twin`, `visp`, `big`) for `perf`;
//! - `reps CASE N`: N detections of each image of one case (`perf stat` counts);
//! - `dump FILE`: every detected corner (case, image, row, col, u, v, quality) to FILE;
//! - `diff FILE_A FILE_B`: the largest and RMS position difference of two dumps;
//! - `png DIR`: writes the twin images as `DIR/twin_7x10.png`, `DIR/big_28x17.png`;
//! - `truth FILE`: the true corners of the twin images (`twin`, `big`) in the format of
//!   `dump`, for `diff` against a dump (the error against the truth).

use std::collections::HashMap;
use std::hint::black_box;
use std::path::{Path, PathBuf};

use stripecal::io::{load_gray, read_rig, save_gray_png};
use stripecal::model::image::AnyGray;
use stripecal::vision::chessboard::{detect_chessboard, ChessboardOptions};
use stripecal::Board;
use stripecal_sim::truth::target_truth;
use stripecal_sim::{SimConfig, Twin};

fn cpu_ns() -> u64 {
    let s = std::fs::read_to_string("/proc/thread-self/schedstat").unwrap();
    s.split_whitespace().next().unwrap().parse().unwrap()
}

/// The 28 x 17 board at 1928 x 1208 (the hp3-chessboard rig with a larger sensor and
/// board: squares of 3 mm, about 35 px).
pub fn big_overrides() -> serde_json::Value {
    serde_json::json!({
        "camera": {"width": 1928, "height": 1208, "u0": 964.0, "v0": 604.0},
        "board": {"rows": 17, "cols": 28, "pitch_mm": 3.0, "square_mm": 3.0},
    })
}

fn twin_view(over: serde_json::Value) -> (AnyGray, Board) {
    let cfg = SimConfig::preset("hp3-chessboard")
        .unwrap()
        .with_overrides(&over)
        .unwrap();
    let twin = Twin::new(cfg).unwrap();
    let poses = twin.calibration_poses().unwrap();
    let img = twin
        .render_view(&poses[0].q_deg, 0)
        .unwrap()
        .board_image
        .unwrap();
    (img, twin.board.clone())
}

type Case = (String, Vec<(String, AnyGray)>, Board);

fn cases(which: &str) -> Vec<Case> {
    let mut out = Vec::new();
    let want = |n: &str| which == "all" || which.split(',').any(|w| w == n);
    if want("twin") {
        let (img, b) = twin_view(serde_json::json!({}));
        out.push(("twin".into(), vec![("view0".into(), img)], b));
    }
    if want("visp") {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../shared/realdata/visp_franka");
        if dir.is_dir() {
            let board = read_rig(dir.join("rig.json")).unwrap().board;
            let mut imgs = Vec::new();
            for k in 1..=8 {
                let name = format!("franka_image-{k}.png");
                imgs.push((
                    name.clone(),
                    load_gray(dir.join("images").join(&name)).unwrap(),
                ));
            }
            out.push(("visp".into(), imgs, board));
        } else {
            eprintln!("visp: {} not found, skipped", dir.display());
        }
    }
    if want("big") {
        let (img, b) = twin_view(big_overrides());
        out.push(("big".into(), vec![("view0".into(), img)], b));
    }
    out
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mode = args.first().map(String::as_str).unwrap_or("time");
    let opts = ChessboardOptions::default();
    match mode {
        "time" => {
            let secs: f64 = args.get(1).map(|s| s.parse().unwrap()).unwrap_or(2.0);
            for (name, imgs, board) in cases("all") {
                let mut per = Vec::new();
                let reps = (secs / 0.2).ceil() as usize;
                for _ in 0..reps {
                    let t0 = cpu_ns();
                    let mut n = 0u64;
                    while cpu_ns() - t0 < 200_000_000 {
                        for (_, img) in &imgs {
                            black_box(detect_chessboard(img.view().unwrap(), &board, &opts).ok());
                            n += 1;
                        }
                    }
                    per.push((cpu_ns() - t0) as f64 / n as f64 / 1e6);
                }
                per.sort_by(f64::total_cmp);
                let pts: usize = imgs
                    .iter()
                    .map(|(_, i)| {
                        detect_chessboard(i.view().unwrap(), &board, &opts)
                            .map(|d| d.points.len())
                            .unwrap_or(0)
                    })
                    .sum();
                println!(
                    "{name:5} {} image(s), {pts} corners: cpu min {:8.3} ms/img, median {:8.3}",
                    imgs.len(),
                    per[0],
                    per[per.len() / 2]
                );
            }
        }
        "loop" => {
            let secs: f64 = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(10.0);
            let cs = cases(&args[1]);
            let t0 = cpu_ns();
            while ((cpu_ns() - t0) as f64) < secs * 1e9 {
                for (_, imgs, board) in &cs {
                    for (_, img) in imgs {
                        black_box(detect_chessboard(img.view().unwrap(), board, &opts).ok());
                    }
                }
            }
        }
        "reps" => {
            let n: usize = args.get(2).map(|s| s.parse().unwrap()).unwrap_or(100);
            let cs = cases(&args[1]);
            for _ in 0..n {
                for (_, imgs, board) in &cs {
                    for (_, img) in imgs {
                        black_box(detect_chessboard(img.view().unwrap(), board, &opts).ok());
                    }
                }
            }
        }
        "dump" => {
            let mut s = String::new();
            for (name, imgs, board) in cases("all") {
                for (iname, img) in &imgs {
                    match detect_chessboard(img.view().unwrap(), &board, &opts) {
                        Ok(d) => {
                            for p in &d.points {
                                s += &format!(
                                    "{name} {iname} {} {} {:.9} {:.9} {:.6e} {}\n",
                                    p.row, p.col, p.u, p.v, p.quality_px, p.flags.0
                                );
                            }
                            for p in &d.dropped {
                                s += &format!(
                                    "{name} {iname} dropped {} {} {}\n",
                                    p.row, p.col, p.reason
                                );
                            }
                        }
                        Err(e) => s += &format!("{name} {iname} error {e}\n"),
                    }
                }
            }
            std::fs::write(&args[1], s).unwrap();
        }
        "diff" => {
            let read = |p: &str| -> HashMap<String, [f64; 3]> {
                std::fs::read_to_string(p)
                    .unwrap()
                    .lines()
                    .filter_map(|l| {
                        let f: Vec<&str> = l.split_whitespace().collect();
                        let u = f.get(4)?.parse().ok()?;
                        let v = f.get(5)?.parse().ok()?;
                        let q = f.get(6)?.parse().ok()?;
                        Some((f[..4].join(" "), [u, v, q]))
                    })
                    .collect()
            };
            let (a, b) = (read(&args[1]), read(&args[2]));
            let mut per: HashMap<String, (usize, f64, f64, f64)> = HashMap::new();
            for (k, pa) in &a {
                let case = k.split(' ').next().unwrap().to_string();
                let e = per.entry(case).or_default();
                if let Some(pb) = b.get(k) {
                    let d = (pa[0] - pb[0]).hypot(pa[1] - pb[1]);
                    e.0 += 1;
                    e.1 = e.1.max(d);
                    e.2 += d * d;
                    e.3 = e.3.max((pa[2] / pb[2] - 1.0).abs());
                }
            }
            println!(
                "{} corners in A, {} in B, {} in both",
                a.len(),
                b.len(),
                a.keys().filter(|k| b.contains_key(*k)).count()
            );
            let mut keys: Vec<_> = per.keys().cloned().collect();
            keys.sort();
            for k in keys {
                let (n, mx, ss, q) = per[&k];
                println!(
                    "{k:5} {n:5} common: max {mx:.2e} px, rms {:.2e} px, quality max rel diff {q:.2e}",
                    (ss / n.max(1) as f64).sqrt()
                );
            }
        }
        "truth" => {
            let mut s = String::new();
            for (name, over) in [("twin", serde_json::json!({})), ("big", big_overrides())] {
                let cfg = SimConfig::preset("hp3-chessboard")
                    .unwrap()
                    .with_overrides(&over)
                    .unwrap();
                let twin = Twin::new(cfg).unwrap();
                let poses = twin.calibration_poses().unwrap();
                let scene = twin.scene(&poses[0].q_deg, false).unwrap();
                for t in target_truth(&scene, &twin.camera, 0.0) {
                    s += &format!(
                        "{name} view0 {} {} {:.9} {:.9} 1 0\n",
                        t.row, t.col, t.u, t.v
                    );
                }
            }
            std::fs::write(&args[1], s).unwrap();
        }
        "png" => {
            let dir = PathBuf::from(&args[1]);
            std::fs::create_dir_all(&dir).unwrap();
            let (img, _) = twin_view(serde_json::json!({}));
            save_gray_png(dir.join("twin_7x10.png"), &img).unwrap();
            let (img, _) = twin_view(big_overrides());
            save_gray_png(dir.join("big_28x17.png"), &img).unwrap();
        }
        other => panic!("unknown mode {other}"),
    }
}
