//! The extractor on a SYMMETRIC stripe (a Gaussian of sigma SIGMA px, the first
//! argument, default 1.2, integrated over each pixel, 16 bits, area 60 000 on a flat
//! 3 000 background, the centre's pixel phase swept over the rows) with noise of 2 gray
//! levels (514 in 16 bits): the mean and median of (found - true) centre over DRAWS noisy
//! images (the second argument, default 20), against the noise-free image. Any shift is
//! the extraction's own, not a profile's. Formerly the ignored test
//! `stripe_bias::noise_on_a_symmetric_stripe` of the twin's integration tests (its knobs
//! `STRIPE_SYM_SIGMA`, `STRIPE_SYM_DRAWS`).

fn main() {
    use stripecal::model::image::{AnyView, ImageView};
    use stripecal::numerics::rng::SplitMix64;
    use stripecal::vision::stripe::{extract_stripe, StripeDirection, StripeOptions};
    let args: Vec<String> = std::env::args().skip(1).collect();
    let sigma: f64 = args.first().map_or(1.2, |a| a.parse().unwrap());
    let draws: usize = args.get(1).map_or(20, |a| a.parse().unwrap());
    let (w, h) = (128usize, 2000usize);
    let centre = |row: usize| 60.0 + 0.0137 * row as f64;
    let erf = |x: f64| {
        let t = 1.0 / (1.0 + 0.327_591_1 * x.abs());
        let y = 1.0
            - (((((1.061_405_429 * t - 1.453_152_027) * t) + 1.421_413_741) * t - 0.284_496_736)
                * t
                + 0.254_829_592)
                * t
                * (-x * x).exp();
        if x < 0.0 {
            -y
        } else {
            y
        }
    };
    let clean: Vec<f64> = (0..w * h)
        .map(|k| {
            let (x, row) = ((k % w) as f64, k / w);
            let s = std::f64::consts::SQRT_2 * sigma;
            let c = centre(row);
            // 60 000 times the Gaussian's share of the pixel (its area 1).
            3000.0 + 60000.0 * 0.5 * (erf((x + 0.5 - c) / s) - erf((x - 0.5 - c) / s))
        })
        .collect();
    let opts = StripeOptions {
        direction: StripeDirection::Cols,
        ..Default::default()
    };
    let errors = |noise: f64, seed: u64| -> Vec<f64> {
        let mut rng = SplitMix64(seed);
        let data: Vec<u16> = clean
            .iter()
            .map(|&v| (v + noise * rng.normal()).round().clamp(0.0, 65535.0) as u16)
            .collect();
        let img = ImageView::from_slice(&data, w, h).unwrap();
        let s = extract_stripe(AnyView::U16(img), &opts).unwrap();
        s.points
            .iter()
            .map(|p| p.u - centre(p.v.round() as usize))
            .collect()
    };
    let e0 = errors(0.0, 1);
    let m0 = e0.iter().sum::<f64>() / e0.len() as f64;
    let mut all = Vec::new();
    for d in 0..draws {
        all.extend(errors(514.0, 100 + d as u64));
    }
    let n = all.len() as f64;
    let mean = all.iter().sum::<f64>() / n;
    let sd = (all.iter().map(|e| (e - mean).powi(2)).sum::<f64>() / n).sqrt();
    all.sort_by(f64::total_cmp);
    println!(
        "  SYM sigma {sigma} px: noise-free mean error {m0:+.5} px over {} rows; noisy mean \
         {mean:+.5} +- {:.5} px, median {:+.5} px, sd {sd:.4} px over {} points",
        e0.len(),
        sd / n.sqrt(),
        all[all.len() / 2],
        all.len()
    );
}
