//! The sphere's arc in one profile: a robust circle fit in the profile plane.
//!
//! A profile of a sphere (points `(x, z)` in the sensor's plane y = 0) holds the circle
//! where the laser plane cuts the sphere, of radius `r = sqrt(R^2 - y0^2)` (`y0` the
//! plane's offset from the sphere's centre), beside points of other things (the table,
//! the stand, spikes). The profiler looks at the sphere from its near side, so the arc
//! it sees lies between the sensor and the circle's centre: `z < cz` on the arc.
//!
//! ## Method
//!
//! RANSAC over circles through three points (sorted along x, at least
//! [`MIN_SAMPLE_SPAN_MM`] apart), scored on a subsample by the points within a band of
//! the circle on its near side; circles larger than the sphere allows (`max_radius`)
//! are refused, so a straight stretch of table never wins. The best circle is refined
//! by Gauss-Newton on the geometric distance `|p - c| - r` over its points, and the
//! points re-selected within [`BAND_SIGMAS`] robust sigmas (`1.4826 MAD`, at least
//! [`MIN_BAND_MM`]) until the selection settles. Deterministic: the samples come from
//! a fixed-seed generator.

use crate::numerics::rng::SplitMix64;

/// RANSAC samples per profile.
const SAMPLES: usize = 256;
/// Points scored per sample (a subsample of the profile).
const SCORED: usize = 300;
/// The three points of a sample lie at least this far apart along x, mm.
pub const MIN_SAMPLE_SPAN_MM: f64 = 2.0;
/// Half-width of RANSAC's inlier band, mm (a coarse band: the refinement narrows it).
const RANSAC_BAND_MM: f64 = 0.25;
/// The refined selection keeps points within this many robust sigmas of the circle.
pub const BAND_SIGMAS: f64 = 5.0;
/// ... and never narrower than this, mm.
pub const MIN_BAND_MM: f64 = 0.003;

/// The arc found in one profile.
#[derive(Debug, Clone, PartialEq)]
pub struct Arc {
    /// The circle's centre `(x, z)` in the sensor frame, mm.
    pub centre: [f64; 2],
    pub radius: f64,
    /// Indices (into the profile's points) of the arc's points.
    pub inliers: Vec<usize>,
    /// RMS of the arc's points' distances from the circle, mm.
    pub rms_mm: f64,
    /// Extent of the arc's points along x, mm.
    pub span_mm: f64,
    /// Where the circle's centre lies from the arc along z: +1 beyond it (`cz > z`, z
    /// counts away from the sensor), -1 (z counts towards the sensor).
    pub side: f64,
}

/// What may be accepted as the sphere's arc.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ArcOptions {
    /// The largest circle a plane can cut from the sphere (its radius, with a margin);
    /// without a declared diameter a bound on any sphere the profiler can see.
    pub max_radius: f64,
    /// The fewest points an arc may have.
    pub min_points: usize,
    /// The shortest extent along x, mm.
    pub min_span_mm: f64,
    /// The least depth of the arc (sagitta over its extent), mm: a straight stretch is
    /// no arc.
    pub min_sagitta_mm: f64,
    /// The arc's [`Arc::side`] when known (`None`: either, each sample's own).
    pub side: Option<f64>,
}

impl Default for ArcOptions {
    fn default() -> Self {
        ArcOptions {
            max_radius: 1000.0,
            min_points: 30,
            min_span_mm: 4.0,
            min_sagitta_mm: 0.3,
            side: None,
        }
    }
}

/// Why no arc was accepted.
#[derive(Debug, Clone, PartialEq)]
pub enum NoArc {
    TooFewPoints(usize),
    /// No circle of the allowed size has enough points near it.
    NotFound,
    /// The best circle's arc is too short or too flat to be the sphere's.
    TooFlat {
        span_mm: f64,
        sagitta_mm: f64,
    },
}

impl std::fmt::Display for NoArc {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            NoArc::TooFewPoints(n) => write!(f, "only {n} points in the profile"),
            NoArc::NotFound => write!(
                f,
                "no arc of the sphere in the profile (no circle of the sphere's size has \
                 enough points on it: the line misses the sphere?)"
            ),
            NoArc::TooFlat {
                span_mm,
                sagitta_mm,
            } => write!(
                f,
                "the best arc is too short or too flat to be the sphere's ({span_mm:.2} mm \
                 long, {sagitta_mm:.3} mm deep)"
            ),
        }
    }
}

