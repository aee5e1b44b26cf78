//! Ball scans of the twin corrected for the stripe bias, one per run of a JSON list
//! `[[preset, overrides, every], ...]` (a file, `-` for stdin; `remainders.py runs`
//! writes it): each run's figures and one `SWEEP {json}` line (the errors and changes in
//! mm, full precision) that `remainders.py table` reads. `--true-model`: the correction
//! takes the twin's true sheet sigma, PSF sigma and emitter (the remainder is then the
//! model's own). Formerly the ignored test `stripe_bias::sweep` of the twin's
//! integration tests (its runs in `STRIPE_BIAS_RUNS`, `STRIPE_BIAS_TRUE_MODEL=1`).

use std::io::Read;

use stripe_bias_studies::run;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let known = args.iter().any(|a| a == "--true-model");
    let path = args
        .iter()
        .find(|a| *a != "--true-model")
        .expect("usage: sweep [--true-model] RUNS.json|-");
    let text = if path == "-" {
        let mut s = String::new();
        std::io::stdin().read_to_string(&mut s).unwrap();
        s
    } else {
        std::fs::read_to_string(path).unwrap()
    };
    let runs: Vec<(String, serde_json::Value, usize)> = serde_json::from_str(&text).unwrap();
    for (preset, over, every) in runs {
        let r = run(&preset, over.clone(), every, known);
        r.report(&format!("{preset} {over} every {every}"));
        let c = &r.corr;
        let truth_c = c.uncorrected.center_mm - r.c0;
        let e1 = c.fit.center_mm - truth_c;
        println!(
            "SWEEP {}",
            serde_json::json!({
                "preset": preset, "overrides": over, "every": every,
                "diameter_error_mm": [r.d0, r.d1()], "diameter_change_mm": c.diameter_change_mm,
                "diameter_systematic_mm": c.diameter_systematic_mm,
                "center_error_mm": [r.c0.as_slice(), e1.as_slice()],
                "center_change_mm": c.center_change_mm.as_slice(),
            })
        );
    }
}
