//! Writes ten small twin datasets (every preset, the verification artefacts, a bench, a
//! colour twin and a 28 x 17 board at 1928 x 1208) into `DIR/<case>` and prints the
//! seconds each took: the renderer's speed, and, with `diff -r` of two builds' folders,
//! proof that a change to the renderer leaves every image the same byte for byte.
//!
//! Run: `cargo run --release -p stripecal-benches --example render_cmp -- DIR [CASE]`
//! (cases: paper wide chess asym sheet profiler verify bench colour big).
use std::path::Path;
use stripecal_sim::{SimConfig, Twin};
fn main() {
    let out = std::env::args().nth(1).unwrap();
    // `n` calibration views, no scan
    let views = |n: usize| serde_json::json!({"poses": {"count": n}, "scan": {"enabled": false}});
    let cases: Vec<(&str, &str, serde_json::Value)> = vec![
        (
            "paper",
            "hp3-paper",
            serde_json::json!({"poses": {"count": 4}, "scan": {"step_mm": 2.0}}),
        ),
        ("wide", "hp3-wide", views(3)),
        ("chess", "hp3-chessboard", views(4)),
        ("asym", "hp3-asymmetric", views(3)),
        ("sheet", "hp3-sheet", views(3)),
        ("profiler", "hp3-profiler", serde_json::json!({})),
        (
            "verify",
            "hp3-paper",
            serde_json::json!({"seed": 2, "poses": {"count": 2}, "scan": {"enabled": false}, "verify": {"enabled": true, "step_mm": 8.0}}),
        ),
        (
            "bench",
            "hp3-paper",
            serde_json::json!({"bench": {"enabled": true}}),
        ),
        (
            "colour",
            "hp3-paper",
            serde_json::json!({"poses": {"count": 2}, "scan": {"enabled": false}, "imaging": {"colour": true}}),
        ),
        (
            "big",
            "hp3-chessboard",
            serde_json::json!({"poses": {"count": 1}, "scan": {"enabled": false},
            "camera": {"width": 1928, "height": 1208, "u0": 964.0, "v0": 604.0},
            "board": {"rows": 17, "cols": 28, "pitch_mm": 3.0, "square_mm": 3.0}}),
        ),
    ];
    let only = std::env::args().nth(2);
    for (name, preset, over) in cases {
        if only.as_deref().is_some_and(|o| o != name) {
            continue;
        }
        let t = std::time::Instant::now();
        let cfg = match SimConfig::preset(preset).unwrap().with_overrides(&over) {
            Ok(c) => c,
            Err(e) => {
                eprintln!("{name}: {e}");
                continue;
            }
        };
        let twin = Twin::new(cfg).unwrap();
        match twin.write(&Path::new(&out).join(name), &mut |_, _, _| {}) {
            Ok(_) => println!("{name}: {:.2} s", t.elapsed().as_secs_f64()),
            Err(e) => println!("{name}: error {e}"),
        }
    }
}
