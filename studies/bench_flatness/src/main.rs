//! The bench mode's flatness figures on the twin (docs/flatness.md, "Measured on the
//! twin"): hp3-paper in bench mode, 15 views (3 partial), view 4 bent by 1 mm about
//! board y, seeds 1..=3 (or the seeds given as arguments); per view its circles detected
//! in the rendered image and `calib::flatness::view_flatness` from the true pose.
//! Formerly the ignored test `flatness_figures_three_seeds` of
//! crates/stripecal-sim/tests/it/bench_twin.rs.

use stripecal::calib::flatness::{view_flatness, FlatnessOptions};
use stripecal::calib::CircleObs;
use stripecal::vision::target::{detect_target, TargetOptions};
use stripecal_sim::{SimConfig, Twin};

/// The bench twin of `seed`: 15 views, 3 partial, view 4 bent by 1 mm about board y.
fn twin(seed: u64) -> Twin {
    let bench = serde_json::json!({"enabled": true, "views": 15, "partial_views": 3,
        "bow": {"views": [4], "sag_mm": 1.0, "axis_deg": 90.0}});
    let cfg = SimConfig::hp3_paper()
        .with_overrides(&serde_json::json!({"seed": seed, "bench": bench}))
        .unwrap();
    Twin::new(cfg).unwrap()
}

/// Prints every view's flatness figure of the twin of `seed`.
fn figures(seed: u64) {
    let tw = twin(seed);
    for (i, v) in tw.bench_views().unwrap().iter().enumerate() {
        let r = tw.render_bench_view(v, i).unwrap();
        let d = match detect_target(
            r.board_image.view().unwrap(),
            &tw.board,
            &TargetOptions::default(),
        ) {
            Ok(d) => d,
            Err(e) => {
                println!("seed {seed} view {i}: not detected: {e}");
                continue;
            }
        };
        let obs: Vec<CircleObs> = d
            .points
            .iter()
            .map(|p| CircleObs {
                row: p.row,
                col: p.col,
                u: p.u,
                v: p.v,
            })
            .collect();
        let kind = if v.bow.is_some() {
            "BENT"
        } else if v.partial {
            "part"
        } else {
            "flat"
        };
        match view_flatness(
            &tw.camera,
            &tw.board,
            &obs,
            &v.cam_board,
            &FlatnessOptions::default(),
        ) {
            Ok(f) => println!(
                "seed {seed} view {i:2} {kind} pts {:2} depth {:5.1} tilt {:4.1}: sag {:+.4} +- {:.4} mm ({:5.1} sigma) axis {:+6.1} W {:.1}",
                f.points, v.standoff_mm, v.tilt_deg, f.sag_mm, f.sigma_mm, f.significance(), f.axis_deg, f.width_mm
            ),
            Err(e) => println!("seed {seed} view {i}: {e}"),
        }
    }
}

fn main() {
    let seeds: Vec<u64> = std::env::args()
        .skip(1)
        .map(|a| a.parse().expect("a seed"))
        .collect();
    for seed in if seeds.is_empty() {
        vec![1, 2, 3]
    } else {
        seeds
    } {
        figures(seed);
    }
}
