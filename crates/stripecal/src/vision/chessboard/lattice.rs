//! Lattice bookkeeping shared by the growth and the later stages: integer coordinates
//! of nodes, the local affine model of the lattice around a position, a bucket index
//! of points, and the chessboard colour of a cell.

use crate::vision::affine::{neighbourhood, spans_plane};
pub(crate) use crate::vision::coord::{Coord, CoordMap, CoordSet};

/// Local affine model of the lattice: image position of a lattice site and the image
/// vectors of one step along `+i` and `+j`.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Local {
    pub p: [f64; 2],
    pub di: [f64; 2],
    pub dj: [f64; 2],
}

impl Local {
    /// The shorter of the two steps, px.
    pub fn pitch(&self) -> f64 {
        norm(self.di).min(norm(self.dj))
    }
}

#[inline]
pub(crate) fn norm(a: [f64; 2]) -> f64 {
    (a[0] * a[0] + a[1] * a[1]).sqrt()
}

#[inline]
pub(crate) fn cross(a: [f64; 2], b: [f64; 2]) -> f64 {
    a[0] * b[1] - a[1] * b[0]
}

/// Weighted affine fit of the sites within Chebyshev radius `rad` of `t` (`t` itself
/// excluded) to their positions `pos[node]`: the predicted [`Local`] at `t`. `None`
/// with fewer than 3 sites or collinear ones.
pub(crate) fn predict(at: &CoordMap<usize>, pos: &[[f64; 2]], t: Coord, rad: i32) -> Option<Local> {
    let mut n = [[0f64; 3]; 3];
    let mut bx = [0f64; 3];
    let mut by = [0f64; 3];
    let mut count = 0;
    // (the products in this order, `wgt * f[r] * f[c]`: the circles' AffineFit rounds
    // differently, and the corners must stay bit for bit)
    for (di, dj) in neighbourhood(rad) {
        let Some(&k) = at.get(&(t.0 + di, t.1 + dj)) else {
            continue;
        };
        let p = *pos.get(k)?;
        let wgt = 1.0 / (di * di + dj * dj) as f64;
        let f = [di as f64, dj as f64, 1.0];
        for r in 0..3 {
            for c in 0..3 {
                n[r][c] += wgt * f[r] * f[c];
            }
            bx[r] += wgt * f[r] * p[0];
            by[r] += wgt * f[r] * p[1];
        }
        count += 1;
    }
    if count < 3 {
        return None;
    }
    let m = nalgebra::Matrix3::from_fn(|r, c| n[r][c]);
    if !spans_plane(&m) {
        return None;
    }
    let inv = m.try_inverse()?;
    let px = inv * nalgebra::Vector3::from(bx);
    let py = inv * nalgebra::Vector3::from(by);
    let out = Local {
        p: [px[2], py[2]],
        di: [px[0], py[0]],
        dj: [px[1], py[1]],
    };
    (out.p[0].is_finite() && out.p[1].is_finite() && out.pitch() > 1e-6).then_some(out)
}

/// [`predict`] from radius 2, else radius 3.
pub(crate) fn predict_any(at: &CoordMap<usize>, pos: &[[f64; 2]], t: Coord) -> Option<Local> {
    predict(at, pos, t, 2).or_else(|| predict(at, pos, t, 3))
}

/// Whether lattice cell `(i, j)` (between sites `(i, j)` and `(i + 1, j + 1)`) is dark
/// for colour phase `phase`.
#[inline]
pub(crate) fn cell_dark(i: i32, j: i32, phase: u8) -> bool {
    (i as i64 + j as i64 + phase as i64).rem_euclid(2) == 0
}

/// Bounding box of the sites: `(imin, imax, jmin, jmax)`.
pub(crate) fn extent<'a>(keys: impl Iterator<Item = &'a Coord>) -> Option<(i32, i32, i32, i32)> {
    let mut e: Option<(i32, i32, i32, i32)> = None;
    for &(i, j) in keys {
        e = Some(match e {
            None => (i, i, j, j),
            Some((a, b, c, d)) => (a.min(i), b.max(i), c.min(j), d.max(j)),
        });
    }
    e
}

