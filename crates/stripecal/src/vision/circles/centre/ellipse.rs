//! An ellipse fitted to edge points: an algebraic conic fit with `A + C = 1`, gradient
//! re-weighting towards the geometric fit and one round of outlier removal.

/// A fitted ellipse.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Ellipse {
    pub centre: [f64; 2],
    /// Semi-axes (major, minor), px.
    pub axes: [f64; 2],
    /// Angle of the major axis from +u towards +v, radians.
    pub angle: f64,
    /// RMS geometric residual of the edge points, px.
    pub rms: f64,
}

/// Conic `A x^2 + B xy + C y^2 + D x + E y + F = 0` in normalised coordinates.
type Conic = [f64; 6];

fn conic_eval(c: &Conic, x: f64, y: f64) -> (f64, f64) {
    let f = c[0] * x * x + c[1] * x * y + c[2] * y * y + c[3] * x + c[4] * y + c[5];
    let gx = 2.0 * c[0] * x + c[1] * y + c[3];
    let gy = c[1] * x + 2.0 * c[2] * y + c[4];
    (f, (gx * gx + gy * gy).sqrt())
}

/// Weighted algebraic fit with `A + C = 1`.
fn conic_fit(p: &[[f64; 2]], wts: &[f64]) -> Option<Conic> {
    let mut n = nalgebra::SMatrix::<f64, 5, 5>::zeros();
    let mut r = nalgebra::SVector::<f64, 5>::zeros();
    for (q, &wt) in p.iter().zip(wts) {
        if wt <= 0.0 {
            continue;
        }
        let (x, y) = (q[0], q[1]);
        let f = nalgebra::SVector::<f64, 5>::from([x * x - y * y, x * y, x, y, 1.0]);
        n += f * f.transpose() * wt;
        r += f * (-y * y) * wt;
    }
    let s = n.cholesky()?.solve(&r);
    Some([s[0], s[1], 1.0 - s[0], s[2], s[3], s[4]])
}

/// Fits an ellipse to edge points (px) with `rounds` (at least 2) of gradient
/// re-weighting, the second with outlier removal; `None` if too few points or not an
/// ellipse.
pub(crate) fn fit_ellipse(pts: &[[f64; 2]], rounds: usize) -> Option<Ellipse> {
    if pts.len() < 10 {
        return None;
    }
    let n = pts.len() as f64;
    let mx = pts.iter().map(|p| p[0]).sum::<f64>() / n;
    let my = pts.iter().map(|p| p[1]).sum::<f64>() / n;
    let scale = (pts
        .iter()
        .map(|p| (p[0] - mx).powi(2) + (p[1] - my).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    if scale.is_nan() || scale <= 1e-9 {
        return None;
    }
    let q: Vec<[f64; 2]> = pts
        .iter()
        .map(|p| [(p[0] - mx) / scale, (p[1] - my) / scale])
        .collect();
    let mut wts = vec![1.0; q.len()];
    let mut c = conic_fit(&q, &wts)?;
    let mut dropped = false;
    for it in 0..rounds.max(2) {
        // gradient re-weighting (Sampson-like), and one round of outlier removal
        let mut res = Vec::with_capacity(q.len());
        for (p, wt) in q.iter().zip(wts.iter_mut()) {
            let (f, g) = conic_eval(&c, p[0], p[1]);
            if *wt > 0.0 {
                *wt = 1.0 / (g * g).max(1e-12);
                res.push((f / g.max(1e-12)).abs());
            } else {
                res.push(f64::INFINITY);
            }
        }
        if it == 1 && !dropped {
            let used: Vec<f64> = res.iter().copied().filter(|r| r.is_finite()).collect();
            let rms = (used.iter().map(|r| r * r).sum::<f64>() / used.len() as f64).sqrt();
            let lim = 3.0 * rms.max(0.05 / scale);
            for (wt, r) in wts.iter_mut().zip(&res) {
                if *r > lim {
                    *wt = 0.0;
                }
            }
            dropped = true;
            if wts.iter().filter(|&&w| w > 0.0).count() < 10 {
                return None;
            }
        }
        c = conic_fit(&q, &wts)?;
    }
    let disc = 4.0 * c[0] * c[2] - c[1] * c[1];
    if disc.is_nan() || disc <= 0.0 {
        return None;
    }
    // centre: [2A B; B 2C] x = -[D; E]
    let xc = (c[1] * c[4] - 2.0 * c[2] * c[3]) / disc;
    let yc = (c[1] * c[3] - 2.0 * c[0] * c[4]) / disc;
    // axes: translate to the centre, F' = F + (D xc + E yc) / 2
    let f0 = c[5] + 0.5 * (c[3] * xc + c[4] * yc);
    let m = nalgebra::Matrix2::new(c[0], 0.5 * c[1], 0.5 * c[1], c[2]);
    let eig = m.symmetric_eigen();
    let (l0, l1) = (eig.eigenvalues[0], eig.eigenvalues[1]);
    if !(-f0 / l0 > 0.0 && -f0 / l1 > 0.0) {
        return None;
    }
    let (s0, s1) = ((-f0 / l0).sqrt(), (-f0 / l1).sqrt());
    let (major, minor, k) = if s0 >= s1 { (s0, s1, 0) } else { (s1, s0, 1) };
    let v = eig.eigenvectors.column(k);
    let mut angle = v[1].atan2(v[0]);
    if angle < -std::f64::consts::FRAC_PI_2 {
        angle += std::f64::consts::PI;
    } else if angle > std::f64::consts::FRAC_PI_2 {
        angle -= std::f64::consts::PI;
    }
    let mut ss = 0.0;
    let mut cnt = 0.0;
    for (p, &wt) in q.iter().zip(&wts) {
        if wt > 0.0 {
            let (f, g) = conic_eval(&c, p[0], p[1]);
            ss += (f / g.max(1e-12)).powi(2);
            cnt += 1.0;
        }
    }
    Some(Ellipse {
        centre: [mx + xc * scale, my + yc * scale],
        axes: [major * scale, minor * scale],
        angle,
        rms: (ss / cnt).sqrt() * scale,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ellipse_fit_recovers_a_rotated_ellipse() {
        let (cx, cy, a, b, th) = (31.3, -7.25, 12.0, 5.5, 0.6f64);
        let pts: Vec<[f64; 2]> = (0..60)
            .map(|k| {
                let t = std::f64::consts::TAU * k as f64 / 60.0;
                let (x, y) = (a * t.cos(), b * t.sin());
                [
                    cx + x * th.cos() - y * th.sin(),
                    cy + x * th.sin() + y * th.cos(),
                ]
            })
            .collect();
        let e = fit_ellipse(&pts, 4).unwrap();
        assert!((e.centre[0] - cx).abs() < 1e-9 && (e.centre[1] - cy).abs() < 1e-9);
        assert!((e.axes[0] - a).abs() < 1e-9 && (e.axes[1] - b).abs() < 1e-9);
        assert!((e.angle - th).abs() < 1e-9, "{}", e.angle);
        assert!(e.rms < 1e-9);
        assert!(fit_ellipse(&pts[..5], 4).is_none());
    }
}
