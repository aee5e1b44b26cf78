//! Renders a dataset of a preset: `cargo run --release -p stripecal-sim --example
//! render_dataset -- PRESET OUT [OVERRIDES_JSON]`; prints the folders and the time.

use stripecal_sim::{SimConfig, Twin};

fn main() {
    let args: Vec<String> = std::env::args().collect();
    if args.len() < 3 {
        eprintln!("usage: render_dataset PRESET OUT [OVERRIDES_JSON]");
        std::process::exit(2);
    }
    let mut cfg = SimConfig::preset(&args[1]).expect("preset");
    if let Some(o) = args.get(3) {
        let v: serde_json::Value = serde_json::from_str(o).expect("overrides JSON");
        cfg = cfg.with_overrides(&v).expect("overrides");
    }
    let twin = Twin::new(cfg).expect("twin");
    let t0 = std::time::Instant::now();
    let s = twin
        .write(std::path::Path::new(&args[2]), &mut |_, _, _| {})
        .expect("write");
    println!("{s:#?}");
    println!("seconds: {:.1}", t0.elapsed().as_secs_f64());
}