/// The circle through three points `(x, z)`; `None` when they are (nearly) collinear.
fn circle_through(a: [f64; 2], b: [f64; 2], c: [f64; 2]) -> Option<([f64; 2], f64)> {
    let (bx, bz) = (b[0] - a[0], b[1] - a[1]);
    let (cx, cz) = (c[0] - a[0], c[1] - a[1]);
    let d = 2.0 * (bx * cz - bz * cx);
    if d.abs() < 1e-12 {
        return None;
    }
    let (b2, c2) = (bx * bx + bz * bz, cx * cx + cz * cz);
    let ux = (cz * b2 - bz * c2) / d;
    let uz = (bx * c2 - cx * b2) / d;
    let r = (ux * ux + uz * uz).sqrt();
    Some(([a[0] + ux, a[1] + uz], r))
}

/// Gauss-Newton on `|p - c| - r` over `pts[idx]`; the refined circle.
fn refine(pts: &[[f64; 2]], idx: &[usize], centre: [f64; 2], radius: f64) -> ([f64; 2], f64) {
    let (mut c, mut r) = (centre, radius);
    for _ in 0..8 {
        let mut n = [[0.0; 3]; 3];
        let mut g = [0.0; 3];
        for &i in idx {
            let (dx, dz) = (pts[i][0] - c[0], pts[i][1] - c[1]);
            let d = (dx * dx + dz * dz).sqrt().max(1e-12);
            let e = d - r;
            let j = [-dx / d, -dz / d, -1.0];
            for a in 0..3 {
                g[a] += j[a] * e;
                for b in 0..3 {
                    n[a][b] += j[a] * j[b];
                }
            }
        }
        let Some(step) = solve3(&n, &g) else { break };
        c[0] -= step[0];
        c[1] -= step[1];
        r -= step[2];
        if step.iter().map(|s| s.abs()).fold(0.0, f64::max) < 1e-10 {
            break;
        }
    }
    (c, r)
}

/// `N x = g` for a 3 x 3 symmetric positive definite `N` (LU); `None` if singular.
fn solve3(n: &[[f64; 3]; 3], g: &[f64; 3]) -> Option<[f64; 3]> {
    let m = nalgebra::Matrix3::from_fn(|i, j| n[i][j]);
    let x = m.lu().solve(&nalgebra::Vector3::new(g[0], g[1], g[2]))?;
    x.iter().all(|v| v.is_finite()).then(|| [x[0], x[1], x[2]])
}

/// The points of `pts` within `band` of the circle, on its near side (`side (z - cz) <
/// 0`).
fn near(pts: &[[f64; 2]], centre: [f64; 2], radius: f64, band: f64, side: f64) -> Vec<usize> {
    (0..pts.len())
        .filter(|&i| {
            let (dx, dz) = (pts[i][0] - centre[0], pts[i][1] - centre[1]);
            side * dz < 0.0 && ((dx * dx + dz * dz).sqrt() - radius).abs() < band
        })
        .collect()
}