/// A bucket index of points for radius queries.
pub(crate) struct Buckets {
    size: f64,
    nx: usize,
    ny: usize,
    start: Vec<u32>,
    items: Vec<u32>,
}

impl Buckets {
    /// Index of `pts` in a `w x h` area with buckets of `size` px.
    pub fn new(pts: &[[f64; 2]], w: usize, h: usize, size: f64) -> Buckets {
        let nx = (w as f64 / size).ceil().max(1.0) as usize;
        let ny = (h as f64 / size).ceil().max(1.0) as usize;
        let cell = |p: &[f64; 2]| {
            let cx = ((p[0] / size).floor().max(0.0) as usize).min(nx - 1);
            let cy = ((p[1] / size).floor().max(0.0) as usize).min(ny - 1);
            cy * nx + cx
        };
        let mut count = vec![0u32; nx * ny + 1];
        for p in pts {
            count[cell(p) + 1] += 1;
        }
        for k in 1..count.len() {
            count[k] += count[k - 1];
        }
        let mut fill = count.clone();
        let mut items = vec![0u32; pts.len()];
        for (k, p) in pts.iter().enumerate() {
            let c = cell(p);
            items[fill[c] as usize] = k as u32;
            fill[c] += 1;
        }
        Buckets {
            size,
            nx,
            ny,
            start: count,
            items,
        }
    }

    /// Calls `f(index)` for every point in the buckets overlapping the square of
    /// half-side `r` around `p` (the caller checks the distance).
    pub fn visit(&self, p: [f64; 2], r: f64, mut f: impl FnMut(usize)) {
        if !(p[0].is_finite() && p[1].is_finite() && r.is_finite()) {
            return;
        }
        let lo = |v: f64| ((v - r) / self.size).floor().max(0.0) as usize;
        let hi = |v: f64, n: usize| (((v + r) / self.size).floor().max(0.0) as usize).min(n - 1);
        let (x0, x1) = (lo(p[0]).min(self.nx - 1), hi(p[0], self.nx));
        let (y0, y1) = (lo(p[1]).min(self.ny - 1), hi(p[1], self.ny));
        for cy in y0..=y1 {
            for cx in x0..=x1 {
                let c = cy * self.nx + cx;
                let (a, b) = (self.start[c] as usize, self.start[c + 1] as usize);
                for &k in &self.items[a..b] {
                    f(k as usize);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn predict_recovers_an_affine_lattice() {
        let mut at = CoordMap::default();
        let mut pos = Vec::new();
        for i in -1..=1 {
            for j in -1..=1 {
                if (i, j) == (0, 0) {
                    continue;
                }
                at.insert((i, j), pos.len());
                pos.push([
                    10.0 + 3.0 * i as f64 - j as f64,
                    20.0 + i as f64 + 4.0 * j as f64,
                ]);
            }
        }
        let l = predict(&at, &pos, (0, 0), 1).unwrap();
        assert!((l.p[0] - 10.0).abs() < 1e-9 && (l.p[1] - 20.0).abs() < 1e-9);
        assert!((l.di[0] - 3.0).abs() < 1e-9 && (l.dj[1] - 4.0).abs() < 1e-9);
    }

    #[test]
    fn buckets_visit_nearby_points() {
        let pts = [[1.0, 1.0], [50.0, 50.0], [99.0, 99.0]];
        let b = Buckets::new(&pts, 100, 100, 16.0);
        let mut seen = Vec::new();
        b.visit([52.0, 48.0], 5.0, |k| seen.push(k));
        assert_eq!(seen, vec![1]);
        seen.clear();
        b.visit([f64::NAN, 0.0], 5.0, |k| seen.push(k));
        assert!(seen.is_empty());
    }
}
