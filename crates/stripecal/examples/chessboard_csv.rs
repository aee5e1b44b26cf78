//! Prints the chessboard corners detected in every view of a dataset folder as CSV
//! (`image,row,col,u,v`), for comparisons with other detectors; refusals and dropped
//! corners go to stderr.
//!
//! `cargo run --release -p stripecal --example chessboard_csv -- <dataset folder>`

use std::path::Path;

use stripecal::io::{load_gray, read_rig};
use stripecal::vision::chessboard::{detect_chessboard, ChessboardOptions};

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = std::env::args()
        .nth(1)
        .ok_or("usage: chessboard_csv <dataset folder>")?;
    let dir = Path::new(&dir);
    let rig = read_rig(dir.join("rig.json"))?;
    let views = std::fs::read_to_string(dir.join("views.csv"))?;
    println!("image,row,col,u,v");
    for line in views.lines().skip(1).filter(|l| !l.trim().is_empty()) {
        let name = line.split(',').next().unwrap_or_default();
        let img = load_gray(dir.join(name))?;
        match detect_chessboard(img.view()?, &rig.board, &ChessboardOptions::default()) {
            Ok(d) => {
                for p in &d.points {
                    println!("{name},{},{},{:.4},{:.4}", p.row, p.col, p.u, p.v);
                }
                for x in &d.dropped {
                    eprintln!(
                        "{name}: dropped ({}, {}) at ({:.0}, {:.0}): {}",
                        x.row, x.col, x.u, x.v, x.reason
                    );
                }
            }
            Err(e) => eprintln!("{name}: {e}"),
        }
    }
    Ok(())
}