/// The sphere's arc in a profile (module docs); `seed` makes the samples reproducible.
pub fn find_arc(pts: &[[f64; 2]], opts: &ArcOptions, seed: u64) -> Result<Arc, NoArc> {
    if pts.len() < opts.min_points.max(3) {
        return Err(NoArc::TooFewPoints(pts.len()));
    }
    let mut order: Vec<usize> = (0..pts.len()).collect();
    order.sort_by(|&a, &b| pts[a][0].total_cmp(&pts[b][0]));
    let stride = (pts.len() / SCORED).max(1);
    let scored: Vec<[f64; 2]> = order.iter().step_by(stride).map(|&i| pts[i]).collect();
    let mut rng = SplitMix64(seed ^ 0x9e37_79b9_7f4a_7c15);
    let n = order.len();
    let mut best: Option<(usize, [f64; 2], f64, f64)> = None;
    for _ in 0..SAMPLES {
        let mut s = [rng.below(n), rng.below(n), rng.below(n)];
        s.sort_unstable();
        let [a, b, c] = s.map(|k| pts[order[k]]);
        if b[0] - a[0] < 0.5 * MIN_SAMPLE_SPAN_MM || c[0] - b[0] < 0.5 * MIN_SAMPLE_SPAN_MM {
            continue;
        }
        let Some((centre, r)) = circle_through(a, b, c) else {
            continue;
        };
        // the sample's own side: the centre lies beyond its middle point
        let side = (centre[1] - b[1]).signum();
        if r > opts.max_radius || opts.side.is_some_and(|s| s != side) {
            continue;
        }
        let score = scored
            .iter()
            .filter(|p| {
                let (dx, dz) = (p[0] - centre[0], p[1] - centre[1]);
                side * dz < 0.0 && ((dx * dx + dz * dz).sqrt() - r).abs() < RANSAC_BAND_MM
            })
            .count();
        if best.is_none_or(|(s, _, _, _)| score > s) {
            best = Some((score, centre, r, side));
        }
    }
    let Some((score, mut centre, mut radius, side)) = best else {
        return Err(NoArc::NotFound);
    };
    if score * stride < opts.min_points {
        return Err(NoArc::NotFound);
    }
    let mut inliers = near(pts, centre, radius, RANSAC_BAND_MM, side);
    for _ in 0..4 {
        if inliers.len() < opts.min_points {
            return Err(NoArc::NotFound);
        }
        (centre, radius) = refine(pts, &inliers, centre, radius);
        let mut dev: Vec<f64> = inliers
            .iter()
            .map(|&i| {
                let (dx, dz) = (pts[i][0] - centre[0], pts[i][1] - centre[1]);
                ((dx * dx + dz * dz).sqrt() - radius).abs()
            })
            .collect();
        dev.sort_by(f64::total_cmp);
        let sigma = 1.4826 * dev[dev.len() / 2];
        let band = (BAND_SIGMAS * sigma).max(MIN_BAND_MM);
        let next = near(pts, centre, radius, band, side);
        let settled = next == inliers;
        inliers = next;
        if settled {
            break;
        }
    }
    if inliers.len() < opts.min_points || radius > opts.max_radius {
        return Err(NoArc::NotFound);
    }
    (centre, radius) = refine(pts, &inliers, centre, radius);
    let (lo, hi) = inliers.iter().fold((f64::MAX, f64::MIN), |(lo, hi), &i| {
        (lo.min(pts[i][0]), hi.max(pts[i][0]))
    });
    let span = hi - lo;
    let half = (0.5 * span).min(radius);
    let sagitta = radius - (radius * radius - half * half).max(0.0).sqrt();
    if span < opts.min_span_mm || sagitta < opts.min_sagitta_mm {
        return Err(NoArc::TooFlat {
            span_mm: span,
            sagitta_mm: sagitta,
        });
    }
    let ss: f64 = inliers
        .iter()
        .map(|&i| {
            let (dx, dz) = (pts[i][0] - centre[0], pts[i][1] - centre[1]);
            ((dx * dx + dz * dz).sqrt() - radius).powi(2)
        })
        .sum();
    Ok(Arc {
        centre,
        radius,
        rms_mm: (ss / inliers.len() as f64).sqrt(),
        inliers,
        span_mm: span,
        side,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A profile of a sphere of radius 40 cut 20 mm from its centre (circle radius
    /// 34.64), its centre at (5, 300), a table at z = 340 beside it, noise 0.01 and
    /// spikes: the arc is found with its points, the table's and the spikes left out.
    #[test]
    fn finds_the_sphere_beside_the_table_and_spikes() {
        let (cx, cz, r) = (5.0, 300.0, (40.0f64 * 40.0 - 20.0 * 20.0).sqrt());
        let mut rng = SplitMix64(7);
        let mut pts = Vec::new();
        let mut on_arc = 0;
        let mut x = -45.0;
        while x <= 45.0 {
            let dx: f64 = x - cx;
            let mut z = if dx.abs() < r {
                on_arc += 1;
                cz - (r * r - dx * dx).sqrt()
            } else {
                340.0
            };
            z += 0.01 * rng.normal();
            if rng.uniform() < 0.01 {
                z += 2.0;
            }
            pts.push([x, z]);
            x += 0.03;
        }
        let arc = find_arc(&pts, &ArcOptions::default(), 1).unwrap();
        assert_eq!(arc.side, 1.0);
        assert!((arc.centre[0] - cx).abs() < 0.01, "{:?}", arc.centre);
        assert!((arc.centre[1] - cz).abs() < 0.01, "{:?}", arc.centre);
        assert!((arc.radius - r).abs() < 0.01, "{}", arc.radius);
        assert!(arc.rms_mm < 0.012, "{}", arc.rms_mm);
        // the arc's points (minus ~1 % spikes and the odd far noise) are kept
        assert!(arc.inliers.len() as f64 > 0.97 * on_arc as f64);
        assert!(arc.inliers.len() <= on_arc);
        // a vendor whose z counts towards the sensor: the same arc, the other side
        let flipped: Vec<[f64; 2]> = pts.iter().map(|p| [p[0], -p[1]]).collect();
        let arc2 = find_arc(&flipped, &ArcOptions::default(), 1).unwrap();
        assert_eq!(arc2.side, -1.0);
        assert!((arc2.centre[1] + cz).abs() < 0.01 && (arc2.radius - r).abs() < 0.01);
        assert_eq!(arc2.inliers, arc.inliers);
        let forced = ArcOptions {
            side: Some(1.0),
            ..ArcOptions::default()
        };
        assert!(find_arc(&flipped, &forced, 1).is_err());
        // a profile of the table alone has no arc
        let table: Vec<[f64; 2]> = (0..3000)
            .map(|i| [-45.0 + 0.03 * i as f64, 340.0 + 0.01 * rng.normal()])
            .collect();
        assert!(find_arc(&table, &ArcOptions::default(), 1).is_err());
    }
}
