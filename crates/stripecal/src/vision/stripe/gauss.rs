//! The Gaussian centre of a stripe profile: a Gauss-Newton fit of
//! `A exp(-(x - c)^2 / 2 s^2)` to the background-free residuals around the centroid.

/// Gauss-Newton fit of `A exp(-(x - c)^2 / 2 s^2)` to the residuals `res` over
/// `c +- (h + 1)`.
pub(super) fn gauss_fit(
    res: &[f32],
    c0: f32,
    a0: f32,
    w: f32,
    h: f32,
    xmin: usize,
    xmax: usize,
) -> Option<f64> {
    let i0 = ((c0 - h - 1.0).round().max(xmin as f32)) as usize;
    let i1 = ((c0 + h + 1.0).round().min(xmax as f32)) as usize;
    if i1 < i0 + 3 {
        return None;
    }
    let (mut amp, mut c, mut s) = (a0 as f64, c0 as f64, (w / 2.3548).max(0.3) as f64);
    for _ in 0..10 {
        let mut jtj = [[0.0f64; 3]; 3];
        let mut jtr = [0.0f64; 3];
        for (i, &v) in res.iter().enumerate().take(i1 + 1).skip(i0) {
            let x = i as f64;
            let y = v as f64;
            let t = (x - c) / s;
            let e = (-0.5 * t * t).exp();
            let f = amp * e;
            let j = [e, f * t / s, f * t * t / s];
            let res = y - f;
            for r in 0..3 {
                jtr[r] += j[r] * res;
                for q in 0..3 {
                    jtj[r][q] += j[r] * j[q];
                }
            }
        }
        let delta = solve3(&jtj, &jtr)?;
        amp += delta[0];
        c += delta[1];
        s += delta[2];
        if !(amp > 0.0 && s > 0.2 && s < w as f64 && (c - c0 as f64).abs() < 0.5 * w as f64) {
            return None;
        }
        if delta[1].abs() < 1e-5 {
            return Some(c);
        }
    }
    Some(c)
}

/// Solves a 3x3 symmetric system (Cramer's rule); `None` when singular.
fn solve3(a: &[[f64; 3]; 3], b: &[f64; 3]) -> Option<[f64; 3]> {
    let det = |m: &[[f64; 3]; 3]| {
        m[0][0] * (m[1][1] * m[2][2] - m[1][2] * m[2][1])
            - m[0][1] * (m[1][0] * m[2][2] - m[1][2] * m[2][0])
            + m[0][2] * (m[1][0] * m[2][1] - m[1][1] * m[2][0])
    };
    let d = det(a);
    if !d.is_finite() || d.abs() <= 1e-12 {
        return None;
    }
    let mut out = [0.0; 3];
    for (k, o) in out.iter_mut().enumerate() {
        let mut m = *a;
        for r in 0..3 {
            m[r][k] = b[r];
        }
        *o = det(&m) / d;
    }
    Some(out)
}
